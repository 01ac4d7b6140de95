//! A process's first sweep against the same sweep recycled: what a tool that sweeps
//! once pays. The canopy scene (32 points a side), 26 bins, 4 passes.
//!
//! `cargo run --release -p lightgrid-measure --example first_sweep [N]` (N points a
//! side, default 32). The first sweep is once per process, so the example runs itself
//! in 25 fresh processes, one after the other, and prints the median of their ratios
//! (each process: its first sweep against the median of 15 recycled ones). (With 9
//! processes the median moved by 0.1 from run to run on the 2-core VM.)

use std::time::Instant;

use lightgrid_core::{SweepOptions, Sweeper};
use lightgrid_measure::scenes::Scene;
use lightgrid_sweep_cpu::CpuSweeper;

/// Set in the child processes: measure once and print `first recycled` in seconds.
const CHILD: &str = "LIGHTGRID_FIRST_SWEEP_CHILD";
/// Fresh processes measured.
const PROCESSES: usize = 25;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let n: u32 = match std::env::args().nth(1) {
        Some(s) => s.parse()?,
        None => 32,
    };
    if std::env::var_os(CHILD).is_some() {
        let (first, recycled) = measure(n)?;
        println!("{first} {recycled}");
        return Ok(());
    }
    let mut runs: Vec<(f64, f64)> = Vec::new();
    for _ in 0..PROCESSES {
        let out = std::process::Command::new(std::env::current_exe()?)
            .arg(n.to_string())
            .env(CHILD, "1")
            .output()?;
        if !out.status.success() {
            return Err(format!(
                "a measuring process failed: {}",
                String::from_utf8_lossy(&out.stderr)
            )
            .into());
        }
        let text = String::from_utf8(out.stdout)?;
        let v: Vec<f64> = text
            .split_whitespace()
            .map(str::parse)
            .collect::<Result<_, _>>()?;
        let [first, recycled] = v[..] else {
            return Err(format!("unexpected output from a measuring process: {text}").into());
        };
        runs.push((first, recycled));
    }
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let ratios: Vec<f64> = runs.iter().map(|(f, r)| f / r).collect();
    let (lo, hi) = ratios
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), &x| (a.min(x), b.max(x)));
    println!(
        "{n}^3 canopy, 4 passes, {PROCESSES} fresh processes: first sweep {:.1} ms, recycled {:.1} ms (medians); first / recycled {:.2}x (median; {lo:.2}-{hi:.2}x)",
        median(runs.iter().map(|r| r.0).collect()) * 1e3,
        median(runs.iter().map(|r| r.1).collect()) * 1e3,
        median(ratios),
    );
    Ok(())
}

/// This process's first sweep and the median of 15 recycled ones, in seconds.
fn measure(n: u32) -> Result<(f64, f64), Box<dyn std::error::Error>> {
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
    Ok((first, times[times.len() / 2]))
}
