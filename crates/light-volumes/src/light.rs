//! Local light sources and how they emit rays.

use std::f32::consts::TAU;

use lightgrid_core::GridError;
pub use lightgrid_core::LightKind;
use lightgrid_core::glam::Vec3;
pub use lightgrid_core::lights::spot_falloff;

/// A light: shape, colour and intensity. The traced volume is for white light of unit
/// power; colour × intensity scale it when volumes are merged (as 3DWorld does).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Light {
    /// Shape.
    pub kind: LightKind,
    /// Linear RGB colour.
    pub colour: Vec3,
    /// Emitted power (the volume's unit).
    pub intensity: f32,
}

impl Light {
    /// Checks every field; errors name it.
    pub fn validate(&self) -> Result<(), GridError> {
        if !(self.colour.is_finite() && self.colour.cmpge(Vec3::ZERO).all()) {
            return Err(GridError::invalid(
                "colour",
                self.colour,
                "must be finite and >= 0",
            ));
        }
        if !(self.intensity.is_finite() && self.intensity >= 0.0) {
            return Err(GridError::invalid(
                "intensity",
                self.intensity,
                "must be finite and >= 0",
            ));
        }
        self.kind.validate()
    }

    /// Adds the shape to a cache key (colour and intensity excluded: volumes are stored
    /// as white light).
    pub fn hash_shape(&self, h: &mut lightgrid_core::hash::ContentHash) {
        self.kind.hash_into(h);
    }

    /// One emitted ray from uniform numbers `r` in `[0, 1)`: origin, unit direction and
    /// weight (the fraction of the light's unit power it carries, before dividing by the
    /// ray count; 1 except in a spot's falloff).
    pub fn emit(&self, r: [f32; 4]) -> (Vec3, Vec3, f32) {
        match self.kind {
            LightKind::Point { position } => (position, sphere(r[0], r[1]), 1.0),
            LightKind::Line { a, b } => (a + (b - a) * r[2], sphere(r[0], r[1]), 1.0),
            LightKind::Area { centre, u, v } => {
                let n = u.cross(v).normalize();
                let o = centre + u * (2.0 * r[2] - 1.0) + v * (2.0 * r[3] - 1.0);
                (o + n * 1e-4, cosine(n, r[0], r[1]), 1.0)
            }
            LightKind::Spot {
                position,
                direction,
                inner,
                outer,
            } => {
                // Uniform over the outer cone's solid angle, weighted by the falloff; the
                // weights are normalised so the spot emits unit power.
                let axis = direction.normalize();
                let cos_outer = outer.cos();
                let z = 1.0 - r[0] * (1.0 - cos_outer);
                let s = (1.0 - z * z).max(0.0).sqrt();
                let phi = TAU * r[1];
                let t1 = axis.any_orthonormal_vector();
                let t2 = axis.cross(t1);
                let dir = (t1 * (s * phi.cos()) + t2 * (s * phi.sin()) + axis * z).normalize();
                let w = spot_falloff(z, inner.cos(), cos_outer) / spot_mean_falloff(inner, outer);
                (position, dir, w)
            }
        }
    }
}

/// Mean of [`spot_falloff`] over the outer cone (uniform in `cos`), for normalisation.
fn spot_mean_falloff(inner: f32, outer: f32) -> f32 {
    let (ci, co) = (inner.cos(), outer.cos());
    if (1.0 - co) <= 0.0 {
        return 1.0;
    }
    // ∫ over cos in [co, 1]: full part (1 - ci) plus the smoothstep part (ci - co) / 2.
    ((1.0 - ci) + 0.5 * (ci - co)) / (1.0 - co)
}

fn sphere(a: f32, b: f32) -> Vec3 {
    let z = 1.0 - 2.0 * a;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = TAU * b;
    Vec3::new(r * phi.cos(), z, r * phi.sin())
}

/// A cosine-distributed direction about unit `n`.
pub fn cosine(n: Vec3, a: f32, b: f32) -> Vec3 {
    let r = a.sqrt();
    let phi = TAU * b;
    let z = (1.0 - a).max(0.0).sqrt();
    let t1 = n.any_orthonormal_vector();
    let t2 = n.cross(t1);
    (t1 * (r * phi.cos()) + t2 * (r * phi.sin()) + n * z).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rng(seed: u64) -> impl FnMut() -> [f32; 4] {
        let mut r = fastrand::Rng::with_seed(seed);
        move || [r.f32(), r.f32(), r.f32(), r.f32()]
    }

    #[test]
    fn every_light_emits_unit_mean_weight() {
        let lights = [
            LightKind::Point {
                position: Vec3::ZERO,
            },
            LightKind::Line {
                a: Vec3::ZERO,
                b: Vec3::X,
            },
            LightKind::Area {
                centre: Vec3::ZERO,
                u: Vec3::X,
                v: Vec3::Z,
            },
            LightKind::Spot {
                position: Vec3::ZERO,
                direction: Vec3::NEG_Y,
                inner: 0.3,
                outer: 0.8,
            },
        ];
        for kind in lights {
            let l = Light {
                kind,
                colour: Vec3::ONE,
                intensity: 1.0,
            };
            l.validate().unwrap();
            let mut r = rng(3);
            let n = 200_000;
            let mean: f32 = (0..n).map(|_| l.emit(r()).2).sum::<f32>() / n as f32;
            assert!((mean - 1.0).abs() < 0.01, "{kind:?}: {mean}");
        }
    }

    #[test]
    fn area_light_emits_to_its_front_only_and_spot_inside_its_cone() {
        let area = Light {
            kind: LightKind::Area {
                centre: Vec3::ZERO,
                u: Vec3::X,
                v: Vec3::NEG_Z,
            },
            colour: Vec3::ONE,
            intensity: 1.0,
        };
        // X × -Z = +Y.
        let mut r = rng(1);
        for _ in 0..1000 {
            let (o, d, _) = area.emit(r());
            assert!(d.y > 0.0 && o.x.abs() <= 1.0 && o.z.abs() <= 1.0);
        }
        let spot = Light {
            kind: LightKind::Spot {
                position: Vec3::ZERO,
                direction: Vec3::NEG_Y,
                inner: 0.2,
                outer: 0.5,
            },
            colour: Vec3::ONE,
            intensity: 1.0,
        };
        for _ in 0..1000 {
            let (_, d, w) = spot.emit(r());
            assert!(d.dot(Vec3::NEG_Y) >= 0.5f32.cos() - 1e-5);
            assert!(w >= 0.0);
        }
    }

    #[test]
    fn bad_lights_are_typed_errors() {
        let mut l = Light {
            kind: LightKind::Line {
                a: Vec3::ONE,
                b: Vec3::ONE,
            },
            colour: Vec3::ONE,
            intensity: 1.0,
        };
        assert!(l.validate().unwrap_err().to_string().contains("b"));
        l.kind = LightKind::Point {
            position: Vec3::NAN,
        };
        assert!(l.validate().unwrap_err().to_string().contains("position"));
        l.kind = LightKind::Point {
            position: Vec3::ZERO,
        };
        l.intensity = -1.0;
        assert!(l.validate().unwrap_err().to_string().contains("intensity"));
    }
}
