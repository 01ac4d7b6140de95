//! Exact segment-in-cell walking (a 3D DDA) in grid coordinates, where point `(i, j, k)`
//! is the centre of cell `(i, j, k)` and the cell spans `± 0.5` around it.
//!
//! One implementation for every tracer: sweep-cpu's Monte Carlo reference walks its
//! paths with [`exit`] and [`cross`], and `light-volumes` deposits its rays' segments
//! with [`walk_segment`], so both put a segment's light into exactly the cells it
//! crosses, with exactly the length inside each.

use glam::{IVec3, Vec3};

/// Distance along unit-speed `dir` from `pos` (inside `cell`) to the cell's exit face,
/// and the axis of that face. `f32::INFINITY` (axis 0) for a zero direction.
#[inline]
pub fn exit(cell: IVec3, pos: Vec3, dir: Vec3) -> (f32, usize) {
    let mut s_exit = f32::INFINITY;
    let mut axis = 0;
    for a in 0..3 {
        let t = if dir[a] > 0.0 {
            (cell[a] as f32 + 0.5 - pos[a]) / dir[a]
        } else if dir[a] < 0.0 {
            (cell[a] as f32 - 0.5 - pos[a]) / dir[a]
        } else {
            f32::INFINITY
        };
        let t = t.max(0.0);
        if t < s_exit {
            s_exit = t;
            axis = a;
        }
    }
    (s_exit, axis)
}

/// Distance along `dir` from `pos` (inside the box `[lo, hi]`) to where the ray leaves
/// the box, at least 0; `f32::INFINITY` where it never does (a zero direction, or one
/// along an axis whose bounds are infinite).
#[inline]
pub fn box_exit(pos: Vec3, dir: Vec3, lo: Vec3, hi: Vec3) -> f32 {
    let mut t = f32::INFINITY;
    for a in 0..3 {
        if dir[a] > 0.0 {
            t = t.min((hi[a] - pos[a]) / dir[a]);
        } else if dir[a] < 0.0 {
            t = t.min((lo[a] - pos[a]) / dir[a]);
        }
    }
    t.max(0.0)
}

/// Steps from `cell` into its neighbour along `axis` in the direction of `dir`, putting
/// `pos` exactly on the shared face (no drift over long walks). Returns the step (±1).
#[inline]
pub fn cross(cell: &mut IVec3, pos: &mut Vec3, axis: usize, dir: Vec3) -> i32 {
    let step = if dir[axis] > 0.0 { 1 } else { -1 };
    pos[axis] = cell[axis] as f32 + 0.5 * step as f32;
    cell[axis] += step;
    step
}

/// Walks the segment `a → b` (grid coordinates) through a grid of `dims` cells, calling
/// `visit(cell, length)` for every cell it crosses inside the grid, in order, with the
/// length of the segment inside that cell (grid units). The lengths inside the grid sum
/// to the segment's clipped length. Parts outside the grid are skipped.
pub fn walk_segment(a: Vec3, b: Vec3, dims: IVec3, mut visit: impl FnMut(IVec3, f32)) {
    let d = b - a;
    let len = d.length();
    if len.is_nan() || len <= 0.0 || !len.is_finite() {
        return;
    }
    let dir = d / len;
    // Clip to the grid's box [-0.5, dims - 0.5] (slab test).
    let (lo, hi) = (Vec3::splat(-0.5), dims.as_vec3() - Vec3::splat(0.5));
    let (mut t0, mut t1) = (0.0f32, len);
    for k in 0..3 {
        if dir[k] == 0.0 {
            if a[k] < lo[k] || a[k] > hi[k] {
                return;
            }
        } else {
            let (ta, tb) = ((lo[k] - a[k]) / dir[k], (hi[k] - a[k]) / dir[k]);
            t0 = t0.max(ta.min(tb));
            t1 = t1.min(ta.max(tb));
        }
    }
    if t0 >= t1 {
        return;
    }
    let mut pos = a + dir * t0;
    let mut cell = (pos + Vec3::splat(0.5))
        .floor()
        .as_ivec3()
        .clamp(IVec3::ZERO, dims - IVec3::ONE);
    let mut left = t1 - t0;
    loop {
        let (s, axis) = exit(cell, pos, dir);
        if s >= left {
            if left > 0.0 {
                visit(cell, left);
            }
            return;
        }
        if s > 0.0 {
            visit(cell, s);
        }
        left -= s;
        pos += dir * s;
        cross(&mut cell, &mut pos, axis, dir);
        if cell.cmplt(IVec3::ZERO).any() || cell.cmpge(dims).any() {
            return;
        }
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_ray_leaves_a_box_where_it_meets_its_nearest_face() {
        let (lo, hi) = (Vec3::new(-1.0, 0.0, 2.0), Vec3::new(3.0, 5.0, 4.0));
        let p = Vec3::new(0.0, 1.0, 3.0);
        assert_eq!(super::box_exit(p, Vec3::X, lo, hi), 3.0);
        assert_eq!(super::box_exit(p, -Vec3::Z, lo, hi), 1.0);
        let d = Vec3::new(1.0, 1.0, 0.0).normalize();
        assert!((super::box_exit(p, d, lo, hi) - 3.0 * 2f32.sqrt()).abs() < 1e-5);
        assert_eq!(super::box_exit(p, Vec3::ZERO, lo, hi), f32::INFINITY);
        let tall = Vec3::new(3.0, f32::INFINITY, 4.0);
        assert_eq!(super::box_exit(p, Vec3::Y, lo, tall), f32::INFINITY);
        // On a face, leaving: 0.
        assert_eq!(
            super::box_exit(Vec3::new(3.0, 1.0, 3.0), Vec3::X, lo, hi),
            0.0
        );
    }

    use super::*;
    use proptest::prelude::*;

    #[test]
    fn axis_segment_gives_unit_lengths() {
        let mut v = Vec::new();
        walk_segment(
            Vec3::new(-0.5, 1.0, 2.0),
            Vec3::new(3.5, 1.0, 2.0),
            IVec3::new(4, 3, 3),
            |c, l| v.push((c, l)),
        );
        assert_eq!(v.len(), 4);
        for (i, (c, l)) in v.iter().enumerate() {
            assert_eq!(*c, IVec3::new(i as i32, 1, 2));
            assert!((l - 1.0).abs() < 1e-6);
        }
    }

    #[test]
    fn outside_parts_are_clipped() {
        let mut total = 0.0;
        walk_segment(
            Vec3::new(-10.0, 0.0, 0.0),
            Vec3::new(10.0, 0.0, 0.0),
            IVec3::new(2, 1, 1),
            |_, l| total += l,
        );
        assert!((total - 2.0).abs() < 1e-5);
        let mut n = 0;
        walk_segment(
            Vec3::new(-3.0, 5.0, 0.0),
            Vec3::new(-1.0, 5.0, 0.0),
            IVec3::new(2, 1, 1),
            |_, _| n += 1,
        );
        assert_eq!(n, 0);
    }

    proptest! {
        /// Lengths sum to the clipped length, every visited cell is inside the grid and
        /// adjacent to the previous one, and the brute-force length inside each cell
        /// (fine sampling of the segment) agrees.
        #[test]
        fn walk_matches_brute_force(
            ax in -2.0f32..7.0, ay in -2.0f32..5.0, az in -2.0f32..6.0,
            bx in -2.0f32..7.0, by in -2.0f32..5.0, bz in -2.0f32..6.0,
        ) {
            let dims = IVec3::new(5, 3, 4);
            let (a, b) = (Vec3::new(ax, ay, az), Vec3::new(bx, by, bz));
            let mut cells = Vec::new();
            walk_segment(a, b, dims, |c, l| cells.push((c, l)));
            let inside = |p: Vec3| {
                let c = (p + Vec3::splat(0.5)).floor().as_ivec3();
                (c.cmpge(IVec3::ZERO).all() && c.cmplt(dims).all()).then_some(c)
            };
            let n = 20_000;
            let step = (b - a).length() / n as f32;
            let mut brute = std::collections::HashMap::new();
            for i in 0..n {
                let p = a + (b - a) * ((i as f32 + 0.5) / n as f32);
                if let Some(c) = inside(p) {
                    *brute.entry(c).or_insert(0.0f32) += step;
                }
            }
            let total: f32 = cells.iter().map(|x| x.1).sum();
            let brute_total: f32 = brute.values().sum();
            prop_assert!((total - brute_total).abs() < 2e-3 * (b - a).length().max(1.0));
            for w in cells.windows(2) {
                prop_assert_eq!((w[1].0 - w[0].0).abs().element_sum(), 1);
            }
            for (c, l) in &cells {
                prop_assert!(c.cmpge(IVec3::ZERO).all() && c.cmplt(dims).all());
                let bl = brute.get(c).copied().unwrap_or(0.0);
                prop_assert!((l - bl).abs() < 2e-3 * (b - a).length().max(1.0), "{c} {l} {bl}");
            }
        }
    }
}
