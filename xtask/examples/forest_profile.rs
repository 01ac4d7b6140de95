//! Times the bench forest's sweep (16³, 4 passes, the default smoothing: the headline setting
//! of `cargo xtask bench`) many times over, for a profiler:
//! `cargo run --release -p xtask --example forest_profile -- [n] [repeats] [rule]`
//! (`rule`: `profile`, the default, or `source`, the flat source). `TILE=k` lays `k`
//! copies of the forest side by side along x: under its periodic sides every copy
//! gets the same light, so the time of a copy tells what rows `k` times as long
//! save; `PASSES=n` runs `n` passes.
use lightgrid_core::{SweepOptions, Sweeper};
use std::time::Instant;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let n: u32 = args.get(1).map_or(Ok(16), |s| s.parse())?;
    let repeats: u32 = args.get(2).map_or(Ok(200), |s| s.parse())?;
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut s = xtask::bench::scenes::forest(n, &root.join("assets"))?;
    let tile: u32 = std::env::var("TILE")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1)
        .max(1);
    if tile > 1 {
        let d = *s.material.desc();
        let dims = d.dims() * lightgrid_core::glam::UVec3::new(tile, 1, 1);
        let desc = lightgrid_core::GridDesc::new(d.origin(), d.h(), dims)?;
        let cells = (0..desc.point_count())
            .map(|i| {
                let p = desc.coords(i).expect("in the grid");
                let q = lightgrid_core::glam::UVec3::new(p.x % d.dims().x, p.y, p.z);
                s.material.data()[d.index(q).expect("in the forest")]
            })
            .collect();
        s.material = lightgrid_core::MaterialGrid::new(desc, cells)?;
    }
    println!("{} ({tile} side by side along x)", s.about);
    let mut o = SweepOptions::multi_bounce();
    o.max_passes = std::env::var("PASSES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(4);
    o.tolerance = 0.0;
    o.medium = match args.get(3).map(String::as_str) {
        None | Some("profile") => lightgrid_core::MediumEmission::Profile,
        Some("source") => lightgrid_core::MediumEmission::Source,
        Some(other) => anyhow::bail!("unknown medium rule {other:?} (profile or source)"),
    };
    let mut sweeper = lightgrid_sweep_cpu::CpuSweeper::new();
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
        "{}, {} passes, {:?}: fastest {:.2} ms, median {:.2} ms over {repeats}",
        s.material.desc().dims(),
        o.max_passes,
        o.medium,
        times[0],
        times[times.len() / 2]
    );
    Ok(())
}
