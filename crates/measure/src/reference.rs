//! The Monte Carlo reference: the same physical problem as the sweep, in the continuous
//! limit, solved by tracing light paths.
//!
//! **The problem.** Each material cell with `p > 0` is a homogeneous medium with
//! extinction `σ = -ln(p) / h`, single-scattering albedo = reflectance (per RGB channel),
//! and isotropic scattering. A cell with `p = 0` is opaque: its faces are diffuse
//! (Lambertian) surfaces of albedo = reflectance. (A face that scatters isotropically
//! would have unbounded radiance at grazing angles, and so would the fluence near it.) It is lit through its faces by
//! the [`Boundary`]: radiance constant within each bin (within each half of a horizontal
//! bin), `top` entering through the top face and, with open sides, through the sides
//! (travelling downward), `bottom` through the bottom face and the sides (travelling
//! upward). Periodic sides wrap paths around. Given halos and per-point tops are not
//! supported (a typed error).
//!
//! **The estimator.** Paths start on a face with probability proportional to the flux
//! entering there (exact per bin: `dirs::bin_region` clips each bin to the half-space
//! that enters the face), then fly through the cells with exact segment-in-cell lengths
//! (3D DDA), scatter at collisions (weight × albedo), and end when they leave the grid
//! or their weight falls below 1e-6 of where it started (that remainder is tallied as
//! `terminated`). Every segment deposits `weight × length` into the bin of its direction
//! in the cell it crosses (the track-length estimator, 3DWorld's "every cell a ray
//! passes"); divided by the cell volume this is the light a bin holds at the cell's point,
//! directly comparable with the sweep's light grid.
//!
//! **Determinism.** Paths are traced in batches; each path draws from its own random
//! stream (seed, path index), and deposits are added to `f64` tallies in path order, so a
//! run is identical for the same seed and path count on any number of threads. A time
//! budget stops between batches.

use std::time::{Duration, Instant};

use lightgrid_core::dda;
use lightgrid_core::dirs::{self, NUM_DIRS};
use lightgrid_core::glam::{DVec3, IVec3, UVec3, Vec3};
use lightgrid_core::light::AMBIENT_AXES;
use lightgrid_core::{
    BinLight, Boundary, Grid, GridError, LightGrid, MaterialGrid, SideBoundary, SweepError,
    TopBoundary,
};
use rayon::prelude::*;

use lightgrid_sweep_cpu::EnergyBalance;

/// Options of a reference run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReferenceOptions {
    /// Paths to trace.
    pub paths: u64,
    /// Stop early (between batches) after this long.
    pub time_budget: Option<Duration>,
    /// Random seed.
    pub seed: u64,
    /// Most scattering events of one path before it is terminated.
    pub max_events: u32,
    /// Longest track of one path, in multiples of `nx + ny + nz` cells, before it is
    /// terminated. Bounds the heavy tail of grazing paths between periodic layers (their
    /// track-length estimate has unbounded variance); the cut weight is reported as
    /// `pending`.
    pub max_track: f32,
}

/// Most paths one reference run may trace (2^40, about a day on a workstation).
pub const MAX_PATHS: u64 = 1 << 40;

impl ReferenceOptions {
    /// Checks the options: `paths` in 1..=[`MAX_PATHS`], `max_events` at least 1,
    /// `max_track` finite and > 0. Errors name the field.
    pub fn validate(&self) -> Result<(), GridError> {
        if !(1..=MAX_PATHS).contains(&self.paths) {
            return Err(GridError::invalid(
                "paths",
                self.paths,
                "must be in 1..=2^40",
            ));
        }
        if self.max_events == 0 {
            return Err(GridError::invalid("max_events", 0, "must be at least 1"));
        }
        if !(self.max_track.is_finite() && self.max_track > 0.0) {
            return Err(GridError::invalid(
                "max_track",
                self.max_track,
                "must be finite and > 0",
            ));
        }
        Ok(())
    }
}

impl Default for ReferenceOptions {
    fn default() -> Self {
        Self {
            paths: 1_000_000,
            time_budget: None,
            seed: 1,
            max_events: 100_000,
            max_track: 16.0,
        }
    }
}

/// The result of a reference run.
#[derive(Debug, Clone)]
pub struct Reference {
    /// Light per point and bin (the cell's mean over its volume).
    pub light: LightGrid,
    /// Paths traced.
    pub paths: u64,
    /// Flux tallies in the sweep's units (light × `h²` per point); `pending` holds the
    /// weight of terminated paths.
    pub balance: EnergyBalance,
    /// Standard error of each point's average light (RGB), from 8 interleaved groups of
    /// paths.
    pub std_error: Vec<Vec3>,
    /// The collimated sun's uncollided light per point (cell mean of `E T`, RGB; zero
    /// without a sun): kept out of `light`, whose bins hold only the light that has
    /// scattered at least once, because a bin cannot hold a beam's exact direction.
    pub direct: Vec<Vec3>,
    /// The irradiance of `light` on the six axes ([`AMBIENT_AXES`] order) per point,
    /// tallied from the paths' exact directions (`Σ w ℓ max(0, -n·ω)`): no bins, so no
    /// assumption about how light is spread inside one (the horizon's, say).
    pub irradiance: Vec<[Vec3; 6]>,
}

/// A collimated sun for [`trace_with_sun`]: irradiance `irradiance` (RGB, on a plane
/// facing it) arriving from direction `to_sun`, exactly, through the grid's faces.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CollimatedSun {
    /// Direction toward the sun (any length; at or below the horizon it lights nothing
    /// through the top).
    pub to_sun: Vec3,
    /// Irradiance normal to the beam.
    pub irradiance: Vec3,
}

impl Reference {
    /// Root-mean-square over points of (standard error / value) of the average light,
    /// over points whose average exceeds `floor` (luminance).
    pub fn relative_std_error(&self, floor: f32) -> f64 {
        let mut sum = 0.0;
        let mut n = 0usize;
        for (b, se) in self.light.data().iter().zip(&self.std_error) {
            let a = lightgrid_core::light::luminance(b.average());
            if a > floor {
                let r = lightgrid_core::light::luminance(*se) / a;
                sum += (r * r) as f64;
                n += 1;
            }
        }
        if n == 0 { 0.0 } else { (sum / n as f64).sqrt() }
    }
}

const GROUPS: usize = 8;
const BATCH: u64 = 1 << 14;

/// One way light enters: a face, a boundary's bin, the part of the bin that enters.
struct SourceComponent {
    /// Inward normal of the face.
    normal: IVec3,
    bin: usize,
    /// Planes the direction must be on the positive side of.
    planes: Vec<DVec3>,
    /// Flux entering (RGB), light × h² per point units.
    flux: Vec3,
    /// A collimated beam's exact direction (no sampling; uncollided light is tallied in
    /// `Reference::direct`).
    exact: Option<Vec3>,
}

struct BinCap {
    basis: (Vec3, Vec3, Vec3),
    cos_max: f32,
}

fn bin_caps() -> Vec<BinCap> {
    let g = dirs::bins();
    (0..NUM_DIRS)
        .map(|d| {
            let u = dirs::dir_unit(d);
            let ud = u.as_dvec3();
            let cos_min = g.polygons[d].iter().map(|v| v.dot(ud)).fold(1.0, f64::min);
            let t1 = u.any_orthonormal_vector();
            BinCap {
                basis: (t1, u.cross(t1), u),
                cos_max: (cos_min - 1e-4) as f32,
            }
        })
        .collect()
}

fn sources(
    boundary: &Boundary,
    dims: UVec3,
    open: bool,
) -> Result<Vec<SourceComponent>, SweepError> {
    let top = match &boundary.top {
        TopBoundary::Uniform(b) => **b,
        TopBoundary::PerPoint(_) => {
            return Err(SweepError::Invalid(GridError::invalid(
                "top",
                "PerPoint",
                "the Monte Carlo reference supports a uniform top only",
            )));
        }
    };
    if boundary.sides.halo().is_some() {
        return Err(SweepError::Invalid(GridError::invalid(
            "sides",
            "Given",
            "the Monte Carlo reference supports open and periodic sides only",
        )));
    }
    let faces = entry_faces(dims, open);
    let mut out = Vec::new();
    for (light, vertical) in [(&top, DVec3::NEG_Y), (&boundary.bottom, DVec3::Y)] {
        for d in 0..NUM_DIRS {
            let v = light.0[d];
            if v == Vec3::ZERO || dirs::dir_ivec(d).y as f64 * vertical.y < 0.0 {
                continue; // empty, or a bin this boundary does not carry
            }
            let (omega_half, _) = dirs::bin_region(d, &[vertical]);
            if omega_half <= 0.0 {
                continue;
            }
            let radiance = v / omega_half as f32;
            for &(n, area) in &faces {
                let planes = vec![vertical, n.as_dvec3()];
                let (w, m) = dirs::bin_region(d, &planes);
                let cosine = n.as_dvec3().dot(m);
                if w <= 0.0 || cosine <= 0.0 {
                    continue;
                }
                out.push(SourceComponent {
                    normal: n,
                    bin: d,
                    planes,
                    flux: radiance * (cosine * area) as f32,
                    exact: None,
                });
            }
        }
    }
    Ok(out)
}

/// The faces light may enter by, as (inward normal, area in cells): top and bottom, and
/// the four sides when they are open.
fn entry_faces(dims: UVec3, open: bool) -> Vec<(IVec3, f64)> {
    let (nx, ny, nz) = (dims.x as f64, dims.y as f64, dims.z as f64);
    let mut faces = vec![(IVec3::NEG_Y, nx * nz), (IVec3::Y, nx * nz)];
    if open {
        faces.extend([
            (IVec3::X, ny * nz),
            (IVec3::NEG_X, ny * nz),
            (IVec3::Z, nx * ny),
            (IVec3::NEG_Z, nx * ny),
        ]);
    }
    faces
}

/// The collimated sun's components: every face the beam enters (the top, and the sides
/// when they are open), flux `E (d · n) area`.
fn sun_sources(
    sun: &CollimatedSun,
    dims: UVec3,
    open: bool,
) -> Result<Vec<SourceComponent>, SweepError> {
    let Some(s) = lightgrid_sweep_cpu::sun::sun_direction(sun.to_sun)? else {
        return Ok(Vec::new());
    };
    if !sun.irradiance.is_finite() || sun.irradiance.min_element() < 0.0 {
        return Err(GridError::invalid(
            "sun.irradiance",
            sun.irradiance,
            "must be finite and >= 0",
        )
        .into());
    }
    let d = -s;
    Ok(entry_faces(dims, open)
        .into_iter()
        .filter_map(|(n, area)| {
            // Only the faces the beam enters (the bottom never: the sun is above).
            let c = d.dot(n.as_vec3());
            (c > 0.0 && sun.irradiance != Vec3::ZERO).then(|| SourceComponent {
                normal: n,
                bin: dirs::nearest_dir(d),
                planes: Vec::new(),
                flux: sun.irradiance * (c * area as f32),
                exact: Some(d),
            })
        })
        .collect())
}

/// The reference's tallies: an RGB sum per slot (cell × 26 + bin), in `f64`, added in
/// path order. Ten million deposits of 0.1 into one slot stay within 1e-12 of the exact
/// sum (an `f32` running sum drifts by percents); `tests/stress.rs` checks it.
#[derive(Debug, Clone, PartialEq)]
pub struct Tally {
    sums: Vec<f64>,
}

impl Tally {
    /// `slots` zeroed sums.
    pub fn new(slots: usize) -> Self {
        Self {
            sums: vec![0.0; slots * 3],
        }
    }
    /// Adds `v` to slot `slot` (panics past the end: an internal index).
    #[inline]
    pub fn add(&mut self, slot: usize, v: Vec3) {
        let b = slot * 3;
        self.sums[b] += v.x as f64;
        self.sums[b + 1] += v.y as f64;
        self.sums[b + 2] += v.z as f64;
    }
    /// The sum of slot `slot`.
    pub fn get(&self, slot: usize) -> DVec3 {
        let b = slot * 3;
        DVec3::new(self.sums[b], self.sums[b + 1], self.sums[b + 2])
    }
}

/// One deposit: cell index × 26 + bin, and the light added (weight × length).
type Deposit = (u32, Vec3);

/// A scattered path's deposit: cell index × 26 + bin, the light added (weight ×
/// length) and its exact direction (for the six axes' irradiance).
type BinDeposit = (u32, Vec3, Vec3);

struct PathResult {
    deposits: Vec<BinDeposit>,
    /// Deposits of a collimated beam before its first collision: (cell, light).
    direct: Vec<Deposit>,
    w0: Vec3,
    absorbed: Vec3,
    escaped: [Vec3; 3], // top, bottom, sides
    terminated: Vec3,
    /// Face the path entered by: 0 top, 1 bottom, 2 side.
    entry: usize,
}

struct Tracer<'a> {
    dims: IVec3,
    sigma: Vec<f32>,
    albedo: Vec<Vec3>,
    periodic: bool,
    comps: &'a [SourceComponent],
    cdf: Vec<f64>,
    caps: Vec<BinCap>,
    max_events: u32,
    max_track: f32,
}

impl Tracer<'_> {
    fn cell_index(&self, c: IVec3) -> usize {
        (c.x + self.dims.x * (c.z + self.dims.z * c.y)) as usize
    }

    fn sample_bin_direction(&self, rng: &mut fastrand::Rng, comp: &SourceComponent) -> Vec3 {
        let cap = &self.caps[comp.bin];
        let n = comp.normal.as_vec3();
        loop {
            let cos_t = 1.0 - rng.f32() * (1.0 - cap.cos_max);
            let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
            let phi = std::f32::consts::TAU * rng.f32();
            let (a, b, c) = cap.basis;
            let t = a * (sin_t * phi.cos()) + b * (sin_t * phi.sin()) + c * cos_t;
            if dirs::nearest_dir(t) != comp.bin {
                continue;
            }
            if comp.planes.iter().any(|p| p.as_vec3().dot(t) <= 0.0) {
                continue;
            }
            // Cosine-weighted by rejection: accept with probability n·t.
            if rng.f32() < n.dot(t) {
                return t;
            }
        }
    }

    fn trace(&self, index: u64, seed: u64) -> PathResult {
        let mut rng = fastrand::Rng::with_seed(seed ^ index.wrapping_mul(0x9E37_79B9_7F4A_7C15));
        let total = self.cdf.last().copied().unwrap_or(0.0);
        let pick = rng.f64() * total;
        let k = self
            .cdf
            .partition_point(|&c| c <= pick)
            .min(self.comps.len() - 1);
        let comp = &self.comps[k];
        let prob = (self.cdf[k] - if k == 0 { 0.0 } else { self.cdf[k - 1] }) / total;
        let w0 = comp.flux / prob as f32;
        let d = self.dims;
        let dims_f = d.as_vec3();
        // Start on the face.
        let n = comp.normal;
        let mut pos = Vec3::new(
            rng.f32() * dims_f.x - 0.5,
            rng.f32() * dims_f.y - 0.5,
            rng.f32() * dims_f.z - 0.5,
        );
        for axis in 0..3 {
            if n[axis] > 0 {
                pos[axis] = -0.5;
            } else if n[axis] < 0 {
                pos[axis] = dims_f[axis] - 0.5;
            }
        }
        let mut cell = (pos + Vec3::splat(0.5))
            .floor()
            .as_ivec3()
            .clamp(IVec3::ZERO, d - IVec3::ONE);
        for axis in 0..3 {
            if n[axis] > 0 {
                cell[axis] = 0;
            } else if n[axis] < 0 {
                cell[axis] = d[axis] - 1;
            }
        }
        let mut dir = match comp.exact {
            Some(d) => d,
            None => self.sample_bin_direction(&mut rng, comp),
        };
        let mut uncollided = comp.exact.is_some();
        let mut w = w0;
        let mut res = PathResult {
            direct: Vec::new(),
            deposits: Vec::with_capacity(32),
            w0,
            absorbed: Vec3::ZERO,
            escaped: [Vec3::ZERO; 3],
            terminated: Vec3::ZERO,
            entry: match n.y {
                -1 => 0,
                1 => 1,
                _ => 2,
            },
        };
        let w_min = w0.max_element() * 1e-6;
        let mut tau = -(1.0 - rng.f32()).ln();
        let mut bin = dirs::nearest_dir(dir);
        let mut events = 0u32;
        let mut track = 0.0f32;
        // The face the path entered its current cell through: axis and travel direction.
        let mut entry_axis = (0..3).find(|&a| n[a] != 0).unwrap_or(1);
        let mut entry_step = n[entry_axis];
        loop {
            let ci = self.cell_index(cell);
            let sigma = self.sigma[ci];
            let collide_at_entry = sigma == f32::INFINITY;
            // Distance to the exit of the current cell (lightgrid_core::dda: the walk shared
            // with light-volumes).
            let (s_exit, axis) = if collide_at_entry {
                (f32::INFINITY, 0)
            } else {
                dda::exit(cell, pos, dir)
            };
            let collide = collide_at_entry || (sigma > 0.0 && sigma * s_exit >= tau);
            if collide {
                if !collide_at_entry {
                    let s = tau / sigma;
                    if uncollided {
                        res.direct.push((ci as u32, w * s));
                    } else {
                        res.deposits
                            .push(((ci * NUM_DIRS + bin) as u32, w * s, dir));
                    }
                    pos += dir * s;
                }
                uncollided = false;
                let a = self.albedo[ci];
                res.absorbed += w * (Vec3::ONE - a);
                w *= a;
                events += 1;
                if w.max_element() < w_min || events >= self.max_events {
                    res.terminated += w;
                    return res;
                }
                if collide_at_entry {
                    // An opaque cell is a diffuse (Lambertian) surface: the path leaves
                    // back through its entry face, cosine-distributed about its normal.
                    let step = -entry_step;
                    let mut normal = Vec3::ZERO;
                    normal[entry_axis] = step as f32;
                    dir = lambertian(&mut rng, normal);
                    pos[entry_axis] = cell[entry_axis] as f32 + 0.5 * step as f32;
                    cell[entry_axis] += step;
                    if let Some(face) = self.wrap_or_escape(&mut cell, &mut pos, entry_axis, step) {
                        res.escaped[face] += w;
                        return res;
                    }
                    entry_step = step;
                } else {
                    dir = isotropic(&mut rng);
                }
                bin = dirs::nearest_dir(dir);
                tau = -(1.0 - rng.f32()).ln();
                continue;
            }
            if s_exit > 0.0 {
                if uncollided {
                    res.direct.push((ci as u32, w * s_exit));
                } else {
                    res.deposits
                        .push(((ci * NUM_DIRS + bin) as u32, w * s_exit, dir));
                }
                track += s_exit;
                if track > self.max_track {
                    res.terminated += w;
                    return res;
                }
            }
            tau -= sigma * s_exit;
            pos += dir * s_exit;
            // Step into the next cell, exactly onto the shared face.
            let step = dda::cross(&mut cell, &mut pos, axis, dir);
            if let Some(face) = self.wrap_or_escape(&mut cell, &mut pos, axis, step) {
                res.escaped[face] += w;
                return res;
            }
            entry_axis = axis;
            entry_step = step;
        }
    }

    /// After a step of `step` along `axis` into `cell`: `Some(face)` (0 top, 1 bottom,
    /// 2 side) when the path left the grid, wrapping instead with periodic sides.
    fn wrap_or_escape(
        &self,
        cell: &mut IVec3,
        pos: &mut Vec3,
        axis: usize,
        step: i32,
    ) -> Option<usize> {
        let d = self.dims;
        if cell[axis] >= 0 && cell[axis] < d[axis] {
            return None;
        }
        if axis == 1 {
            return Some(if step > 0 { 0 } else { 1 });
        }
        if !self.periodic {
            return Some(2);
        }
        let wrap = d[axis];
        cell[axis] = cell[axis].rem_euclid(wrap);
        pos[axis] += if step > 0 {
            -(wrap as f32)
        } else {
            wrap as f32
        };
        None
    }
}

/// A cosine-distributed direction about unit `normal`.
pub(crate) fn lambertian(rng: &mut fastrand::Rng, normal: Vec3) -> Vec3 {
    let r = rng.f32().sqrt();
    let phi = std::f32::consts::TAU * rng.f32();
    let z = (1.0 - r * r).max(0.0).sqrt();
    let t1 = normal.any_orthonormal_vector();
    let t2 = normal.cross(t1);
    (t1 * (r * phi.cos()) + t2 * (r * phi.sin()) + normal * z).normalize()
}

/// A direction drawn uniformly on the sphere.
pub(crate) fn isotropic(rng: &mut fastrand::Rng) -> Vec3 {
    let z = 1.0 - 2.0 * rng.f32();
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = std::f32::consts::TAU * rng.f32();
    Vec3::new(r * phi.cos(), z, r * phi.sin())
}

/// Traces the reference solution. `progress(done, total)` is called after every batch.
pub fn trace(
    material: &MaterialGrid,
    boundary: &Boundary,
    options: &ReferenceOptions,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<Reference, SweepError> {
    trace_with_sun(material, boundary, None, options, progress)
}

/// [`trace`] with a collimated sun besides the boundary light: its paths start along
/// its exact direction, and their light before the first collision goes to
/// `Reference::direct`, not to the bins.
pub fn trace_with_sun(
    material: &MaterialGrid,
    boundary: &Boundary,
    sun: Option<&CollimatedSun>,
    options: &ReferenceOptions,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<Reference, SweepError> {
    let desc = *material.desc();
    boundary.validate(&desc)?;
    lightgrid_sweep_cpu::sweep::check_boundary_scale(boundary)?;
    options.validate()?;
    let n = desc.point_count();
    lightgrid_core::limits::check_memory(
        &format!("Monte Carlo reference of {} points", n),
        lightgrid_core::limits::checked_bytes(
            "points",
            &[n as u64, (NUM_DIRS * 24 + GROUPS * 24 + 64) as u64],
        )?,
    )?;
    let dims = desc.dims();
    let periodic = matches!(boundary.sides, SideBoundary::Periodic);
    let mut comps = sources(boundary, dims, !periodic)?;
    if let Some(sun) = sun {
        comps.extend(sun_sources(sun, dims, !periodic)?);
    }
    if comps.is_empty() {
        return Ok(Reference {
            light: Grid::from_trusted(desc, vec![BinLight::ZERO; n]),
            paths: 0,
            balance: EnergyBalance::default(),
            std_error: vec![Vec3::ZERO; n],
            direct: vec![Vec3::ZERO; n],
            irradiance: vec![[Vec3::ZERO; 6]; n],
        });
    }
    let tracer = Tracer::new(material, &comps, periodic, options);
    let mut tallies = Tallies::new(n);
    let start = Instant::now();
    let mut done = 0u64;
    while done < options.paths {
        if let Some(b) = options.time_budget
            && done > 0
            && start.elapsed() >= b
        {
            break;
        }
        let count = BATCH.min(options.paths - done);
        let results: Vec<PathResult> = (done..done + count)
            .into_par_iter()
            .map(|i| tracer.trace(i, options.seed))
            .collect();
        tallies.add(done, &results);
        done += count;
        progress(done, options.paths);
    }
    tallies.finish(desc, done)
}

impl<'a> Tracer<'a> {
    /// A tracer through `material` from the boundary's (and the sun's) sources `comps`.
    fn new(
        material: &MaterialGrid,
        comps: &'a [SourceComponent],
        periodic: bool,
        options: &ReferenceOptions,
    ) -> Self {
        let dims = material.desc().dims();
        let mut cdf = Vec::with_capacity(comps.len());
        let mut acc = 0.0;
        for c in comps {
            acc += c.flux.element_sum() as f64;
            cdf.push(acc);
        }
        Tracer {
            dims: dims.as_ivec3(),
            sigma: extinction(material),
            albedo: material.data().iter().map(|m| m.reflectance).collect(),
            periodic,
            comps,
            cdf,
            caps: bin_caps(),
            max_events: options.max_events,
            max_track: options.max_track.max(1.0) * (dims.x + dims.y + dims.z) as f32,
        }
    }
}

/// Each cell's extinction per cell length, `-ln(pass)`; infinity for an opaque cell.
pub(crate) fn extinction(material: &MaterialGrid) -> Vec<f32> {
    material
        .data()
        .iter()
        .map(|m| {
            if m.pass <= 0.0 {
                f32::INFINITY
            } else {
                -m.pass.ln()
            }
        })
        .collect()
}

/// What the paths deposit, summed in path order: light per point and bin, direct sun
/// per point, per point its average light in [`GROUPS`] groups of paths (for the
/// standard error), and the energy balance.
struct Tallies {
    light: Tally,
    direct: Tally,
    /// Per point and axis ([`AMBIENT_AXES`]): the scattered light's irradiance.
    irradiance: Tally,
    groups: Vec<[f64; 3]>,
    bal: EnergyBalance,
}

impl Tallies {
    fn new(n: usize) -> Self {
        Self {
            light: Tally::new(n * NUM_DIRS),
            direct: Tally::new(n),
            irradiance: Tally::new(n * 6),
            groups: vec![[0f64; 3]; n * GROUPS],
            bal: EnergyBalance::default(),
        }
    }

    /// The paths `done..` (`results`, in order).
    fn add(&mut self, done: u64, results: &[PathResult]) {
        let bal = &mut self.bal;
        for (k, r) in results.iter().enumerate() {
            let group = (done as usize + k) % GROUPS;
            *[&mut bal.top_in, &mut bal.bottom_in, &mut bal.side_in][r.entry] += r.w0.as_dvec3();
            bal.absorbed += r.absorbed.as_dvec3();
            bal.top_out += r.escaped[0].as_dvec3();
            bal.bottom_out += r.escaped[1].as_dvec3();
            bal.side_out += r.escaped[2].as_dvec3();
            bal.pending += r.terminated.as_dvec3();
            for &(cell, v) in &r.direct {
                self.direct.add(cell as usize, v);
            }
            for &(slot, v, dir) in &r.deposits {
                let s = slot as usize;
                self.light.add(s, v);
                let cell = s / NUM_DIRS;
                for (k, n) in AMBIENT_AXES.iter().enumerate() {
                    let c = -n.dot(dir);
                    if c > 0.0 {
                        self.irradiance.add(cell * 6 + k, v * c);
                    }
                }
                let g = &mut self.groups[(s / NUM_DIRS) * GROUPS + group];
                g[0] += v.x as f64;
                g[1] += v.y as f64;
                g[2] += v.z as f64;
            }
        }
    }

    /// The reference from `done` paths: each path carries its weight / paths; cells
    /// have unit volume (h = 1 units). An error if a value overflowed.
    fn finish(self, desc: lightgrid_core::GridDesc, done: u64) -> Result<Reference, SweepError> {
        let n = desc.point_count();
        let inv = 1.0 / done as f64;
        let mut bal = self.bal;
        bal.top_in *= inv;
        bal.bottom_in *= inv;
        bal.side_in *= inv;
        bal.absorbed *= inv;
        bal.top_out *= inv;
        bal.bottom_out *= inv;
        bal.side_out *= inv;
        bal.pending *= inv;
        let light = &self.light;
        let data: Vec<BinLight> = (0..n)
            .map(|p| {
                BinLight(std::array::from_fn(|d| {
                    (light.get(p * NUM_DIRS + d) * inv).as_vec3()
                }))
            })
            .collect();
        let std_error = std_errors(&self.groups, n, inv);
        // Light at most 1e30 over a grid of at most 2^32 points stays finite; check
        // anyway so that no NaN or infinity can leave.
        let direct: Vec<Vec3> = (0..n)
            .map(|p| (self.direct.get(p) * inv).as_vec3())
            .collect();
        let irradiance: Vec<[Vec3; 6]> = (0..n)
            .map(|p| std::array::from_fn(|k| (self.irradiance.get(p * 6 + k) * inv).as_vec3()))
            .collect();
        let bad_light = data.iter().position(|b| !b.is_valid()).or(irradiance
            .iter()
            .position(|a| a.iter().any(|v| !v.is_finite())));
        let bad_direct = direct.iter().position(|v| !v.is_finite());
        if let Some((field, p)) = bad_light
            .map(|p| ("light", p))
            .or(bad_direct.map(|p| ("direct", p)))
        {
            return Err(GridError::invalid(
                format!("{field}[{p}]"),
                "NaN or infinity",
                "the reference overflowed: light too large for this grid",
            )
            .into());
        }
        Ok(Reference {
            light: Grid::from_trusted(desc, data),
            paths: done,
            balance: bal,
            std_error,
            direct,
            irradiance,
        })
    }
}

/// Standard error of the mean of each point's average light, from its group estimates
/// (`groups`: per point, [`GROUPS`] sums; `inv`: 1 / paths).
fn std_errors(groups: &[[f64; 3]], n: usize, inv: f64) -> Vec<Vec3> {
    let four_pi = 4.0 * std::f64::consts::PI;
    (0..n)
        .map(|p| {
            let est: Vec<DVec3> = (0..GROUPS)
                .map(|g| {
                    DVec3::from_array(groups[p * GROUPS + g]) * (GROUPS as f64 * inv / four_pi)
                })
                .collect();
            let mean = est.iter().copied().sum::<DVec3>() / GROUPS as f64;
            let var = est.iter().map(|e| (*e - mean) * (*e - mean)).sum::<DVec3>()
                / (GROUPS as f64 - 1.0);
            (var / GROUPS as f64).map(f64::sqrt).as_vec3()
        })
        .collect()
}
