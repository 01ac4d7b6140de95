//! A scripted fly-through over the shipped DEM with a procedural forest: per frame, the
//! points swept, grids alive per depth, memory and skipped work; then the same path with
//! node grids of 16, 32 and 64 points for the time/memory table in the crate docs.
//!
//! `cargo run --release -p lightgrid-terrain-lod --example flythrough [-- 16 32]` (node
//! sizes to run; all three by default)

use std::time::Instant;

use lightgrid_core::BinLight;
use lightgrid_core::glam::Vec3;
use lightgrid_sweep_cpu::CpuSweeper;
use lightgrid_terrain_lod::{
    BYTES_26_F32, BYTES_26_PACKED, BYTES_AVG_DOM, Hierarchy, HierarchyParams,
};

#[path = "../tests/demo/mod.rs"]
mod demo;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let hm = demo::jacksboro(&demo::assets_dir())?;
    let forest = demo::Forest::flythrough();
    let (sky, _) = BinLight::uniform(Vec3::new(0.6, 0.7, 1.0)).split_vertical();
    let camera = |f: u32| {
        let (x, z) = (500.0 + 10.0 * f as f32, 520.0 + 8.0 * f as f32);
        Vec3::new(x, hm.height_at(x, z) + 20.0, z)
    };
    println!(
        "node points | frames | total s | ms/frame | points swept | 26-bin f32 MB | packed MB | avg+dom MB"
    );
    let mut sizes: Vec<u32> = std::env::args()
        .skip(1)
        .map(|a| a.parse())
        .collect::<Result<_, _>>()?;
    if sizes.is_empty() {
        sizes = vec![16, 32, 64];
    }
    for node_points in sizes {
        let composer = forest.composer(&hm)?;
        let params = HierarchyParams {
            node_points,
            finest_cell: 1.0,
            max_levels: 48,
            budget_points: node_points as u64 * node_points as u64 * 48 * 2,
            // Without the default apron of 6 cells (for 32-point nodes): the issue-43
            // speed configuration, whose 16-point nodes it would cost 3.06 times the
            // sky sweep's points.
            apron: 0,
            ..Default::default()
        };
        let t = Instant::now();
        let mut h = Hierarchy::new(
            &hm,
            Box::new(composer),
            Box::new(CpuSweeper::new()),
            sky,
            params,
        )?;
        let setup = t.elapsed().as_secs_f64();
        let mut swept = 0;
        let frames = 30;
        let mut last = None;
        let mut times = lightgrid_terrain_lod::StageTimes::default();
        for f in 0..frames {
            let s = h.update(camera(f))?;
            swept += s.points_swept;
            times.material += s.times.material;
            times.boundary += s.times.boundary;
            times.sky_sweep += s.times.sky_sweep;
            if node_points == 32 {
                println!(
                    "  frame {f:2}: swept {:6} points, built {:2}, pending {:2}, evicted {:2}, bare skipped {:2}, alive {:?}, {:.1} MB",
                    s.points_swept,
                    s.built,
                    s.pending,
                    s.evicted,
                    s.skipped_bare,
                    s.alive_per_depth,
                    s.bytes(BYTES_26_F32) as f64 / 1e6
                );
            }
            last = Some(s);
        }
        let secs = t.elapsed().as_secs_f64();
        let s = last.expect("frames ran");
        println!(
            "{node_points:11} | {frames:6} | {secs:7.2} | {:8.1} | {swept:12} | {:13.1} | {:9.1} | {:10.1}",
            secs * 1e3 / frames as f64,
            s.bytes(BYTES_26_F32) as f64 / 1e6,
            s.bytes(BYTES_26_PACKED) as f64 / 1e6,
            s.bytes(BYTES_AVG_DOM) as f64 / 1e6
        );
        let per_frame = |d: std::time::Duration| d.as_secs_f64() * 1e3 / frames as f64;
        println!(
            "{:11}   of which setup (Hierarchy::new) {:.0} ms, the frames {:.1} ms a frame; stages a frame, summed over threads: material {:.1} ms, boundaries {:.1} ms, sky sweeps {:.1} ms",
            "",
            setup * 1e3,
            (secs - setup) * 1e3 / frames as f64,
            per_frame(times.material),
            per_frame(times.boundary),
            per_frame(times.sky_sweep),
        );
    }
    Ok(())
}
