//! Instances outside the camera's view left out of a draw: each mesh's bounding sphere,
//! moved and scaled by an instance's matrix, against the six planes of the view
//! frustum. Only instances wholly outside a plane are dropped, so an image is the same
//! with or without culling; what is saved is the vertex work of instances the camera
//! cannot see (a software rasteriser runs every vertex of every instance drawn on one
//! thread: the demo's forest views see a fraction of its 1,500 trees).

use lightgrid_core::glam::{Mat4, Vec3, Vec4};

/// A sphere bounding a mesh's vertices: the centre of their box and the largest
/// distance from it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bound {
    /// Centre, in the mesh's space.
    pub centre: Vec3,
    /// Radius.
    pub radius: f32,
}

impl Bound {
    /// The sphere around `positions` (a point at the origin for none).
    pub fn of(positions: impl Iterator<Item = Vec3> + Clone) -> Self {
        let (lo, hi) = positions.clone().fold(
            (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
            |(lo, hi), p| (lo.min(p), hi.max(p)),
        );
        if lo.cmpgt(hi).any() {
            return Self {
                centre: Vec3::ZERO,
                radius: 0.0,
            };
        }
        let centre = 0.5 * (lo + hi);
        let radius = positions.map(|p| p.distance(centre)).fold(0.0f32, f32::max);
        Self { centre, radius }
    }

    /// The sphere centred on the origin holding `positions` (a mesh turned about its
    /// origin, as a billboard is).
    pub fn around_origin(positions: impl Iterator<Item = Vec3>) -> Self {
        Self {
            centre: Vec3::ZERO,
            radius: positions.map(Vec3::length).fold(0.0f32, f32::max),
        }
    }

    /// The sphere around the mesh placed by `model` (column-major model-to-world): its
    /// centre moved, its radius scaled by the matrix's largest axis length.
    pub fn placed(&self, model: &Mat4) -> Self {
        let scale = model
            .x_axis
            .truncate()
            .length()
            .max(model.y_axis.truncate().length())
            .max(model.z_axis.truncate().length());
        Self {
            centre: model.transform_point3(self.centre),
            radius: self.radius * scale,
        }
    }
}

/// The distance from `eye` to `instance`'s origin (its model matrix's translation):
/// what [`crate::Renderer::set_draw_range`] tests, the same for every mesh of a model.
pub fn distance(instance: &crate::MeshInstance, eye: Vec3) -> f32 {
    Vec3::new(
        instance.model[3][0],
        instance.model[3][1],
        instance.model[3][2],
    )
    .distance(eye)
}

/// The six planes of a view frustum (wgpu's clip space: `-w ≤ x, y ≤ w`, `0 ≤ z ≤ w`),
/// each `(n, d)` with `n · p + d ≥ 0` inside, `n` of unit length.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frustum {
    planes: [Vec4; 6],
}

impl Frustum {
    /// The frustum of a projection × view matrix (Gribb and Hartmann's rows).
    pub fn of(view_proj: &Mat4) -> Self {
        let r = |i: usize| view_proj.row(i);
        let planes = [
            r(3) + r(0),
            r(3) - r(0),
            r(3) + r(1),
            r(3) - r(1),
            r(2),
            r(3) - r(2),
        ]
        .map(|p| {
            let n = p.truncate().length();
            if n > 0.0 && n.is_finite() { p / n } else { p }
        });
        Self { planes }
    }

    /// Whether any of `sphere` may be inside (false only where it lies wholly outside
    /// one plane). A sphere that is not finite counts as inside.
    pub fn may_see(&self, sphere: &Bound) -> bool {
        if !(sphere.centre.is_finite() && sphere.radius.is_finite()) {
            return true;
        }
        self.planes
            .iter()
            .all(|p| p.truncate().dot(sphere.centre) + p.w >= -sphere.radius)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Camera;

    fn camera() -> (Camera, Mat4) {
        let c = Camera::look_at(Vec3::ZERO, Vec3::new(0.0, 0.0, -10.0));
        (c, c.view_proj(16.0 / 9.0))
    }

    #[test]
    fn spheres_in_front_are_seen_and_those_behind_or_aside_are_not() {
        let (_, vp) = camera();
        let f = Frustum::of(&vp);
        let at = |x: f32, y: f32, z: f32, r: f32| Bound {
            centre: Vec3::new(x, y, z),
            radius: r,
        };
        assert!(f.may_see(&at(0.0, 0.0, -10.0, 0.5)));
        assert!(!f.may_see(&at(0.0, 0.0, 10.0, 0.5)), "behind");
        assert!(!f.may_see(&at(100.0, 0.0, -10.0, 1.0)), "far to the right");
        assert!(!f.may_see(&at(0.0, -100.0, -10.0, 1.0)), "far below");
        assert!(
            !f.may_see(&at(0.0, 0.0, -6000.0, 1.0)),
            "past the far plane"
        );
        // Straddling a side plane: the 60° vertical field of view at 10 m reaches
        // y = 10 tan 30° = 5.77; a sphere just above it reaching into it is seen.
        let edge = 10.0 * 30f32.to_radians().tan();
        assert!(f.may_see(&at(0.0, edge + 0.9, -10.0, 1.0)));
        assert!(!f.may_see(&at(0.0, edge + 1.2, -10.0, 1.0)));
        // Behind the eye but reaching past the near plane.
        assert!(f.may_see(&at(0.0, 0.0, 0.5, 1.0)));
    }

    #[test]
    fn a_placed_sphere_follows_the_instance_matrix() {
        let b = Bound::of([Vec3::new(-1.0, 0.0, 0.0), Vec3::new(1.0, 2.0, 0.0)].into_iter());
        assert_eq!(b.centre, Vec3::new(0.0, 1.0, 0.0));
        assert!((b.radius - 2f32.sqrt()).abs() < 1e-6);
        let m = Mat4::from_scale_rotation_translation(
            Vec3::new(1.0, 3.0, 2.0),
            lightgrid_core::glam::Quat::from_rotation_y(0.7),
            Vec3::new(5.0, 0.0, -4.0),
        );
        let p = b.placed(&m);
        assert!((p.centre - Vec3::new(5.0, 3.0, -4.0)).length() < 1e-5);
        assert!((p.radius - 3.0 * 2f32.sqrt()).abs() < 1e-5);
        // Every placed vertex lies in the placed sphere.
        for v in [Vec3::new(-1.0, 0.0, 0.0), Vec3::new(1.0, 2.0, 0.0)] {
            assert!(m.transform_point3(v).distance(p.centre) <= p.radius + 1e-5);
        }
    }

    #[test]
    fn bad_values_are_drawn_rather_than_dropped() {
        let (_, vp) = camera();
        let f = Frustum::of(&vp);
        let nan = Bound {
            centre: Vec3::NAN,
            radius: 1.0,
        };
        assert!(f.may_see(&nan));
        assert_eq!(Bound::of(std::iter::empty()).radius, 0.0);
    }
}
