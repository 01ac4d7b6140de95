//! [`SeededRng`]: the generator for *content* (procedural trees, bushes, rocks, scattered
//! forests), whose output stream is part of what a seed means.
//!
//! Statistics (the Monte Carlo reference, property tests, fuzzing) use `fastrand`. Content
//! does not, because a seed written in a scene file must give the same tree after
//! `cargo update`: fastrand changed its stream in a minor release (2.1.0, "the algorithm
//! emits different constants for different seeds", see its changelog), and every demo
//! image, bench scene and flythrough would have changed with it. This generator's stream
//! is pinned by a known-answer test.

/// xorshift64* (Marsaglia's xorshift with Vigna's multiplier), seeded through one
/// multiplication by the golden ratio so that nearby seeds give unrelated streams.
/// Deterministic and identical on every platform.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SeededRng(u64);

impl SeededRng {
    /// The generator for `seed` (any value, zero included).
    pub const fn new(seed: u64) -> Self {
        Self(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }

    /// The next 64 raw bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    /// Uniform in `[0, 1)`, 24 bits.
    pub fn f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }

    /// Uniform in `[lo, hi)`.
    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.f32()
    }

    /// A uniformly distributed unit vector (Archimedes: uniform height, uniform angle).
    pub fn unit(&mut self) -> glam::Vec3 {
        let z = self.range(-1.0, 1.0);
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = self.range(0.0, std::f32::consts::TAU);
        glam::Vec3::new(r * phi.cos(), z, r * phi.sin())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The stream is part of the content: these values must never change.
    #[test]
    fn known_stream() {
        let mut r = SeededRng::new(7);
        let first: Vec<u64> = (0..3).map(|_| r.next_u64()).collect();
        let mut again = SeededRng::new(7);
        assert_eq!(first, (0..3).map(|_| again.next_u64()).collect::<Vec<_>>());
        assert_eq!(first, KNOWN_7);
    }

    const KNOWN_7: [u64; 3] = [
        0x671e_db9d_e9e9_afb7,
        0x67e5_3669_d5fb_6b34,
        0x974e_a030_4616_1d80,
    ];

    #[test]
    fn uniform_moments() {
        let mut r = SeededRng::new(1);
        let n = 100_000;
        let (mut m1, mut m2) = (0.0f64, 0.0f64);
        let mut v = glam::DVec3::ZERO;
        for _ in 0..n {
            let x = r.f32() as f64;
            assert!((0.0..1.0).contains(&x));
            m1 += x;
            m2 += x * x;
            let u = r.unit();
            assert!((u.length() - 1.0).abs() < 1e-5);
            v += u.as_dvec3();
        }
        // Mean 1/2 and second moment 1/3 within 5 standard errors; unit vectors average
        // to zero.
        assert!((m1 / n as f64 - 0.5).abs() < 5.0 * (1.0 / 12.0f64 / n as f64).sqrt());
        assert!((m2 / n as f64 - 1.0 / 3.0).abs() < 5.0 * 0.3 / (n as f64).sqrt());
        assert!((v / n as f64).length() < 5.0 * (1.0 / 3.0f64 / n as f64).sqrt() * 1.8);
    }
}
