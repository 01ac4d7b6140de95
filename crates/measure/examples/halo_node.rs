//! One of the hierarchy's nodes swept again and again: 16 × 40 × 16 points of dense
//! foliage over an opaque ground, its sides a given halo (as a coarser grid hands it
//! over), sky light from above, 2 passes with the horizon halves kept (the hierarchy's
//! defaults for its forest). Such small dense nodes are where the hierarchy's frames
//! go, and where a sweep's fixed costs per level (the halo's ring, checks, tables)
//! show beside the kernel's.
//!
//! `cargo run --release -p lightgrid-measure --example halo_node`
//! (`RAYON_NUM_THREADS=1` for one core, as the hierarchy sweeps its nodes side by
//! side; `NY=` levels, `PASSES=` passes, `DENS=` the percent of foliage cells in the
//! lower two thirds (60), `SIDES=given|halves|periodic` (`halves`: the horizontal
//! bins' downward halves given too, as the hierarchy hands them over; `periodic`: no
//! halo), `RULE=profile|source` the medium rule).

use std::time::Instant;

use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::{
    BinLight, Boundary, GridDesc, HaloLayout, Material, MaterialGrid, SideBoundary, SweepOptions,
    Sweeper,
};
use lightgrid_sweep_cpu::CpuSweeper;

/// Sweeps timed (after one that is not).
const SWEEPS: usize = 60;

fn env(name: &str, default: u32) -> Result<u32, Box<dyn std::error::Error>> {
    Ok(match std::env::var(name) {
        Ok(s) => s.parse().map_err(|e| format!("{name}={s}: {e}"))?,
        Err(_) => default,
    })
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let ny = env("NY", 40)?.max(4);
    let passes = env("PASSES", 2)?;
    let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(16, ny, 16))?;
    let mut rng = fastrand::Rng::with_seed(7);
    let foliage = env("DENS", 60)?.min(100) as f32 / 100.0;
    let cells = (0..desc.point_count())
        .map(|i| {
            let y = desc.coords(i).map_or(0, |c| c.y);
            if y < 3 {
                Material {
                    reflectance: Vec3::splat(0.2),
                    pass: 0.0,
                }
            } else if y < ny * 2 / 3 && rng.f32() < foliage {
                Material {
                    reflectance: Vec3::new(0.1, 0.3, 0.1),
                    pass: 0.3 + 0.6 * rng.f32(),
                }
            } else {
                Material::EMPTY
            }
        })
        .collect();
    let m = MaterialGrid::new(desc, cells)?;
    let sky = BinLight::uniform(Vec3::new(0.6, 0.7, 1.0));
    let halo = (0..HaloLayout::new(desc.dims()).len())
        .map(|i| sky.scaled(0.5 + (i % 7) as f32 / 14.0))
        .collect();
    let sides = match std::env::var("SIDES").as_deref() {
        Err(_) | Ok("given") => SideBoundary::Given(halo),
        Ok("halves") => SideBoundary::GivenHalves {
            down: halo
                .iter()
                .map(|b| {
                    lightgrid_core::HorizonLight(std::array::from_fn(|k| {
                        b.0[k + lightgrid_core::dirs::FIRST_HORIZONTAL] * 0.6
                    }))
                })
                .collect(),
            light: halo,
            cells: None,
        },
        Ok("periodic") => SideBoundary::Periodic,
        Ok(s) => return Err(format!("SIDES={s}: given, halves or periodic").into()),
    };
    let side_name = match &sides {
        SideBoundary::Given(_) => "given",
        SideBoundary::GivenHalves { .. } => "given with halves",
        _ => "periodic",
    };
    let b = Boundary {
        sides,
        ..Boundary::open_sky(sky)
    };
    let mut o = SweepOptions::multi_bounce();
    o.medium = match std::env::var("RULE").as_deref() {
        Err(_) | Ok("profile") => lightgrid_core::MediumEmission::Profile,
        Ok("source") => lightgrid_core::MediumEmission::Source,
        Ok(s) => return Err(format!("RULE={s}: profile or source").into()),
    };
    o.max_passes = passes;
    o.tolerance = 0.0;
    o.outputs = o.outputs.with_horizon();
    let mut s = CpuSweeper::new();
    let out = s.sweep(&m, &b, &o)?;
    s.recycle(out);
    let mut ms = Vec::with_capacity(SWEEPS);
    for _ in 0..SWEEPS {
        let t = Instant::now();
        let out = s.sweep(&m, &b, &o)?;
        ms.push(t.elapsed().as_secs_f64() * 1e3);
        s.recycle(out);
    }
    ms.sort_by(f64::total_cmp);
    println!(
        "16 x {ny} x 16 node, sides {}, {passes} passes, {} threads: median {:.2} ms, tenth percentile {:.2} ms ({:.2} us a point a pass)",
        side_name,
        rayon::current_num_threads(),
        ms[SWEEPS / 2],
        ms[SWEEPS / 10],
        ms[SWEEPS / 2] * 1e3 / (desc.point_count() as f64 * passes.max(1) as f64),
    );
    Ok(())
}
