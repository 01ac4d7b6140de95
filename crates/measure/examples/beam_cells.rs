//! Where a low sun's light in a patchy canopy is off, cell by cell: the sweep's sun
//! light in the medium cells (the beam's first collisions swept, plus the beam's mean
//! transmittance) against the Monte Carlo reference, on the patchy canopy
//! (`lightgrid_measure::sun_measure::patchy_canopy`, 16 × 10 × 16, periodic, azimuth
//! 20°): the scattered light's ratio level by level, the cells over 5 % off (of those
//! whose reference noise is under 1 %) and the worst ten.
//!
//! Two ways to see what the error is made of:
//! - `--refine K`: the sweep (beam and scattered light) on the same media cut into
//!   cells K times smaller (each cell's pass-through `p^(1/K)`), averaged back over
//!   each cell: what is left is not the cell size's.
//! - `--smoothing S`: the sweep's smoothing ([`SweepOptions::smoothing`]; the
//!   presets' 0.5): more blurs the 26 directions' ray effects.
//! - `--albedo A --ground G`: the media's and the ground's albedo (0.7 and 0.2):
//!   `--albedo 0.1 --ground 0` leaves the once-scattered light nearly alone.
//! - `--beam-refine K`: the beam's first collisions on cells K times smaller, summed
//!   back into each cell with their height moments, swept on the cells: what is left
//!   is not where the beam collides within a cell.
//! - `--refine 2 --spread`: the beam's collisions on the cells spread over the sweep's
//!   cells half as large (each cell's two halves in height by its first moment, even
//!   across x and z): what is left is not the transport's cell size.
//! - `--gather [--orders N --rays R]`: the first scatterings gathered
//!   by rays at any sun ([`Gather::LOW_SUN`] unless changed), the sweep carrying the
//!   rest; `--swept`: none gathered. Without either, the preset's ([`Gather::AUTO`]:
//!   gathered at or below 30°, swept above).
//!
//! `cargo run --release -p lightgrid-measure --example beam_cells -- [--paths N]
//! [--elevation DEG] [--refine K [--spread]] [--beam-refine K] [--smoothing S]
//! [--albedo A] [--ground G] [--gather | --swept]` (2 M paths: about 10 s).

use lightgrid_core::CellSource;
use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::light::luminance;
use lightgrid_core::{
    BinLight, Boundary, Gather, GridDesc, Material, MaterialGrid, SideBoundary, SweepOptions,
    Sweeper,
};
use lightgrid_measure::sun_measure::{patchy_canopy, sun_reference};
use lightgrid_sky::Sun;
use lightgrid_sweep_cpu::CpuSweeper;
use lightgrid_sweep_cpu::beam::FirstCollisions;
use lightgrid_sweep_cpu::sun::{BeamOptions, first_collisions};

/// `m` with every cell cut into `k³` cells of the same media (opaque and clear cells
/// as they are, a medium's pass-through `p^(1/k)` over the smaller cell).
fn refined(m: &MaterialGrid, k: u32) -> Result<MaterialGrid, Box<dyn std::error::Error>> {
    let d = m.desc();
    let fine = GridDesc::new(d.origin(), d.h() / k as f32, d.dims() * k)?;
    let cells = (0..fine.point_count())
        .map(|i| {
            let c = fine.coords(i).expect("in range") / k;
            let src = m.data()[d.index(c).expect("in range")];
            Material {
                pass: if src.pass > 0.0 && src.pass < 1.0 {
                    src.pass.powf(1.0 / k as f32)
                } else {
                    src.pass
                },
                ..src
            }
        })
        .collect();
    Ok(MaterialGrid::new(fine, cells)?)
}

/// `fine`'s collisions (on cells `k` times smaller than `coarse`'s) summed back into
/// the cells of `coarse`, with their height moments, and the transmittance `mean_t`
/// (`coarse`'s own).
fn summed_back(
    fine: &CellSource,
    coarse: &GridDesc,
    k: u32,
    mean_t: Option<Vec<f32>>,
) -> Result<FirstCollisions, Box<dyn std::error::Error>> {
    let n = coarse.point_count();
    let (mut removed, mut c1, mut c2) = (vec![Vec3::ZERO; n], vec![0.0f64; n], vec![0.0f64; n]);
    let heights = fine.heights().ok_or("no height moments")?;
    let kf = k as f64;
    for (i, r) in fine.removed().iter().enumerate() {
        let c = fine.desc().coords(i).ok_or("index")?;
        let j = coarse.index(c / k).ok_or("index")?;
        // Flux per `h²` of the finer cells, per `h²` of the cell.
        let r = *r / (k * k) as f32;
        removed[j] += r;
        let w = luminance(r) as f64;
        // The finer cell's height `y ∈ [-1, 1]` within the cell: `(y_f + off) / k`.
        let off = 2.0 * (c.y % k) as f64 + 1.0 - kf;
        let (m1, m2) = (heights[i][0] as f64, heights[i][1] as f64);
        let y2 = ((2.0 * m2 + 1.0) / 3.0 + 2.0 * off * m1 + off * off) / (kf * kf);
        c1[j] += w * (m1 + off) / kf;
        c2[j] += w * (3.0 * y2 - 1.0) / 2.0;
    }
    let heights = (0..n)
        .map(|j| match luminance(removed[j]) as f64 {
            w if w > 0.0 => [(c1[j] / w) as f32, (c2[j] / w) as f32],
            _ => [0.0, 0.0],
        })
        .collect();
    Ok(FirstCollisions {
        source: CellSource::with_heights(*coarse, removed, heights, fine.dir())?,
        budget: Default::default(),
        mean_transmittance: mean_t,
    })
}

/// `coarse`'s collisions spread over the cells of `fine` (half as large): each cell's
/// two halves in height by its first height moment, even across x and z and within
/// each half.
fn spread_in_two(
    coarse: &CellSource,
    fine: &GridDesc,
) -> Result<CellSource, Box<dyn std::error::Error>> {
    let heights = coarse.heights().ok_or("no height moments")?;
    let n = fine.point_count();
    let mut removed = vec![Vec3::ZERO; n];
    for (i, r) in removed.iter_mut().enumerate() {
        let c = fine.coords(i).ok_or("index")?;
        let j = coarse.desc().index(c / 2).ok_or("index")?;
        // A profile `(1 + 3 m1 y) / 2` puts `1/2 ± 3 m1 / 4` in the upper and lower
        // half (all in one where `|m1| > 2/3`: the halves' weights, `upper + lower = 2`).
        let upper = (1.0 + 1.5 * heights[j][0]).clamp(0.0, 2.0);
        let half = if c.y % 2 == 0 { 2.0 - upper } else { upper };
        // Flux per `h²` of the cell, over 8 cells of a quarter of its area.
        *r = coarse.removed()[j] / 2.0 * half;
    }
    Ok(CellSource::with_heights(
        *fine,
        removed,
        vec![[0.0, 0.0]; n],
        coarse.dir(),
    )?)
}

/// Whether `name` is among the arguments.
fn flag(name: &str) -> bool {
    std::env::args().any(|a| a == name)
}

fn arg<T: std::str::FromStr>(name: &str, default: T) -> Result<T, String> {
    let args: Vec<String> = std::env::args().collect();
    match args.iter().position(|a| a == name) {
        None => Ok(default),
        Some(i) => args
            .get(i + 1)
            .and_then(|v| v.parse().ok())
            .ok_or_else(|| format!("{name} takes a number")),
    }
}

/// One medium cell: its relative error, coordinates, the sweep's and the reference's
/// scattered light, and the reference's relative noise.
struct Cell {
    rel: f64,
    at: UVec3,
    swept: f64,
    reference: f64,
    noise: f64,
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let paths: u64 = arg("--paths", 2_000_000)?;
    let elevation: f32 = arg("--elevation", 10.0)?;
    let k: u32 = arg("--refine", 1u32)?.clamp(1, 4);
    let mut o = SweepOptions::multi_bounce();
    o.tolerance = 1e-6;
    o.max_passes = 64;
    o.smoothing = arg("--smoothing", o.smoothing)?;
    let (albedo, ground): (f32, f32) = (arg("--albedo", 0.7)?, arg("--ground", 0.2)?);
    let canopy = patchy_canopy(16, 3);
    let cells = canopy
        .data()
        .iter()
        .map(|c| Material {
            reflectance: Vec3::splat(if c.pass > 0.0 { albedo } else { ground }),
            ..*c
        })
        .collect();
    let m = MaterialGrid::new(*canopy.desc(), cells)?;
    let e = Vec3::ONE;
    let s = Sun::at(elevation.to_radians(), 20f32.to_radians(), e).direction;
    let dark = Boundary {
        sides: SideBoundary::Periodic,
        ..Boundary::open_sky(BinLight::ZERO)
    };
    let reference = sun_reference(&m, &dark, s, paths, 11)?;
    // The sweep on the (refined) grid, averaged back over each cell.
    let fine = refined(&m, k)?;
    let open = |_: Vec3| 1.0;
    let beam = first_collisions(
        &fine,
        s,
        e,
        true,
        &open,
        &BeamOptions::DEFAULT.with_mean_transmittance(),
    )?;
    // Where the level bias comes from: the beam on finer cells summed back into each
    // cell (`--beam-refine K`), or the beam on the cells spread over the finer cells
    // of the sweep (`--refine 2 --spread`).
    let beam = match (arg("--beam-refine", 1u32)?.clamp(1, 4), k, flag("--spread")) {
        (bk, 1, false) if bk > 1 => {
            let b = first_collisions(&refined(&m, bk)?, s, e, true, &open, &BeamOptions::DEFAULT)?;
            summed_back(&b.source, m.desc(), bk, beam.mean_transmittance)?
        }
        (1, 2, true) => {
            let coarse = first_collisions(&m, s, e, true, &open, &BeamOptions::DEFAULT)?;
            FirstCollisions {
                source: spread_in_two(&coarse.source, fine.desc())?,
                ..beam
            }
        }
        (1, _, false) => beam,
        _ => return Err("--beam-refine needs --refine 1; --spread needs --refine 2".into()),
    };
    if flag("--gather") {
        o.gather = Gather {
            orders: arg("--orders", Gather::LOW_SUN.orders)?,
            rays: arg("--rays", Gather::LOW_SUN.rays)?,
            ..Gather::LOW_SUN
        };
    } else if flag("--swept") {
        o.gather = Gather::OFF;
    }
    // As the sun's entry points do (`Gather::for_sun`): the preset's `Gather::AUTO`
    // gathers a sun at or below 30°.
    o.gather = o.gather.for_sun(s);
    let t0 = std::time::Instant::now();
    let scattered = CpuSweeper::new()
        .sweep_with_source(&fine, &dark, &beam.source, &o)?
        .bins
        .ok_or("no bins")?;
    let swept_s = t0.elapsed().as_secs_f64();
    let mean_t = beam
        .mean_transmittance
        .as_deref()
        .ok_or("no transmittance")?;
    let n = m.data().len();
    let (mut direct, mut light) = (vec![0.0f64; n], vec![0.0f64; n]);
    let w = 1.0 / (k * k * k) as f64;
    for (i, b) in scattered.data().iter().enumerate() {
        let c = fine.desc().coords(i).ok_or("index")? / k;
        let j = m.desc().index(c).ok_or("index")?;
        light[j] += luminance(b.average()) as f64 * w;
        direct[j] += luminance(e * mean_t[i]) as f64 * w;
    }
    let four_pi = 4.0 * std::f64::consts::PI;
    let mut cells = Vec::new();
    for (i, c) in m.data().iter().enumerate() {
        if c.pass <= 0.0 || c.pass >= 1.0 {
            continue;
        }
        let sr = luminance(reference.light.data()[i].average()) as f64;
        let dr = luminance(reference.direct[i]) as f64 / four_pi;
        let total = sr + dr;
        cells.push(Cell {
            rel: (light[i] + direct[i] / four_pi) / total - 1.0,
            at: m.desc().coords(i).ok_or("index")?,
            swept: light[i],
            reference: sr,
            noise: luminance(reference.std_error[i]) as f64 / total,
        });
    }
    let header = format!(
        "patchy canopy 16 x 10 x 16 (albedo {albedo}, ground {ground}), periodic, sun {elevation}° (azimuth 20°), {paths} reference paths; sweep cells 1/{k} m, smoothing {}",
        o.smoothing
    );
    report(&header, &o.gather, swept_s, &cells, m.desc().dims().y);
    Ok(())
}

/// Prints the scene's line (`header`), the sweep's time and how its scattered light was
/// found, each level's sweep over the reference and the worst of the quiet cells.
fn report(header: &str, gather: &Gather, swept_s: f64, cells: &[Cell], levels: u32) {
    println!("{header}");
    println!(
        "  scattered light: {:.3} s ({})",
        swept_s,
        if gather.is_on() {
            format!(
                "first {} scatterings gathered, {} directions for the first, a quarter as many for later ones",
                gather.orders, gather.rays
            )
        } else {
            "swept".into()
        }
    );
    for y in 0..levels {
        let level: Vec<&Cell> = cells.iter().filter(|c| c.at.y == y).collect();
        if level.is_empty() {
            continue;
        }
        let (a, r): (f64, f64) = level
            .iter()
            .fold((0.0, 0.0), |(a, r), c| (a + c.swept, r + c.reference));
        println!(
            "  level {y}: scattered light, sweep over reference {:.4} ({} cells)",
            a / r,
            level.len()
        );
    }
    let quiet: Vec<&Cell> = cells.iter().filter(|c| c.noise < 0.01).collect();
    let over = quiet.iter().filter(|c| c.rel.abs() > 0.05).count();
    println!(
        "  {over} of {} cells (reference noise under 1 %) over 5 % off",
        quiet.len()
    );
    let mut worst = quiet;
    worst.sort_by(|a, b| b.rel.abs().total_cmp(&a.rel.abs()));
    println!("  worst: error, cell, scattered light swept / reference, reference noise");
    for c in worst.iter().take(10) {
        println!(
            "  {:+6.1} %  ({:2}, {}, {:2})  {:.5} / {:.5}  {:.1} %",
            100.0 * c.rel,
            c.at.x,
            c.at.y,
            c.at.z,
            c.swept,
            c.reference,
            100.0 * c.noise
        );
    }
}
