//! Reads across the seams of grids tiled side by side.
//!
//! Tiles of one lattice (the same cell size, `dims` points across a rectangle `dims × h`
//! wide, the next tile's first point one cell past the last) leave a strip one cell
//! wide between the outermost points of two neighbours. A lookup there, read from the
//! tile serving it alone, is clamped to that tile's outermost points; one grid over
//! both tiles would interpolate between the two tiles' points. The lookup's eight
//! corners lie in at most four tiles (two across x, two across z), and each tile's own
//! clamped read at the point returns the corners it holds, interpolated along the axes
//! it spans. So the read across the seam is the sum of those tiles' own reads, each
//! weighted by its share of the corners ([`seam_shares`]): exact for any value that
//! blends linearly. `lightgrid_terrain_lod`'s nodes of one depth are such tiles, and
//! its reads (CPU and light volume) and `lightgrid_render`'s layered sampling on the
//! device follow this rule.

use glam::{IVec2, Vec3};

use crate::GridDesc;

/// The tiles a trilinear lookup at `q` reads from when the tile of `desc` serves it: up
/// to four `(offset, weight)`, the offset from the serving tile's index (its own
/// `(0, 0)` first unless its weight is 0), the weights summing to 1; the first `n` are
/// used. One entry, `((0, 0), 1)`, where `q` lies within the tile's points across (x
/// and z). `q` is taken within a cell of the tile's points (a point of its rectangle
/// read at most half a cell further out); a weight is at most 1.
///
/// ```
/// use lightgrid_core::glam::{IVec2, UVec3, Vec3};
/// use lightgrid_core::{GridDesc, seam::seam_shares};
/// // 16 points across at 1 m from (0.5, 0, 0.5): the tile's rectangle is 0..16 m.
/// let desc = GridDesc::new(Vec3::new(0.5, 0.0, 0.5), 1.0, UVec3::new(16, 8, 16))?;
/// // A quarter cell before its first point: a quarter from the neighbour before it.
/// let (w, n) = seam_shares(&desc, Vec3::new(0.25, 1.0, 8.0));
/// assert_eq!(&w[..n], &[(IVec2::ZERO, 0.75), (IVec2::new(-1, 0), 0.25)]);
/// # Ok::<(), lightgrid_core::GridError>(())
/// ```
pub fn seam_shares(desc: &GridDesc, q: Vec3) -> ([(IVec2, f32); 4], usize) {
    let g = desc.to_grid(q);
    let last = desc.dims().as_vec3() - 1.0;
    // Per axis: (neighbour's offset, its weight); the serving tile keeps the rest.
    let axis = |g: f32, last: f32| -> (i32, f32) {
        if g < 0.0 {
            (-1, (-g).min(1.0))
        } else if g > last {
            (1, (g - last).min(1.0))
        } else {
            (0, 0.0)
        }
    };
    let (ox, wx) = axis(g.x, last.x);
    let (oz, wz) = axis(g.z, last.z);
    let mut out = [(IVec2::ZERO, 0.0f32); 4];
    let mut n = 0;
    for (dx, fx) in [(0, 1.0 - wx), (ox, wx)] {
        for (dz, fz) in [(0, 1.0 - wz), (oz, wz)] {
            // (On an axis with no neighbour its second entry weighs 0.)
            let w = fx * fz;
            if w > 0.0 {
                out[n] = (IVec2::new(dx, dz), w);
                n += 1;
            }
        }
    }
    if n == 0 {
        // (Only where a weight rounds to 0 and 1 at once: q on the far points.)
        out[0] = (IVec2::ZERO, 1.0);
        n = 1;
    }
    (out, n)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::UVec3;

    fn desc() -> GridDesc {
        // 16 points across at 1 m from (0.5, 0, 0.5): the rectangle is [0, 16] m.
        GridDesc::new(Vec3::new(0.5, 0.0, 0.5), 1.0, UVec3::new(16, 8, 16)).unwrap()
    }

    fn weights(q: Vec3) -> Vec<(IVec2, f32)> {
        let (w, n) = seam_shares(&desc(), q);
        w[..n].to_vec()
    }

    #[test]
    fn within_the_points_the_tile_reads_alone() {
        for q in [
            Vec3::new(0.5, 3.0, 0.5),
            Vec3::new(15.5, -2.0, 15.5),
            Vec3::new(7.2, 40.0, 9.9),
        ] {
            assert_eq!(weights(q), vec![(IVec2::ZERO, 1.0)], "{q}");
        }
    }

    #[test]
    fn across_one_seam_the_weights_are_the_fractions_toward_each_point() {
        // A quarter cell before the first point: a quarter toward the neighbour's
        // last point (one cell back).
        let w = weights(Vec3::new(0.25, 1.0, 8.0));
        assert_eq!(w, vec![(IVec2::ZERO, 0.75), (IVec2::new(-1, 0), 0.25)]);
        // Past the last point in z by 0.4 of a cell.
        let w = weights(Vec3::new(8.0, 1.0, 15.9));
        assert_eq!(w.len(), 2);
        assert_eq!(w[1].0, IVec2::new(0, 1));
        assert!((w[0].1 - 0.6).abs() < 1e-5 && (w[1].1 - 0.4).abs() < 1e-5);
    }

    #[test]
    fn at_a_corner_four_tiles_share_the_read_bilinearly() {
        let w = weights(Vec3::new(15.75, 1.0, 0.0));
        assert_eq!(w.len(), 4);
        let expect = [
            (IVec2::new(0, 0), 0.75 * 0.5),
            (IVec2::new(0, -1), 0.75 * 0.5),
            (IVec2::new(1, 0), 0.25 * 0.5),
            (IVec2::new(1, -1), 0.25 * 0.5),
        ];
        for (o, e) in expect {
            let got = w.iter().find(|x| x.0 == o).unwrap().1;
            assert!((got - e).abs() < 1e-6, "{o}: {got} against {e}");
        }
        let sum: f32 = w.iter().map(|x| x.1).sum();
        assert!((sum - 1.0).abs() < 1e-6);
    }

    #[test]
    fn a_read_a_whole_cell_out_is_the_neighbours_alone() {
        // (A point on the rectangle's edge read half a cell further out.)
        let w = weights(Vec3::new(-0.5, 1.0, 4.0));
        assert_eq!(w, vec![(IVec2::new(-1, 0), 1.0)]);
    }
}
