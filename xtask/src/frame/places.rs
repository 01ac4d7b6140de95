//! Where the finest depth's nesting error lies: its probes against the 1 m sweep by
//! the way they face (terrain vertices, volume points facing up, down and sideways)
//! and by how far they read from their node's nearest side (in cells). A node's
//! light enters through its top and its sides from the coarser grid; the groups say
//! which hand-over, and which directions of the light, the error comes with.

use lightgrid_core::GridDesc;
use serde::Serialize;

use super::{Acc3, Errors, Parts, Probe};

/// The facing groups, in [`Places::facing`]'s order.
pub(super) const FACINGS: [&str; 4] = [
    "terrain vertices",
    "facing up",
    "facing down",
    "facing sideways",
];

/// The groups of distance from the node's nearest side of points, in cells, in
/// [`Places::side`]'s order: a seam's probes lie between two nodes' points (read
/// from both, `lightgrid_core::seam`).
pub(super) const SIDES: [&str; 5] = [
    "a seam (beyond them)",
    "under 1",
    "1 to 2",
    "2 to 4",
    "4 or more",
];

/// The finest depth's probes (against the 1 m sweep) grouped by facing and by their
/// distance from their node's nearest side.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct Places {
    /// Terrain vertices, volume points facing up, facing down, facing sideways.
    pub facing: [Place; 4],
    /// In a seam between two nodes' points; under 1 cell from the node's nearest side
    /// of points, 1 to 2, 2 to 4, 4 or more.
    pub side: [Place; 5],
}

/// One group's errors and its share of the depth's squared sky error.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct Place {
    /// Bias and RMSE relative to the group's own mean.
    pub errors: Errors,
    /// The group's part of the sum of squared sky errors over all the depth's probes.
    pub sky_share: f64,
}

/// Accumulates [`Places`].
#[derive(Default, Clone)]
pub(super) struct PlaceTally {
    facing: [Acc3; 4],
    side: [Acc3; 5],
}

/// The facing group of probe `p`.
fn facing(p: &Probe) -> usize {
    if p.vertex {
        0
    } else if p.n.y > 0.5 {
        1
    } else if p.n.y < -0.5 {
        2
    } else {
        3
    }
}

/// The four sides of a grid's points, in [`nearest_side`]'s order.
pub(super) const SIDE_NAMES: [&str; 4] = ["-x", "+x", "-z", "+z"];

/// A point `p`'s nearest of the four sides of the points of the grid `desc`
/// ([`SIDE_NAMES`]' index) and its distance from it, in cells (negative beyond them,
/// in a seam).
pub(super) fn nearest_side(desc: &GridDesc, p: lightgrid_core::glam::Vec3) -> (usize, f32) {
    let (o, h) = (desc.origin(), desc.h());
    let far = o + (desc.dims().as_vec3() - 1.0) * h;
    [p.x - o.x, far.x - p.x, p.z - o.z, far.z - p.z]
        .into_iter()
        .enumerate()
        .map(|(k, d)| (k, d / h))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap_or((0, 0.0))
}

/// The side group of a point `p` read from the grid `desc`: its distance from the
/// nearest of the four sides of the grid's points, in cells (negative in a seam).
fn side(desc: &GridDesc, p: lightgrid_core::glam::Vec3) -> usize {
    match nearest_side(desc, p).1 {
        d if d < 0.0 => 0,
        d if d < 1.0 => 1,
        d if d < 2.0 => 2,
        d if d < 4.0 => 3,
        _ => 4,
    }
}

impl PlaceTally {
    /// Probe `p`, read from the grid `desc`: the hierarchy's `h`, the reference's `r`.
    pub(super) fn add(&mut self, desc: &GridDesc, p: &Probe, h: Parts, r: Parts) {
        self.facing[facing(p)].add(h, r);
        self.side[side(desc, p.p)].add(h, r);
    }

    pub(super) fn places(&self) -> Places {
        let total: f64 = self.facing.iter().map(|a| a.0[0].d2).sum();
        let place = |a: &Acc3| Place {
            errors: a.errors(),
            sky_share: if total > 0.0 { a.0[0].d2 / total } else { 0.0 },
        };
        Places {
            facing: self.facing.each_ref().map(place),
            side: self.side.each_ref().map(place),
        }
    }
}

/// The report's lines for `p` (none where no probe was tallied).
pub(super) fn lines(p: &Places) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    if p.facing.iter().all(|g| g.errors.both.n == 0) {
        return s;
    }
    let _ = writeln!(
        s,
        "  the finest depth by where its probes read (against the 1 m sweep; RMSE relative to the group's mean, and the group's share of the depth's squared sky error):"
    );
    let groups = FACINGS
        .iter()
        .zip(&p.facing)
        .map(|(n, g)| (format!("facing: {n}"), g))
        .chain(
            SIDES
                .iter()
                .zip(&p.side)
                .map(|(n, g)| (format!("cells from the side: {n}"), g)),
        );
    for (name, g) in groups {
        let e = &g.errors;
        let _ = writeln!(
            s,
            "    {name:32} {:7} probes: sky bias {:+5.1} % RMSE {:5.1} % (share {:4.1} %), sun {:+5.1} / {:5.1} %, both {:+5.1} / {:5.1} %",
            e.both.n,
            100.0 * e.sky.bias,
            100.0 * e.sky.rmse,
            100.0 * g.sky_share,
            100.0 * e.sun.bias,
            100.0 * e.sun.rmse,
            100.0 * e.both.bias,
            100.0 * e.both.rmse
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use lightgrid_core::glam::{UVec3, Vec3};

    fn probe(p: Vec3, n: Vec3, vertex: bool) -> Probe {
        Probe { p, n, vertex }
    }

    /// Distances from the nearest side in cells, on a grid of 2 m cells whose points
    /// span 0..30 m (beyond 30 m: a seam).
    #[test]
    fn side_groups_count_cells_from_the_nearest_side() {
        let d = GridDesc::new(Vec3::ZERO, 2.0, UVec3::new(16, 4, 16)).unwrap();
        assert_eq!(side(&d, Vec3::new(31.0, 0.0, 15.0)), 0);
        assert_eq!(side(&d, Vec3::new(1.0, 0.0, 15.0)), 1);
        assert_eq!(side(&d, Vec3::new(15.0, 0.0, 28.5)), 1);
        assert_eq!(side(&d, Vec3::new(3.0, 0.0, 15.0)), 2);
        assert_eq!(side(&d, Vec3::new(15.0, 0.0, 25.0)), 3);
        assert_eq!(side(&d, Vec3::new(15.0, 0.0, 15.0)), 4);
    }

    /// Each probe lands in one facing group and one side group; the shares of the
    /// squared sky error sum to 1, and an exact group has none.
    #[test]
    fn groups_partition_the_probes_and_their_squared_error() {
        let d = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(16, 4, 16)).unwrap();
        let mut t = PlaceTally::default();
        let parts = |sky: f32| Parts {
            sky,
            sun: 0.0,
            direct: 0.0,
        };
        let at = Vec3::new(8.0, 1.0, 8.0);
        t.add(&d, &probe(at, Vec3::Y, true), parts(1.1), parts(1.0));
        t.add(&d, &probe(at, Vec3::Y, false), parts(1.0), parts(1.0));
        t.add(&d, &probe(at, -Vec3::Y, false), parts(0.5), parts(0.4));
        let edge = Vec3::new(0.5, 1.0, 8.0);
        t.add(&d, &probe(edge, Vec3::X, false), parts(2.0), parts(1.8));
        let p = t.places();
        let n: Vec<usize> = p.facing.iter().map(|g| g.errors.sky.n).collect();
        assert_eq!(n, [1, 1, 1, 1]);
        assert_eq!(p.side[1].errors.sky.n, 1);
        assert_eq!(p.side[4].errors.sky.n, 3);
        let share: f64 = p.facing.iter().map(|g| g.sky_share).sum();
        assert!((share - 1.0).abs() < 1e-12, "{share}");
        assert_eq!(p.facing[1].sky_share, 0.0);
        assert!((p.facing[3].errors.sky.bias - 0.2 / 1.8).abs() < 1e-6);
        assert!(lines(&p).contains("facing sideways"));
        assert_eq!(lines(&Places::default()), "");
    }
}
