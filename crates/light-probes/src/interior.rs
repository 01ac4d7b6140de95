//! Interior volumes (The Division's rooms): a box with its own probes, which see the
//! outside only through openings (outside surfaces lit by the exterior probes), and
//! whose light stays on its side of the box's faces in the merged volume.

use lightgrid_core::GridError;
use lightgrid_core::glam::Vec3;
use lightgrid_material_voxelizer::voxelize::RayScene;

use crate::ProbeSet;

/// Most probes [`InteriorBox::place`] puts in one box.
pub const MAX_INTERIOR_PROBES: usize = 1 << 20;

/// A room's box.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InteriorBox {
    /// Lowest corner, world.
    pub lo: Vec3,
    /// Highest corner, world.
    pub hi: Vec3,
    /// Depth, metres, over which the room's probes take over from the exterior's
    /// inside the box ([`InteriorBox::weight`]): 0 at the faces, 1 this deep inside.
    /// Walls block the exterior probes anyway; the blend shows at openings.
    pub blend: f32,
}

impl InteriorBox {
    /// Checks the corners (finite, `lo < hi` on every axis) and the blend depth
    /// (finite, >= 0); errors name the field.
    pub fn validate(&self) -> Result<(), GridError> {
        if !(self.lo.is_finite() && self.hi.is_finite()) {
            return Err(GridError::invalid("lo", self.lo, "corners must be finite"));
        }
        if !self.lo.cmplt(self.hi).all() {
            return Err(GridError::invalid(
                "hi",
                self.hi,
                "must exceed lo on every axis",
            ));
        }
        if !(self.blend.is_finite() && self.blend >= 0.0) {
            return Err(GridError::invalid(
                "blend",
                self.blend,
                "must be finite and >= 0",
            ));
        }
        Ok(())
    }

    /// Whether `p` lies inside (faces included).
    pub fn contains(&self, p: Vec3) -> bool {
        p.cmpge(self.lo).all() && p.cmple(self.hi).all()
    }

    /// Distance from `p` to the box (0 inside).
    pub fn distance(&self, p: Vec3) -> f32 {
        (self.lo - p).max(p - self.hi).max(Vec3::ZERO).length()
    }

    /// The room's share of the light at `p`: 0 outside, rising linearly to 1 at `blend`
    /// metres inside (1 everywhere inside when `blend` is 0).
    pub fn weight(&self, p: Vec3) -> f32 {
        if !self.contains(p) {
            return 0.0;
        }
        let depth = (p - self.lo).min(self.hi - p).min_element();
        if self.blend <= 0.0 {
            1.0
        } else {
            (depth / self.blend).clamp(0.0, 1.0)
        }
    }

    /// Probe positions filling the box: the centres of cells of about `spacing` metres
    /// (at least one a side). Errors name a bad box or spacing, or one that would place
    /// more than [`MAX_INTERIOR_PROBES`].
    pub fn place(&self, spacing: f32) -> Result<Vec<Vec3>, GridError> {
        self.validate()?;
        if !(spacing.is_finite() && spacing > 0.0) {
            return Err(GridError::invalid(
                "spacing",
                spacing,
                "must be finite and > 0",
            ));
        }
        let size = self.hi - self.lo;
        let cells = (size / spacing).ceil().max(Vec3::ONE);
        if cells.x as f64 * cells.y as f64 * cells.z as f64 > MAX_INTERIOR_PROBES as f64 {
            return Err(GridError::invalid(
                "spacing",
                spacing,
                "places more than MAX_INTERIOR_PROBES probes in the box",
            ));
        }
        let n = cells.as_uvec3();
        let cell = size / n.as_vec3();
        let mut out = Vec::new();
        for k in 0..n.z {
            for j in 0..n.y {
                for i in 0..n.x {
                    let c = Vec3::new(i as f32, j as f32, k as f32) + 0.5;
                    out.push(self.lo + c * cell);
                }
            }
        }
        Ok(out)
    }
}

/// The exterior probes lighting a surface at `point` seen through a room's openings:
/// of the `4 k` exterior probes nearest it that lie outside `room`, the `k` nearest with
/// a clear line to it (else the nearest), with their distances.
pub(crate) fn nearest_visible(
    scene: &RayScene<'_>,
    exterior: &ProbeSet,
    room: &InteriorBox,
    point: Vec3,
    k: usize,
) -> Vec<(u32, f32)> {
    let want = 4 * k.max(1);
    let mut best: Vec<(f32, u32)> = Vec::with_capacity(want + 1);
    for (i, p) in exterior.probes().iter().enumerate() {
        if room.contains(p.position) {
            continue;
        }
        let d = p.position.distance(point);
        if best.len() < want || d < best[want - 1].0 {
            let at = best.partition_point(|(b, j)| (*b, *j) < (d, i as u32));
            best.insert(at, (d, i as u32));
            best.truncate(want);
        }
    }
    let clear = |q: u32, dist: f32| {
        let to = exterior.probes()[q as usize].position - point;
        dist < 1e-4 || scene.closest_hit(point, to / dist, dist, 0.5).is_none()
    };
    let mut out: Vec<(u32, f32)> = best
        .iter()
        .filter(|(d, q)| clear(*q, *d))
        .take(k)
        .map(|(d, q)| (*q, *d))
        .collect();
    if out.is_empty() {
        out.extend(best.first().map(|(d, q)| (*q, *d)));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn room() -> InteriorBox {
        InteriorBox {
            lo: Vec3::new(0.0, 0.0, 0.0),
            hi: Vec3::new(4.0, 3.0, 6.0),
            blend: 1.0,
        }
    }

    #[test]
    fn distance_weight_and_placement() {
        let r = room();
        let c = Vec3::new(1.0, 1.0, 1.0);
        assert_eq!(r.distance(c), 0.0);
        assert!((r.distance(Vec3::new(7.0, -4.0, 1.0)) - 5.0).abs() < 1e-6);
        assert_eq!(r.weight(Vec3::new(-0.1, 1.0, 1.0)), 0.0);
        assert!((r.weight(Vec3::new(0.5, 1.5, 3.0)) - 0.5).abs() < 1e-6);
        assert_eq!(r.weight(Vec3::new(2.0, 1.5, 3.0)), 1.0);
        let p = r.place(2.0).unwrap();
        assert_eq!(p.len(), 2 * 2 * 3);
        assert!(r.place(1e-4).unwrap_err().to_string().contains("spacing"));
        assert!(
            r.place(f32::NAN)
                .unwrap_err()
                .to_string()
                .contains("spacing")
        );
        assert!(p.iter().all(|q| r.contains(*q)));
        let mut bad = r;
        bad.hi.y = -1.0;
        assert!(bad.validate().unwrap_err().to_string().contains("hi"));
        bad = r;
        bad.blend = f32::NAN;
        assert!(bad.validate().unwrap_err().to_string().contains("blend"));
    }
}
