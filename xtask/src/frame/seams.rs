//! Where the finest nodes' points read across a seam. At the last camera, once its
//! nodes are all built, the probes the finest depth serves are split by where their
//! read falls: within the serving node's points, or in the strip one cell wide between
//! its outermost points and its neighbour's (the read point is the probe moved half a
//! cell along its normal, as the sampler reads it). Each part is measured against the
//! 1 m sweep, whose points are the finest nodes' own: inside a node the two agree but
//! for what nesting hands over; across a seam the node's read is clamped to its own
//! outermost points where the single sweep interpolates between the two nodes' points.

use lightgrid_terrain_lod::Hierarchy;
use serde::Serialize;

use super::{Acc3, Errors, Parts, Probe};

/// The finest depth's probes at the last camera, settled, by where they read.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct Seams {
    /// Reads within the serving node's points.
    pub inside: Errors,
    /// Reads in the strip between two nodes' points.
    pub across: Errors,
}

/// Whether `p`'s read (moved half a cell along `n`) falls outside the serving grid's
/// points across (x or z).
pub(super) fn across_seam(h: &Hierarchy, p: &Probe) -> bool {
    let d = h.grid_at(p.p).desc();
    let g = d.to_grid(p.p + p.n * (0.5 * d.h()));
    let last = d.dims().as_vec3() - 1.0;
    g.x < 0.0 || g.z < 0.0 || g.x > last.x || g.z > last.z
}

/// The errors of the finest depth's probes, `hier` against `refs` (the 1 m sweep), by
/// where they read.
pub(super) fn measure(h: &Hierarchy, probes: &[Probe], hier: &[Parts], refs: &[Parts]) -> Seams {
    let finest = h.params().finest_cell;
    let (mut inside, mut across) = (Acc3::default(), Acc3::default());
    for ((p, a), r) in probes.iter().zip(hier).zip(refs) {
        if h.grid_at(p.p).desc().h() != finest {
            continue;
        }
        if across_seam(h, p) {
            across.add(*a, *r);
        } else {
            inside.add(*a, *r);
        }
    }
    Seams {
        inside: inside.errors(),
        across: across.errors(),
    }
}

/// The report's line.
pub(super) fn line(s: &Seams) -> String {
    let part = |e: &Errors| {
        format!(
            "sky {:.1}, sun {:.1}, direct sun {:.1} ({} probes)",
            100.0 * e.sky.rmse,
            100.0 * e.sun.rmse,
            100.0 * e.direct.rmse,
            e.both.n
        )
    };
    format!(
        "  at the last camera, settled, the finest depth's probes by where they read (RMSE % against the 1 m sweep): within a node's points {}; across a seam between two nodes' points {}\n",
        part(&s.inside),
        part(&s.across)
    )
}
