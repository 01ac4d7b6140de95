//! What terrain costs the sweep: a grid of the hierarchy's world-grid shape (102 × 9 ×
//! 87 points, 16 m) over opaque ground, flat or rolling, with a few medium cells on it,
//! swept four passes with the sun's first collisions as its source (as `Hierarchy::
//! set_sun` sweeps the world grid), recycled; the median of 8, and the time per level
//! computed, beside the 64³ canopy's (sky only; its levels above all material are
//! copied, not computed). A rolling ground exposes side faces in every column, and
//! every exposed surface cell runs phase 2's emission rounds one cell at a time.
//!
//! `cargo run --release -p lightgrid-measure --example surface_levels`

use std::time::Instant;

use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::{
    BinLight, Boundary, GridDesc, Material, MaterialGrid, SideBoundary, SweepOptions, Sweeper,
};

fn grid(rolling: bool) -> MaterialGrid {
    let desc = GridDesc::new(Vec3::ZERO, 16.0, UVec3::new(102, 9, 87)).expect("valid");
    let mut rng = fastrand::Rng::with_seed(1);
    let cells = (0..desc.point_count())
        .map(|i| {
            let c = desc.coords(i).expect("in range");
            let ground = if rolling {
                2 + ((c.x as f32 * 0.1).sin() * 2.0 + 2.0) as u32
            } else {
                2
            };
            if c.y < ground {
                Material {
                    reflectance: Vec3::splat(0.3),
                    pass: 0.0,
                }
            } else if c.y == ground && rng.f32() < 0.2 {
                Material {
                    reflectance: Vec3::splat(0.6),
                    pass: 0.5,
                }
            } else {
                Material::EMPTY
            }
        })
        .collect();
    MaterialGrid::new(desc, cells).expect("valid")
}

/// The median of 8 sweeps by one recycling sweeper (ms) and the levels computed.
fn median_of_8(
    sweep: &mut dyn FnMut(&mut lightgrid_sweep_cpu::CpuSweeper) -> lightgrid_core::SweepOutput,
) -> (f64, u64) {
    let mut s = lightgrid_sweep_cpu::CpuSweeper::new();
    let mut times = Vec::new();
    let mut levels = 0;
    for _ in 0..8 {
        let t = Instant::now();
        let out = sweep(&mut s);
        times.push(t.elapsed().as_secs_f64() * 1e3);
        levels = out.stats.levels_computed;
        s.recycle(out);
    }
    times.sort_by(f64::total_cmp);
    (times[times.len() / 2], levels)
}

fn main() {
    let mut o = SweepOptions::multi_bounce();
    o.max_passes = 4;
    o.tolerance = 1e-3;
    let to_sun = Vec3::new(0.5, 0.6, 0.3);
    // The throughput example's 64³ canopy beside them: its levels above all material
    // are copied, not computed, so points a second over the whole grid overstate
    // what a computed level costs.
    {
        let (m, b) = lightgrid_measure::scenes::Scene::Canopy.build(64);
        let (median, levels) = median_of_8(&mut |s| s.sweep(&m, &b, &o).expect("sweeps"));
        println!(
            "64^3 canopy (4 096 points a level, sky): {median:.1} ms, {levels} levels computed, {:.2} ms a level",
            median / levels.max(1) as f64
        );
    }
    println!("102 x 9 x 87 points, 4 passes, sun's first collisions as the source, recycled");
    println!("ground     sides      median ms   levels computed   ms a level");
    for rolling in [false, true] {
        let m = grid(rolling);
        for periodic in [false, true] {
            let src =
                lightgrid_sweep_cpu::sun::first_collision(&m, to_sun, Vec3::ONE, periodic, &|_| {
                    1.0
                })
                .expect("a valid sun");
            let mut b = Boundary::open_sky(BinLight::ZERO);
            if periodic {
                b.sides = SideBoundary::Periodic;
            }
            let (median, levels) =
                median_of_8(&mut |s| s.sweep_with_source(&m, &b, &src, &o).expect("sweeps"));
            println!(
                "{:9}  {:9}  {median:9.1}   {levels:15}   {:10.2}",
                if rolling { "rolling" } else { "flat" },
                if periodic { "periodic" } else { "open" },
                median / levels.max(1) as f64
            );
        }
    }
}
