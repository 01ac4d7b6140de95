//! The sun's first collisions by beam tracing: parallel rays along the sun's exact
//! direction, each carrying its share of the beam's flux from where it enters the grid
//! to where it leaves or is used up, depositing in every cell exactly what it loses
//! there (`w T (1 - p^ℓ)`, all of `w T` in an opaque cell). So the beam is conserved
//! ray by ray: the first collisions plus what leaves through the bottom and the open
//! sides equal what enters through the top and the sides facing the sun
//! ([`BeamBudget`]), at any elevation and azimuth, over any media (issue 44).
//!
//! **The rays.** Every face of the grid's box that faces the sun (the top; on open
//! sides, the x and z faces toward it) gets `k` ray entry points per cell face, `k`
//! the first Fibonacci number at least `RAYS_PER_CELL · n·s`, so that every cell is
//! crossed by at least [`RAYS_PER_CELL`] rays however the sun stands; each ray
//! carries the flux `n·s / k` (per `h²`, times the irradiance). The points of a cell
//! face are a Fibonacci (rank-1) lattice, `((i + ½)/k, ((i F_{j-1} mod k) + ½)/k)`:
//! evenly spread in every direction, so the oblique chords through the cells below are
//! sampled without the regular grid's aliasing, and periodic with the cell, so every
//! cell of a flat ground takes exactly `E cos θ` (a unit-periodic point set shifted
//! any amount still puts `k` points in every unit square). With periodic sides the
//! rays enter through the top only and wrap at the sides, as the world repeats.
//!
//! **What a ray starts with** is the transmittance `outside` (1 for open sky; for a
//! node of the hierarchy, a march to the sky through the grids around it), clamped to
//! `[0, 1]`, read at the corners of the entry faces' cells and interpolated bilinearly
//! where the ray enters: a call a corner, not a call a ray (in a hierarchy each call is
//! a march of its own).
//!
//! **Where in a cell** the beam collides: per cell the collisions' Legendre moments
//! in height (`C₁/C₀`, `C₂/C₀`: the sweep's profile rule starts from them) and their
//! mean position across the cell in x and z (a low beam entering a cell through its
//! side collides near that side; a gather places the cell's first scattering by them:
//! [`crate::CellSource::with_across`], `crate::gather`), each in closed form along
//! every segment.
//!
//! **Determinism**: rays run in parallel in fixed chunks, and their deposits are added
//! in ray order in `f64`, so the result does not depend on the thread count (a world
//! bake repeats bit for bit).
//!
//! ```
//! use lightgrid_core::glam::{UVec3, Vec3};
//! use lightgrid_core::{GridDesc, Material, MaterialGrid};
//! use lightgrid_sweep_cpu::beam::{BeamOptions, first_collisions};
//!
//! // A slab of medium over opaque ground, open sides, a sun 10° above the horizon.
//! let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(8, 4, 8))?;
//! let cells = (0..desc.point_count())
//!     .map(|i| match desc.coords(i).unwrap().y {
//!         0 => Material { reflectance: Vec3::splat(0.2), pass: 0.0 },
//!         1 | 2 => Material { reflectance: Vec3::splat(0.7), pass: 0.5 },
//!         _ => Material::EMPTY,
//!     })
//!     .collect();
//! let m = MaterialGrid::new(desc, cells)?;
//! let e = 10f32.to_radians();
//! let to_sun = Vec3::new(e.cos(), e.sin(), 0.0);
//! let f = first_collisions(&m, to_sun, Vec3::ONE, false, &|_| 1.0, &BeamOptions::DEFAULT)?;
//! // Every ray's flux is accounted for: deposited, or gone through the open sides.
//! assert!(f.budget.relative_error() < 1e-9);
//! assert_eq!(f.budget.left_bottom, 0.0); // the ground stops what reaches it
//! // What entered: the top and the side facing the sun, `E (s_y · 64 + s_x · 32)`.
//! let want = (to_sun.y * 64.0 + to_sun.x * 32.0) as f64;
//! assert!((f.budget.entered - want).abs() < 1e-4 * want);
//! # Ok::<(), lightgrid_core::GridError>(())
//! ```
//!
//! The rule it replaces, `E cos θ (T_top - T_bottom)` per medium cell, counted only
//! what crosses a cell's top and bottom: over a patchy canopy under a 10° sun a fifth
//! of the beam was never deposited (issue 44).

use lightgrid_core::glam::{IVec3, Vec3};
use lightgrid_core::{GridDesc, GridError, MaterialGrid};
use rayon::prelude::*;

use crate::sun::{MAX_STEPS_PER_CELL, sun_direction};

/// The least number of rays that cross any cell (rays per cell area normal to the beam).
pub const RAYS_PER_CELL: u32 = 16;

/// A ray's deposit in a cell: its index, and the collided flux, its two height
/// moments and the track (flux × length).
type Deposit = (u32, [f64; 6]);

/// Rays traced per parallel task (fixed, so the sums' order is too).
const CHUNK: usize = 256;

/// Where the beam went, in flux per `h²` for unit normal irradiance (multiply by the
/// irradiance for a colour). `entered == collided + left_bottom + left_sides + stopped`
/// to rounding, ray by ray.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct BeamBudget {
    /// Through the faces facing the sun, times the transmittance `outside` there.
    pub entered: f64,
    /// Deposited in the cells (the first collisions).
    pub collided: f64,
    /// Left through the bottom face.
    pub left_bottom: f64,
    /// Left through open sides.
    pub left_sides: f64,
    /// Still travelling after [`MAX_STEPS_PER_CELL`] × (nx + ny + nz) cell steps (a
    /// periodic sun within a fraction of a degree of the horizon): neither deposited
    /// nor left.
    pub stopped: f64,
}

impl BeamBudget {
    /// `|entered - (collided + left + stopped)| / entered` (0 when nothing entered).
    pub fn relative_error(&self) -> f64 {
        let out = self.collided + self.left_bottom + self.left_sides + self.stopped;
        if self.entered > 0.0 {
            (self.entered - out).abs() / self.entered
        } else {
            out.abs()
        }
    }

    fn add(&mut self, o: &BeamBudget) {
        self.entered += o.entered;
        self.collided += o.collided;
        self.left_bottom += o.left_bottom;
        self.left_sides += o.left_sides;
        self.stopped += o.stopped;
    }
}

/// The sun's first collisions and where the rest of the beam went.
#[derive(Debug, Clone)]
pub struct FirstCollisions {
    /// What the beam loses per cell (flux per `h²`, RGB), along `-to_sun`.
    pub source: crate::CellSource,
    /// The beam's accounts, for unit irradiance.
    pub budget: BeamBudget,
    /// Each cell's mean transmittance (over its volume, by the rays' track lengths:
    /// a cell average, as a Monte Carlo tally's; the march's values are at the
    /// points), where [`BeamOptions::mean_transmittance`] asked for it.
    pub mean_transmittance: Option<Vec<f32>>,
}

/// The sun's first collisions: what a beam of normal irradiance `irradiance` (RGB)
/// toward `to_sun` loses in each cell (module docs), as a [`crate::CellSource`] for
/// [`crate::run_with_source`]; `periodic` as the sweep's sides, `outside(world)` the
/// transmittance the beam already has where it enters the grid's box. The sweep emits
/// a medium cell's deposit by the medium rule and an opaque cell's by the surface rule.
/// A sun at or below the horizon deposits nothing.
pub fn first_collision(
    material: &MaterialGrid,
    to_sun: Vec3,
    irradiance: Vec3,
    periodic: bool,
    outside: &(dyn Fn(Vec3) -> f32 + Sync),
) -> Result<crate::CellSource, GridError> {
    Ok(first_collisions(
        material,
        to_sun,
        irradiance,
        periodic,
        outside,
        &BeamOptions::DEFAULT,
    )?
    .source)
}

/// How the beam is traced ([`first_collisions`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BeamOptions {
    /// The least number of rays that cross a cell (1 to 4096): time grows with it,
    /// the cells' error falls (`cargo run --release -p lightgrid-measure --example
    /// beam`).
    pub rays_per_cell: u32,
    /// Also tally each cell's mean transmittance ([`FirstCollisions::mean_transmittance`]).
    pub mean_transmittance: bool,
}

impl BeamOptions {
    /// [`RAYS_PER_CELL`] rays, no transmittance tally: what sweeps use.
    pub const DEFAULT: Self = Self {
        rays_per_cell: RAYS_PER_CELL,
        mean_transmittance: false,
    };

    /// These options with `rays_per_cell` rays.
    pub const fn with_rays(mut self, rays_per_cell: u32) -> Self {
        self.rays_per_cell = rays_per_cell;
        self
    }

    /// These options with the cells' mean transmittance tallied.
    pub const fn with_mean_transmittance(mut self) -> Self {
        self.mean_transmittance = true;
        self
    }
}

impl Default for BeamOptions {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// [`first_collision`] with the beam's [`BeamBudget`], traced with `options`.
pub fn first_collisions(
    material: &MaterialGrid,
    to_sun: Vec3,
    irradiance: Vec3,
    periodic: bool,
    outside: &(dyn Fn(Vec3) -> f32 + Sync),
    options: &BeamOptions,
) -> Result<FirstCollisions, GridError> {
    let desc = *material.desc();
    let rays_per_cell = options.rays_per_cell;
    if !(1..=4096).contains(&rays_per_cell) {
        return Err(GridError::invalid(
            "rays_per_cell",
            rays_per_cell,
            "must be 1 to 4096",
        ));
    }
    if !irradiance.is_finite() || irradiance.min_element() < 0.0 {
        return Err(GridError::invalid(
            "irradiance",
            irradiance,
            "must be finite and >= 0",
        ));
    }
    let Some(s) = sun_direction(to_sun)? else {
        return Ok(FirstCollisions {
            source: crate::CellSource::new(
                desc,
                vec![Vec3::ZERO; desc.point_count()],
                Vec3::NEG_Y,
            )?,
            budget: BeamBudget::default(),
            mean_transmittance: options
                .mean_transmittance
                .then(|| vec![0.0; desc.point_count()]),
        });
    };
    let mut faces = entry_faces(&desc, s, periodic, rays_per_cell);
    // What the beam has already lost, read at the entry faces' cell corners (one call
    // a corner: in a hierarchy each call marches to the sky) and bilinear between.
    let clamp01 = |o: f32| if o.is_nan() { 0.0 } else { o.clamp(0.0, 1.0) };
    for f in &mut faces {
        let nu = f.n[0] as usize + 1;
        f.corners = (0..nu * (f.n[1] as usize + 1))
            .into_par_iter()
            .map(|c| {
                let (u, v) = ((c % nu) as f32 - 0.5, (c / nu) as f32 - 0.5);
                let p = match f.axis {
                    0 => Vec3::new(f.at, u, v),
                    1 => Vec3::new(u, f.at, v),
                    _ => Vec3::new(u, v, f.at),
                };
                clamp01(outside(desc.origin() + p * desc.h()))
            })
            .collect();
    }
    let rays: usize = faces.iter().map(|f| f.rays()).sum();
    let tracer = Tracer {
        desc,
        dims: desc.dims().as_ivec3(),
        pass: material.data().iter().map(|m| m.pass).collect(),
        sigma: material
            .data()
            .iter()
            .map(|m| -(m.pass.clamp(f32::MIN_POSITIVE, 1.0) as f64).ln())
            .collect(),
        dir: -s,
        periodic,
        track: options.mean_transmittance,
        max_steps: MAX_STEPS_PER_CELL * desc.dims().element_sum(),
    };
    // Per cell: the collided flux, its height moments (flux × C₁/C₀, × C₂/C₀), the
    // track (flux × length) and its first moments across (flux × x̄, × z̄).
    let mut sum = vec![[0f64; 6]; desc.point_count()];
    let mut budget = BeamBudget::default();
    // Waves of chunks, a few a thread: the deposits waiting to be summed are bounded
    // by the wave (a ray through thin media deposits in every cell it crosses), and
    // the sums run in ray order whatever the threads.
    let chunks = rays.div_ceil(CHUNK);
    let wave = (8 * rayon::current_num_threads()).max(16);
    for w0 in (0..chunks).step_by(wave) {
        let parts: Vec<(Vec<Deposit>, BeamBudget)> = (w0..(w0 + wave).min(chunks))
            .into_par_iter()
            .map(|c| {
                let mut dep = Vec::new();
                let mut b = BeamBudget::default();
                for r in c * CHUNK..((c + 1) * CHUNK).min(rays) {
                    let (start, weight, t0) = ray_start(&faces, r);
                    tracer.trace(start, weight, t0, &mut dep, &mut b);
                }
                (dep, b)
            })
            .collect();
        for (dep, b) in parts {
            for (i, v) in dep {
                let c = &mut sum[i as usize];
                for k in 0..6 {
                    c[k] += v[k];
                }
            }
            budget.add(&b);
        }
    }
    let removed = sum
        .iter()
        .map(|v| irradiance * (v[0] as f32).max(0.0))
        .collect();
    // Two of the sums per unit of collided flux (0 where none collided), each clamped
    // to `[lo, 1]`.
    let per_flux = |k: [usize; 2], lo: [f64; 2]| -> Vec<[f32; 2]> {
        sum.iter()
            .map(|v| {
                if v[0] > 0.0 {
                    [0, 1].map(|j| (v[k[j]] / v[0]).clamp(lo[j], 1.0) as f32)
                } else {
                    [0.0; 2]
                }
            })
            .collect()
    };
    let heights = per_flux([1, 2], [-1.0, -0.5]);
    let across = per_flux([4, 5], [-1.0, -1.0]);
    // Volume per cell is 1 (grid units); the rays' track lengths times their flux per
    // unit projected area integrate the transmittance over it.
    let mean_transmittance = options
        .mean_transmittance
        .then(|| sum.iter().map(|v| (v[3] as f32).clamp(0.0, 1.0)).collect());
    Ok(FirstCollisions {
        source: crate::CellSource::with_heights(desc, removed, heights, -s)?.with_across(across)?,
        budget,
        mean_transmittance,
    })
}

/// Where along a segment of optical length `t` (`keep = e^-t`), from local height `y0`
/// to `y1`, the light entering it collides: `(C₁/C₀, C₂/C₀)`, `Cₙ = ∫₀ᵗ Pₙ(y(s)) e^-s ds`
/// (as `profile::Segment::collided`, in closed form: `γ(1..3, t)` from `e^-t`, a
/// series below `t = 10⁻³`), and where along it on average, as a fraction of its
/// length: `γ(2, t) / (t γ(1, t))` (½ when thin, `1/t` when thick), by which a
/// coordinate linear along the segment (x, z) has its mean over the collisions.
fn height_moments(t: f64, keep: f64, y0: f64, y1: f64) -> (f64, f64, f64) {
    let (g1, g2, g3) = gammas(t, keep);
    if g1 <= 0.0 || t * g1 <= 0.0 {
        return (0.5 * (y0 + y1), 0.5 * (3.0 * y0 * y0 - 1.0), 0.5);
    }
    let d = (y1 - y0) / t;
    let c1 = y0 * g1 + d * g2;
    let c2 = 0.5 * (3.0 * y0 * y0 - 1.0) * g1 + 3.0 * y0 * d * g2 + 1.5 * d * d * g3;
    (
        (c1 / g1).clamp(-1.0, 1.0),
        (c2 / g1).clamp(-0.5, 1.0),
        g2 / (t * g1),
    )
}

/// `γ(1, t)`, `γ(2, t)`, `γ(3, t)` (the lower incomplete gamma functions: `γ(n, t) =
/// ∫₀ᵗ sⁿ⁻¹ e^-s ds`) from `keep = e^-t`; a series below `t = 10⁻³`.
fn gammas(t: f64, keep: f64) -> (f64, f64, f64) {
    if t > 1e-3 {
        (
            1.0 - keep,
            1.0 - keep * (1.0 + t),
            2.0 - keep * (t * t + 2.0 * t + 2.0),
        )
    } else {
        let t2 = t * t;
        (
            t - t2 / 2.0 + t2 * t / 6.0,
            t2 / 2.0 - t2 * t / 3.0 + t2 * t2 / 8.0,
            t2 * t / 3.0 - t2 * t2 / 4.0,
        )
    }
}

/// A point's local coordinate along axis `k` in `cell` (centred on its integer
/// coordinates, as the tracer's cells are), -1 to 1.
fn local_at(pos: Vec3, cell: IVec3, k: usize) -> f64 {
    (2.0 * (pos[k] - cell[k] as f32)).clamp(-1.0, 1.0) as f64
}

/// One face of the box the beam enters by: `axis` its normal's axis, at coordinate
/// `at` (grid units), spanning `n[0] × n[1]` cells along the other two axes (`u`, `v`
/// in increasing axis order), `k` rays per cell face on a Fibonacci lattice
/// (`k = F_j`, generator `F_{j-1}`), each carrying `weight`.
#[derive(Debug, Clone)]
struct Face {
    axis: usize,
    at: f32,
    n: [u32; 2],
    k: u32,
    g: u32,
    shift: [f32; 2],
    weight: f64,
    /// `outside` at the face cells' corners, `(n[0] + 1) × (n[1] + 1)`, `u` fastest.
    corners: Vec<f32>,
}

impl Face {
    fn rays(&self) -> usize {
        self.n[0] as usize * self.n[1] as usize * self.k as usize
    }
}

/// The smallest Fibonacci number `F_j >= want` (at least 1) and `F_{j-1}`.
fn fibonacci_at_least(want: f32) -> (u32, u32) {
    let (mut a, mut b) = (1u32, 1u32);
    while (b as f32) < want {
        (a, b) = (b, a + b);
    }
    (b, a)
}

/// The faces facing the sun `s` (unit, `s.y > 0`).
fn entry_faces(desc: &GridDesc, s: Vec3, periodic: bool, rays_per_cell: u32) -> Vec<Face> {
    let d = desc.dims();
    let mut faces = Vec::new();
    for axis in 0..3 {
        if axis != 1 && periodic {
            continue;
        }
        let cos = s[axis].abs();
        if cos <= 0.0 {
            continue;
        }
        let (k, g) = fibonacci_at_least(rays_per_cell as f32 * cos);
        let n = match axis {
            0 => [d.y, d.z],
            1 => [d.x, d.z],
            _ => [d.x, d.y],
        };
        let at = if s[axis] > 0.0 {
            d[axis] as f32 - 0.5
        } else {
            -0.5
        };
        // The lattice is anchored in the world: the rays through a face are those
        // through the lattice `h (ℤ² + points)` on the world plane through 0 normal to
        // `axis`, carried along the sun to the face; so grids of one cell size trace
        // the same rays wherever their boxes start (a grid's lower levels swept on
        // their own take what the whole grid's rays bring them).
        let (o, h) = (desc.origin().as_dvec3(), desc.h() as f64);
        let sd = s.as_dvec3();
        let plane = o[axis] + at as f64 * h;
        let [b, c] = match axis {
            0 => [1, 2],
            1 => [0, 2],
            _ => [0, 1],
        };
        let shift = [b, c].map(|e| {
            let u = (plane * sd[e] / sd[axis] - o[e]) / h + 0.5;
            (u - u.floor()) as f32
        });
        faces.push(Face {
            axis,
            at,
            n,
            k,
            g,
            shift,
            weight: cos as f64 / k as f64,
            corners: Vec::new(),
        });
    }
    faces
}

/// Ray `r`'s entry point (grid units), flux, and the transmittance it brings.
fn ray_start(faces: &[Face], mut r: usize) -> (Vec3, f64, f64) {
    for f in faces {
        let total = f.rays();
        if r >= total {
            r -= total;
            continue;
        }
        let k = f.k as usize;
        let (cell, i) = (r / k, r % k);
        let (cu, cv) = (cell % f.n[0] as usize, cell / f.n[0] as usize);
        // The rank-1 lattice (i/k, i g/k), centred in its strata: every unit square
        // of the face, shifted any amount, holds exactly k of its points.
        let j = (i * f.g as usize) % k;
        let wrap = |x: f32| x - x.floor();
        let u = cu as f32 - 0.5 + wrap((i as f32 + 0.5) / k as f32 + f.shift[0]);
        let v = cv as f32 - 0.5 + wrap((j as f32 + 0.5) / k as f32 + f.shift[1]);
        let p = match f.axis {
            0 => Vec3::new(f.at, u, v),
            1 => Vec3::new(u, f.at, v),
            _ => Vec3::new(u, v, f.at),
        };
        // Bilinear between the face cell's corners.
        let nu = f.n[0] as usize + 1;
        let (fu, fv) = (u + 0.5 - cu as f32, v + 0.5 - cv as f32);
        let at = |i: usize, j: usize| f.corners[(cu + i) + nu * (cv + j)] as f64;
        let (fu, fv) = (fu.clamp(0.0, 1.0) as f64, fv.clamp(0.0, 1.0) as f64);
        let t0 = (at(0, 0) * (1.0 - fu) + at(1, 0) * fu) * (1.0 - fv)
            + (at(0, 1) * (1.0 - fu) + at(1, 1) * fu) * fv;
        return (p, f.weight, t0);
    }
    unreachable!("ray index within the faces' rays")
}

struct Tracer {
    desc: GridDesc,
    dims: IVec3,
    pass: Vec<f32>,
    /// Extinction per cell length, `-ln p` (where `0 < p < 1`).
    sigma: Vec<f64>,
    dir: Vec3,
    periodic: bool,
    track: bool,
    max_steps: u32,
}

impl Tracer {
    /// Follows one ray from `start` (on an entry face) with flux `weight` and
    /// transmittance `t0`, pushing its deposits (merged per cell run) and booking it in
    /// `b`.
    fn trace(&self, start: Vec3, weight: f64, t0: f64, dep: &mut Vec<Deposit>, b: &mut BeamBudget) {
        let mut flux = weight * t0;
        b.entered += flux;
        if flux <= 0.0 {
            return;
        }
        let dims = self.dims;
        let dir = self.dir;
        // The cell the ray enters: the entry face's coordinate is on a boundary, so
        // round the other axes and step inside along the face's axis.
        let mut cell = (start + dir * 1e-4).round().as_ivec3();
        cell = cell.clamp(IVec3::ZERO, dims - IVec3::ONE);
        let mut pos = start;
        // Deposits `c` (flux and its height moments) in cell `i`, merged per cell run.
        let mut deposit = |i: u32, c: [f64; 6], dep: &mut Vec<Deposit>| {
            b.collided += c[0];
            match dep.last_mut() {
                Some((j, w)) if *j == i => {
                    for k in 0..6 {
                        w[k] += c[k];
                    }
                }
                _ => dep.push((i, c)),
            }
        };
        for _ in 0..self.max_steps {
            let i = self.desc.index_unchecked(cell.as_uvec3());
            let p = self.pass[i];
            let (len, axis) = lightgrid_core::dda::exit(cell, pos, dir);
            if p <= 0.0 {
                deposit(i as u32, [flux, 0.0, 0.0, 0.0, 0.0, 0.0], dep);
                return;
            }
            let y0 = local_at(pos, cell, 1);
            if self.track && p >= 1.0 && len > 0.0 {
                deposit(i as u32, [0.0, 0.0, 0.0, flux * len as f64, 0.0, 0.0], dep);
            }
            if p < 1.0 && len > 0.0 {
                let sigma = self.sigma[i];
                let t = sigma * len as f64;
                let keep = (-t).exp();
                let lost = flux * (1.0 - keep);
                // ∫ flux ds over the segment: the flux lost over the extinction.
                let track = lost / sigma;
                let end = pos + dir * len;
                let (m1, m2, along) = height_moments(t, keep, y0, local_at(end, cell, 1));
                // Across: x and z are linear along the segment too.
                let across = |k: usize| {
                    let (a0, a1) = (local_at(pos, cell, k), local_at(end, cell, k));
                    (a0 + (a1 - a0) * along).clamp(-1.0, 1.0)
                };
                let (mx, mz) = (across(0), across(2));
                flux *= keep;
                if flux < 1e-30 * weight {
                    let all = lost + flux;
                    deposit(
                        i as u32,
                        [all, all * m1, all * m2, track, all * mx, all * mz],
                        dep,
                    );
                    return;
                }
                deposit(
                    i as u32,
                    [lost, lost * m1, lost * m2, track, lost * mx, lost * mz],
                    dep,
                );
            }
            pos += dir * len;
            let step = lightgrid_core::dda::cross(&mut cell, &mut pos, axis, dir);
            if cell[axis] >= 0 && cell[axis] < dims[axis] {
                continue;
            }
            if axis == 1 {
                b.left_bottom += flux;
                return;
            }
            if !self.periodic {
                b.left_sides += flux;
                return;
            }
            let n = dims[axis];
            cell[axis] = cell[axis].rem_euclid(n);
            pos[axis] += if step > 0 { -(n as f32) } else { n as f32 };
        }
        b.stopped += flux;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The closed form the tracer uses equals `profile::Segment::collided` (the series
    /// and incomplete gamma functions the profile rule's tables come from), across
    /// optical lengths from the series' range to thick cells, rising and falling.
    #[test]
    fn height_moments_are_the_segments_collisions() {
        for t in [1e-7, 5e-4, 1e-3, 2e-3, 0.05, 0.7, 1.99, 2.01, 9.0, 60.0] {
            for (y0, y1) in [
                (1.0, -1.0),
                (0.3, -0.9),
                (-1.0, 1.0),
                (0.5, 0.5),
                (-0.2, 0.6),
            ] {
                let c = crate::profile::Segment { t, y0, y1 }.collided();
                let (m1, m2, along) = height_moments(t, (-t).exp(), y0, y1);
                let (w1, w2) = (c[1] / c[0], c[2] / c[0]);
                assert!(
                    (m1 - w1).abs() < 1e-6 && (m2 - w2).abs() < 1e-6,
                    "t {t}, y {y0}..{y1}: ({m1}, {m2}) vs ({w1}, {w2})"
                );
                // A coordinate linear along the segment, as x and z are: its mean over
                // the collisions is where along the segment they fall on average.
                let across = y0 + (y1 - y0) * along;
                assert!((across - w1).abs() < 1e-6, "t {t}: {across} vs {w1}");
            }
        }
    }

    /// A low beam entering a dense slab through its side collides near that side: the
    /// sunward cells' mean position leans toward the sun, less so farther in, not at
    /// all across the beam; a sun from the other side mirrors it.
    #[test]
    fn a_low_beam_collides_near_the_side_it_enters() {
        let desc =
            GridDesc::new(Vec3::ZERO, 1.0, lightgrid_core::glam::UVec3::new(4, 3, 4)).unwrap();
        let cells = (0..desc.point_count())
            .map(|i| match desc.coords(i).unwrap().y {
                0 => lightgrid_core::Material::opaque(Vec3::splat(0.2)),
                1 => lightgrid_core::Material {
                    reflectance: Vec3::splat(0.7),
                    pass: 0.05,
                },
                _ => lightgrid_core::Material::EMPTY,
            })
            .collect();
        let m = MaterialGrid::new(desc, cells).unwrap();
        let e = 5f32.to_radians();
        let across = |sign: f32| {
            let to_sun = Vec3::new(sign * e.cos(), e.sin(), 0.0);
            // Many rays a cell: the lattice's own scatter of where they enter (some
            // 0.2 in z̄ at the default 16) is then small.
            let options = BeamOptions::DEFAULT.with_rays(1024);
            first_collisions(&m, to_sun, Vec3::ONE, false, &|_| 1.0, &options)
                .unwrap()
                .source
                .across()
                .unwrap()
                .to_vec()
        };
        let (east, west) = (across(1.0), across(-1.0));
        let at = |a: &[[f32; 2]], x: u32, z: u32| a[desc.index((x, 1, z).into()).unwrap()];
        for z in 0..4 {
            let (sunward, next) = (at(&east, 3, z), at(&east, 2, z));
            // Optical depth 3 a cell: about a third of the way in, on average.
            assert!(sunward[0] > 0.3 && sunward[0] < 0.5, "{sunward:?}");
            assert!(next[0] < sunward[0], "{next:?} against {sunward:?}");
            for x in 0..4 {
                let (a, b) = (at(&east, x, z), at(&west, 3 - x, z));
                assert!(a[1].abs() < 0.01, "across the beam: {a:?}");
                assert!((a[0] + b[0]).abs() < 0.01, "mirror: {a:?} against {b:?}");
            }
        }
    }
}
