//! Times the bench forest's sweep (16³, 4 passes, smoothing 0.25: the headline setting
//! of `cargo xtask bench`) many times over, for a profiler:
//! `cargo run --release -p xtask --example forest_profile -- [n] [repeats] [rule]`
//! (`rule`: `profile`, the default, or `source`, the flat source).
use lightgrid_core::{SweepOptions, Sweeper};
use std::time::Instant;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let n: u32 = args.get(1).map_or(Ok(16), |s| s.parse())?;
    let repeats: u32 = args.get(2).map_or(Ok(200), |s| s.parse())?;
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let s = xtask::bench::scenes::forest(n, &root.join("../shared/testdata"))?;
    println!("{}", s.about);
    let mut o = SweepOptions::multi_bounce();
    o.max_passes = std::env::var("PASSES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(4);
    o.tolerance = 0.0;
    o.smoothing = 0.25;
    o.medium = match args.get(3).map(String::as_str) {
        None | Some("profile") => lightgrid_core::MediumEmission::Profile,
        Some("source") => lightgrid_core::MediumEmission::Source,
        Some(other) => anyhow::bail!("unknown medium rule {other:?} (profile or source)"),
    };
    let mut sweeper = sweep_cpu::CpuSweeper::new();
    let mut out = None;
    let mut times = Vec::new();
    for _ in 0..repeats {
        if let Some(prev) = out.take() {
            sweeper.recycle(prev);
        }
        let t = Instant::now();
        out = Some(sweeper.sweep(&s.material, &s.boundary, &o)?);
        times.push(t.elapsed().as_secs_f64() * 1e3);
    }
    times.sort_by(f64::total_cmp);
    println!(
        "{n}³, {} passes, {:?}: fastest {:.2} ms, median {:.2} ms over {repeats}",
        o.max_passes,
        o.medium,
        times[0],
        times[times.len() / 2]
    );
    Ok(())
}
