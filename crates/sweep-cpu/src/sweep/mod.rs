//! The sweep itself. The semantics are in the crate docs; these modules follow them
//! step by step (the step names in comments refer to them). This module holds the
//! entry points and the public specification; the parts, leaves first:
//!
//! - `tables`: the channels, path exponents, surface weights and segment mean, shared
//!   with the GPU sweeper (`pub`, re-exported here).
//! - `platform`: cache hints and huge pages (`unsafe`), fresh buffers.
//! - `rows`: a level's light as padded rows, rings of wrapped columns, slot-plane taps.
//! - `pending`, `emission`, `sink`: light waiting in media, what cells emit, where a
//!   point's light lands and how it resolves.
//! - `ctx`: one sweep's fixed context and the light from outside.
//! - `oracle`: the scalar phases 1 and 3, as the specification reads.
//! - `phase1`, `phase2`, `phase3`: a level's three phases on the fast path; their row
//!   kernels run on the widest vectors the CPU has ([`crate::isa`]).
//! - `memory`: what a sweeper keeps between sweeps, per-level planes, work buffers.
//! - `passes`, `debt`: the pass loop to convergence and the acceleration's bookkeeping.

use std::f32::consts::PI;
use std::sync::OnceLock;

use lightgrid_core::dirs::{self, NUM_DIRS, NUM_SWEEP_DIRS};
use lightgrid_core::glam::{DVec3, IVec3, UVec3, Vec3};
use lightgrid_core::light::luminance;
use lightgrid_core::{
    AverageLight, BinLight, Boundary, CellSource, DominantDir, Grid, GridError, MaterialGrid,
    MediumEmission, SideBoundary, SweepError, SweepOptions, SweepOutput, SweepStats, TopBoundary,
};
use rayon::prelude::*;

use crate::isa::vectorised;

use crate::medium;

mod ctx;
mod debt;
mod emission;
mod helper;
mod memory;
mod oracle;
mod passes;
mod pending;
mod phase1;
mod phase2;
mod phase3;
mod platform;
mod ring_paths;
mod rows;
mod sink;
mod tables;
#[cfg(test)]
mod tests;

use ctx::*;
use debt::*;
use emission::*;
use helper::{Helper, Sweeping};
pub(crate) use memory::*;
use oracle::*;
use passes::*;
use pending::*;
use phase1::*;
use phase2::*;
use phase3::*;
pub use platform::*;
use ring_paths::*;
use rows::*;
use sink::*;
pub use tables::*;

/// Fewest points one parallel task of a level's fast phases handles: a 16 × 16 level
/// runs as two tasks, one a core (the bench forest, 16³, 4 passes: 6.8 ms at 512 points,
/// one task a level, 4.4 ms at 128; below 64, rayon's per-task cost shows).
pub const MIN_POINTS_PER_TASK: usize = 128;

/// Most points one parallel task of phases 2 and 3 handles: their rows differ in cost
/// with the material they hold, so the level is cut into many small tasks that the
/// threads take as they free up (two tasks of 128 points left one thread waiting on
/// the other: the bench forest, 16³, two passes, 2.63–2.67 ms before, 2.51–2.55 ms
/// after). Phase 1 keeps [`MIN_POINTS_PER_TASK`]: each thread then gathers from the
/// rows it wrote a level before (small tasks there, which move rows between cores,
/// gained nothing).
pub const MAX_POINTS_PER_UNEVEN_TASK: usize = 32;

/// Levels of more points than this fetch each block's cell profiles ahead of the
/// profile rule's loops over the stencil slots, which read each profile one value at a
/// time: 512 cells' profiles take 635 KB, and a level's that outgrow the 1 MB L2 came
/// from farther out (the crate docs, "Tenth round").
pub const FETCH_PROFILES_ABOVE: usize = 512;

/// Flux balance of a sweep, per RGB channel, in units of light × `h²` per point
/// (multiply by `h²` for power). Every term is non-negative; `input()` equals
/// `absorbed + escaped() + pending` to float rounding.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct EnergyBalance {
    /// Entered through the top face.
    pub top_in: DVec3,
    /// Entered through the bottom face.
    pub bottom_in: DVec3,
    /// Entered through the side faces.
    pub side_in: DVec3,
    /// Left through the top face.
    pub top_out: DVec3,
    /// Left through the bottom face.
    pub bottom_out: DVec3,
    /// Left through the side faces.
    pub side_out: DVec3,
    /// Absorbed by material.
    pub absorbed: DVec3,
    /// Scattered light not yet transported when the passes stopped.
    pub pending: DVec3,
    /// Taken from a beam inside the grid by a [`CellSource`] (the sun's first
    /// collisions): absorbed or scattered into the bins.
    pub source_in: DVec3,
}

impl EnergyBalance {
    /// Everything that entered.
    pub fn input(&self) -> DVec3 {
        self.top_in + self.bottom_in + self.side_in + self.source_in
    }
    /// Everything that left.
    pub fn escaped(&self) -> DVec3 {
        self.top_out + self.bottom_out + self.side_out
    }
    /// `|input - absorbed - escaped - pending| / input`, worst RGB channel (0 for no input).
    pub fn relative_error(&self) -> f64 {
        let diff = (self.input() - self.absorbed - self.escaped() - self.pending).abs();
        let inp = self.input();
        (0..3)
            .map(|i| {
                if inp[i] > 0.0 {
                    diff[i] / inp[i]
                } else {
                    diff[i]
                }
            })
            .fold(0.0, f64::max)
    }
}

/// A sweep's outputs and its energy balance.
#[derive(Debug, Clone)]
pub struct Sweep {
    /// What the [`lightgrid_core::Sweeper`] trait returns.
    pub output: SweepOutput,
    /// The flux balance.
    pub balance: EnergyBalance,
}

/// The boundary light of the virtual level beyond the grid at column `(x, z)` (clamped
/// to the columns the top holds: the grid's, or the grid's and its ring's): the bottom
/// light on upward passes, the top light (uniform or per point) on downward ones. Part
/// of the specification, shared with the GPU sweeper.
pub fn virtual_level_light(
    boundary: &Boundary,
    up: bool,
    x: i32,
    z: i32,
    dims: lightgrid_core::glam::UVec3,
) -> &BinLight {
    if up {
        return &boundary.bottom;
    }
    match &boundary.top {
        TopBoundary::Uniform(b) => b,
        TopBoundary::PerPoint(v) => {
            let (nx, nz) = (dims.x as i32, dims.z as i32);
            if v.len() == (nx * nz) as usize {
                &v[(x.clamp(0, nx - 1) + nx * z.clamp(0, nz - 1)) as usize]
            } else {
                // Over the ring too (`HaloLayout::columns`).
                let w = lightgrid_core::HALO_WIDTH;
                let (x, z) = (x.clamp(-w, nx + w - 1), z.clamp(-w, nz + w - 1));
                &v[((x + w) + (nx + 2 * w) * (z + w)) as usize]
            }
        }
    }
}

/// Checks the inputs of a sweep as [`run`] does (options, boundary against the grid,
/// boundary light at most [`MAX_LIGHT`]).
pub fn validate_inputs(
    material: &MaterialGrid,
    boundary: &Boundary,
    options: &SweepOptions,
) -> Result<(), SweepError> {
    options.validate()?;
    // The checks and `check_boundary_scale` in one pass.
    boundary.validate_for_sweep(material.desc())?;
    let desc = material.desc();
    lightgrid_core::limits::check_memory(
        &format!("a sweep of {} points", desc.point_count()),
        sweep_bytes(desc),
    )?;
    Ok(())
}

/// Most bytes [`run`] holds at once for a grid: per point the accumulated bins (312),
/// up to three pending-scatter records (144: two, and a third in accelerated passes;
/// only levels with material hold them), ln(pass) and exposure (8), the output (312)
/// and the quiet mask (1); per level its transmittance planes with their ring (eleven
/// planes of `(nx + 4) × (nz + 4)` floats, the one store of its transmittances, kept
/// for the sweep's later passes); per point of one level the level buffers (four
/// 17-channel levels: the two in use, light from outside, the upward light waiting
/// above all material: 816), its two sets of slot planes (removed light, then what
/// paths carry; the profile rule's emission: 2 × 147 floats), the transmittance after
/// each path's centre (68) and the source rule's sources and masks (38): 2098, with
/// per row of a level the rings of the two sets of slot planes (2 × 2 × 2 columns ×
/// 147 planes × 4 bytes); and the profile rule's cell profiles, one per
/// distinct depth of medium and direction, at most two a point and [`crate::profile`]'s
/// cap (held once a process, whatever its sweepers: those of another sweep of the same
/// depths are the same memory).
pub fn sweep_bytes(desc: &lightgrid_core::GridDesc) -> u64 {
    let profiles = (2 * desc.point_count()).min(crate::profile::Profiles::KEEP) as u64
        * std::mem::size_of::<crate::profile::CellProfile>() as u64;
    let d = desc.dims();
    let rings = d.z as u64 * (2 * 2 * RING * SLOTS * 3 * 4) as u64;
    let planes = d.y as u64
        * ((d.x as usize + 2 * Planes::R) * (d.z as usize + 2 * Planes::R) * Planes::PER_LEVEL * 4)
            as u64;
    desc.point_count() as u64 * (312 + 144 + 8 + 312 + 1)
        + desc.level_len() as u64 * 2098
        + rings
        + planes
        + profiles
}

/// Checks that no boundary light is over [`MAX_LIGHT`] (1e30): an error naming
/// the part (`top`, `bottom`, `sides`) otherwise. The Monte Carlo reference
/// (`lightgrid-measure`) checks its boundary the same way.
pub fn check_boundary_scale(boundary: &Boundary) -> Result<(), GridError> {
    let big = |b: &BinLight| b.0.iter().any(|v| v.max_element() > MAX_LIGHT);
    let err = |field: &str| {
        Err(GridError::invalid(
            field,
            "a value over 1e30",
            "boundary light must be <= 1e30",
        ))
    };
    let top_big = match &boundary.top {
        TopBoundary::Uniform(b) => big(b),
        TopBoundary::PerPoint(v) => v.iter().any(big),
    };
    if top_big {
        return err("top");
    }
    if big(&boundary.bottom) {
        return err("bottom");
    }
    // A node's halo holds some 17,000 bins: one pass over their values that vectorises.
    if let Some(h) = boundary.sides.halo()
        && bytemuck::cast_slice::<BinLight, f32>(h)
            .iter()
            .fold(false, |big, &x| big | (x > MAX_LIGHT))
    {
        return err("sides");
    }
    Ok(())
}

/// A level conserves the flux it gathers, so the passes book its flux as what the
/// level before it sent on instead of summing its values (the crate docs, "Energy"):
/// a level without material (every point passes its light on unchanged, and
/// nothing scatters) under periodic sides (every source point of its gather is a grid
/// point, and the gather's weights, `1 − w` and four times `w/4`, sum to 1), other
/// than the first of a pass (which gathers from the boundary).
pub fn conserves_flux(periodic: bool, material: bool, first_level: bool) -> bool {
    periodic && !material && !first_level
}

/// Mask of each opaque cell's faces that can receive light (bit order of
/// [`FACE_NORMALS`]); 0 for cells with `p > 0`.
///
/// A face is exposed when it borders a non-opaque cell, the sky above the top level, or
/// the outside through an open side (the empty world under the sky). Through a given
/// side ([`SideBoundary::Given`], `GivenHalves`: a grid inside a world that goes on) it
/// is not: the world beyond is taken to go on as it is at the side, so a ground's edge
/// cells are ground within ground there, as in one sweep of the whole (their side faces
/// exposed, they sent a share of the ground's bounce light sideways out of the grid:
/// `cargo run --release -p lightgrid-measure --example handover`). The bottom face of a
/// bottom-level cell is **never** exposed: below the grid is the ground the bottom level
/// stands on, not empty space, so an opaque cell there emits nothing downward (emitting
/// half the ground's bounce light into nothing was a leak: a one-level ground reflected
/// half its albedo).
pub fn exposure(material: &MaterialGrid, sides: &SideBoundary) -> Vec<u8> {
    exposure_of(
        material,
        matches!(sides, SideBoundary::Periodic),
        sides.halo().is_some(),
    )
}

/// [`exposure`] for sides that are periodic (`periodic`), given (`given`), or else
/// open.
pub fn exposure_of(material: &MaterialGrid, periodic: bool, given: bool) -> Vec<u8> {
    let d = *material.desc();
    let dims = d.dims().as_ivec3();
    let cells = material.data();
    (0..d.point_count())
        .into_par_iter()
        .map(|i| {
            if cells[i].pass > 0.0 {
                return 0;
            }
            let p = d.coords(i).expect("index in range").as_ivec3();
            let mut mask = 0u8;
            for (f, n) in FACE_NORMALS.iter().enumerate() {
                let mut q = p + n.as_ivec3();
                if periodic && n.y == 0.0 {
                    q.x = q.x.rem_euclid(dims.x);
                    q.z = q.z.rem_euclid(dims.z);
                }
                let open = if q.y < 0 {
                    false // the ground below the grid
                } else if q.y >= dims.y {
                    true // the sky above it
                } else if q.cmplt(IVec3::ZERO).any() || q.cmpge(dims).any() {
                    !given // beyond a side: open, or the world as it is at the side
                } else {
                    cells[d.index_unchecked(q.as_uvec3())].pass > 0.0
                };
                if open {
                    mask |= 1 << f;
                }
            }
            mask
        })
        .collect()
}

/// The reflectance a sweep gives a cell with exposure mask `exposed` ([`exposure`]): its
/// own, but 0 for an opaque cell with no exposed face. Such a cell lies inside a solid;
/// what reaches it is light a sweep path's long step carried past the solid's surface
/// cell (a path from outside a side, or one that cuts a corner), and it stops there,
/// absorbed, instead of being scattered on into the solid's other cells, from cell to
/// cell through the whole of it (before this rule, a node's ground took in its side
/// halo's light and spread it through every cell of the ground: every opaque cell of
/// a 16 × 20 × 16 ground lit, and opaque levels cost more than empty ones). The CPU and
/// GPU sweepers both read the material through this rule.
#[inline]
pub fn swept_reflectance(m: &lightgrid_core::Material, exposed: u8) -> Vec3 {
    if m.pass <= 0.0 && exposed == 0 {
        Vec3::ZERO
    } else {
        m.reflectance
    }
}

/// Runs the sweep; see the crate docs for the semantics.
pub fn run(
    material: &MaterialGrid,
    boundary: &Boundary,
    options: &SweepOptions,
) -> Result<Sweep, SweepError> {
    run_with_source(material, boundary, None, options)
}

/// [`run`] with light already deposited in cells (see [`CellSource`]).
pub fn run_with_source(
    material: &MaterialGrid,
    boundary: &Boundary,
    source: Option<&CellSource>,
    options: &SweepOptions,
) -> Result<Sweep, SweepError> {
    run_impl(material, boundary, source, options, true)
}

/// The sweep written as the crate docs say it, step by step, with none of the fast
/// path's shortcuts: the oracle the fast path ([`run`], [`run_with_source`]) is
/// property-tested against (the light bit for bit, the energy balance to `f64` rounding)
/// and benchmarked beside.
pub fn run_scalar(
    material: &MaterialGrid,
    boundary: &Boundary,
    source: Option<&CellSource>,
    options: &SweepOptions,
) -> Result<Sweep, SweepError> {
    run_impl(material, boundary, source, options, false)
}

fn run_impl(
    material: &MaterialGrid,
    boundary: &Boundary,
    source: Option<&CellSource>,
    options: &SweepOptions,
    fast: bool,
) -> Result<Sweep, SweepError> {
    run_reusing(
        material,
        boundary,
        source,
        options,
        fast,
        &mut Spare::default(),
    )
}

/// [`run_impl`] writing into `spare`'s memory where it fits (and leaving what the output
/// does not use there).
pub(crate) fn run_reusing(
    material: &MaterialGrid,
    boundary: &Boundary,
    source: Option<&CellSource>,
    options: &SweepOptions,
    fast: bool,
    spare: &mut Spare,
) -> Result<Sweep, SweepError> {
    validate_inputs(material, boundary, options)?;
    // The halo's light carried through its given cells (`SideBoundary::halo_cells`).
    let carried = lightgrid_core::halo_carry::carried_boundary(boundary, material.desc().dims());
    let boundary = &*carried;
    // A gather for low suns alone (`Gather::AUTO`) is the sun's entry points' to apply:
    // a source given here is swept as it is.
    if source.is_some() && options.gather.for_source().is_on() {
        return Err(GridError::invalid(
            "gather",
            options.gather.orders,
            "is a sweeper's (`CpuSweeper::sweep_with_source`, `gather::sweep_gathered`): this sweep carries every scattering",
        )
        .into());
    }
    // Enclosed opaque cells absorb what reaches them: the phases read a cell's
    // reflectance through [`swept_reflectance`] and its exposure.
    let exposed = exposure(material, &boundary.sides);
    let desc = *material.desc();
    if let Some(src) = source
        && *src.desc() != desc
    {
        return Err(GridError::invalid(
            "source",
            src.desc(),
            "must lie on the material grid's descriptor",
        )
        .into());
    }
    let n = desc.point_count();
    let mut avg = take_buffer(&mut spare.average, n);
    let mut dom = take_buffer(&mut spare.dominant, n);
    let (want_avg, want_dom) = (options.outputs.average, options.outputs.dominant);
    let mut run = Run {
        material,
        exposed,
        boundary,
        source,
        options,
        fast,
        avg: &mut avg,
        dom: &mut dom,
        work: spare.work.take(),
    };
    let (bins, horizon, ok, balance, stats) = if options.outputs.horizon {
        // The split bins, then apart: the 26 bins and the downward halves.
        let (g, ok, balance, stats) = run.run(take_buffer(&mut spare.split, n));
        let mut bins = take_buffer(&mut spare.bins, n);
        let mut down = take_buffer(&mut spare.horizon, n);
        bins.par_chunks_mut(RESOLVE_CHUNK)
            .zip(down.par_chunks_mut(RESOLVE_CHUNK))
            .zip(g.par_chunks(RESOLVE_CHUNK))
            .for_each(|((b, h), g)| {
                for ((b, h), s) in b.iter_mut().zip(h).zip(g) {
                    *b = s.bins;
                    *h = s.down.within(&s.bins);
                }
            });
        spare.split = g;
        (
            Some(Grid::from_trusted(desc, bins)),
            Some(Grid::from_trusted(desc, down)),
            ok,
            balance,
            stats,
        )
    } else if options.outputs.bins {
        let (g, ok, balance, stats) = run.run(take_buffer(&mut spare.bins, n));
        (Some(Grid::from_trusted(desc, g)), None, ok, balance, stats)
    } else {
        let (_, ok, balance, stats) = run.run(fresh_buffer::<AvgAcc>(n));
        (None, None, ok, balance, stats)
    };
    spare.work = run.work.take();
    // Outputs not asked for keep their memory for the next sweep.
    let average = if want_avg {
        Some(Grid::from_trusted(desc, avg))
    } else {
        spare.average = avg;
        None
    };
    let dominant = if want_dom {
        Some(Grid::from_trusted(desc, dom))
    } else {
        spare.dominant = dom;
        None
    };
    if !ok {
        return Err(SweepError::Backend {
            backend: "cpu",
            message: "light overflowed f32 (boundary light too large for this grid)".into(),
        });
    }
    Ok(Sweep {
        output: SweepOutput {
            bins,
            horizon,
            average,
            dominant,
            stats,
            resident: None,
        },
        balance,
    })
}
