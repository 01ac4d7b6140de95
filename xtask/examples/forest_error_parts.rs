//! Where the bench forest's error comes from: the sweep (4 passes, the default smoothing, as the
//! bench's headline) against a Monte Carlo reference for the sky alone, the bin-spread
//! sun alone, and both (`sky_and_sun`), on the same forest.
//! `cargo run --release -p xtask --example forest_error_parts -- [n] [paths]`.
use lightgrid_core::{BinLight, Boundary, SideBoundary, SweepOptions, glam::Vec3};
use lightgrid_measure::reference::{ReferenceOptions, trace};

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let n: u32 = args.get(1).map_or(Ok(16), |s| s.parse())?;
    let paths: u64 = args.get(2).map_or(Ok(4_000_000), |s| s.parse())?;
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let s = xtask::bench::scenes::forest(n, &root.join("assets"))?;
    let both = s.boundary.clone();
    let (sky, _) = BinLight::uniform(Vec3::ONE).split_vertical();
    let sky_only = Boundary {
        sides: SideBoundary::Periodic,
        ..Boundary::open_sky(sky)
    };
    let mut sun = both.clone();
    if let lightgrid_core::TopBoundary::Uniform(t) = &mut sun.top {
        for (v, k) in t.0.iter_mut().zip(sky.0.iter()) {
            *v -= *k;
        }
    }
    let mut o = SweepOptions::multi_bounce();
    // The bench's 4 passes, or (`PASSES=n`) more: converged, to tell the rules' light
    // apart from how fast they get there.
    o.max_passes = std::env::var("PASSES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(4);
    o.tolerance = 0.0;
    let only: Option<String> = args.get(3).cloned();
    for (name, b) in [
        ("sky and sun", &both),
        ("sky only", &sky_only),
        ("sun in a bin only", &sun),
    ] {
        if only.as_deref().is_some_and(|o| o != name) {
            continue;
        }
        let r = trace(
            &s.material,
            b,
            &ReferenceOptions {
                paths,
                seed: 0x5eed,
                ..Default::default()
            },
            &|_, _| {},
        )?;
        // The reference's own noise, as the bench states it.
        let noise = r.relative_std_error(0.0);
        if name == "sky only" {
            // By where the point is: inside a medium, in air beside one, elsewhere; the
            // source rule against the escape rule.
            let d = *s.material.desc();
            let cells = s.material.data();
            let medium = |i: usize| cells[i].pass > 0.0 && cells[i].pass < 1.0;
            let class = |i: usize| -> usize {
                if medium(i) {
                    return 0;
                }
                if cells[i].pass <= 0.0 {
                    return 3;
                }
                let c = d.coords(i).expect("in range").as_ivec3();
                let near = (-1..=1).any(|dx| {
                    (-1..=1).any(|dy| {
                        (-1..=1).any(|dz| {
                            let q = c + lightgrid_core::glam::IVec3::new(dx, dy, dz);
                            q.min_element() >= 0
                                && q.cmplt(d.dims().as_ivec3()).all()
                                && medium(d.index(q.as_uvec3()).expect("inside"))
                        })
                    })
                });
                if near { 1 } else { 2 }
            };
            for rule in [
                lightgrid_core::MediumEmission::Source,
                lightgrid_core::MediumEmission::Profile,
                lightgrid_core::MediumEmission::Escape,
            ] {
                let mut o2 = o;
                o2.medium = rule;
                let sw = lightgrid_sweep_cpu::run(&s.material, b, &o2)?;
                let bins = sw.output.bins.as_ref().expect("bins");
                let mut acc = [[0f64; 4]; 3];
                for i in 0..d.point_count() {
                    let k = class(i);
                    if k == 3 {
                        continue;
                    }
                    let a = lightgrid_core::light::luminance(bins.data()[i].average()) as f64;
                    let rr = lightgrid_core::light::luminance(r.light.data()[i].average()) as f64;
                    acc[k][0] += (a - rr).powi(2);
                    acc[k][1] += rr * rr;
                    acc[k][2] += a - rr;
                    acc[k][3] += rr;
                }
                for (k, label) in ["in media", "air beside media", "other air"]
                    .iter()
                    .enumerate()
                {
                    println!(
                        "  {rule:?} rule, {label:17}: relative RMSE {:.4}, bias {:+.2} %",
                        (acc[k][0] / acc[k][1].max(1e-30)).sqrt(),
                        100.0 * acc[k][2] / acc[k][3].max(1e-30)
                    );
                }
            }
        }
        for (smoothing, rule) in [
            (0.0f32, lightgrid_core::MediumEmission::Source),
            (0.25, lightgrid_core::MediumEmission::Source),
            (0.5, lightgrid_core::MediumEmission::Source),
            (0.25, lightgrid_core::MediumEmission::Profile),
            (0.5, lightgrid_core::MediumEmission::Profile),
        ] {
            o.smoothing = smoothing;
            o.medium = rule;
            let sw = lightgrid_sweep_cpu::run(&s.material, b, &o)?;
            let e = lightgrid_measure::scenes::compare(
                sw.output.bins.as_ref().expect("bins"),
                &r.light,
                &s.material,
            );
            println!(
                "{name:18} smoothing {smoothing:4}, {rule:?}: average {:.4}, irradiance {:.4} (reference noise {noise:.4})",
                e.average, e.irradiance
            );
        }
    }
    Ok(())
}
