//! A cell source's first scatterings gathered by rays ([`lightgrid_core::Gather`]),
//! the sweep carrying the rest.
//!
//! The 26 bins carry light between cells along 26 directions: under a low sun the
//! light scattered off a canopy's lit patches reaches the cells between those
//! directions too little and those along them too much (the discrete directions' ray
//! effects; a patchy canopy under a 10° sun has 87 of 407 cells over 5 % off against
//! Monte Carlo swept, the worst −17 %). Gathered, a cell's light of each of the first
//! `orders` scatterings is its mean radiance over `rays` directions (a spherical
//! Fibonacci set), each direction's light carried by parallel rays across the whole
//! grid (long characteristics): along each ray, every cell it crosses emits what the
//! scattering before left in it (a medium cell `a R / 4π` per unit of length, shaped in
//! height by the collisions' moments and, for the beam's, across the cell by where in x
//! and z it collided ([`CellSource::across`]); an opaque cell's exposed faces
//! `a R / (π n)` where the ray leaves it), attenuated by the exact transmittance, and
//! the ray's light is integrated over its track through every cell it crosses. A bin's light in a cell is
//! the mean over the volume its directions' rays sampled there (a horizontal bin's two
//! halves each their own mean), so light even across a cell is exact whatever volume
//! the rays happened to sample: over an infinite Lambertian ground the light above is
//! exact to rounding. What that light collides with (a medium cell's fluence times its
//! optical depth, an opaque cell's faces' irradiance from the rays that meet them) is
//! the source of the next scattering, and after the last the sweep's
//! ([`Gathered::rest`]). The sweep is linear, so the light is the gathered orders plus
//! the sweep of the rest with the boundary's light ([`sweep_gathered`]). Opaque points
//! get none of the gathered light (they hold next to nothing in a sweep either:
//! `lightgrid_core::validity`).
//!
//! Rays enter through the faces the light crosses inwards (the top or the bottom alone
//! where the sides wrap), about one a unit of area across the direction (`COVER`), at
//! points of a Kronecker sequence from a random offset, their count rounded at random
//! (so a grazing direction over periodic sides may send one long ray, or none); they
//! bring nothing from beyond the grid: the boundary's light, and the source's light
//! that comes back through a given side, are the sweep's.
//!
//! A low beam entering a dense cell through its side collides near that side, and
//! the light it scatters leaves mostly through that side: spread evenly across the
//! cell, a patchy canopy's cells beside the lit ones took up to 7 % too much at a 20°
//! sun; placed by the collisions' mean position across the cell (a density linear in x
//! and in z with that mean, a ramp toward the face where a linear one would turn
//! negative), the worst cell is 3.5 % off at 10°, 20° and 30° alike (2,048
//! directions, against 8 M Monte Carlo paths; `docs/measurements.md`).
//!
//! Cost: each direction's rays cross about every cell once, so an order costs about
//! `rays ×` the grid's cells (`LOW_SUN`: 2,048 directions for the first order, 512
//! for the second): the patchy canopy's 16 × 10 × 16 cells in about 0.2 s against the
//! sweep's 20 ms on two cores (`docs/measurements.md`): a bake's cost, which
//! `SweepOptions::multi_bounce` pays for a sun at or below 30° only (`Gather::AUTO`);
//! its buffers about 1.6 kB a point while it runs (0.75 of it each bin's sums); `cargo run
//! --release -p lightgrid-measure
//! --example beam_cells -- --gather` prints its time beside its error.
//!
//! ```
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! use lightgrid_core::glam::{UVec3, Vec3};
//! use lightgrid_core::{
//!     BinLight, Boundary, Gather, GridDesc, Material, MaterialGrid, SideBoundary, Sweeper,
//!     SweepOptions,
//! };
//! use lightgrid_sweep_cpu::{CpuSweeper, sun::first_collision};
//! // A ground and a clump of foliage, periodic, under a 10° sun.
//! let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(8, 6, 8))?;
//! let cells = (0..desc.point_count())
//!     .map(|i| match desc.coords(i).unwrap() {
//!         p if p.y == 0 => Material::opaque(Vec3::splat(0.2)),
//!         p if p.y == 2 && p.x < 3 && p.z < 3 => Material { reflectance: Vec3::splat(0.7), pass: 0.5 },
//!         _ => Material::EMPTY,
//!     })
//!     .collect();
//! let material = MaterialGrid::new(desc, cells)?;
//! let to_sun = Vec3::new(10f32.to_radians().cos(), 10f32.to_radians().sin(), 0.0);
//! let beam = first_collision(&material, to_sun, Vec3::ONE, true, &|_| 1.0)?;
//! let dark = Boundary { sides: SideBoundary::Periodic, ..Boundary::open_sky(BinLight::ZERO) };
//! let mut options = SweepOptions::multi_bounce();
//! options.gather = Gather { rays: 1024, ..Gather::LOW_SUN };
//! let light = CpuSweeper::new().sweep_with_source(&material, &dark, &beam, &options)?;
//! assert!(light.bins.unwrap().max_value() > 0.0);
//! # Ok(())
//! # }
//! ```

use lightgrid_core::dirs::{FIRST_HORIZONTAL, HORIZONTAL_BINS, NUM_DIRS, nearest_dir};
use lightgrid_core::glam::{IVec3, Vec3};
use lightgrid_core::light::luminance;
use lightgrid_core::{
    BinLight, CellSource, Gather, GridDesc, GridError, HorizonGrid, HorizonLight, LightGrid,
    MaterialGrid, Outputs, SweepError, SweepOptions, SweepOutput,
};
use rayon::prelude::*;

/// The gathered light of a cell source's first scatterings, and what it collides with.
#[derive(Debug, Clone, PartialEq)]
pub struct Gathered {
    /// The light of the gathered scatterings, per point (light as the bins hold it: the
    /// cell's mean radiance integrated over each bin). Opaque cells hold none.
    pub light: LightGrid,
    /// The downward-travelling halves of its horizontal bins.
    pub horizon: HorizonGrid,
    /// What the last gathered scattering collides with, for the sweep (the source
    /// itself when nothing is gathered).
    pub rest: CellSource,
}

/// One direction of the set: where its light comes from (`w`; the light travels along
/// `-w`) and whether it travels down (then it belongs to its horizontal bin's
/// downward half too, where the bin is horizontal).
#[derive(Clone, Copy)]
struct Dir {
    w: Vec3,
    down: bool,
}

/// The spherical Fibonacci set of `n` directions, grouped by the bin their light
/// travels in (`nearest_dir` of the travel).
fn directions(n: u32) -> Vec<Vec<Dir>> {
    let mut by_bin = vec![Vec::new(); NUM_DIRS];
    for i in 0..n {
        let y = 1.0 - (2.0 * i as f64 + 1.0) / n as f64;
        let r = (1.0 - y * y).max(0.0).sqrt();
        let a = i as f64 * std::f64::consts::PI * (3.0 - 5f64.sqrt());
        let w = Vec3::new((r * a.cos()) as f32, y as f32, (r * a.sin()) as f32);
        let travel = -w;
        let bin = nearest_dir(travel);
        by_bin[bin].push(Dir {
            w,
            down: horizontal(bin) && travel.y < 0.0,
        });
    }
    by_bin
}

/// Whether `bin` is one of the eight horizontal bins (which keep halves).
fn horizontal(bin: usize) -> bool {
    (FIRST_HORIZONTAL..FIRST_HORIZONTAL + HORIZONTAL_BINS).contains(&bin)
}

/// What each cell emits in one scattering: per unit of length and solid angle in a
/// medium cell (`a R / 4π`, with its height moments), per unit solid angle from each
/// exposed face of an opaque cell (`a R / (π n)`).
struct Emission {
    value: Vec<Vec3>,
    heights: Vec<[f32; 2]>,
    /// First moments across (x, z) per cell; empty: even across.
    across: Vec<[f32; 2]>,
}

/// The fewest directions an order takes.
const MIN_RAYS: u32 = 64;

/// Rays a direction sends through each unit of area across it: about one track
/// through every cell a direction.
const COVER: f32 = 1.0;

/// How far one ray goes, in cells (periodic sides wrap it; its expected count of cells
/// a direction is `COVER` times the grid's whatever its slope).
const REACH: f32 = 1.0e6;

/// Sub-steps a ray takes through a medium cell: the height of the light it leaves
/// there (the collisions' moments) and of the emission's shape within it.
const SUB: usize = 4;

/// A density over a cell's width (`x` from -1 to 1) of mean 1 whose mean position is
/// `a`, at `x`: `1 + 3 a x` while that stays non-negative (`|a| ≤ 1/3`), beyond it a
/// ramp rising from `3|a| - 2` to the face `a` leans to (`|a|` at most 0.99: the ramp
/// at most 0.03 wide).
#[inline]
fn lean(a: f32, x: f32) -> f32 {
    if a.abs() <= 1.0 / 3.0 {
        return 1.0 + 3.0 * a * x;
    }
    let (a, x) = if a < 0.0 { (-a, -x) } else { (a, x) };
    let from = 3.0 * a.min(0.99) - 2.0;
    let w = 1.0 - from;
    4.0 * (x - from).max(0.0) / (w * w)
}

/// The rays' generator's seed.
const SEED: u64 = 0x6761_7468_6572;

/// The grid as the rays read it.
struct Medium<'a> {
    desc: GridDesc,
    dims: IVec3,
    periodic: bool,
    /// Optical depth across a cell (0 for empty and opaque cells).
    depth: Vec<f32>,
    opaque: Vec<bool>,
    exposed: &'a [u8],
}

/// One bin's sums over its directions' rays, per point: `∫ L ds` times each ray's
/// cross-section (`light`; for an opaque point the radiance its faces receive times
/// the cross-section), the same of the light travelling down (`down`, horizontal bins
/// alone), the cross-section times the length crossed (`cover`: the cell's volume as
/// the rays sampled it; `cover_down` the downward directions' share) and the luminance-weighted height moments `P1`, `P2` of the
/// light within a medium cell.
struct BinSums {
    light: Vec<Vec3>,
    down: Vec<Vec3>,
    cover: Vec<f32>,
    cover_down: Vec<f32>,
    moments: Vec<[f32; 2]>,
    /// How many of the bin's directions travel down.
    down_dirs: usize,
}

impl<'a> Medium<'a> {
    /// `material` as the rays read it; `exposed`: its cells' exposed faces.
    fn new(material: &MaterialGrid, periodic: bool, exposed: &'a [u8]) -> Self {
        let desc = *material.desc();
        let cells = material.data();
        Self {
            desc,
            dims: desc.dims().as_ivec3(),
            periodic,
            depth: cells
                .iter()
                .map(|c| {
                    if c.pass > 0.0 && c.pass < 1.0 {
                        -c.pass.ln()
                    } else {
                        0.0
                    }
                })
                .collect(),
            opaque: cells.iter().map(|c| c.pass <= 0.0).collect(),
            exposed,
        }
    }

    /// One ray of direction `dir`, entering at `p` (cell units, grid frame) into
    /// `cell`, travelling along `t = -w` until it leaves the grid: the light it carries
    /// (nothing from beyond the grid; an opaque cell's exposed face emits its value
    /// where the ray leaves it) summed into every non-opaque cell it crosses and onto
    /// every opaque cell's face it meets, times `weight`, its cross-section.
    fn trace(&self, e: &Emission, p: Vec3, cell: IVec3, dir: Dir, weight: f32, s: &mut BinSums) {
        let t = -dir.w;
        let mut cell = cell;
        let step = IVec3::new(
            if t.x > 0.0 { 1 } else { -1 },
            if t.y > 0.0 { 1 } else { -1 },
            if t.z > 0.0 { 1 } else { -1 },
        );
        let mut next = Vec3::ZERO;
        let mut inv = Vec3::ZERO;
        for k in 0..3 {
            if t[k] == 0.0 {
                next[k] = f32::INFINITY;
                inv[k] = f32::INFINITY;
                continue;
            }
            inv[k] = 1.0 / t[k].abs();
            let f = (p[k] - cell[k] as f32).clamp(0.0, 1.0);
            next[k] = (if step[k] > 0 { 1.0 - f } else { f }) * inv[k];
        }
        let (mut at, mut light) = (0.0f32, Vec3::ZERO);
        // What the wrapped sides added to `cell` (x, z), so that the ray's point
        // `p + t s + shift` stays in `cell`'s frame.
        let mut shift = Vec3::ZERO;
        let mut was_opaque: Option<usize> = None;
        // (Where the sides wrap, `cell`'s x and z stay within the grid.)
        while at < REACH {
            if cell.y < 0
                || cell.y >= self.dims.y
                || cell.x < 0
                || cell.z < 0
                || cell.x >= self.dims.x
                || cell.z >= self.dims.z
            {
                break;
            }
            let j = self.desc.index_unchecked(cell.as_uvec3());
            let axis = if next.x <= next.y && next.x <= next.z {
                0
            } else if next.y <= next.z {
                1
            } else {
                2
            };
            let exit = next[axis];
            if self.opaque[j] {
                if was_opaque.is_none() {
                    // The face it meets receives the light it carries.
                    s.light[j] += light * weight;
                }
                was_opaque = Some(j);
            } else {
                if let Some(o) = was_opaque.take() {
                    // Leaving an opaque cell through an exposed face: its emission.
                    light = e.value[o];
                }
                let ds = exit - at;
                let d = self.depth[j];
                if d > 0.0 {
                    let [m1, m2] = e.heights[j];
                    let [ax, az] = e.across.get(j).copied().unwrap_or([0.0; 2]);
                    let level = ax == 0.0 && az == 0.0;
                    let flat = m1 == 0.0 && m2 == 0.0 && level;
                    let h = ds / SUB as f32;
                    let x = d * h;
                    let lost = -(-x).exp_m1();
                    let tau = 1.0 - lost;
                    // ∫ τ over the sub-step, and ∫ (1 - τ) / d.
                    let span = lost / d;
                    let rise = if x < 1e-3 {
                        h * h * (0.5 - x / 6.0)
                    } else {
                        (h - span) / d
                    };
                    let (mut sum, mut m) = (Vec3::ZERO, [0.0f32; 2]);
                    for q in 0..SUB {
                        let s_mid = at + h * (q as f32 + 0.5);
                        let y = 2.0 * (p.y + t.y * s_mid - cell.y as f32) - 1.0;
                        let shape = if flat {
                            1.0
                        } else {
                            let height =
                                (1.0 + 3.0 * m1 * y + 2.5 * m2 * (3.0 * y * y - 1.0)).max(0.0);
                            if level {
                                height
                            } else {
                                let x = 2.0 * (p.x + shift.x + t.x * s_mid - cell.x as f32) - 1.0;
                                let z = 2.0 * (p.z + shift.z + t.z * s_mid - cell.z as f32) - 1.0;
                                height * lean(ax, x) * lean(az, z)
                            }
                        };
                        let src = e.value[j] * shape;
                        let part = light * span + src * rise;
                        light = light * tau + src * span;
                        sum += part;
                        let w = luminance(part);
                        m[0] += w * y;
                        m[1] += w * (1.5 * y * y - 0.5);
                    }
                    s.light[j] += sum * weight;
                    if dir.down {
                        s.down[j] += sum * weight;
                    }
                    s.moments[j][0] += m[0] * weight;
                    s.moments[j][1] += m[1] * weight;
                } else {
                    s.light[j] += light * (ds * weight);
                    if dir.down {
                        s.down[j] += light * (ds * weight);
                    }
                }
                s.cover[j] += ds * weight;
                if dir.down {
                    s.cover_down[j] += ds * weight;
                }
            }
            at = exit;
            next[axis] += inv[axis];
            cell[axis] += step[axis];
            if self.periodic && axis != 1 {
                if cell[axis] < 0 {
                    cell[axis] += self.dims[axis];
                    shift[axis] += self.dims[axis] as f32;
                } else if cell[axis] >= self.dims[axis] {
                    cell[axis] -= self.dims[axis];
                    shift[axis] -= self.dims[axis] as f32;
                }
            }
        }
    }

    /// Every ray of direction `dir`: entering through each face of the grid the light
    /// crosses inwards (the top or the bottom alone where the sides wrap), `COVER` rays
    /// a unit of area across the direction, placed by a Kronecker sequence from a
    /// random offset (`rng`), their count rounded at random so that every ray's
    /// cross-section is the same expected share.
    fn direction(&self, e: &Emission, dir: Dir, rng: &mut fastrand::Rng, s: &mut BinSums) {
        let t = -dir.w;
        let dims = self.dims.as_vec3();
        for axis in 0..3 {
            if t[axis] == 0.0 || (self.periodic && axis != 1) {
                continue;
            }
            let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
            let area = dims[a] * dims[b];
            let expected = COVER * t[axis].abs() * area;
            let count = (expected + rng.f32()).floor() as u32;
            if count == 0 {
                continue;
            }
            let weight = t[axis].abs() * area / expected;
            let (o1, o2) = (rng.f32(), rng.f32());
            for k in 0..count {
                // The plastic number's Kronecker sequence (R2).
                let u = (o1 + k as f32 * 0.754_877_7).fract();
                let v = (o2 + k as f32 * 0.569_840_3).fract();
                let mut p = Vec3::ZERO;
                let mut cell = IVec3::ZERO;
                p[a] = u * dims[a];
                p[b] = v * dims[b];
                cell[a] = (p[a] as i32).min(self.dims[a] - 1);
                cell[b] = (p[b] as i32).min(self.dims[b] - 1);
                if t[axis] > 0.0 {
                    p[axis] = 0.0;
                    cell[axis] = 0;
                } else {
                    p[axis] = dims[axis];
                    cell[axis] = self.dims[axis] - 1;
                }
                self.trace(e, p, cell, dir, weight, s);
            }
        }
    }
}

/// `source`'s first `params.orders` scatterings in `material` gathered by rays, and what
/// the last collides with ([`Gathered::rest`]); `sides`: the sweep's (periodic ones
/// wrap; which opaque faces are surfaces, [`crate::sweep::exposure`]). Errors name a bad
/// parameter or a source on another grid.
pub fn gather(
    material: &MaterialGrid,
    sides: &lightgrid_core::SideBoundary,
    source: &CellSource,
    params: &Gather,
) -> Result<Gathered, GridError> {
    params.validate()?;
    let desc = *material.desc();
    if *source.desc() != desc {
        return Err(GridError::invalid(
            "source",
            source.desc(),
            "must lie on the material grid's descriptor",
        ));
    }
    if let Some(i) = source
        .removed()
        .iter()
        .position(|r| r.max_element() > lightgrid_core::MAX_LIGHT)
    {
        return Err(GridError::invalid(
            format!("source.removed[{i}]"),
            source.removed()[i],
            "must be <= 1e30 to be gathered",
        ));
    }
    let _span = tracing::info_span!(
        "gather",
        orders = params.orders,
        points = desc.point_count()
    )
    .entered();
    let n = desc.point_count();
    let cells = material.data();
    let periodic = matches!(sides, lightgrid_core::SideBoundary::Periodic);
    let exposed = crate::sweep::exposure(material, sides);
    let medium = Medium::new(material, periodic, &exposed);
    let albedo: Vec<Vec3> = cells
        .iter()
        .zip(&exposed)
        .map(|(c, &e)| crate::sweep::swept_reflectance(c, e))
        .collect();
    // The later orders' light comes from sources spread wider and smoother than the
    // beam's lit patches: a quarter of the rays gathers it as well (the patchy canopy
    // at 10°: the worst cell 4.4 % against 4.5 % with all of them, 8 M paths).
    let (first, later) = (
        directions(params.rays),
        directions((params.rays / 4).max(MIN_RAYS)),
    );
    let mut light = vec![BinLight::ZERO; n];
    let mut halves = vec![HorizonLight([Vec3::ZERO; HORIZONTAL_BINS]); n];
    let mut removed: Vec<Vec3> = source.removed().to_vec();
    let mut heights: Vec<[f32; 2]> = match source.heights() {
        Some(h) => h.to_vec(),
        None => vec![[0.0; 2]; n],
    };
    for order in 0..params.orders {
        let dirs = if order == 0 { &first } else { &later };
        let count: usize = dirs.iter().map(Vec::len).sum();
        let d_omega = 4.0 * std::f32::consts::PI / count as f32;
        let e = Emission {
            value: (0..n)
                .map(|i| {
                    let r = removed[i] * albedo[i];
                    if medium.opaque[i] {
                        let faces = medium.exposed[i].count_ones().max(1) as f32;
                        r / (std::f32::consts::PI * faces)
                    } else if medium.depth[i] > 0.0 {
                        r / (4.0 * std::f32::consts::PI)
                    } else {
                        Vec3::ZERO
                    }
                })
                .collect(),
            heights: std::mem::take(&mut heights),
            // The beam's collisions alone are placed across their cells; the later
            // orders' sources are spread wider.
            across: match (order, source.across()) {
                (0, Some(a)) => a.to_vec(),
                _ => Vec::new(),
            },
        };
        let sums: Vec<BinSums> = dirs
            .par_iter()
            .enumerate()
            .map(|(bin, set)| {
                let horizontal = horizontal(bin);
                let mut s = BinSums {
                    light: vec![Vec3::ZERO; n],
                    down: if horizontal {
                        vec![Vec3::ZERO; n]
                    } else {
                        Vec::new()
                    },
                    cover: vec![0.0; n],
                    cover_down: if horizontal { vec![0.0; n] } else { Vec::new() },
                    moments: vec![[0.0; 2]; n],
                    down_dirs: set.iter().filter(|d| d.down).count(),
                };
                // The same rays whatever the threads: one generator a bin and order.
                let mut rng = fastrand::Rng::with_seed(SEED ^ ((order as u64) << 32) ^ bin as u64);
                for dir in set {
                    medium.direction(&e, *dir, &mut rng, &mut s);
                }
                s
            })
            .collect();
        let order: Vec<(BinLight, HorizonLight, Vec3, [f32; 2])> = (0..n)
            .into_par_iter()
            .map(|i| cell_order(&medium, &sums, dirs, d_omega, i))
            .collect();
        removed.clear();
        heights.clear();
        for (i, (b, hz, r, m)) in order.into_iter().enumerate() {
            light[i] += b;
            for k in 0..HORIZONTAL_BINS {
                halves[i].0[k] += hz.0[k];
            }
            removed.push(r);
            heights.push(m);
        }
    }
    // Sources up to 1e30 stay far below f32's range; a NaN or infinity would be a
    // defect, refused rather than passed on.
    if light.iter().any(|b| !b.0.iter().all(|v| v.is_finite())) {
        return Err(GridError::invalid(
            "source",
            "light not finite",
            "its gathered light overflowed",
        ));
    }
    Ok(Gathered {
        light: LightGrid::from_trusted(desc, light),
        horizon: HorizonGrid::from_trusted(desc, halves),
        rest: CellSource::with_heights(desc, removed, heights, source.dir())?,
    })
}

/// One scattering at point `i` from the bins' sums: its light (each bin's mean
/// radiance over the volume its rays sampled, times the bin's solid angle), horizontal
/// halves, what it collides with there (flux per `h²`: a medium cell's optical depth
/// times its light, an opaque cell's faces' irradiance) and the height moments of
/// those collisions.
fn cell_order(
    medium: &Medium<'_>,
    sums: &[BinSums],
    dirs: &[Vec<Dir>],
    d_omega: f32,
    i: usize,
) -> (BinLight, HorizonLight, Vec3, [f32; 2]) {
    let mut b = BinLight::ZERO;
    let mut hz = HorizonLight([Vec3::ZERO; HORIZONTAL_BINS]);
    if medium.opaque[i] {
        let r = sums.iter().map(|s| s.light[i]).sum::<Vec3>() * d_omega;
        return (b, hz, r, [0.0; 2]);
    }
    let (mut s0, mut s1, mut s2) = (0.0f64, 0.0f64, 0.0f64);
    for (bin, (s, set)) in sums.iter().zip(dirs).enumerate() {
        let cover = s.cover[i];
        if cover <= 0.0 {
            continue;
        }
        let scale = set.len() as f32 * d_omega / cover;
        let mut l = s.light[i] * scale;
        if !s.down.is_empty() {
            // A horizontal bin's halves each their own mean (their light differs most:
            // over a ground, none travels down), weighted by their directions.
            let down_dirs = s.down_dirs as f32;
            let (cd, cu) = (s.cover_down[i], cover - s.cover_down[i]);
            let down = if cd > 0.0 {
                s.down[i] * (down_dirs * d_omega / cd)
            } else {
                Vec3::ZERO
            };
            let up = if cu > 0.0 {
                (s.light[i] - s.down[i]) * ((set.len() as f32 - down_dirs) * d_omega / cu)
            } else {
                Vec3::ZERO
            };
            hz.0[bin - FIRST_HORIZONTAL] = down;
            l = down + up;
        }
        b.0[bin] = l;
        // (The moments pooled over the bin's directions, as their weights are.)
        s0 += luminance(s.light[i] * scale) as f64;
        s1 += (s.moments[i][0] * scale) as f64;
        s2 += (s.moments[i][1] * scale) as f64;
    }
    let d = medium.depth[i];
    if d <= 0.0 {
        return (b, hz, Vec3::ZERO, [0.0; 2]);
    }
    let total: Vec3 = b.0.iter().sum();
    let m = if s0 > 0.0 {
        [
            (s1 / s0).clamp(-1.0, 1.0) as f32,
            (s2 / s0).clamp(-0.5, 1.0) as f32,
        ]
    } else {
        [0.0; 2]
    };
    (b, hz, total * d, m)
}

/// A sweep of a cell source in `material` lit by `boundary` with its first scatterings
/// gathered when `options.gather.for_source()` asks (a gather for every sun: the sun's
/// entry points make a gather for low suns one where it applies; [`gather`], wrapping
/// where the sides are periodic): `sweep` (the sweeper's own sweep with a source,
/// called once, with `options.gather` off and the bins on) sweeps what they collide
/// with and the boundary's light, and the gathered light is added to its bins and
/// horizon halves; the average and the dominant direction, where asked for, are those
/// of the sum. With the gather off, `sweep` is called with it off. A sweeper's device copy
/// of the bins ([`SweepOutput::resident`]) does not hold the gathered light, so it is
/// left out.
pub fn sweep_gathered(
    material: &MaterialGrid,
    boundary: &lightgrid_core::Boundary,
    source: &CellSource,
    options: &SweepOptions,
    sweep: impl FnOnce(&CellSource, &SweepOptions) -> Result<SweepOutput, SweepError>,
) -> Result<SweepOutput, SweepError> {
    // A gather limited to low suns does not apply to a source whose sun is unknown
    // (the sun's entry points have made it one for every source where it applies).
    let mut given = *options;
    given.gather = options.gather.for_source();
    if !given.gather.is_on() {
        return sweep(source, &given);
    }
    let options = &given;
    options.validate()?;
    let g = gather(material, &boundary.sides, source, &options.gather)?;
    let mut o = *options;
    o.gather = Gather::OFF;
    o.outputs = Outputs {
        bins: true,
        ..options.outputs
    };
    let mut out = sweep(&g.rest, &o)?;
    let mut bins = out.bins.take().ok_or_else(|| {
        SweepError::Invalid(GridError::invalid(
            "outputs",
            "bins",
            "the sweeper gave no bins",
        ))
    })?;
    for (b, add) in bins.data_mut().iter_mut().zip(g.light.data()) {
        for d in 0..NUM_DIRS {
            b.0[d] += add.0[d];
        }
    }
    if let Some(h) = out.horizon.as_mut() {
        for (h, add) in h.data_mut().iter_mut().zip(g.horizon.data()) {
            for k in 0..HORIZONTAL_BINS {
                h.0[k] += add.0[k];
            }
        }
    }
    out.average = options.outputs.average.then(|| bins.average_grid());
    out.dominant = options.outputs.dominant.then(|| bins.dominant_grid());
    out.bins = options.outputs.bins.then_some(bins);
    out.resident = None;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use lightgrid_core::glam::UVec3;
    use lightgrid_core::{Material, SideBoundary, SweepOptions};

    fn params(orders: u32, rays: u32) -> Gather {
        Gather {
            orders,
            rays,
            ..Gather::LOW_SUN
        }
    }

    /// An infinite Lambertian ground of albedo 0.3 (one opaque level, periodic sides)
    /// under empty cells, and a source of `r` on each ground cell.
    fn ground(r: f32) -> (MaterialGrid, CellSource) {
        let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(8, 6, 8)).unwrap();
        let cells = (0..desc.point_count())
            .map(|i| {
                if i < desc.level_len() {
                    Material::opaque(Vec3::splat(0.3))
                } else {
                    Material::EMPTY
                }
            })
            .collect();
        let removed = (0..desc.point_count())
            .map(|i| {
                if i < desc.level_len() {
                    Vec3::splat(r)
                } else {
                    Vec3::ZERO
                }
            })
            .collect();
        let src = CellSource::new(desc, removed, Vec3::new(0.3, -0.5, 0.1)).unwrap();
        (MaterialGrid::new(desc, cells).unwrap(), src)
    }

    /// Over an infinite Lambertian ground of exitance `M = ρ r` the light coming up is
    /// `M / π` from every direction below the horizon: every empty cell's average light
    /// is `M / (2π)`, none of it travels down (a surface facing down receives `M`, one
    /// facing up nothing), and the ground's faces receive nothing of their own light
    /// (the rest is empty).
    #[test]
    fn an_infinite_lambertian_ground_known_answer() {
        let (m, src) = ground(0.5);
        let g = gather(&m, &SideBoundary::Periodic, &src, &params(1, 4096)).unwrap();
        let exact = 0.3 * 0.5 / (2.0 * std::f32::consts::PI);
        let d = *m.desc();
        for i in d.level_len()..d.point_count() {
            let b = g.light.data()[i];
            let avg = b.average().x;
            assert!(
                (avg / exact - 1.0).abs() < 0.01,
                "point {i}: {avg} against {exact}"
            );
            for k in 0..NUM_DIRS {
                if lightgrid_core::dirs::dir_unit(k).y < 0.0 {
                    assert_eq!(b.0[k], Vec3::ZERO, "bin {k} travels down");
                }
            }
            // The horizontal bins' light travels up, none of it in the downward halves,
            // so read with them a surface facing down receives the ground's exitance
            // and one facing up nothing.
            let hz = g.horizon.data()[i];
            assert_eq!(hz.0, [Vec3::ZERO; HORIZONTAL_BINS]);
            let down = b.irradiance_split(Vec3::NEG_Y, &hz).x;
            assert!(
                (down / 0.15 - 1.0).abs() < 0.01,
                "point {i}: facing down {down}"
            );
            assert_eq!(b.irradiance_split(Vec3::Y, &hz).x, 0.0);
        }
        assert!(g.rest.removed().iter().all(|r| *r == Vec3::ZERO));
    }

    /// A cell whose beam collided near one side lights the cells beyond that side more
    /// than those beyond the other (the source leans as `CellSource::across` says),
    /// and as much as its mirror image does the other way; an even cell lights both
    /// alike. A thick cell of medium alone in clear space, open sides.
    #[test]
    fn a_source_placed_across_its_cell_lights_that_side() {
        let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(5, 3, 5)).unwrap();
        let centre = desc.index(UVec3::new(2, 1, 2)).unwrap();
        let mut cells = vec![Material::EMPTY; desc.point_count()];
        cells[centre] = Material {
            reflectance: Vec3::ONE,
            pass: 0.02,
        };
        let m = MaterialGrid::new(desc, cells).unwrap();
        let mut removed = vec![Vec3::ZERO; desc.point_count()];
        removed[centre] = Vec3::ONE;
        let sides = |lean: f32| {
            let mut across = vec![[0.0; 2]; desc.point_count()];
            across[centre] = [lean, 0.0];
            let src = CellSource::new(desc, removed.clone(), Vec3::NEG_X)
                .unwrap()
                .with_across(across)
                .unwrap();
            // Many directions: the cells beside the source see it over a wide solid
            // angle, each direction's rays crossing both cells only now and then.
            let g = gather(&m, &SideBoundary::Open, &src, &params(1, 65536)).unwrap();
            let at = |x: u32| {
                g.light.data()[desc.index(UVec3::new(x, 1, 2)).unwrap()]
                    .average()
                    .x
            };
            (at(1), at(3))
        };
        let (even, east, west) = (sides(0.0), sides(0.8), sides(-0.8));
        assert!((even.0 / even.1 - 1.0).abs() < 0.02, "even: {even:?}");
        assert!(east.1 > 1.5 * east.0, "leaning +x: {east:?}");
        assert!(
            (east.1 / west.0 - 1.0).abs() < 0.02,
            "mirror: {east:?} {west:?}"
        );
        assert!(
            (east.0 / west.1 - 1.0).abs() < 0.02,
            "mirror: {east:?} {west:?}"
        );
    }

    /// The gather is linear in the source: a ground of twice the source, twice the
    /// light, bit for bit (the rays' sums are the same sums, doubled).
    #[test]
    fn twice_the_source_twice_the_light() {
        let (m, one) = ground(0.25);
        let (_, two) = ground(0.5);
        let p = params(2, 256);
        let (a, b) = (
            gather(&m, &SideBoundary::Periodic, &one, &p).unwrap(),
            gather(&m, &SideBoundary::Periodic, &two, &p).unwrap(),
        );
        for (x, y) in a.light.data().iter().zip(b.light.data()) {
            for k in 0..NUM_DIRS {
                assert_eq!(x.0[k] * 2.0, y.0[k]);
            }
        }
    }

    /// The rays are the same whatever the threads (one generator a bin and order, each
    /// bin summed by one thread in its directions' order): one thread or two, the same
    /// bits; and a patch of medium lit from one side lights cells on every side of it
    /// (the directions between the 26 bins' reach them too), none of it in opaque cells.
    #[test]
    fn the_same_bits_on_any_threads_and_light_all_round() {
        let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(9, 7, 9)).unwrap();
        let centre = desc.index(UVec3::new(4, 3, 4)).unwrap();
        let cells = (0..desc.point_count())
            .map(|i| match desc.coords(i).unwrap() {
                p if p.y == 0 => Material::opaque(Vec3::splat(0.2)),
                _ if i == centre => Material {
                    reflectance: Vec3::splat(0.8),
                    pass: 0.3,
                },
                _ => Material::EMPTY,
            })
            .collect();
        let m = MaterialGrid::new(desc, cells).unwrap();
        let removed = (0..desc.point_count())
            .map(|i| if i == centre { Vec3::ONE } else { Vec3::ZERO })
            .collect();
        let src = CellSource::new(desc, removed, Vec3::new(0.9, -0.2, 0.1)).unwrap();
        let run = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| gather(&m, &SideBoundary::Open, &src, &params(2, 512)).unwrap())
        };
        let (a, b) = (run(1), run(2));
        assert_eq!(a, b);
        // Every empty cell two cells from the patch, on the ground's level above and
        // around it, receives light; the ground's cells hold none and collide some.
        for i in 0..desc.point_count() {
            let p = desc.coords(i).unwrap().as_ivec3();
            let c = IVec3::new(4, 3, 4);
            if p.y == 0 {
                assert_eq!(a.light.data()[i], BinLight::ZERO);
                continue;
            }
            if (p - c).abs().max_element() == 2 {
                assert!(a.light.data()[i].average().x > 0.0, "cell {p}");
            }
        }
        assert!(
            a.rest.removed()[..desc.level_len()]
                .iter()
                .any(|r| r.x > 0.0)
        );
    }

    /// Nothing gathered: no light, the rest is the source.
    #[test]
    fn a_lean_is_a_density_of_mean_one_centred_where_asked() {
        let n = 200_000;
        for a in [
            -1.0f32,
            -0.99,
            -0.6,
            -1.0 / 3.0,
            -0.1,
            0.0,
            0.2,
            1.0 / 3.0,
            0.5,
            0.9,
            1.0,
        ] {
            let (mut mean, mut first) = (0.0f64, 0.0f64);
            for i in 0..n {
                let x = -1.0 + 2.0 * (i as f32 + 0.5) / n as f32;
                let f = lean(a, x);
                assert!(f >= 0.0 && f.is_finite(), "lean({a}, {x}) = {f}");
                mean += f as f64 / n as f64;
                first += (f * x) as f64 / n as f64;
            }
            let want = a.clamp(-0.99, 0.99) as f64;
            assert!((mean - 1.0).abs() < 1e-3, "a {a}: mean {mean}");
            assert!((first - want).abs() < 1e-3, "a {a}: first moment {first}");
        }
    }

    #[test]
    fn no_orders_no_light() {
        let (m, src) = ground(0.5);
        let g = gather(&m, &SideBoundary::Periodic, &src, &params(0, 256)).unwrap();
        assert!(g.light.data().iter().all(|b| *b == BinLight::ZERO));
        assert_eq!(g.rest.removed(), src.removed());
    }

    /// Bad parameters and a source on another grid are refused by name, and the plain
    /// sweep refuses a gather it would not do.
    #[test]
    fn bad_input_is_named() {
        let (m, src) = ground(0.5);
        let name = |e: GridError| e.to_string();
        let e = gather(&m, &SideBoundary::Periodic, &src, &params(5, 256)).unwrap_err();
        assert!(name(e).contains("gather.orders"));
        let e = gather(&m, &SideBoundary::Periodic, &src, &params(1, 10)).unwrap_err();
        assert!(name(e).contains("gather.rays"));
        let other = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(4, 6, 8)).unwrap();
        let moved =
            CellSource::new(other, vec![Vec3::ZERO; other.point_count()], Vec3::NEG_Y).unwrap();
        let e = gather(&m, &SideBoundary::Periodic, &moved, &Gather::LOW_SUN).unwrap_err();
        assert!(name(e).contains("source"));
        let big = CellSource::new(
            *m.desc(),
            vec![Vec3::splat(1e35); m.desc().point_count()],
            Vec3::NEG_Y,
        )
        .unwrap();
        let e = gather(&m, &SideBoundary::Periodic, &big, &Gather::LOW_SUN).unwrap_err();
        assert!(name(e).contains("source.removed[0]"));
        // The largest source allowed gathers to finite light.
        let most = CellSource::new(
            *m.desc(),
            vec![Vec3::splat(1e30); m.desc().point_count()],
            Vec3::NEG_Y,
        )
        .unwrap();
        let g = gather(&m, &SideBoundary::Periodic, &most, &params(4, 64)).unwrap();
        assert!(
            g.light
                .data()
                .iter()
                .all(|b| b.0.iter().all(|v| v.is_finite()))
        );
        let mut o = SweepOptions::multi_bounce();
        o.gather = Gather::LOW_SUN;
        let b = lightgrid_core::Boundary {
            sides: lightgrid_core::SideBoundary::Periodic,
            ..lightgrid_core::Boundary::open_sky(BinLight::ZERO)
        };
        let e = crate::run_with_source(&m, &b, Some(&src), &o).unwrap_err();
        assert!(e.to_string().contains("gather"), "{e}");
    }
}
