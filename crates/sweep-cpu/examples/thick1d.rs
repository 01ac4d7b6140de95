//! Where thick dark cells lose their light (issue 13): Chandrasekhar's half-space
//! albedo (zenith beam) of a discrete-ordinates slab whose ordinates are the sweep's
//! channels (the bins' mean cosines, as `do1d`), in cells of optical depth 0.05 to 3
//! with a flat source in each cell (the sweep's source rule without its up/down
//! split), against the same with the beam's first collisions emitted from their exact
//! exponential profile inside each cell and only later generations flat.
//!
//! Measured: at depth 3 the flat source is −48 / −41 / −23 / −7.5 % (w 0.1 / 0.5 / 0.9 /
//! 0.99); with the first collisions exact, −0.5 / −8.2 / −8.8 / −3.0 %. The first
//! generation is what a dark thick cell gets wrong; later generations need the split
//! (which the 3D sweep has: +0.4 % at w 0.9).
//!
//! `cargo run --release -p sweep-cpu --example thick1d`
use lightgrid_core::dirs;
use lightgrid_core::glam::DVec3;

/// Reflected flux of a half-space (optical depth 50, cells of `dz`) under a unit zenith
/// beam; `exact_first`: the beam's first collisions emitted from their exponential
/// profile (exact integrals along each ordinate), else spread flat over each cell.
fn albedo(q: &[(f64, f64)], w: f64, dz: f64, exact_first: bool) -> f64 {
    let n = (50.0 / dz).ceil() as usize;
    let mut phi = vec![0.0f64; n];
    let mut refl = 0.0;
    let c = w / (4.0 * std::f64::consts::PI);
    for _ in 0..40000 {
        let za = |i: usize| i as f64 * dz;
        let beam_avg = |i: usize| ((-za(i)).exp() - (-(za(i) + dz)).exp()) / dz;
        let jf: Vec<f64> = (0..n)
            .map(|i| c * (phi[i] + if exact_first { 0.0 } else { beam_avg(i) }))
            .collect();
        let mut next = vec![0.0f64; n];
        refl = 0.0;
        for &(mu, wt) in q {
            let t = (-dz / mu).exp();
            for down in [true, false] {
                let mut psi = 0.0;
                for k in 0..n {
                    let i = if down { k } else { n - 1 - k };
                    let (mut out, mut avg) = (psi * t + jf[i] * (1.0 - t), jf[i]);
                    if exact_first {
                        let e = (-za(i)).exp() * c;
                        let b = if down {
                            if (mu - 1.0).abs() < 1e-9 {
                                e * (-dz).exp() * dz / mu
                            } else {
                                e * (-dz / mu).exp() * (1.0 - (-dz * (1.0 - 1.0 / mu)).exp())
                                    / (mu - 1.0)
                            }
                        } else {
                            e * (1.0 - (-dz * (1.0 + 1.0 / mu)).exp()) / (mu + 1.0)
                        };
                        out += b;
                        avg += c * beam_avg(i);
                    }
                    next[i] += wt * (avg + (psi - out) * mu / dz);
                    psi = out;
                }
                if !down {
                    refl += wt * mu * psi;
                }
            }
        }
        let change: f64 = next.iter().zip(&phi).map(|(a, b)| (a - b).abs()).sum();
        phi = next;
        if change < 1e-12 {
            break;
        }
    }
    refl
}

fn main() {
    let g = dirs::bins();
    let mut means = Vec::new();
    for b in 0..17 {
        let om = if b < 9 { g.omega[b] } else { 0.5 * g.omega[b] };
        let mean = dirs::clipped_cosine(b, -DVec3::Y) / om;
        means.push((mean, om));
    }
    for dz in [0.05, 0.69, 1.5, 3.0] {
        for w in [0.1, 0.5, 0.9, 0.99] {
            let exact = sweep_cpu::exact::half_space_albedo_beam(w, 1.0);
            let (a, b) = (albedo(&means, w, dz, false), albedo(&means, w, dz, true));
            println!(
                "cell depth {dz:>4} w {w:>4}: flat {:+7.2} %  first collisions exact {:+7.2} %",
                100.0 * (a / exact - 1.0),
                100.0 * (b / exact - 1.0)
            );
        }
    }
}
