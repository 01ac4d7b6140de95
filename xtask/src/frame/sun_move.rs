//! Time of day: the sun moved 20° higher once the last camera's nodes are all built (the
//! move's own effect, not the path's), timed from `set_sun` until a frame installs the
//! new sun and until one finds nothing left to do, and the light measured as `set_sun`
//! returns and once settled against the reference swept for the new sun.

use std::time::{Duration, Instant};

use anyhow::Result;
use lightgrid_core::glam::Vec3;
use lightgrid_terrain_lod::{Hierarchy, HierarchyParams, SunLight};

use super::reference::Reference;
use super::{Acc3, Errors, Parts, Probe, SUN_E, process_cpu_ms, sample_parts, settle, sun_dir};

/// What a moved sun cost and how its light compares.
pub(super) struct SunMove {
    /// `set_sun`'s wall time (the world grid's new sun), ms.
    pub world_ms: f64,
    /// The process's CPU time in `set_sun`, ms, where the platform tells.
    pub cpu_ms: Option<f64>,
    /// Grids whose direct sun `set_sun` re-marched.
    pub marched: usize,
    /// Frames before the one that installed the new sun.
    pub wait_frames: u32,
    /// The longest of those, ms.
    pub wait_max_ms: f64,
    /// From `set_sun` until the frame that installs it began, ms.
    pub landed_ms: f64,
    /// That frame's time, ms.
    pub frame_ms: f64,
    /// Its sun responses built.
    pub built: u32,
    /// Its sun responses left.
    pub pending: u32,
    /// From `set_sun` until every wanted node's sun is the new one, ms.
    pub settled_ms: f64,
    /// Frames until then.
    pub settled_frames: u32,
    /// The probes' error as `set_sun` returns.
    pub error_at_once: Errors,
    /// The same once settled.
    pub error_settled: Errors,
}

/// Moves the sun of `h`, settled at `cam`, from `elevation` to 20° higher and measures
/// it at `probes` against `reference` (swept again for the new sun), frames at `pace`.
pub(super) fn measure(
    h: &mut Hierarchy,
    reference: &mut Reference,
    params: &HierarchyParams,
    probes: &[Probe],
    (elevation, cam, pace): (f32, Vec3, Duration),
) -> Result<SunMove> {
    let moved = sun_dir((elevation + 20.0).min(89.0));
    let cpu = process_cpu_ms();
    let t = Instant::now();
    h.set_sun(Some(SunLight {
        to_sun: moved,
        irradiance: SUN_E,
    }))?;
    let world_ms = t.elapsed().as_secs_f64() * 1e3;
    let cpu_ms = cpu.zip(process_cpu_ms()).map(|(a, b)| b - a);
    let marched = h.layers().iter().filter(|l| l.sun.is_some()).count();
    let at_once = sample_parts(h, probes, moved)?;
    // Frames at the budget's pace until one installs the new sun (at once unbudgeted).
    let (mut wait_frames, mut wait_max_ms) = (0u32, 0.0f64);
    let (s, frame_ms) = loop {
        let f = Instant::now();
        let s = h.update(cam)?;
        let ms = f.elapsed().as_secs_f64() * 1e3;
        if !h.sun_moving() {
            break (s, ms);
        }
        wait_frames += 1;
        wait_max_ms = wait_max_ms.max(ms);
        anyhow::ensure!(
            wait_frames < 100_000,
            "the moved sun's world grid never landed"
        );
        std::thread::sleep(pace.saturating_sub(f.elapsed()));
    };
    let landed_ms = t.elapsed().as_secs_f64() * 1e3 - frame_ms;
    // Then until a frame finds nothing left to do (it counts).
    let settled_frames = wait_frames + 1 + settle(h, cam, pace)?;
    let settled_ms = t.elapsed().as_secs_f64() * 1e3;
    let settled = sample_parts(h, probes, moved)?;
    reference.sweep_sun(params, moved)?;
    let refs = reference.sky_and_sun(probes)?;
    let error_of = |parts: &[Parts]| {
        let mut acc = Acc3::default();
        for (hp, r) in parts.iter().zip(&refs) {
            acc.add(*hp, *r);
        }
        acc.errors()
    };
    Ok(SunMove {
        world_ms,
        cpu_ms,
        marched,
        wait_frames,
        wait_max_ms,
        landed_ms,
        frame_ms,
        built: s.sun_built,
        pending: s.sun_pending,
        settled_ms,
        settled_frames,
        error_at_once: error_of(&at_once),
        error_settled: error_of(&settled),
    })
}
