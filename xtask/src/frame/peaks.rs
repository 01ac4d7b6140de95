//! The largest nesting error against the local brightest value (issue 43: "3 % max of
//! the local brightest value away from shadow edges").
//!
//! Each probe's error against one sweep at its serving depth's own cell, `|h − r|`, is
//! divided by the brightest reference value among its neighbours on the probes'
//! lattice (itself and the probes one lattice step away on every axis: a terrain
//! vertex's 3 × 3, a volume point's 3 × 3 × 3 on all six axes: the brightest light
//! near it, whichever way it faces), for sky, sun and both apart. A probe is at a
//! shadow edge where the direct sun of its neighbours facing its way (the same
//! reference's) spans more than half their brightest: its error there is counted
//! apart, for sun and both (the sky has no sun's shadow edge; its probes all count).
//! The largest of these per depth is the figure; the 99.9th percentile beside it says
//! whether it is one probe or many, and [`Worst`] says where the largest lies and what
//! both sides read there.

use serde::Serialize;

use super::{Parts, Probe, VERTEX_SIDE, VOLUME_LEVELS, VOLUME_SIDE};

/// Where the neighbours' direct sun spans more than this share of their brightest, a
/// probe is at a shadow edge.
const EDGE_SPAN: f32 = 0.5;

/// The probes' lattice: `VERTEX_SIDE²` terrain vertices (x major), then
/// `VOLUME_SIDE² × VOLUME_LEVELS` volume points of six axes each ([`super::probes`]).
fn neighbours(i: usize, out: &mut Vec<usize>) {
    out.clear();
    let nv = VERTEX_SIDE * VERTEX_SIDE;
    let near = |c: usize, n: usize| c.saturating_sub(1)..=(c + 1).min(n - 1);
    if i < nv {
        let (x, z) = (i / VERTEX_SIDE, i % VERTEX_SIDE);
        for a in near(x, VERTEX_SIDE) {
            for b in near(z, VERTEX_SIDE) {
                out.push(a * VERTEX_SIDE + b);
            }
        }
        return;
    }
    let j = i - nv;
    let level = (j / 6) % VOLUME_LEVELS;
    let column = j / (6 * VOLUME_LEVELS);
    let (x, z) = (column / VOLUME_SIDE, column % VOLUME_SIDE);
    for a in near(x, VOLUME_SIDE) {
        for b in near(z, VOLUME_SIDE) {
            for l in near(level, VOLUME_LEVELS) {
                let first = nv + ((a * VOLUME_SIDE + b) * VOLUME_LEVELS + l) * 6;
                out.extend(first..first + 6);
            }
        }
    }
}

/// The worst errors of one depth over the path, relative to the local brightest value.
#[derive(Debug, Clone, Default, Serialize)]
pub struct Peaks {
    /// Probes served by the depth.
    pub probes: u64,
    /// Of them, at a shadow edge (left out of `sun` and `both`).
    pub at_edges: u64,
    /// Largest error of sky, sun and both, each over its local brightest.
    pub max: [f32; 3],
    /// The 99.9th percentile of the same.
    pub p999: [f32; 3],
    /// Where the largest of sky, sun and both lies (`None` without probes).
    pub worst: [Option<Worst>; 3],
}

/// The probe with a depth's largest error of one part, and what it reads.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct Worst {
    /// The error over the local brightest value.
    pub relative: f32,
    /// The frame it was read in.
    pub frame: u32,
    /// Where the probe lies (world metres).
    pub at: [f32; 3],
    /// The normal it reads the light on.
    pub facing: [f32; 3],
    /// A terrain vertex (else a volume point).
    pub vertex: bool,
    /// Its distance from the nearest side of its grid's points, in cells (negative in a
    /// seam).
    pub cells_from_side: f32,
    /// That side: `-x`, `+x`, `-z` or `+z`.
    pub side: &'static str,
    /// The hierarchy's value of the part.
    pub hierarchy: f32,
    /// The reference's value of the part.
    pub reference: f32,
    /// The brightest reference value of the part among its neighbours.
    pub brightest: f32,
    /// The reference's direct sun at the probe.
    pub direct: f32,
}

/// Where a frame's probes lie, for [`Worst`].
pub(super) struct Frame<'a> {
    /// The frame's number on the path.
    pub frame: u32,
    /// The probes (`super::probes`' lattice).
    pub probes: &'a [Probe],
    /// Probe `i`'s nearest side of its serving grid's points
    /// ([`super::places::SIDE_NAMES`]' index) and its distance from it, in cells (asked
    /// only of a probe that becomes a depth's worst).
    pub side_of: &'a dyn Fn(usize) -> (usize, f32),
}

/// The relative errors of every probe by depth, as the path goes.
#[derive(Default)]
pub(super) struct PeakTally {
    /// By depth: the relative errors of sky, sun and both (sun and both away from
    /// shadow edges), the probes at edges, and the probe with the largest of each.
    by_depth: Vec<DepthTally>,
}

/// One depth's relative errors of sky, sun and both, its probes at edges, and the
/// probe with the largest of each ([`PeakTally`]).
type DepthTally = ([Vec<f32>; 3], u64, [Option<Worst>; 3]);

impl PeakTally {
    /// A frame's probes (`at`): `depth[i]` the depth serving probe `i` (its reference
    /// `refs[depth]`, `None` where it has none), `h` the hierarchy's read.
    pub(super) fn add(
        &mut self,
        at: &Frame,
        depth: &[usize],
        h: &[Parts],
        refs: &[Option<&[Parts]>],
    ) {
        let mut near = Vec::with_capacity(27 * 6);
        for (i, (&d, hp)) in depth.iter().zip(h).enumerate() {
            let Some(Some(r)) = refs.get(d) else {
                continue;
            };
            debug_assert_eq!(r.len(), h.len());
            neighbours(i, &mut near);
            let (mut sky, mut sun, mut both) = (0.0f32, 0.0f32, 0.0f32);
            let (mut lo, mut hi) = (f32::INFINITY, 0.0f32);
            let nv = VERTEX_SIDE * VERTEX_SIDE;
            for &k in &near {
                let q = r[k];
                sky = sky.max(q.sky);
                sun = sun.max(q.sun);
                both = both.max(q.sky + q.sun);
                // Shadow edges among the neighbours facing the probe's way.
                if i < nv || (k - nv) % 6 == (i - nv) % 6 {
                    lo = lo.min(q.direct);
                    hi = hi.max(q.direct);
                }
            }
            let edge = hi > 0.0 && hi - lo > EDGE_SPAN * hi;
            if self.by_depth.len() <= d {
                self.by_depth.resize_with(d + 1, Default::default);
            }
            let (errs, edges, worsts) = &mut self.by_depth[d];
            let q = r[i];
            let parts = [
                (hp.sky, q.sky, sky),
                (hp.sun, q.sun, sun),
                (hp.sky + hp.sun, q.sky + q.sun, both),
            ];
            if edge {
                *edges += 1;
            }
            // The sky has no shadow edge: its probes all count.
            let counted = if edge { 1 } else { 3 };
            for (k, (hv, rv, m)) in parts.into_iter().enumerate().take(counted) {
                let e = if m > 0.0 { (hv - rv).abs() / m } else { 0.0 };
                errs[k].push(e);
                let worst = &mut worsts[k];
                if worst.is_none_or(|w| e > w.relative) {
                    let p = &at.probes[i];
                    let (side, cells) = (at.side_of)(i);
                    *worst = Some(Worst {
                        relative: e,
                        frame: at.frame,
                        at: p.p.to_array(),
                        facing: p.n.to_array(),
                        vertex: p.vertex,
                        cells_from_side: cells,
                        side: super::places::SIDE_NAMES[side],
                        hierarchy: hv,
                        reference: rv,
                        brightest: m,
                        direct: q.direct,
                    });
                }
            }
        }
    }

    /// The figures by depth (depths without probes empty).
    pub(super) fn peaks(&self) -> Vec<Peaks> {
        self.by_depth
            .iter()
            .map(|(errs, edges, worst)| {
                let mut max = [0.0; 3];
                let mut p999 = [0.0; 3];
                for (k, e) in errs.iter().enumerate() {
                    let mut v = e.clone();
                    v.sort_by(f32::total_cmp);
                    max[k] = v.last().copied().unwrap_or(0.0);
                    p999[k] = v
                        .get(((v.len() as f64 * 0.999) as usize).min(v.len().saturating_sub(1)))
                        .copied()
                        .unwrap_or(0.0);
                }
                Peaks {
                    probes: errs[0].len() as u64,
                    at_edges: *edges,
                    max,
                    p999,
                    worst: *worst,
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn neighbours_are_the_lattice_steps_around_a_probe_on_every_axis() {
        let mut n = Vec::new();
        // A corner vertex: 2 × 2; an inner one: 3 × 3, one step apart.
        neighbours(0, &mut n);
        assert_eq!(n, vec![0, 1, VERTEX_SIDE, VERTEX_SIDE + 1]);
        neighbours(VERTEX_SIDE + 1, &mut n);
        assert_eq!(n.len(), 9);
        // An inner volume point: 27 points of six axes, its own among them, each once.
        let nv = VERTEX_SIDE * VERTEX_SIDE;
        let i = nv + ((VOLUME_SIDE + 1) * VOLUME_LEVELS + 1) * 6 + 4;
        neighbours(i, &mut n);
        assert_eq!(n.len(), 27 * 6);
        assert!(n.contains(&i));
        let mut m = n.clone();
        m.sort();
        m.dedup();
        assert_eq!(m.len(), n.len());
        assert!(n.iter().all(|&k| k >= nv));
        // The last probe: a corner of the top level.
        let last = nv + VOLUME_SIDE * VOLUME_SIDE * VOLUME_LEVELS * 6 - 1;
        neighbours(last, &mut n);
        assert_eq!(n.len(), 8 * 6);
        assert!(n.iter().all(|&k| k <= last));
    }

    #[test]
    fn the_worst_error_is_relative_to_the_brightest_neighbour_and_edges_apart() {
        let nv = VERTEX_SIDE * VERTEX_SIDE;
        let total = nv + VOLUME_SIDE * VOLUME_SIDE * VOLUME_LEVELS * 6;
        let flat = Parts {
            sky: 1.0,
            sun: 2.0,
            direct: 1.0,
        };
        let mut r = vec![flat; total];
        // A bright neighbour of vertex (1, 1) and a shadow beside vertex (30, 30).
        r[VERTEX_SIDE + 2].sky = 4.0;
        r[30 * VERTEX_SIDE + 31].direct = 0.0;
        let mut h = r.clone();
        h[VERTEX_SIDE + 1].sky += 0.2; // 0.2 of its brightest neighbour's 4
        h[30 * VERTEX_SIDE + 30].sun += 1.0; // at an edge: not counted
        h[5 * VERTEX_SIDE + 5].sun += 0.1; // 0.1 / 2
        let depth = vec![1; total];
        let probes: Vec<Probe> = (0..total)
            .map(|i| Probe {
                p: lightgrid_core::glam::Vec3::new(i as f32, 0.0, 0.0),
                n: lightgrid_core::glam::Vec3::Y,
                vertex: i < nv,
            })
            .collect();
        let at = Frame {
            frame: 7,
            probes: &probes,
            side_of: &|i| (i % 4, i as f32 / 2.0),
        };
        let mut t = PeakTally::default();
        t.add(&at, &depth, &h, &[None, Some(&r)]);
        let p = &t.peaks()[1];
        assert_eq!(p.probes, total as u64);
        // Every probe whose 3 × 3 holds the dark vertex is at an edge: 9 of them.
        assert_eq!(p.at_edges, 9);
        assert!((p.max[0] - 0.05).abs() < 1e-6, "{p:?}");
        assert!((p.max[1] - 0.05).abs() < 1e-6, "{p:?}");
        assert!((p.max[2] - 0.1 / 3.0).abs() < 1e-6, "{p:?}");
        // The largest of sky and of sun: where they lie and what each side read.
        let sky = p.worst[0].expect("a sky probe");
        let i = VERTEX_SIDE + 1;
        assert_eq!(
            (sky.frame, sky.at[0], sky.cells_from_side),
            (7, i as f32, i as f32 / 2.0)
        );
        assert!(sky.vertex && sky.facing == [0.0, 1.0, 0.0]);
        assert_eq!(sky.side, ["-x", "+x", "-z", "+z"][i % 4]);
        assert!((sky.hierarchy - 1.2).abs() < 1e-6 && sky.reference == 1.0);
        assert_eq!((sky.brightest, sky.direct), (4.0, 1.0));
        assert!((sky.relative - p.max[0]).abs() < 1e-9);
        let sun = p.worst[1].expect("a sun probe");
        assert_eq!(sun.at[0], (5 * VERTEX_SIDE + 5) as f32);
        assert!((sun.hierarchy - 2.1).abs() < 1e-6);
        assert_eq!((sun.reference, sun.brightest), (2.0, 2.0));
        assert!(p.worst[2].is_some());
        // Depth 0 has no reference: nothing counted.
        let mut t = PeakTally::default();
        t.add(&at, &vec![0; total], &h, &[None, Some(&r)]);
        assert!(t.peaks().iter().all(|p| p.probes == 0));
    }
}
