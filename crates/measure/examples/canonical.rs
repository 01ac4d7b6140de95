//! Sweeps the canonical scenes and compares each with the Monte Carlo reference, with
//! each medium emission rule (the default first).
//!
//! `cargo run --release -p lightgrid-measure --example canonical -- [size] [paths] [smoothing]`

use std::time::Instant;

use lightgrid_core::{MediumEmission, SweepOptions};
use lightgrid_measure::reference::{ReferenceOptions, trace};
use lightgrid_measure::scenes::{Scene, compare};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let n: u32 = args.first().and_then(|a| a.parse().ok()).unwrap_or(16);
    let paths: u64 = args
        .get(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(2_000_000);
    let smoothing: f32 = args
        .get(2)
        .and_then(|a| a.parse().ok())
        .unwrap_or(SweepOptions::multi_bounce().smoothing);
    println!(
        "{:<12} {:>9} {:>9} {:>10} {:>10} {:>9} {:>7}",
        "scene", "sweep ms", "mc s", "avg err", "irr err", "mc rse", "passes"
    );
    for scene in Scene::ALL {
        let (m, b) = scene.build(n);
        let mut o = SweepOptions::multi_bounce();
        o.tolerance = 1e-4;
        o.smoothing = smoothing;
        let t = Instant::now();
        let r = trace(
            &m,
            &b,
            &ReferenceOptions {
                paths,
                ..Default::default()
            },
            &|_, _| {},
        )
        .expect("reference");
        let mc_s = t.elapsed().as_secs_f64();
        for medium in [
            MediumEmission::Profile,
            MediumEmission::Source,
            MediumEmission::Escape,
        ] {
            o.medium = medium;
            // The fastest of three (the first also builds the profile rule's tables,
            // once per process).
            let mut sweep_ms = f64::INFINITY;
            let mut s = None;
            for _ in 0..3 {
                let t = Instant::now();
                s = Some(lightgrid_sweep_cpu::run(&m, &b, &o).expect("sweep"));
                sweep_ms = sweep_ms.min(t.elapsed().as_secs_f64() * 1e3);
            }
            let s = s.expect("swept");
            let e = compare(s.output.bins.as_ref().unwrap(), &r.light, &m);
            println!(
                "{:<12} {:>9.2} {:>9.2} {:>10.4} {:>10.4} {:>9.4} {:>7}  {medium:?}",
                scene.name(),
                sweep_ms,
                mc_s,
                e.average,
                e.irradiance,
                r.relative_std_error(0.0),
                s.output.stats.passes
            );
        }
    }
}
