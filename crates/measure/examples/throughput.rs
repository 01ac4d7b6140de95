//! Points per second of the sweep, quickly (criterion's `cargo bench -p lightgrid-measure` is
//! the measurement of record): the 64³ canopy with 26-bin output, one downward pass and
//! four passes, and a small tall grid (16 × 16 × 64), for the fast path into recycled
//! memory (`CpuSweeper::recycle`), into fresh memory, and the scalar oracle it must
//! equal.
//!
//! `cargo run --release -p lightgrid-measure --example throughput [source|profile|escape]`
//! (the medium emission rule; the default rule when left out).

use std::time::Instant;

use lightgrid_core::{MaterialGrid, Outputs, SweepOptions, Sweeper};
use lightgrid_measure::scenes::Scene;

fn best_of(n: usize, mut f: impl FnMut()) -> f64 {
    (0..n)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let medium = match std::env::args().nth(1).as_deref() {
        None => SweepOptions::multi_bounce().medium,
        Some("source") => lightgrid_core::MediumEmission::Source,
        Some("profile") => lightgrid_core::MediumEmission::Profile,
        Some("escape") => lightgrid_core::MediumEmission::Escape,
        Some(other) => return Err(format!("unknown medium rule {other:?}").into()),
    };
    println!("medium rule: {medium:?}");
    let (canopy, b) = Scene::Canopy.build(64);
    let (tall, tb) = {
        let (m, b) = Scene::Canopy.build(64);
        // The lower-left 16 x 16 columns, all 64 levels.
        let d = *m.desc();
        let sub = lightgrid_core::GridDesc::new(
            d.origin(),
            d.h(),
            lightgrid_core::glam::UVec3::new(16, 64, 16),
        )?;
        let cells = (0..sub.point_count())
            .map(|i| *m.get(sub.coords(i).expect("in range")).expect("inside"))
            .collect();
        (MaterialGrid::new(sub, cells)?, b)
    };
    println!(
        "{:34} {:>14} {:>12} {:>12}",
        "case", "recycled Mpt/s", "fast Mpt/s", "oracle Mpt/s"
    );
    for (name, m, bd, passes) in [
        ("64^3 canopy, 26 bins, 1 pass", &canopy, &b, 1),
        ("64^3 canopy, 26 bins, 4 passes", &canopy, &b, 4),
        ("16x64x16 canopy, 26 bins, 1 pass", &tall, &tb, 1),
    ] {
        let mut o = SweepOptions::multi_bounce();
        o.outputs = Outputs::ALL;
        o.max_passes = passes;
        o.tolerance = 0.0;
        o.medium = medium;
        let pts = m.desc().point_count() as f64;
        let mut sweeper = lightgrid_sweep_cpu::CpuSweeper::new();
        let recycled = best_of(8, || {
            let out = sweeper.sweep(m, bd, &o).expect("sweep");
            sweeper.recycle(out);
        });
        let fast = best_of(5, || {
            lightgrid_sweep_cpu::run(m, bd, &o).expect("sweep");
        });
        let oracle = best_of(3, || {
            lightgrid_sweep_cpu::sweep::run_scalar(m, bd, None, &o).expect("sweep");
        });
        println!(
            "{name:34} {:14.2} {:12.2} {:12.2}",
            pts / recycled / 1e6,
            pts / fast / 1e6,
            pts / oracle / 1e6
        );
    }
    Ok(())
}
