//! How the 26 bins read irradiance across the horizon (issue 44): a horizontal bin holds
//! light travelling slightly down and slightly up, and `BinLight::irradiance` reads it
//! as even across the horizon. Against exact answers (an infinite Lambertian ground
//! under a uniform sky) and against the Monte Carlo reference's irradiance tally, which
//! uses the paths' exact directions (`Reference::irradiance`), on canopies.
//!
//! `cargo run --release -p lightgrid-measure --example horizon -- [paths]` (2 000 000)

use lightgrid_core::glam::Vec3;
use lightgrid_core::light::{AMBIENT_AXES, luminance};
use lightgrid_core::{Boundary, MaterialGrid, SideBoundary, SweepOptions};
use lightgrid_measure::reference::{ReferenceOptions, trace};
use lightgrid_measure::scenes::Scene;

fn converged() -> SweepOptions {
    let mut o = SweepOptions::multi_bounce();
    o.max_passes = 64;
    o.tolerance = 1e-6;
    o
}

/// Bias and relative RMS of the six axes' irradiance, sweep against the reference's
/// tally, over the cells that are not opaque; then the bias facing up and facing down.
fn axes_errors(m: &MaterialGrid, b: &Boundary, paths: u64) -> [f64; 4] {
    let g = lightgrid_sweep_cpu::run(m, b, &converged())
        .unwrap()
        .output
        .bins
        .unwrap();
    let r = trace(
        m,
        b,
        &ReferenceOptions {
            paths,
            seed: 21,
            max_track: 64.0,
            ..Default::default()
        },
        &|_, _| {},
    )
    .unwrap();
    let (mut s, mut sr, mut se, mut sw) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    // Per axis: sweep and reference sums.
    let mut per = [(0.0f64, 0.0f64); 6];
    for (i, c) in m.data().iter().enumerate() {
        if c.pass <= 0.0 {
            continue;
        }
        for (k, n) in AMBIENT_AXES.iter().enumerate() {
            let a = luminance(g.data()[i].irradiance(*n)) as f64;
            let want = luminance(r.irradiance[i][k]) as f64;
            s += a;
            sr += want;
            per[k].0 += a;
            per[k].1 += want;
            se += (a - want).powi(2);
            sw += want * want;
        }
    }
    let bias = |k: usize| per[k].0 / per[k].1 - 1.0;
    let (up, down) = (
        AMBIENT_AXES.iter().position(|n| n.y > 0.0).unwrap(),
        AMBIENT_AXES.iter().position(|n| n.y < 0.0).unwrap(),
    );
    [s / sr - 1.0, (se / sw).sqrt(), bias(up), bias(down)]
}

fn main() {
    let paths: u64 = std::env::args()
        .nth(1)
        .map(|s| s.parse().expect("paths: a number"))
        .unwrap_or(2_000_000);
    let sky = lightgrid_sky::uniform_sky(Vec3::ONE).unwrap().top;
    println!("Lambertian ground under a uniform sky of radiance 1: the bins' irradiance just");
    println!("above the ground against the exact one (up pi, down a pi, sideways (1 + a) pi / 2)");
    println!("levels  albedo   up (err)          down (err)        sideways (err)");
    for levels in [1u32, 3] {
        for albedo in [0.3f32, 0.8] {
            let m = lightgrid_measure::exact::ground_material(levels, albedo).unwrap();
            let b = Boundary {
                sides: SideBoundary::Periodic,
                ..Boundary::open_sky(sky)
            };
            let g = lightgrid_sweep_cpu::run(&m, &b, &converged())
                .unwrap()
                .output
                .bins
                .unwrap();
            let l = g.data()[m.desc().level_len() * levels as usize];
            let pi = std::f32::consts::PI;
            let row = [
                (l.irradiance(Vec3::Y).x, pi),
                (l.irradiance(Vec3::NEG_Y).x, albedo * pi),
                (l.irradiance(Vec3::X).x, (1.0 + albedo) * pi / 2.0),
            ]
            .map(|(got, want)| format!("{got:.4} ({:+5.1} %)", 100.0 * (got / want - 1.0)));
            println!(
                "{levels:6}  {albedo:6}   {}   {}   {}",
                row[0], row[1], row[2]
            );
        }
    }
    println!();
    println!(
        "six axes' irradiance per cell, sweep (bins) against the reference's tally ({paths} paths)"
    );
    println!("scene                     bias      relative RMS   bias facing up   facing down");
    for scene in [
        Scene::Canopy,
        Scene::CanopyOneLevelGround,
        Scene::UniformFog,
    ] {
        let (m, b) = scene.build(16);
        let e = axes_errors(&m, &b, paths);
        println!(
            "{:24}  {:+.4}   {:.4}         {:+.4}          {:+.4}",
            scene.name(),
            e[0],
            e[1],
            e[2],
            e[3]
        );
    }
    let m = lightgrid_measure::sun_measure::patchy_canopy(16, 3);
    let b = Boundary {
        sides: SideBoundary::Periodic,
        ..Boundary::open_sky(sky)
    };
    let e = axes_errors(&m, &b, paths);
    println!(
        "{:24}  {:+.4}   {:.4}         {:+.4}          {:+.4}",
        "patchy canopy, sky", e[0], e[1], e[2], e[3]
    );
}
