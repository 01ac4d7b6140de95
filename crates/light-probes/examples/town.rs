//! Probes in the shipped Kenney town (two buildings and two tree tiles on a 40 m
//! ground, from `light-volumes`): bake time and bytes per probe, relight time per frame
//! per 1000 probes, and the error of probe irradiance against the Monte Carlo
//! reference (`light_probes::reference`) at several sun positions.
//!
//! `cargo run --release -p light-probes --example town -- [samples per axis]` (4000)

use std::time::Instant;

use light_probes::{Lighting, ProbeLight, ProbeParams, ProbeSet, place, reference};
use lightgrid_core::BinLight;
use lightgrid_core::glam::Vec3;
use lightgrid_core::light::luminance;
use material_voxelizer::voxelize::RayScene;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let samples: u32 = std::env::args()
        .nth(1)
        .map(|s| s.parse())
        .transpose()?
        .unwrap_or(4000);
    let model = light_volumes::demo::town(&light_volumes::demo::testdata_dir())?;
    let scene = RayScene::new(&model, obvhs::BvhBuildParams::fast_build());
    let (lo, hi) = model.bounds().ok_or("empty town")?;
    let sky = BinLight::uniform(Vec3::new(0.25, 0.3, 0.4));
    println!(
        "Kenney town: {} triangles, {lo} .. {hi}",
        model.triangles.len()
    );
    for (name, params) in [
        ("standard (4 m, bricks of 4)", ProbeParams::standard()),
        (
            "standard, brick 1",
            ProbeParams {
                brick: 1,
                ..ProbeParams::standard()
            },
        ),
    ] {
        let positions = place(&scene, lo, hi, &params);
        let t = Instant::now();
        let set = ProbeSet::bake(&scene, &positions, &params, &|_, _| {})?;
        let bake = t.elapsed().as_secs_f64();
        println!(
            "\n{name}: {} probes, {} surfels, {} bricks, {} factors; bake {bake:.2} s; {:.0} bytes a probe in all",
            set.probes().len(),
            set.surfels().len(),
            set.brick_count(),
            set.factors().len(),
            set.bytes() as f64 / set.probes().len() as f64
        );
        println!(
            "sun elev azim   sun vis ms  frame ms  per 1000 probes ms   rel RMSE vs reference (noise)"
        );
        // A dozen probes spread over the set for the reference.
        let picks: Vec<usize> = (0..12).map(|i| i * set.probes().len() / 12).collect();
        for (elev, azim) in [(15.0f32, 80.0f32), (40.0, 160.0), (65.0, 220.0)] {
            let (e, a) = (elev.to_radians(), azim.to_radians());
            let to_sun = Vec3::new(e.cos() * a.sin(), e.sin(), -e.cos() * a.cos());
            let lighting = Lighting {
                sky,
                sun: Some((to_sun, Vec3::new(6.0, 5.6, 5.0))),
            };
            let t = Instant::now();
            let vis = set.sun_visibility(&scene, to_sun);
            let t_vis = t.elapsed().as_secs_f64() * 1e3;
            let mut light = ProbeLight::new(&set);
            let frames = 8;
            let t = Instant::now();
            for _ in 0..frames {
                light.frame(&set, &lighting, &vis)?;
            }
            let t_frame = t.elapsed().as_secs_f64() * 1e3 / frames as f64;
            let (mut num, mut den, mut noise) = (0.0f64, 0.0f64, 0.0f64);
            for &i in &picks {
                let p = set.probes()[i].position;
                let (r, se) = reference::irradiance(
                    &scene,
                    &lighting,
                    p,
                    samples,
                    params.max_distance,
                    7 + i as u64,
                );
                let got = light.probes()[i];
                for k in 0..6 {
                    let (g, w) = (luminance(got.0[k]) as f64, luminance(r.0[k]) as f64);
                    num += (g - w).powi(2);
                    den += w * w;
                    noise += (luminance(se.0[k]) as f64).powi(2);
                }
            }
            println!(
                "     {elev:4.0} {azim:4.0}   {t_vis:10.1}  {t_frame:8.2}  {:18.2}   {:.3} ({:.3})",
                t_frame * 1000.0 / set.probes().len() as f64,
                (num / den).sqrt(),
                (noise / den).sqrt()
            );
        }
    }
    Ok(())
}
