//! What a scene edit costs: the fly-through's forest at the library's defaults (32-point
//! nodes, the sun at 30°), settled around a camera; then a box appears beside it (a
//! house under the trees, then a tower above the nodes' columns) and `refresh` frames
//! run until their round ends, then `update` frames until settled. Per edit: the
//! round's frames, time, points swept, nodes rebuilt (and of those, built anew at a new
//! height) and evicted, sun responses swept again; then a hierarchy built over the
//! edited scene from nothing, and the largest difference between the two at points
//! around the box (0: the same light bit for bit).
//!
//! `cargo run --release -p lightgrid-terrain-lod --example scene_edit [-- --with-sky]`
//! (`--with-sky`: the sun's first collisions swept with the sky, as the viewer does)

use std::sync::Arc;
use std::sync::atomic::{AtomicU8, Ordering};
use std::time::Instant;

use lightgrid_core::glam::Vec3;
use lightgrid_core::{BinLight, GridDesc, GridError, LightField, Material, MaterialGrid};
use lightgrid_sweep_cpu::CpuSweeper;
use lightgrid_terrain_lod::{FrameStats, Hierarchy, HierarchyParams, SunLight};

#[path = "../tests/demo/mod.rs"]
mod demo;

/// The forest's composer with one of `boxes` put in (`which`: 0 none, `i` the `i`th).
struct Edited<S> {
    inner: S,
    boxes: Vec<(Vec3, Vec3)>,
    which: Arc<AtomicU8>,
}

impl<S: lightgrid_core::MaterialSource> lightgrid_core::MaterialSource for Edited<S> {
    fn material(&self, desc: &GridDesc) -> Result<MaterialGrid, GridError> {
        let mut g = self.inner.material(desc)?;
        let which = self.which.load(Ordering::Relaxed) as usize;
        let Some(&(lo, hi)) = which.checked_sub(1).and_then(|i| self.boxes.get(i)) else {
            return Ok(g);
        };
        for i in 0..desc.point_count() {
            let p = desc.position(desc.coords(i).expect("in range"));
            if p.cmpge(lo).all() && p.cmplt(hi).all() {
                g.data_mut()[i] = Material::opaque(Vec3::new(0.6, 0.55, 0.5));
            }
        }
        Ok(g)
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let with_sky = std::env::args().any(|a| a == "--with-sky");
    let hm = demo::jacksboro(&demo::assets_dir())?;
    let forest = demo::Forest::flythrough();
    let (sky, _) = BinLight::uniform(Vec3::new(0.6, 0.7, 1.0)).split_vertical();
    let (cx, cz) = (600.0, 610.0);
    let ground = hm.height_at(cx, cz);
    let camera = Vec3::new(cx, ground + 20.0, cz);
    let foot = |dx: f32, dz: f32, size: f32, height: f32| {
        let (x, z) = (cx + dx, cz + dz);
        let g = hm.height_at(x + 0.5 * size, z + 0.5 * size);
        (
            Vec3::new(x, g - 2.0, z),
            Vec3::new(x + size, g + height, z + size),
        )
    };
    let boxes = [
        (
            "a house under the trees (12 x 12 m, 7 m tall)",
            foot(6.0, 4.0, 12.0, 7.0),
        ),
        (
            "a tower above the nodes' columns (8 x 8 m, 60 m tall)",
            foot(-14.0, 6.0, 8.0, 60.0),
        ),
    ];
    let elevation = 30f32.to_radians();
    let sun = SunLight {
        to_sun: Vec3::new(
            elevation.cos() * 20f32.to_radians().cos(),
            elevation.sin(),
            elevation.cos() * 20f32.to_radians().sin(),
        ),
        irradiance: Vec3::splat(3.0),
    };
    let build = |which: u8| -> Result<(Hierarchy, Arc<AtomicU8>), Box<dyn std::error::Error>> {
        let switch = Arc::new(AtomicU8::new(which));
        let source = Edited {
            inner: forest.composer(&hm)?,
            boxes: boxes.iter().map(|b| b.1).collect(),
            which: switch.clone(),
        };
        let mut h = Hierarchy::new(
            &hm,
            Box::new(source),
            Box::new(CpuSweeper::new()),
            sky,
            HierarchyParams {
                sun_with_sky: with_sky,
                ..HierarchyParams::default()
            },
        )?;
        h.set_sun(Some(sun))?;
        let s = h.settle(camera, 400, |_| {})?;
        assert_eq!((s.pending, s.sun_pending), (0, 0), "settled");
        Ok((h, switch))
    };
    let t = Instant::now();
    let (mut h, mut switch) = build(0)?;
    println!(
        "forest at the library's defaults{}, sun at 30°, camera at ({cx}, {:.1}, {cz}): built and settled in {:.2} s",
        if with_sky {
            " (the sun swept with the sky)"
        } else {
            ""
        },
        camera.y,
        t.elapsed().as_secs_f64()
    );
    for (i, (name, (lo, hi))) in boxes.iter().enumerate() {
        switch.store(i as u8 + 1, Ordering::Relaxed);
        let (round, round_ms, round_frames) = frames(|| h.refresh(camera), false)?;
        let (after, after_ms, after_frames) = frames(|| h.update(camera), true)?;
        let t = Instant::now();
        let (fresh, fresh_switch) = build(i as u8 + 1)?;
        let fresh_s = t.elapsed().as_secs_f64();
        // Points around the box: 1.5 m above the ground and at its mid-height.
        let mut worst = (0.0f32, 0.0f32);
        for k in 0..=40 {
            for j in 0..=40 {
                let (x, z) = (
                    lo.x - 20.0 + k as f32 * (hi.x - lo.x + 40.0) / 40.0,
                    lo.z - 20.0 + j as f32 * (hi.z - lo.z + 40.0) / 40.0,
                );
                for y in [hm.height_at(x, z) + 1.5, 0.5 * (lo.y + hi.y)] {
                    let p = Vec3::new(x, y, z);
                    let (a, b) = (h.reading(p, None)?, fresh.reading(p, None)?);
                    worst.0 = worst.0.max((a.sun - b.sun).abs());
                    let dl = (a.light.average() - b.light.average()).abs().max_element();
                    worst.1 = worst.1.max(dl);
                }
            }
        }
        println!("{name}:");
        println!(
            "  refresh round: {round_frames} frames, {round_ms:.0} ms; {} points swept, {} nodes rebuilt ({} of them at a new height), {} evicted, {} sun responses",
            round.points_swept, round.built, round.regrown, round.evicted, round.sun_built
        );
        println!(
            "  then update until settled: {after_frames} frames, {after_ms:.0} ms; {} points swept, {} nodes built, {} sun responses",
            after.points_swept, after.built, after.sun_built
        );
        println!(
            "  a hierarchy built over the edited scene from nothing: {fresh_s:.2} s; the largest difference from it at 3362 points around the box: sun transmittance {:.1e}, average light {:.1e}",
            worst.0, worst.1
        );
        (h, switch) = (fresh, fresh_switch);
    }
    Ok(())
}

/// Frames of `f` until one leaves nothing pending (and with `sun`, no sun response
/// pending; at most 400): their stats summed, milliseconds, frames.
fn frames(
    mut f: impl FnMut() -> Result<FrameStats, lightgrid_terrain_lod::LodError>,
    sun: bool,
) -> Result<(FrameStats, f64, u32), Box<dyn std::error::Error>> {
    let t = Instant::now();
    let mut sum = FrameStats::default();
    for n in 1..=400 {
        let s = f()?;
        sum.points_swept += s.points_swept;
        sum.built += s.built;
        sum.evicted += s.evicted;
        sum.regrown += s.regrown;
        sum.sun_built += s.sun_built;
        if s.pending == 0 && (!sun || s.sun_pending == 0) {
            return Ok((sum, t.elapsed().as_secs_f64() * 1e3, n));
        }
    }
    Err("not settled in 400 frames".into())
}
