//! One stable content hash for cache keys and change detection: FNV-1a 64 over the
//! little-endian bytes of the values, the same on every run, platform and Rust version
//! (unlike `DefaultHasher`), and never over `Debug` text (whose float formatting is not
//! a contract). Not cryptographic.
//!
//! ```
//! use lightgrid_core::hash::ContentHash;
//! use lightgrid_core::glam::Vec3;
//! let mut a = ContentHash::new(b"my-cache-v1");
//! a.f32s(&[1.0, 2.0]).vec3(Vec3::Y).u64(7);
//! let mut b = ContentHash::new(b"my-cache-v1");
//! b.f32s(&[1.0, 2.0]).vec3(Vec3::Y).u64(7);
//! assert_eq!(a.finish(), b.finish());
//! ```

use glam::Vec3;

use crate::{BinLight, Boundary, GridDesc, Material, SideBoundary, SweepOptions, TopBoundary};

/// FNV-1a 64 over the bytes written (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ContentHash(u64);

impl ContentHash {
    /// A hash started with a domain tag (what is keyed, and its version).
    pub fn new(tag: &[u8]) -> Self {
        let mut h = Self(0xcbf2_9ce4_8422_2325);
        h.bytes(tag);
        h
    }
    /// Adds raw bytes.
    pub fn bytes(&mut self, b: &[u8]) -> &mut Self {
        for &x in b {
            self.0 ^= x as u64;
            self.0 = self.0.wrapping_mul(0x100_0000_01b3);
        }
        self
    }
    /// Adds a `u32`.
    pub fn u32(&mut self, v: u32) -> &mut Self {
        self.bytes(&v.to_le_bytes())
    }
    /// Adds a `u64`.
    pub fn u64(&mut self, v: u64) -> &mut Self {
        self.bytes(&v.to_le_bytes())
    }
    /// Adds floats by their bits.
    pub fn f32s(&mut self, v: &[f32]) -> &mut Self {
        for x in v {
            self.bytes(&x.to_bits().to_le_bytes());
        }
        self
    }
    /// Adds a vector.
    pub fn vec3(&mut self, v: Vec3) -> &mut Self {
        self.f32s(&v.to_array())
    }
    /// Adds a grid descriptor (origin, cell size, dims).
    pub fn desc(&mut self, d: &GridDesc) -> &mut Self {
        self.vec3(d.origin()).f32s(&[d.h()]);
        for n in d.dims().to_array() {
            self.u32(n);
        }
        self
    }
    /// Adds 26 bins.
    pub fn bins(&mut self, b: &BinLight) -> &mut Self {
        self.f32s(bytemuck::cast_slice(&b.0))
    }
    /// Adds material cells.
    pub fn materials(&mut self, m: &[Material]) -> &mut Self {
        self.f32s(bytemuck::cast_slice(m))
    }
    /// Adds a boundary (tops, bottom, sides; the mode as a tag).
    pub fn boundary(&mut self, b: &Boundary) -> &mut Self {
        let Boundary { top, bottom, sides } = b;
        match top {
            TopBoundary::Uniform(x) => {
                self.u32(0).bins(x);
            }
            TopBoundary::PerPoint(v) => {
                self.u32(1).u64(v.len() as u64);
                for x in v {
                    self.bins(x);
                }
            }
        }
        self.bins(bottom);
        match sides {
            SideBoundary::Open => {
                self.u32(0);
            }
            SideBoundary::Periodic => {
                self.u32(1);
            }
            SideBoundary::Given(v) => {
                self.u32(2).u64(v.len() as u64);
                for x in v {
                    self.bins(x);
                }
            }
            SideBoundary::GivenHalves { light, down, cells } => {
                self.u32(3).u64(light.len() as u64);
                for x in light {
                    self.bins(x);
                }
                for d in down {
                    for v in &d.0 {
                        self.f32s(&v.to_array());
                    }
                }
                // Hashed only where given: a boundary without them keeps its hash.
                if let Some(cells) = cells {
                    self.u32(1).u64(cells.len() as u64);
                }
                for m in cells.iter().flatten() {
                    self.f32s(&[m.pass]).f32s(&m.reflectance.to_array());
                }
            }
        }
        self
    }
    /// Adds sweep options (every field: a new one fails to compile here until added).
    pub fn options(&mut self, o: &SweepOptions) -> &mut Self {
        let SweepOptions {
            outputs,
            smoothing,
            max_passes,
            tolerance,
            skip_empty_levels,
            medium,
            acceleration,
            gather,
            halo_paths,
        } = *o;
        if halo_paths {
            // (Only when on: the hashes of earlier options stay as they were.)
            self.u32(0x4841_4c4f);
        }
        self.u32(
            outputs.bins as u32
                | (outputs.average as u32) << 1
                | (outputs.dominant as u32) << 2
                | (outputs.horizon as u32) << 3,
        )
        .f32s(&[smoothing, tolerance])
        .u32(max_passes)
        .u32(skip_empty_levels as u32)
        .u32(match medium {
            crate::MediumEmission::Escape => 0,
            crate::MediumEmission::Source => 2,
            crate::MediumEmission::Profile => 3,
        })
        .u32(match acceleration {
            crate::Acceleration::Off => 0,
            crate::Acceleration::Diffusion => 1,
        });
        // Off, the hash is what it was before the field came (baked keys stay).
        if gather.is_on() {
            self.u32(gather.orders).u32(gather.rays);
            // Every sun gathered (90) hashes as before the field came.
            if gather.max_elevation_deg != 90 {
                self.u32(gather.max_elevation_deg);
            }
        }
        self
    }
    /// The hash.
    pub fn finish(&self) -> u64 {
        self.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_fnv_values_and_sensitivity() {
        // FNV-1a 64 of "a" (the published test vector) after an empty tag.
        let mut h = ContentHash::new(b"");
        assert_eq!(h.bytes(b"a").finish(), 0xaf63_dc4c_8601_ec8c);
        // Every input changes the hash: a bit of a float, a dim, the tag, a bin.
        let d = GridDesc::new(Vec3::ZERO, 1.0, glam::UVec3::new(2, 3, 4)).unwrap();
        let d2 = GridDesc::new(Vec3::ZERO, 1.0, glam::UVec3::new(2, 4, 3)).unwrap();
        let key =
            |tag: &[u8], d: &GridDesc, x: f32| ContentHash::new(tag).desc(d).f32s(&[x]).finish();
        let base = key(b"t", &d, 1.0);
        assert_ne!(base, key(b"u", &d, 1.0));
        assert_ne!(base, key(b"t", &d2, 1.0));
        assert_ne!(base, key(b"t", &d, f32::from_bits(1.0f32.to_bits() + 1)));
        let mut b = BinLight::ZERO;
        let h0 = ContentHash::new(b"t").bins(&b).finish();
        b.0[25].z = 1e-30;
        assert_ne!(h0, ContentHash::new(b"t").bins(&b).finish());
    }

    /// A gather's every field changes a sweep's hash when it gathers; off, its other
    /// fields do not (a baked key stays whatever they hold).
    #[test]
    fn the_gather_s_fields_change_the_options_hash() {
        use crate::Gather;
        let hash = |g: Gather| {
            let mut o = SweepOptions::multi_bounce();
            o.gather = g;
            ContentHash::new(b"o").options(&o).finish()
        };
        let before = hash(Gather::OFF);
        let off = Gather {
            rays: 64,
            max_elevation_deg: 10,
            ..Gather::OFF
        };
        assert_eq!(hash(off), before);
        let (low, auto) = (hash(Gather::LOW_SUN), hash(Gather::AUTO));
        assert!(low != before && auto != before && auto != low);
        let rays = hash(Gather {
            rays: 1024,
            ..Gather::AUTO
        });
        let orders = hash(Gather {
            orders: 1,
            ..Gather::AUTO
        });
        assert!(rays != auto && orders != auto && rays != orders);
    }
}
