//! The hand-over through given sides, alone: a 32 × 24 × 32 crop of one 1 m sweep of
//! a 96 × 24 × 96 forest (tree crowns over an opaque ground, periodic sides), handed
//! that sweep's own light and horizon halves at its halo, swept with the hierarchy's
//! options, against the sweep it was cut from. Whatever the crop gets wrong, no better
//! halo from a coarser grid can mend: this is the floor of a node's nesting error.
//!
//! Three scenes: the forest; the forest with a clear band from the halo's outer edge to
//! three cells inside the crop (the paths from halo points then cross only empty cells
//! before they reach the crop's own: the hand-over is exact there, `tests/handover.rs`
//! holds it); and the forest with a clear band outside the crop alone (the halo's own
//! cells empty, the crop's edge cells not). Per scene, over the six axes' irradiance
//! at every non-opaque point of the crop: the largest error over the local brightest
//! value (the 3 × 3 × 3 points around it in the full sweep; issue 43's measure), that
//! largest at 3, 6 (the hierarchy's apron) and 10 or more cells from the crop's sides,
//! and the RMSE; each without and with the halo's paths traced
//! (`SweepOptions::halo_paths`), and without and with the halo's cells given
//! (`SideBoundary::GivenHalves`'s `cells`: its light carried through them,
//! `lightgrid_core::halo_carry`).
//!
//! `cargo run --release -p lightgrid-measure --example handover` (13 minutes)

use lightgrid_core::glam::{IVec3, UVec3, Vec3};
use lightgrid_core::light::{AMBIENT_AXES, luminance};
use lightgrid_core::{
    BinLight, Boundary, GridDesc, HALO_WIDTH, HaloLayout, HorizonGrid, HorizonLight, LightGrid,
    Material, MaterialGrid, SideBoundary, SweepOptions, Sweeper,
};
use lightgrid_sweep_cpu::CpuSweeper;

const N: u32 = 96;
const NY: u32 = 24;
/// The crop's corner and size across.
const X0: u32 = 32;
const W: u32 = 32;
/// Cells from the crop's sides beyond which the largest error is reported.
const FROM_SIDE: [u32; 4] = [0, 3, 6, 10];

/// Which cells near the crop's sides are cleared.
#[derive(Clone, Copy, PartialEq)]
enum Band {
    None,
    /// From `HALO_WIDTH` outside to 3 inside.
    Across,
    /// From `HALO_WIDTH` outside to the side.
    Outside,
}

fn forest(band: Band, ground: bool) -> Result<MaterialGrid, Box<dyn std::error::Error>> {
    let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(N, NY, N))?;
    let mut rng = fastrand::Rng::with_seed(11);
    // Crowns: balls of foliage 2-5 m across, 6-14 m up, of pass-through 0.2-0.8 a cell.
    let crowns: Vec<(Vec3, f32, f32)> = (0..180)
        .map(|_| {
            let c = Vec3::new(
                rng.f32() * N as f32,
                6.0 + 8.0 * rng.f32(),
                rng.f32() * N as f32,
            );
            (c, 2.0 + 3.0 * rng.f32(), 0.2 + 0.6 * rng.f32())
        })
        .collect();
    let w = HALO_WIDTH as u32;
    let inside = if band == Band::Across { 3 } else { 0 };
    let ring =
        |v: u32| (X0 - w..X0 + inside).contains(&v) || (X0 + W - inside..X0 + W + w).contains(&v);
    let within = |v: u32| (X0 - w..X0 + W + w).contains(&v);
    let cells = (0..desc.point_count())
        .map(|i| {
            let p = desc.coords(i).unwrap_or_default();
            if p.y < 2 && ground {
                return Material::opaque(Vec3::splat(0.25));
            }
            if band != Band::None && ((ring(p.x) && within(p.z)) || (ring(p.z) && within(p.x))) {
                return Material::EMPTY;
            }
            let c = p.as_vec3() + 0.5;
            let half = N as f32 / 2.0;
            let pass = crowns.iter().fold(1.0f32, |pass, (cc, r, pp)| {
                // Periodic, as the sweep's sides.
                let mut d = c - *cc;
                for k in [0, 2] {
                    d[k] -= N as f32 * ((d[k] > half) as i32 - (d[k] < -half) as i32) as f32;
                }
                if d.length() < *r { pass * pp } else { pass }
            });
            if pass < 1.0 {
                Material {
                    reflectance: Vec3::new(0.1, 0.35, 0.1),
                    pass,
                }
            } else {
                Material::EMPTY
            }
        })
        .collect();
    Ok(MaterialGrid::new(desc, cells)?)
}

/// The crop's material and its boundary: the sky above, `bins` and `halves` at its halo.
fn crop(
    m: &MaterialGrid,
    (bins, halves): (&LightGrid, &HorizonGrid),
    sky: BinLight,
    (lift, with_cells): (bool, bool),
) -> Result<(MaterialGrid, Boundary), Box<dyn std::error::Error>> {
    let desc = GridDesc::new(
        Vec3::new(X0 as f32, 0.0, X0 as f32),
        1.0,
        UVec3::new(W, NY, W),
    )?;
    let crop_cells: Vec<Material> = (0..desc.point_count())
        .map(|i| {
            let p = desc.coords(i).unwrap_or_default();
            *m.get(UVec3::new(X0 + p.x, p.y, X0 + p.z))
                .unwrap_or(&Material::EMPTY)
        })
        .collect();
    let layout = HaloLayout::new(desc.dims());
    let (mut light, mut down, mut cells) = (
        vec![BinLight::ZERO; layout.len()],
        vec![HorizonLight::default(); layout.len()],
        vec![Material::EMPTY; layout.len()],
    );
    let w = HALO_WIDTH;
    for j in 0..NY {
        for z in -w..W as i32 + w {
            for x in -w..W as i32 + w {
                if let Some(k) = layout.index(x, j, z) {
                    let mut q = UVec3::new((X0 as i32 + x) as u32, j, (X0 as i32 + z) as u32);
                    cells[k] = *m.get(q).ok_or("halo point in the full grid")?;
                    // Lifted out of the ground, as the hierarchy reads its halo near
                    // bare ground (`HierarchyParams::halo_ground_lift`).
                    while lift && q.y + 1 < NY && m.get(q).is_some_and(|c| c.pass == 0.0) {
                        q.y += 1;
                    }
                    light[k] = *bins.get(q).ok_or("halo point in the full grid")?;
                    down[k] = *halves.get(q).ok_or("halo point in the full grid")?;
                }
            }
        }
    }
    let b = Boundary {
        sides: SideBoundary::GivenHalves {
            light,
            down,
            cells: with_cells.then_some(cells),
        },
        ..Boundary::open_sky(sky)
    };
    Ok((MaterialGrid::new(desc, crop_cells)?, b))
}

/// The crop's light `c` against the full sweep's `full` at every non-opaque point of
/// the crop `cm`, over the six axes' irradiance: the largest error over the local
/// brightest value at each of [`FROM_SIDE`]'s distances from the sides or more, and the
/// RMSE over the mean square.
fn errors(
    cm: &MaterialGrid,
    (cb, ch): &(LightGrid, HorizonGrid),
    (fb, fh): &(LightGrid, HorizonGrid),
) -> Result<([f64; 4], f64), Box<dyn std::error::Error>> {
    let irr = |b: &BinLight, h: &HorizonLight, a: usize| {
        luminance(b.irradiance_split(AMBIENT_AXES[a], h)) as f64
    };
    let full_irr = |q: IVec3, a: usize| -> Option<f64> {
        let q = q.try_into().ok()?;
        Some(irr(fb.get(q)?, fh.get(q)?, a))
    };
    let (mut worst, mut se, mut sr) = ([0.0f64; 4], 0.0, 0.0);
    for i in 0..cm.desc().point_count() {
        let p = cm.desc().coords(i).unwrap_or_default();
        if cm.get(p).is_some_and(|m| m.pass == 0.0) {
            continue;
        }
        let q = UVec3::new(X0 + p.x, p.y, X0 + p.z).as_ivec3();
        let from_side = p.x.min(p.z).min(W - 1 - p.x).min(W - 1 - p.z);
        for a in 0..6 {
            let got = irr(cb.get(p).ok_or("point")?, ch.get(p).ok_or("point")?, a);
            let want = full_irr(q, a).ok_or("point")?;
            let mut bright = want;
            for d in (0..27).map(|k| IVec3::new(k % 3 - 1, k / 3 % 3 - 1, k / 9 - 1)) {
                bright = bright.max(full_irr(q + d, a).unwrap_or(0.0));
            }
            let e = (got - want).abs() / bright.max(1e-9);
            for (w, d) in worst.iter_mut().zip(FROM_SIDE) {
                if from_side >= d {
                    *w = w.max(e);
                }
            }
            se += (got - want).powi(2);
            sr += want.powi(2);
        }
    }
    Ok((worst, (se / sr).sqrt()))
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // The hierarchy's sweep options (`HierarchyParams::default().sweep`), with the bins.
    let mut o = SweepOptions::multi_bounce();
    o.max_passes = 4;
    o.tolerance = 0.01;
    o.outputs.bins = true;
    o.outputs.horizon = true;
    o.gather = lightgrid_core::Gather::OFF;
    // And run to convergence: what is left is the hand-over's, not the passes'.
    let mut converged = o;
    converged.max_passes = 64;
    converged.tolerance = 1e-5;
    let (sky, _) = BinLight::uniform(Vec3::new(0.6, 0.7, 1.0)).split_vertical();
    println!(
        "| scene | passes | the halo's paths | largest, all points | largest, 3+ cells from the sides | 6+ | 10+ | RMSE |"
    );
    println!("|---|---|---|---:|---:|---:|---:|---:|");
    for (name, band, (ground, lift), o) in [
        ("forest", Band::None, (true, false), o),
        ("forest", Band::None, (true, false), converged),
        (
            "forest, the halo's ground points lifted",
            Band::None,
            (true, true),
            converged,
        ),
        (
            "forest, the halo's cells clear",
            Band::Outside,
            (true, false),
            converged,
        ),
        (
            "forest, the halo's cells clear, its ground points lifted",
            Band::Outside,
            (true, true),
            converged,
        ),
        (
            "forest, clear from the halo to 3 cells inside",
            Band::Across,
            (true, false),
            converged,
        ),
        (
            "crowns alone, clear from the halo to 3 cells inside",
            Band::Across,
            (false, false),
            converged,
        ),
    ] {
        let m = forest(band, ground)?;
        let full = CpuSweeper::new().sweep(
            &m,
            &Boundary {
                sides: SideBoundary::Periodic,
                ..Boundary::open_sky(sky)
            },
            &o,
        )?;
        let full = (
            full.bins.ok_or("bins asked for")?,
            full.horizon.ok_or("halves asked for")?,
        );
        let passes = if o.max_passes == 4 {
            "the hierarchy's"
        } else {
            "converged"
        };
        for (halo_paths, with_cells) in [(false, false), (true, false), (false, true), (true, true)]
        {
            let (cm, b) = crop(&m, (&full.0, &full.1), sky, (lift, with_cells))?;
            let mut o = o;
            o.halo_paths = halo_paths;
            let c = CpuSweeper::new().sweep(&cm, &b, &o)?;
            let c = (
                c.bins.ok_or("bins asked for")?,
                c.horizon.ok_or("halves asked for")?,
            );
            let (worst, rmse) = errors(&cm, &c, &full)?;
            let w = worst.map(|w| format!("{:.1} %", w * 100.0)).join(" | ");
            let traced = match (halo_paths, with_cells) {
                (false, false) => "no",
                (true, false) => "traced",
                (false, true) => "no, cells given",
                (true, true) => "traced, cells given",
            };
            println!(
                "| {name} | {passes} | {traced} | {w} | {:.2} % |",
                rmse * 100.0
            );
        }
    }
    Ok(())
}
