//! Probe relighting in the Kenney town on the CPU (`lightgrid_light_probes::ProbeLight`, rayon)
//! and on the GPU (`lightgrid_light_probes::GpuProbeRelight`, any adapter): time per
//! frame and per 1 000 probes, and the largest difference between the two.
//!
//! `cargo run --release -p lightgrid-light-probes --example gpu_town`

use std::sync::Arc;
use std::time::Instant;

use lightgrid_core::BinLight;
use lightgrid_core::glam::Vec3;
use lightgrid_light_probes::{Lighting, ProbeLight, ProbeParams, ProbeSet, place};
use lightgrid_material_voxelizer::voxelize::RayScene;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let model = lightgrid_light_volumes::demo::town(&lightgrid_light_volumes::demo::assets_dir())?;
    let scene = RayScene::new(&model, obvhs::BvhBuildParams::fast_build());
    let (lo, hi) = model.bounds().ok_or("empty town")?;
    let ctx = Arc::new(lightgrid_gpu::GpuContext::new()?);
    println!("adapter: {} ({:?})", ctx.info.name, ctx.info.device_type);
    for (name, spacing) in [("4 m", 4.0f32), ("1 m", 1.0)] {
        let params = ProbeParams {
            spacing,
            ..ProbeParams::standard()
        };
        let set = ProbeSet::bake(&scene, &place(&scene, lo, hi, &params), &params, &|_, _| {})?;
        let to_sun = Vec3::new(0.3, 0.64, -0.7);
        let lighting = Lighting {
            sky: BinLight::uniform(Vec3::new(0.25, 0.3, 0.4)),
            sun: Some((to_sun, Vec3::new(6.0, 5.6, 5.0))),
        };
        let vis = set.sun_visibility(&scene, to_sun);
        let mut cpu = ProbeLight::new(&set);
        let mut gpu = lightgrid_light_probes::GpuProbeRelight::new(ctx.clone(), &set)?;
        let frames = 10;
        let t = Instant::now();
        for _ in 0..frames {
            cpu.frame(&set, &lighting, &vis)?;
        }
        let t_cpu = t.elapsed().as_secs_f64() * 1e3 / frames as f64;
        gpu.frame(&lighting, &vis)?;
        gpu.read()?;
        let t = Instant::now();
        for _ in 1..frames {
            gpu.frame(&lighting, &vis)?;
        }
        let g = gpu.read()?; // waits for the device
        let t_gpu = t.elapsed().as_secs_f64() * 1e3 / (frames - 1) as f64;
        let scale = cpu
            .probes()
            .iter()
            .flat_map(|a| a.0)
            .map(|v| v.max_element())
            .fold(0.0, f32::max);
        let diff = cpu
            .probes()
            .iter()
            .zip(&g)
            .flat_map(|(a, b)| (0..6).map(move |k| (a.0[k] - b.0[k]).abs().max_element()))
            .fold(0.0, f32::max);
        let n = set.probes().len() as f64;
        println!(
            "spacing {name}: {} probes, {} surfels, {} bricks: CPU {t_cpu:.2} ms a frame ({:.2} ms per 1000 probes), GPU {t_gpu:.2} ms ({:.2}); largest difference {:.1e} of the largest value",
            set.probes().len(),
            set.surfels().len(),
            set.brick_count(),
            t_cpu * 1000.0 / n,
            t_gpu * 1000.0 / n,
            diff / scale
        );
    }
    Ok(())
}
