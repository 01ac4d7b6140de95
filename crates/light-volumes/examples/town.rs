//! Local lights in a town of the shipped Kenney models: trace speed (BVH only, and with
//! deposits), the cached volume's size before and after compression and the error it
//! costs, and the time to toggle one light among 100.
//!
//! `cargo run --release -p lightgrid-light-volumes --example town`

use std::time::Instant;

use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::{GridDesc, NUM_DIRS};
use lightgrid_light_volumes::{
    CompressedVolume, Light, LightKind, LightSet, TraceParams, demo, trace_light,
};
use lightgrid_material_voxelizer::voxelize::RayScene;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let model = demo::town(&demo::assets_dir())?;
    let t = Instant::now();
    let scene = RayScene::new(&model, obvhs::BvhBuildParams::medium_build());
    println!(
        "town: {} triangles, BVH built in {:.1} ms",
        model.triangles.len(),
        t.elapsed().as_secs_f64() * 1e3
    );
    let desc = GridDesc::new(Vec3::new(-24.0, -0.5, -24.0), 1.0, UVec3::new(49, 17, 49))?;
    let lamp = Light {
        kind: LightKind::Point {
            position: Vec3::new(0.0, 3.0, 0.0),
        },
        colour: Vec3::new(1.0, 0.8, 0.55),
        intensity: 100.0,
    };
    let params = TraceParams::standard();
    // Progress: a line at every tenth of the rays.
    let shown = std::sync::atomic::AtomicU64::new(0);
    let progress = |done: u64, total: u64| {
        let tenth = done * 10 / total;
        if shown.fetch_max(tenth, std::sync::atomic::Ordering::Relaxed) < tenth {
            eprintln!("  tracing: {}%", tenth * 10);
        }
    };
    let (volume, stats) = trace_light(&scene, &desc, &lamp, &params, &progress)?;
    println!(
        "1 light, {} rays: {} segments, {:.0}% hit; wall {:.2} s; BVH {:.2} s and deposits {:.2} s (summed over threads)",
        stats.rays,
        stats.segments,
        100.0 * stats.hits as f64 / stats.segments as f64,
        stats.wall.as_secs_f64(),
        stats.bvh_time.as_secs_f64(),
        stats.deposit_time.as_secs_f64()
    );
    println!(
        "  {:.2} M segments/s per thread in the BVH; {:.2} M segments/s with deposits (all threads)",
        stats.rays_per_second_bvh() / 1e6,
        stats.rays_per_second() / 1e6
    );
    let key = lightgrid_light_volumes::volume_key(&lamp, &model, &desc, &params);
    let packed = CompressedVolume::compress(&volume, key);
    let full = desc.point_count() * NUM_DIRS * 12;
    let back = packed.decode().expect("lit");
    let (mut num, mut den, mut worst) = (0.0f64, 0.0f64, 0.0f32);
    for (i, b) in volume.data().iter().enumerate() {
        let p = desc.position(desc.coords(i).expect("in range"));
        let q = if back.desc().contains(p) {
            back.sample(p)?
        } else {
            lightgrid_core::BinLight::ZERO
        };
        for d in 0..NUM_DIRS {
            let e = (q.0[d] - b.0[d]).abs().max_element();
            worst = worst.max(e);
            num += (e as f64).powi(2);
            den += (b.0[d].max_element() as f64).powi(2);
        }
    }
    println!(
        "  volume: {:.2} MB as f32 bins, {:.3} MB compressed ({:.0}x; box {} of {} points); error: relative RMS {:.4}, largest {:.4} of the maximum",
        full as f64 / 1e6,
        packed.file_bytes() as f64 / 1e6,
        full as f64 / packed.file_bytes() as f64,
        packed.desc.expect("lit").point_count(),
        desc.point_count(),
        (num / den).sqrt(),
        worst / volume.max_value()
    );
    // 100 small lights (lamps and spots along the streets), 20 k rays each.
    let t = Instant::now();
    let mut set = LightSet::new(desc)?;
    let mut ids = Vec::new();
    let quick = TraceParams {
        rays: 20_000,
        ..TraceParams::preview()
    };
    for k in 0..100 {
        let (x, z) = (-18.0 + 4.0 * (k % 10) as f32, -18.0 + 4.0 * (k / 10) as f32);
        let kind = if k % 2 == 0 {
            LightKind::Point {
                position: Vec3::new(x, 2.5, z),
            }
        } else {
            LightKind::Spot {
                position: Vec3::new(x, 4.0, z),
                direction: Vec3::NEG_Y,
                inner: 0.3,
                outer: 0.7,
            }
        };
        let l = Light {
            kind,
            colour: Vec3::new(1.0, 0.9, 0.7),
            intensity: 5.0,
        };
        let (v, _) = trace_light(&scene, &desc, &l, &quick, &|_, _| {})?;
        ids.push(set.add(&CompressedVolume::compress(&v, 0), l.colour, l.intensity)?);
    }
    println!(
        "100 lights traced and merged in {:.2} s",
        t.elapsed().as_secs_f64()
    );
    set.take_dirty();
    let t = Instant::now();
    let toggles = 200;
    let mut points = 0;
    for k in 0..toggles {
        set.set_on(ids[k % 100], k % 200 >= 100)?;
        points += set.take_dirty().map_or(0, |r| r.point_count());
    }
    println!(
        "toggle one of 100 lights: {:.3} ms, {} points touched on average (of {}); {:.1} kB to upload",
        t.elapsed().as_secs_f64() * 1e3 / toggles as f64,
        points / toggles,
        desc.point_count(),
        (points / toggles * NUM_DIRS * 12) as f64 / 1e3
    );
    Ok(())
}
