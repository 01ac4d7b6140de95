//! The sweep's error against smoothing: the bench scenes that smoothing changes (the
//! dense block, the line source through a slit, the checkerboard lattice, the forest),
//! relative RMSE of the average light at smoothing 0, 0.25, 0.35, 0.5 and 0.6 against a
//! Monte Carlo reference traced here (the table behind the presets' smoothing,
//! `sweep-cpu`'s crate docs, "Smoothing"):
//! `cargo run --release -p xtask --example smoothing -- [n] [paths] [passes]`
//! (defaults 16, 4 000 000, 4; about a minute at 24³ and 8 M paths on two cores).
use lightgrid_core::{SweepOptions, Sweeper};
use lightgrid_measure::reference::{ReferenceOptions, trace};

/// Smoothing weights compared.
const WEIGHTS: [f32; 5] = [0.0, 0.25, 0.35, 0.5, 0.6];

fn main() -> anyhow::Result<()> {
    let arg = |i: usize| std::env::args().nth(i);
    let n: u32 = arg(1).map_or(Ok(16), |s| s.parse())?;
    let paths: u64 = arg(2).map_or(Ok(4_000_000), |s| s.parse())?;
    let passes: u32 = arg(3).map_or(Ok(4), |s| s.parse())?;
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let scenes = xtask::bench::scenes::all(n, &root.join("assets"))?;
    println!(
        "{n}³, {passes} passes, {paths} reference paths; relative RMSE of the average light at smoothing {WEIGHTS:?} (default {})",
        SweepOptions::multi_bounce().smoothing
    );
    for s in scenes
        .iter()
        .filter(|s| ["dense-block", "line-source", "lattice", "forest"].contains(&s.name.as_str()))
    {
        let options = ReferenceOptions {
            paths,
            seed: 7,
            ..Default::default()
        };
        let r = trace(&s.material, &s.boundary, &options, &|_, _| {})?;
        let mut line = format!("{:14}", s.name);
        for w in WEIGHTS {
            let mut o = SweepOptions::multi_bounce();
            o.max_passes = passes;
            o.tolerance = 0.0;
            o.smoothing = w;
            let out = lightgrid_sweep_cpu::CpuSweeper::new().sweep(&s.material, &s.boundary, &o)?;
            let bins = out
                .bins
                .as_ref()
                .ok_or_else(|| anyhow::anyhow!("no bins"))?;
            let e = lightgrid_measure::scenes::compare(bins, &r.light, &s.material);
            line += &format!("  {w}: {:.4}", e.average);
        }
        println!("{line}");
    }
    Ok(())
}
