//! The far probes: volume points out to [`REACH`] metres from the camera, where the
//! coarser depths serve once the path is under way. The near probes (`probes`) lie
//! within some 20 m of the camera, which the finest nodes serve once built, so they
//! measure a coarser depth only in the cold start (`served.rs`); these measure each
//! coarser depth where a user sees it, against one sweep at that depth's own cell (the
//! nesting alone: the regions of those sweeps reach this far, the 1 m sweep's does
//! not, so the finest depth's far probes are only counted).

use lightgrid_core::glam::Vec3;
use serde::Serialize;

use super::{Acc3, Errors, Parts, Probe, Served, World};

/// Metres from the camera, along x and z, that the far probes reach.
pub(super) const REACH: f32 = 192.0;
/// Metres between the far probes' columns.
const STEP: f32 = 12.0;
/// Columns within this many metres of the camera along both x and z are left out:
/// the near probes' square (`NEAR_REACH`) and a little more.
const INNER: f32 = 24.0;
/// Heights of the far probes above the ground, metres.
const HEIGHTS: [f32; 3] = [2.0, 6.0, 10.0];

/// The far probes around camera `cam`: columns [`STEP`] metres apart out to [`REACH`]
/// (those within [`INNER`] on both axes left out), at [`HEIGHTS`] above the ground, on
/// six axes each.
pub(super) fn probes(world: &World, cam: Vec3) -> Vec<Probe> {
    let n = (REACH / STEP) as i32;
    let axes = [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z];
    let mut out = Vec::new();
    for i in -n..=n {
        for k in -n..=n {
            let (dx, dz) = (STEP * i as f32, STEP * k as f32);
            if dx.abs() <= INNER && dz.abs() <= INNER {
                continue;
            }
            let (x, z) = (cam.x + dx, cam.z + dz);
            let g = world.hm.height_at(x, z);
            for dy in HEIGHTS {
                let p = Vec3::new(x, g + dy, z);
                out.extend(axes.iter().map(|&n| Probe {
                    p,
                    n,
                    vertex: false,
                }));
            }
        }
    }
    out
}

/// The far probes' errors over a path.
#[derive(Default)]
pub(super) struct FarTally {
    /// By the depth serving a probe, against that depth's own-cell sweep.
    by_depth_own: Vec<Acc3>,
    /// By depth, the probes it served in each frame.
    served: Vec<Vec<u64>>,
}

impl FarTally {
    /// Frame `f`'s far probes: the depth serving each, the hierarchy's parts, and each
    /// depth's own-cell reference (`None` where there is none: the world grid, and the
    /// finest depth, whose 1 m sweep does not reach this far).
    pub(super) fn add(
        &mut self,
        f: u32,
        depths: &[usize],
        parts: &[Parts],
        own_refs: &[Option<&[Parts]>],
    ) {
        for (i, (&d, &hp)) in depths.iter().zip(parts).enumerate() {
            super::served::count(&mut self.served, d, f);
            if self.by_depth_own.len() <= d {
                self.by_depth_own.resize(d + 1, Acc3::default());
            }
            if let Some(r) = own_refs.get(d).copied().flatten() {
                self.by_depth_own[d].add(hp, r[i]);
            }
        }
    }

    /// What the path's far probes measured.
    pub(super) fn far(&self) -> Far {
        Far {
            by_depth_own: self.by_depth_own.iter().map(Acc3::errors).collect(),
            served: self.served.iter().map(|v| Served::of(v)).collect(),
        }
    }
}

/// The far probes over a path.
#[derive(Debug, Clone, Default, Serialize)]
pub struct Far {
    /// By the depth serving a probe, against one sweep of the region at that depth's own
    /// cell (empty errors, `n` 0, where none was measured).
    pub by_depth_own: Vec<Errors>,
    /// By depth, the frames it served far probes in.
    pub served: Vec<Served>,
}

/// The report's line of the far probes at sun `elevation`.
pub(super) fn line(far: &Far, elevation: f32) -> String {
    let mut parts = Vec::new();
    for (d, (e, s)) in far.by_depth_own.iter().zip(&far.served).enumerate() {
        if s.probes == 0 {
            continue;
        }
        parts.push(if e.both.n == 0 {
            format!("depth {d} {} probes (no own-cell sweep)", s.probes)
        } else {
            format!(
                "depth {d} {} / {} / {} ({} probes in {} frames)",
                pair(e.sky),
                pair(e.sun),
                pair(e.both),
                s.probes,
                s.frames
            )
        });
    }
    format!(
        "  far probes ({:.0}–{:.0} m from the camera, {} m above the ground), nesting alone at sun {:.0}° (bias / RMSE % of sky / sun / both against one sweep at each depth's own cell): {}\n",
        INNER,
        REACH,
        HEIGHTS.map(|h| format!("{h:.0}")).join(", "),
        elevation,
        parts.join("; ")
    )
}

/// `bias / RMSE` in percent.
fn pair(e: super::Error) -> String {
    format!("{:+.1} / {:.1}", 100.0 * e.bias, 100.0 * e.rmse)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Parts of one value in every part.
    fn parts(v: f32) -> Parts {
        Parts {
            sky: v,
            sun: v,
            direct: v,
        }
    }

    /// A depth with a reference is measured against it, one without is counted only,
    /// and each probe's frame is kept.
    #[test]
    fn far_probes_are_measured_by_their_depths_own_reference() {
        let mut t = FarTally::default();
        let refs = [parts(1.0), parts(1.0), parts(1.0)];
        let own: [Option<&[Parts]>; 3] = [None, Some(&refs), None];
        // Depth 1 reads 1.1 against 1: +10 %; depth 2 has no reference.
        t.add(3, &[1, 1, 2], &[parts(1.1), parts(1.1), parts(7.0)], &own);
        let far = t.far();
        let e = far.by_depth_own[1];
        assert_eq!(e.sky.n, 2);
        assert!((e.sky.bias - 0.1).abs() < 1e-6, "{}", e.sky.bias);
        assert!((e.both.rmse - 0.1).abs() < 1e-6, "{}", e.both.rmse);
        assert_eq!(far.by_depth_own[2].both.n, 0);
        assert_eq!(far.served[2].probes, 1);
        assert_eq!(far.served[1].most_frame, 3);
        let l = line(&far, 15.0);
        assert!(l.contains("depth 1 +10.0 / 10.0"), "{l}");
        assert!(l.contains("depth 2 1 probes (no own-cell sweep)"), "{l}");
    }
}
