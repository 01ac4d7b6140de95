//! The shapes of local lights, shared by the baked light volumes (`light-volumes`) and
//! the dynamic lights of the renderer (`lightgrid-render`): one type, one validation,
//! one spot falloff.

use std::f32::consts::PI;

use glam::Vec3;

use crate::GridError;
use crate::hash::ContentHash;

/// The shape of a light. Where a renderer cannot draw a shape (an area light is baked
/// only), it says so with an error.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LightKind {
    /// Emits equally in all directions from a point.
    Point {
        /// Position, metres.
        position: Vec3,
    },
    /// A point light limited to a cone, full inside `inner` (half-angle, radians),
    /// falling smoothly to zero at `outer`.
    Spot {
        /// Position.
        position: Vec3,
        /// Axis of the cone (any length > 0).
        direction: Vec3,
        /// Half-angle of full intensity, radians.
        inner: f32,
        /// Half-angle where it reaches zero, radians (`inner <= outer <= π`).
        outer: f32,
    },
    /// A one-sided rectangle `centre ± u ± v` emitting (Lambertian) towards `u × v`.
    Area {
        /// Centre.
        centre: Vec3,
        /// Half of one edge.
        u: Vec3,
        /// Half of the other edge.
        v: Vec3,
    },
    /// A segment `a → b` emitting equally in all directions from every point.
    Line {
        /// One end.
        a: Vec3,
        /// The other end.
        b: Vec3,
    },
}

impl LightKind {
    /// Checks the shape's fields; errors name the field.
    pub fn validate(&self) -> Result<(), GridError> {
        let finite3 = |field: &'static str, v: Vec3| {
            if v.is_finite() {
                Ok(())
            } else {
                Err(GridError::invalid(field, v, "must be finite"))
            }
        };
        match *self {
            LightKind::Point { position } => finite3("position", position),
            LightKind::Spot {
                position,
                direction,
                inner,
                outer,
            } => {
                finite3("position", position)?;
                if !(direction.is_finite() && direction.length_squared() > 0.0) {
                    return Err(GridError::invalid(
                        "direction",
                        direction,
                        "must be finite and non-zero",
                    ));
                }
                if !(inner >= 0.0 && inner <= outer && outer > 0.0 && outer <= PI) {
                    return Err(GridError::invalid(
                        "outer",
                        outer,
                        "need 0 <= inner <= outer <= π and outer > 0",
                    ));
                }
                Ok(())
            }
            LightKind::Area { centre, u, v } => {
                finite3("centre", centre)?;
                finite3("u", u)?;
                finite3("v", v)?;
                if u.cross(v).length_squared() == 0.0 {
                    return Err(GridError::invalid("u", u, "u and v must span an area"));
                }
                Ok(())
            }
            LightKind::Line { a, b } => {
                finite3("a", a)?;
                finite3("b", b)?;
                if a == b {
                    return Err(GridError::invalid("b", b, "must differ from a"));
                }
                Ok(())
            }
        }
    }

    /// Adds the shape to a content hash.
    pub fn hash_into(&self, h: &mut ContentHash) {
        match *self {
            LightKind::Point { position } => h.u32(0).vec3(position),
            LightKind::Spot {
                position,
                direction,
                inner,
                outer,
            } => h
                .u32(1)
                .vec3(position)
                .vec3(direction)
                .f32s(&[inner, outer]),
            LightKind::Area { centre, u, v } => h.u32(2).vec3(centre).vec3(u).vec3(v),
            LightKind::Line { a, b } => h.u32(3).vec3(a).vec3(b),
        };
    }

    /// For a spot: its unit axis and the cosines of its inner and outer half-angles.
    pub fn spot_cone(&self) -> Option<(Vec3, f32, f32)> {
        match *self {
            LightKind::Spot {
                direction,
                inner,
                outer,
                ..
            } => Some((
                crate::unit(direction).unwrap_or(Vec3::ZERO),
                inner.cos(),
                outer.cos(),
            )),
            _ => None,
        }
    }
}

/// Smoothstep from the outer to the inner cone, on the cosine of the angle.
pub fn spot_falloff(cos: f32, cos_inner: f32, cos_outer: f32) -> f32 {
    if cos >= cos_inner {
        return 1.0;
    }
    if cos <= cos_outer {
        return 0.0;
    }
    let x = (cos - cos_outer) / (cos_inner - cos_outer);
    x * x * (3.0 - 2.0 * x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shapes_validate_and_name_the_bad_field() {
        let spot = LightKind::Spot {
            position: Vec3::ZERO,
            direction: Vec3::new(0.0, -2.0, 0.0),
            inner: 0.3,
            outer: 0.6,
        };
        spot.validate().unwrap();
        let (axis, ci, co) = spot.spot_cone().unwrap();
        assert_eq!(axis, Vec3::NEG_Y);
        assert!((ci - 0.3f32.cos()).abs() < 1e-7 && (co - 0.6f32.cos()).abs() < 1e-7);
        let bad = LightKind::Spot {
            position: Vec3::ZERO,
            direction: Vec3::Y,
            inner: 0.7,
            outer: 0.6,
        };
        assert!(bad.validate().unwrap_err().to_string().contains("outer"));
        let line = LightKind::Line {
            a: Vec3::X,
            b: Vec3::X,
        };
        assert!(line.validate().unwrap_err().to_string().contains("b"));
        let area = LightKind::Area {
            centre: Vec3::ZERO,
            u: Vec3::X,
            v: Vec3::X,
        };
        assert!(area.validate().is_err());
        assert!(
            LightKind::Point {
                position: Vec3::NAN
            }
            .validate()
            .is_err()
        );
        assert!(line.spot_cone().is_none());
    }

    #[test]
    fn spot_falloff_is_one_inside_zero_outside_and_monotone() {
        let (ci, co) = (0.9, 0.6);
        assert_eq!(spot_falloff(0.95, ci, co), 1.0);
        assert_eq!(spot_falloff(0.5, ci, co), 0.0);
        let mut last = 0.0;
        for k in 0..=100 {
            let c = co + (ci - co) * k as f32 / 100.0;
            let f = spot_falloff(c, ci, co);
            assert!(f >= last - 1e-7 && (0.0..=1.0).contains(&f));
            last = f;
        }
    }
}
