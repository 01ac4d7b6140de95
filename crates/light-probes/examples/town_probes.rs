//! Probes in the shipped Kenney town (two buildings and two tree tiles on a 40 m
//! ground, from `light-volumes`): bake time and bytes per probe, relight time per frame
//! per 1000 probes, and the error of probe irradiance against the Monte Carlo
//! reference (`lightgrid_light_probes::reference`) at several sun positions.
//!
//! `cargo run --release -p lightgrid-light-probes --example town_probes -- [samples per axis]` (4000)

use std::time::Instant;

use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::light::{AMBIENT_AXES, luminance};
use lightgrid_core::{BinLight, GridDesc, LightField};
use lightgrid_light_probes::{
    Lighting, ProbeLight, ProbeParams, ProbeSet, ProbeVolume, place, place_walls, reference,
};
use lightgrid_material_voxelizer::voxelize::RayScene;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let samples: u32 = std::env::args()
        .nth(1)
        .map(|s| s.parse())
        .transpose()?
        .unwrap_or(4000);
    let model = lightgrid_light_volumes::demo::town(&lightgrid_light_volumes::demo::assets_dir())?;
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
    walls(&scene, lo, hi, sky, samples)?;
    Ok(())
}

/// The merged volume ([`ProbeVolume`]) in front of the buildings' walls, with the
/// column probes alone and with the probes along walls ([`place_walls`]): the relative
/// RMSE of the walls' irradiance (the volume's cube facing away from the wall, at a
/// point half a metre in front of it, 1.5 m up) against the reference.
fn walls(
    scene: &RayScene<'_>,
    lo: Vec3,
    hi: Vec3,
    sky: BinLight,
    samples: u32,
) -> Result<(), Box<dyn std::error::Error>> {
    let params = ProbeParams::standard();
    let columns = place(scene, lo, hi, &params);
    // Wall points: horizontal rays from a 2 m lattice at 1.5 m up.
    let mut points = Vec::new();
    for i in 0..20 {
        for k in 0..20 {
            let o = Vec3::new(
                lo.x + 2.0 * i as f32 + 1.0,
                1.5,
                lo.z + 2.0 * k as f32 + 1.0,
            );
            // Out in the open (not inside a building or under a tree).
            if scene.closest_hit(o, Vec3::Y, 100.0, 0.5).is_some() {
                continue;
            }
            for d in [Vec3::X, Vec3::NEG_X, Vec3::Z, Vec3::NEG_Z] {
                if let Some(h) = scene.closest_hit(o, d, 3.0, 0.5)
                    && h.normal.y.abs() < 0.3
                    && h.t > 0.6
                {
                    points.push((o + d * h.t + h.normal * 0.5, h.normal));
                }
            }
        }
    }
    let (e, a) = (40f32.to_radians(), 160f32.to_radians());
    let to_sun = Vec3::new(e.cos() * a.sin(), e.sin(), -e.cos() * a.cos());
    let lighting = Lighting {
        sky,
        sun: Some((to_sun, Vec3::new(6.0, 5.6, 5.0))),
    };
    let desc = GridDesc::new(
        Vec3::new(lo.x, 0.25, lo.z),
        1.0,
        ((hi - lo) / 1.0).ceil().as_uvec3().max(UVec3::ONE) + UVec3::ONE,
    )?;
    let reference: Vec<(f32, f32)> = points
        .iter()
        .enumerate()
        .map(|(i, (p, n))| {
            let (r, se) = reference::irradiance(
                scene,
                &lighting,
                *p,
                samples,
                params.max_distance,
                99 + i as u64,
            );
            let k = AMBIENT_AXES
                .iter()
                .enumerate()
                .max_by(|x, y| x.1.dot(*n).total_cmp(&y.1.dot(*n)))
                .map(|(k, _)| k)
                .unwrap_or(0);
            (luminance(r.irradiance(*n)), luminance(se.0[k]))
        })
        .collect();
    println!(
        "\nwalls: {} points half a metre in front of walls, 1.5 m up, sun at 40 deg",
        points.len()
    );
    println!("probes                      count  volume s  rel RMSE of wall irradiance (noise)");
    for (name, with_walls) in [("columns only", false), ("columns + along walls", true)] {
        let mut positions = columns.clone();
        if with_walls {
            positions.extend(place_walls(scene, &columns, &params));
        }
        let set = ProbeSet::bake(scene, &positions, &params, &|_, _| {})?;
        let vis = set.sun_visibility(scene, to_sun);
        let mut light = ProbeLight::new(&set);
        for _ in 0..8 {
            light.frame(&set, &lighting, &vis)?;
        }
        let t = Instant::now();
        let volume = ProbeVolume::new(scene, desc, &[&set], &|_, _| {})?;
        let t_volume = t.elapsed().as_secs_f64();
        let resolved = volume.resolve(&[&light])?;
        let (mut num, mut den, mut noise) = (0.0f64, 0.0f64, 0.0f64);
        for ((p, n), (want, se)) in points.iter().zip(&reference) {
            let got = luminance(resolved.irradiance(*p, *n)?) as f64;
            num += (got - *want as f64).powi(2);
            den += (*want as f64).powi(2);
            noise += (*se as f64).powi(2);
        }
        println!(
            "{name:26}  {:5}  {t_volume:8.2}  {:.3} ({:.3})",
            positions.len(),
            (num / den).sqrt(),
            (noise / den).sqrt()
        );
    }
    Ok(())
}
