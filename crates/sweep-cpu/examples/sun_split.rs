//! The sun split against the sun in the bins (issue 14), both against the Monte Carlo
//! reference with a collimated sun along its exact direction: per-point relative RMSE of
//! average light and of irradiance on the six axes (luminance, as `scenes::compare`),
//! sun light only (no sky), suns at several elevations and at azimuth 20 degrees (between
//! bins), on the canopy and dense-block scenes.
//!
//! Bins: the sun's disc split over the bins in the top boundary, swept; its light then
//! moves along the nearest bin and lands with the bin's mean cosine. Split: the exact
//! transmittance (`SunTransmittance::march`) for the direct beam, its first collisions
//! (`first_collision`) swept as a cell source for the scattered light.
//!
//! Then the shadow of a dense block on the ground: the direction from the block to the
//! centroid of the missing ground irradiance, against the exact one (away from the sun).
//!
//! `cargo run --release -p sweep-cpu --example sun_split -- [n] [paths]` (16, 2 000 000)

use lightgrid_core::glam::Vec3;
use lightgrid_core::light::{AMBIENT_AXES, luminance};
use lightgrid_core::{BinLight, Boundary, SweepOptions};
use sweep_cpu::reference::{CollimatedSun, ReferenceOptions, trace_with_sun};
use sweep_cpu::scenes::Scene;
use sweep_cpu::sky::Sun;
use sweep_cpu::sun::first_collision;
use sweep_cpu::{SunTransmittance, run, run_with_source};

/// Average light and the six axis irradiances of every point.
type Field = Vec<(f32, [f32; 6])>;

fn field(bins: &[BinLight], direct: Option<(&[f32], Vec3, Vec3)>) -> Field {
    bins.iter()
        .enumerate()
        .map(|(i, b)| {
            let (mut avg, mut irr) = (b.average(), AMBIENT_AXES.map(|n| b.irradiance(n)));
            if let Some((t, e, s)) = direct {
                avg += e * t[i] / (4.0 * std::f32::consts::PI);
                for (k, n) in AMBIENT_AXES.iter().enumerate() {
                    irr[k] += e * t[i] * n.dot(s).max(0.0);
                }
            }
            (luminance(avg), irr.map(luminance))
        })
        .collect()
}

fn errors(a: &Field, r: &Field, solid: &[bool]) -> (f64, f64) {
    let max = r.iter().map(|x| x.0).fold(0.0, f32::max);
    let (mut na, mut da, mut ni, mut di) = (0.0, 0.0, 0.0, 0.0);
    for ((x, y), &s) in a.iter().zip(r).zip(solid) {
        if s || y.0 <= 1e-3 * max {
            continue;
        }
        na += ((x.0 - y.0) as f64).powi(2);
        da += (y.0 as f64).powi(2);
        for k in 0..6 {
            ni += ((x.1[k] - y.1[k]) as f64).powi(2);
            di += (y.1[k] as f64).powi(2);
        }
    }
    ((na / da).sqrt(), (ni / di).sqrt())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let n: u32 = args.get(1).map(|s| s.parse()).transpose()?.unwrap_or(16);
    let paths: u64 = args
        .get(2)
        .map(|s| s.parse())
        .transpose()?
        .unwrap_or(2_000_000);
    let mut o = SweepOptions::multi_bounce();
    o.tolerance = 1e-5;
    o.max_passes = 64;
    println!("{n}^3 cells, {paths} reference paths; relative RMSE of average light / irradiance");
    println!("scene        elev   bins avg  bins irr   split avg  split irr   ref noise");
    for scene in [Scene::Canopy, Scene::DenseBlock] {
        let (m, b) = scene.build(n);
        let dark = Boundary {
            sides: b.sides.clone(),
            ..Boundary::open_sky(BinLight::ZERO)
        };
        let periodic = matches!(b.sides, lightgrid_core::SideBoundary::Periodic);
        let solid: Vec<bool> = m.data().iter().map(|c| c.pass <= 0.0).collect();
        for elev in [10.0f32, 25.0, 40.0, 60.0, 80.0] {
            let e = Vec3::ONE;
            let sun = Sun::at(elev.to_radians(), 20f32.to_radians(), e);
            let s = sun.direction;
            let reference = trace_with_sun(
                &m,
                &dark,
                Some(&CollimatedSun {
                    to_sun: s,
                    irradiance: e,
                }),
                &ReferenceOptions {
                    paths,
                    time_budget: None,
                    seed: 7,
                    max_events: 256,
                    max_track: 8.0,
                },
                &|_, _| {},
            )?;
            let ref_t: Vec<f32> = reference.direct.iter().map(|d| d.x / e.x).collect();
            let r = field(reference.light.data(), Some((&ref_t, e, s)));
            // The sun in the bins.
            let in_bins = Boundary {
                sides: b.sides.clone(),
                ..Boundary::open_sky(sun.bins()?)
            };
            let binned = run(&m, &in_bins, &o)?.output.bins.expect("bins");
            let fb = field(binned.data(), None);
            // The split.
            let open = |_: Vec3| 1.0;
            let t = SunTransmittance::march(&m, s, periodic, &open)?;
            let src = first_collision(&m, &t, s, e, periodic, &open)?;
            let scattered = run_with_source(&m, &dark, Some(&src), &o)?
                .output
                .bins
                .expect("bins");
            let fs = field(scattered.data(), Some((t.values(), e, s)));
            let (ba, bi) = errors(&fb, &r, &solid);
            let (sa, si) = errors(&fs, &r, &solid);
            println!(
                "{:12} {elev:4.0}   {ba:8.4}  {bi:8.4}   {sa:9.4}  {si:9.4}   {:9.4}",
                scene.name(),
                reference.relative_std_error(0.0)
            );
        }
    }
    shadows(&o)
}

/// Ground irradiance (facing up) one level above the ground, with the sun in the bins
/// and with the split.
fn ground_light(
    m: &lightgrid_core::MaterialGrid,
    sun: &Sun,
    o: &SweepOptions,
) -> Result<(Vec<f32>, Vec<f32>), Box<dyn std::error::Error>> {
    let periodic = lightgrid_core::SideBoundary::Periodic;
    let d = *m.desc();
    let level = d.level_range(1);
    let binned = run(
        m,
        &Boundary {
            sides: periodic.clone(),
            ..Boundary::open_sky(sun.bins()?)
        },
        o,
    )?
    .output
    .bins
    .expect("bins");
    let s = sun.direction;
    let open = |_: Vec3| 1.0;
    let t = SunTransmittance::march(m, s, true, &open)?;
    let src = first_collision(m, &t, s, sun.illuminance, true, &open)?;
    let dark = Boundary {
        sides: periodic,
        ..Boundary::open_sky(BinLight::ZERO)
    };
    let scattered = run_with_source(m, &dark, Some(&src), o)?
        .output
        .bins
        .expect("bins");
    let b: Vec<f32> = binned.data()[level.clone()]
        .iter()
        .map(|l| luminance(l.irradiance(Vec3::Y)))
        .collect();
    let sp: Vec<f32> = scattered.data()[level.clone()]
        .iter()
        .zip(&t.values()[level])
        .map(|(l, t)| luminance(l.irradiance(Vec3::Y) + sun.illuminance * (t * s.y)))
        .collect();
    Ok((b, sp))
}

fn shadows(o: &SweepOptions) -> Result<(), Box<dyn std::error::Error>> {
    use lightgrid_core::glam::UVec3;
    use lightgrid_core::{GridDesc, Material, MaterialGrid};
    let n = 32u32;
    let d = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(n, 10, n))?;
    let c = n / 2;
    let scene = |block: bool| {
        let cells = (0..d.point_count())
            .map(|i| {
                let p = d.coords(i).expect("in range");
                if p.y == 0 {
                    Material::opaque(Vec3::splat(0.3))
                } else if block
                    && (c - 1..c + 1).contains(&p.x)
                    && (c - 1..c + 1).contains(&p.z)
                    && p.y < 7
                {
                    Material {
                        reflectance: Vec3::splat(0.3),
                        pass: 0.05,
                    }
                } else {
                    Material::EMPTY
                }
            })
            .collect();
        MaterialGrid::new(d, cells)
    };
    let (with, without) = (scene(true)?, scene(false)?);
    println!(
        "\nshadow of a 2 x 6 x 2 dense block on a 32 x 32 ground: azimuth of the shadow's centroid"
    );
    println!("sun elev  azim   exact   bins (error)   split (error)");
    for (elev, azim) in [
        (40.0f32, 30.0f32),
        (30.0, 20.0),
        (55.0, 67.0),
        (25.0, 112.0),
    ] {
        let sun = Sun::at(elev.to_radians(), azim.to_radians(), Vec3::ONE);
        let (b1, s1) = ground_light(&with, &sun, o)?;
        let (b0, s0) = ground_light(&without, &sun, o)?;
        let centre = Vec3::new(c as f32 - 0.5, 0.0, c as f32 - 0.5);
        let azimuth = |lit: &[f32], open: &[f32]| {
            let (mut sum, mut acc) = (0.0f32, Vec3::ZERO);
            for (i, (a, b)) in lit.iter().zip(open).enumerate() {
                let deficit = (b - a).max(0.0);
                let p = Vec3::new((i as u32 % n) as f32, 0.0, (i as u32 / n) as f32);
                // Periodic ground: the nearest image of the point.
                let mut off = p - centre;
                off.x -= n as f32 * (off.x / n as f32).round();
                off.z -= n as f32 * (off.z / n as f32).round();
                acc += off * deficit;
                sum += deficit;
            }
            let v = acc / sum.max(1e-12);
            v.x.atan2(-v.z).to_degrees()
        };
        let s = sun.direction;
        let exact = (-s.x).atan2(s.z).to_degrees();
        let (ab, asp) = (azimuth(&b1, &b0), azimuth(&s1, &s0));
        let err = |a: f32| {
            let e = (a - exact + 540.0).rem_euclid(360.0) - 180.0;
            e.abs()
        };
        println!(
            "         {elev:4.0}  {azim:4.0}  {exact:6.1}  {ab:6.1} ({:4.1})   {asp:6.1} ({:4.1})",
            err(ab),
            err(asp)
        );
    }
    Ok(())
}
