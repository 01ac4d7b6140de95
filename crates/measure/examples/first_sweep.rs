//! A process's first sweep against the same sweep recycled: what a tool that sweeps
//! once pays. The canopy scene (32 points a side), 26 bins, 4 passes.
//!
//! `cargo run --release -p lightgrid-measure --example first_sweep [N]` (N points a
//! side, default 32). Run it several times: the first sweep is once per process.

use std::time::Instant;

use lightgrid_core::{SweepOptions, Sweeper};
use lightgrid_measure::scenes::Scene;
use lightgrid_sweep_cpu::CpuSweeper;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let n: u32 = match std::env::args().nth(1) {
        Some(s) => s.parse()?,
        None => 32,
    };
    let (m, b) = Scene::Canopy.build(n);
    let mut o = SweepOptions::multi_bounce();
    o.max_passes = 4;
    let mut s = CpuSweeper::new();
    let t = Instant::now();
    let out = s.sweep(&m, &b, &o)?;
    let first = t.elapsed().as_secs_f64();
    s.recycle(out);
    let mut times: Vec<f64> = (0..15)
        .map(|_| {
            let t = Instant::now();
            let out = s.sweep(&m, &b, &o).expect("the same sweep again");
            let dt = t.elapsed().as_secs_f64();
            s.recycle(out);
            dt
        })
        .collect();
    times.sort_by(f64::total_cmp);
    let recycled = times[times.len() / 2];
    println!(
        "{n}^3 canopy, 4 passes: first sweep {:.1} ms, recycled {:.1} ms (median of 15): {:.2}x",
        first * 1e3,
        recycled * 1e3,
        first / recycled
    );
    Ok(())
}
