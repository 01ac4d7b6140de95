//! The sun's first collisions by beam tracing (`lightgrid_sweep_cpu::beam`): how the
//! cells' deposits converge with the rays per cell, what they cost, and where the beam
//! goes, on a patchy canopy over opaque ground.
//!
//! `cargo run --release -p lightgrid-measure --example beam`

use std::time::Instant;

use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::{GridDesc, Material, MaterialGrid};
use lightgrid_sweep_cpu::beam::{BeamOptions, first_collisions};

fn canopy(n: u32, seed: u64) -> MaterialGrid {
    let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(n, n, n)).unwrap();
    let mut rng = fastrand::Rng::with_seed(seed);
    let top = n / 2;
    let cells = (0..desc.point_count())
        .map(|i| {
            let y = desc.coords(i).unwrap().y;
            let pass = if y == 0 {
                0.0
            } else if y <= top && rng.f32() < 0.5 {
                0.3 + 0.6 * rng.f32()
            } else {
                1.0
            };
            Material {
                reflectance: Vec3::splat(0.5),
                pass,
            }
        })
        .collect();
    MaterialGrid::new(desc, cells).unwrap()
}

fn main() {
    if std::env::args().any(|a| a == "--reference") {
        let paths = 4_000_000;
        let m = lightgrid_measure::sun_measure::patchy_canopy(16, 3);
        let mut o = lightgrid_core::SweepOptions::multi_bounce();
        o.tolerance = 1e-6;
        o.max_passes = 64;
        println!("patchy canopy 16 x 10 x 16, sun only, azimuth 20 deg, {paths} reference paths");
        println!(
            "elev  periodic  collided  bias     rms     max     ref noise  direct rms  scattered bias"
        );
        for elev in [10.0f32, 25.0, 40.0, 60.0] {
            for periodic in [true, false] {
                let e = lightgrid_measure::sun_measure::medium_errors(
                    &m,
                    periodic,
                    elev.to_radians(),
                    20f32.to_radians(),
                    paths,
                    &o,
                )
                .unwrap();
                println!(
                    "{elev:4.0}  {periodic:8}  {:.4}  {:+.4}  {:.4}  {:.4}  {:.4}     {:.4}      {:+.4}",
                    e.collided, e.bias, e.rms, e.max, e.noise, e.direct_rms, e.scattered_bias
                );
            }
        }
        return;
    }
    let n = 32;
    let m = canopy(n, 5);
    let open = |_: Vec3| 1.0;
    println!("patchy canopy {n}^3 over opaque ground; deposits against 1024 rays per cell");
    println!("elev  periodic  rays  ms   rms rel  max/mean  collided  left  budget err");
    for elev in [10.0f32, 25.0, 40.0, 60.0, 80.0] {
        let (e, a) = (elev.to_radians(), 20f32.to_radians());
        let s = Vec3::new(e.cos() * a.cos(), e.sin(), e.cos() * a.sin());
        for periodic in [true, false] {
            let t0 = Instant::now();
            let _ = lightgrid_sweep_cpu::SunTransmittance::march(&m, s, periodic, &open).unwrap();
            println!(
                "      the march (transmittance at the points): {:.1} ms",
                t0.elapsed().as_secs_f64() * 1e3
            );
            let truth = first_collisions(
                &m,
                s,
                Vec3::ONE,
                periodic,
                &open,
                &BeamOptions::DEFAULT.with_rays(1024),
            )
            .unwrap();
            let t = truth.source.removed();
            let mean = t.iter().map(|v| v.x as f64).sum::<f64>() / t.len() as f64;
            for rays in [4u32, 16, 64, 256] {
                let t0 = Instant::now();
                let f = first_collisions(
                    &m,
                    s,
                    Vec3::ONE,
                    periodic,
                    &open,
                    &BeamOptions::DEFAULT.with_rays(rays),
                )
                .unwrap();
                let ms = t0.elapsed().as_secs_f64() * 1e3;
                let (mut se, mut sw, mut worst) = (0.0f64, 0.0f64, 0.0f64);
                for (a, b) in f.source.removed().iter().zip(t) {
                    let (a, b) = (a.x as f64, b.x as f64);
                    se += (a - b).powi(2);
                    sw += b * b;
                    worst = worst.max((a - b).abs());
                }
                let b = f.budget;
                println!(
                    "{elev:4.0}  {periodic:8}  {rays:4}  {ms:5.1}  {:.4}  {:.3}  {:.4}  {:.4}  {:.1e}",
                    (se / sw).sqrt(),
                    worst / mean,
                    b.collided / b.entered,
                    (b.left_bottom + b.left_sides) / b.entered,
                    b.relative_error()
                );
            }
        }
    }
}
