//! A cell source's first scatterings gathered by rays ([`lightgrid_core::Gather`]),
//! the sweep carrying the rest.
//!
//! The 26 bins carry light between cells along 26 directions: under a low sun the
//! light scattered off a canopy's lit patches reaches the cells between those
//! directions too little and those along them too much (the discrete directions' ray
//! effects; a patchy canopy under a 10° sun had 64 of 349 cells over 5 % off against
//! Monte Carlo, the worst −16 %). Gathered, a cell's light of each of the first
//! `orders` scatterings is a sum over `rays` rays from points spread through the cell:
//! along each ray, every cell it crosses emits what the scattering before left in it (a
//! medium cell `a R / 4π` per unit of optical path, shaped in height by the collisions'
//! moments; an opaque cell's exposed faces `a R / (π n)`), attenuated by the exact
//! transmittance between. What that light collides with (a medium cell's fluence times
//! its optical depth, an opaque cell's faces' irradiance) is the source of the next
//! scattering, and after the last the sweep's ([`Gathered::rest`]). The sweep is
//! linear, so the light is the gathered orders plus the sweep of the rest with the
//! boundary's light ([`sweep_gathered`]). Opaque points get none of the gathered light
//! (they hold next to nothing in a sweep either: `lightgrid_core::validity`).
//!
//! Rays that leave the grid (the top, the bottom, open or given sides) take nothing
//! from beyond: the boundary's light, and the source's light that comes back through a
//! given side, are the sweep's. Periodic sides wrap, a ray going at most 4,096 cells.
//!
//! Cost: every non-opaque cell traces `rays` rays through the cells they cross for the
//! first order and a quarter as many for each later one (`LOW_SUN`: 4,096 and 1,024),
//! so a gather is made for a bake, not for a frame (the
//! patchy canopy's 16 × 10 × 16 cells: 1.9 s against the sweep's 12 ms on two cores;
//! its buffers about 0.9 kB a point while it runs); `cargo run --release -p lightgrid-measure
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
use lightgrid_core::light::{AMBIENT_AXES, luminance};
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

/// One ray of a cell's set: where it starts (cell units within the cell), where it
/// goes, the bin of the light it brings back (travelling along `-w`), and that bin's
/// horizontal half (`Some(k)` where the light travels down in horizontal bin `k`).
#[derive(Clone, Copy)]
struct Ray {
    at: Vec3,
    w: Vec3,
    bin: usize,
    down_half: Option<usize>,
}

/// The `n` rays every cell traces: the spherical Fibonacci set of `n` directions, each
/// from its own point of the cell, the points a Latin hypercube (each axis cut into
/// `n` strata, one point in each, the strata of the three axes paired at random:
/// fixed, the same for every cell). The cell's own emission, seen from within it,
/// varies over the cell as much as the rest of the light does over the directions, so
/// both are spread evenly, and independently of each other.
fn rays(n: u32) -> Vec<Ray> {
    let n = n as usize;
    let mut rng = fastrand::Rng::with_seed(0x6761_7468_6572);
    let strata: [Vec<usize>; 3] = std::array::from_fn(|_| {
        let mut v: Vec<usize> = (0..n).collect();
        rng.shuffle(&mut v);
        v
    });
    (0..n)
        .map(|i| {
            let y = 1.0 - (2.0 * i as f64 + 1.0) / n as f64;
            let r = (1.0 - y * y).max(0.0).sqrt();
            let a = i as f64 * std::f64::consts::PI * (3.0 - 5f64.sqrt());
            let w = Vec3::new((r * a.cos()) as f32, y as f32, (r * a.sin()) as f32);
            let at = Vec3::from_array(std::array::from_fn(|c| {
                ((strata[c][i] as f64 + rng.f64()) / n as f64) as f32
            }));
            let travel = -w;
            let bin = nearest_dir(travel);
            let horizontal = (FIRST_HORIZONTAL..FIRST_HORIZONTAL + HORIZONTAL_BINS).contains(&bin);
            Ray {
                at,
                w,
                bin,
                down_half: (horizontal && travel.y < 0.0).then(|| bin - FIRST_HORIZONTAL),
            }
        })
        .collect()
}

/// What each cell emits in one scattering: per unit of optical path and solid angle
/// in a medium cell (`a R / 4π`, with its height moments), per unit solid angle from
/// each exposed face of an opaque cell (`a R / (π n)`).
struct Emission {
    value: Vec<Vec3>,
    heights: Vec<[f32; 2]>,
}

/// The fewest rays a cell and order.
const MIN_RAYS: u32 = 64;

/// How far a ray goes, in cells (periodic sides wrap it).
const REACH: f32 = 4096.0;

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

impl Medium<'_> {
    /// The light arriving at `p` (cell units, grid frame) from direction `w` (travelling
    /// along `-w`): the emission along the ray, attenuated.
    fn march(&self, e: &Emission, p: Vec3, w: Vec3) -> Vec3 {
        let mut cell = p.floor().as_ivec3();
        let step = IVec3::new(
            if w.x > 0.0 { 1 } else { -1 },
            if w.y > 0.0 { 1 } else { -1 },
            if w.z > 0.0 { 1 } else { -1 },
        );
        let mut next = Vec3::ZERO;
        let mut inv = Vec3::ZERO;
        for k in 0..3 {
            if w[k] == 0.0 {
                next[k] = f32::INFINITY;
                inv[k] = f32::INFINITY;
                continue;
            }
            inv[k] = 1.0 / w[k].abs();
            let f = p[k] - cell[k] as f32;
            next[k] = (if step[k] > 0 { 1.0 - f } else { f }) * inv[k];
        }
        // Beyond periodic sides a grazing ray may go far before it meets the ground:
        // what a reach of `REACH` cells leaves out is about `height / REACH` of it.
        let reach = REACH;
        let (mut t, mut at, mut light) = (1.0f32, 0.0f32, Vec3::ZERO);
        while t > 1e-5 && at < reach {
            if cell.y < 0 || cell.y >= self.dims.y {
                break;
            }
            let c = if self.periodic {
                IVec3::new(
                    cell.x.rem_euclid(self.dims.x),
                    cell.y,
                    cell.z.rem_euclid(self.dims.z),
                )
            } else if cell.x < 0 || cell.z < 0 || cell.x >= self.dims.x || cell.z >= self.dims.z {
                break;
            } else {
                cell
            };
            let j = self.desc.index_unchecked(c.as_uvec3());
            if self.opaque[j] {
                light += t * e.value[j];
                break;
            }
            let axis = if next.x <= next.y && next.x <= next.z {
                0
            } else if next.y <= next.z {
                1
            } else {
                2
            };
            let exit = next[axis];
            let d = self.depth[j];
            if d > 0.0 {
                let [m1, m2] = e.heights[j];
                let flat = m1 == 0.0 && m2 == 0.0;
                let sub = if flat { 1 } else { 4 };
                let ds = (exit - at) / sub as f32;
                let tau = (-d * ds).exp();
                let span = (1.0 - tau) / d;
                for q in 0..sub {
                    let shape = if flat {
                        1.0
                    } else {
                        let y =
                            2.0 * (p.y + w.y * (at + ds * (q as f32 + 0.5)) - cell.y as f32) - 1.0;
                        (1.0 + 3.0 * m1 * y + 2.5 * m2 * (3.0 * y * y - 1.0)).max(0.0)
                    };
                    light += t * shape * span * e.value[j];
                    t *= tau;
                }
            }
            at = exit;
            next[axis] += inv[axis];
            cell[axis] += step[axis];
        }
        light
    }
}

/// `source`'s first `params.orders` scatterings in `material` gathered by rays, and what
/// the last collides with ([`Gathered::rest`]); `periodic`: the sides wrap. Errors name
/// a bad parameter or a source on another grid.
pub fn gather(
    material: &MaterialGrid,
    periodic: bool,
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
    let exposed = crate::sweep::exposure(material, periodic);
    let medium = Medium {
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
        exposed: &exposed,
    };
    let albedo: Vec<Vec3> = cells
        .iter()
        .zip(&exposed)
        .map(|(c, &e)| crate::sweep::swept_reflectance(c, e))
        .collect();
    // The later orders' light comes from sources spread wider and smoother than the
    // beam's lit patches: a quarter of the rays gathers it as well (the patchy canopy
    // at 10°: the worst cell 4.4 % against 4.5 % with all of them, 8 M paths).
    let (first, later) = (rays(params.rays), rays((params.rays / 4).max(MIN_RAYS)));
    let mut light = vec![BinLight::ZERO; n];
    let mut halves = vec![HorizonLight([Vec3::ZERO; HORIZONTAL_BINS]); n];
    let mut removed: Vec<Vec3> = source.removed().to_vec();
    let mut heights: Vec<[f32; 2]> = match source.heights() {
        Some(h) => h.to_vec(),
        None => vec![[0.0; 2]; n],
    };
    for order in 0..params.orders {
        let rays = if order == 0 { &first } else { &later };
        let weight = 4.0 * std::f32::consts::PI / rays.len() as f32;
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
        };
        let order: Vec<(BinLight, HorizonLight, Vec3, [f32; 2])> = (0..n)
            .into_par_iter()
            .map(|i| cell_order(&medium, &e, rays, weight, i))
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

/// One scattering at point `i`: its light, horizontal halves, what it collides with
/// there (flux per `h²`) and the height moments of those collisions.
fn cell_order(
    medium: &Medium<'_>,
    e: &Emission,
    rays: &[Ray],
    weight: f32,
    i: usize,
) -> (BinLight, HorizonLight, Vec3, [f32; 2]) {
    let c = medium.desc.coords(i).expect("index in range").as_vec3();
    let mut b = BinLight::ZERO;
    let mut hz = HorizonLight([Vec3::ZERO; HORIZONTAL_BINS]);
    if medium.opaque[i] {
        // The irradiance of the exposed faces: the rays of the face's hemisphere from
        // the cell's points moved onto the face, cosine-weighted.
        let mut r = Vec3::ZERO;
        for (f, n) in AMBIENT_AXES.iter().enumerate() {
            if medium.exposed[i] & (1 << f) == 0 {
                continue;
            }
            for ray in rays {
                let cos = ray.w.dot(*n);
                if cos <= 0.0 {
                    continue;
                }
                let mut p = c + ray.at;
                for k in 0..3 {
                    if n[k] != 0.0 {
                        p[k] = c[k] + if n[k] > 0.0 { 1.0 + 1e-4 } else { -1e-4 };
                    }
                }
                r += medium.march(e, p, ray.w) * (cos * weight);
            }
        }
        return (b, hz, r, [0.0; 2]);
    }
    let (mut s0, mut s1, mut s2) = (0.0f64, 0.0f64, 0.0f64);
    let mut total = Vec3::ZERO;
    for ray in rays {
        let l = medium.march(e, c + ray.at, ray.w) * weight;
        b.0[ray.bin] += l;
        if let Some(k) = ray.down_half {
            hz.0[k] += l;
        }
        total += l;
        let y = 2.0 * ray.at.y as f64 - 1.0;
        let w = luminance(l) as f64;
        s0 += w;
        s1 += w * y;
        s2 += w * (1.5 * y * y - 0.5);
    }
    let d = medium.depth[i];
    if d <= 0.0 {
        return (b, hz, Vec3::ZERO, [0.0; 2]);
    }
    // Collided flux per h²: σ φ̄ h = depth × (the cell's mean fluence, `total`).
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
/// gathered when `options.gather` asks ([`gather`], wrapping where the sides are
/// periodic): `sweep` (the sweeper's own sweep with a source,
/// called once, with `options.gather` off and the bins on) sweeps what they collide
/// with and the boundary's light, and the gathered light is added to its bins and
/// horizon halves; the average and the dominant direction, where asked for, are those
/// of the sum. With the gather off, `sweep` is called as it is. A sweeper's device copy
/// of the bins ([`SweepOutput::resident`]) does not hold the gathered light, so it is
/// left out.
pub fn sweep_gathered(
    material: &MaterialGrid,
    boundary: &lightgrid_core::Boundary,
    source: &CellSource,
    options: &SweepOptions,
    sweep: impl FnOnce(&CellSource, &SweepOptions) -> Result<SweepOutput, SweepError>,
) -> Result<SweepOutput, SweepError> {
    if !options.gather.is_on() {
        return sweep(source, options);
    }
    options.validate()?;
    let periodic = matches!(boundary.sides, lightgrid_core::SideBoundary::Periodic);
    let g = gather(material, periodic, source, &options.gather)?;
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
    use lightgrid_core::{Material, SweepOptions};

    fn params(orders: u32, rays: u32) -> Gather {
        Gather { orders, rays }
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
        let g = gather(&m, true, &src, &params(1, 4096)).unwrap();
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

    /// The gather is linear in the source: a ground of twice the source, twice the
    /// light, bit for bit (the rays' sums are the same sums, doubled).
    #[test]
    fn twice_the_source_twice_the_light() {
        let (m, one) = ground(0.25);
        let (_, two) = ground(0.5);
        let p = params(2, 256);
        let (a, b) = (
            gather(&m, true, &one, &p).unwrap(),
            gather(&m, true, &two, &p).unwrap(),
        );
        for (x, y) in a.light.data().iter().zip(b.light.data()) {
            for k in 0..NUM_DIRS {
                assert_eq!(x.0[k] * 2.0, y.0[k]);
            }
        }
    }

    /// Nothing gathered: no light, the rest is the source.
    #[test]
    fn no_orders_no_light() {
        let (m, src) = ground(0.5);
        let g = gather(&m, true, &src, &params(0, 256)).unwrap();
        assert!(g.light.data().iter().all(|b| *b == BinLight::ZERO));
        assert_eq!(g.rest.removed(), src.removed());
    }

    /// Bad parameters and a source on another grid are refused by name, and the plain
    /// sweep refuses a gather it would not do.
    #[test]
    fn bad_input_is_named() {
        let (m, src) = ground(0.5);
        let name = |e: GridError| e.to_string();
        let e = gather(&m, true, &src, &params(5, 256)).unwrap_err();
        assert!(name(e).contains("gather.orders"));
        let e = gather(&m, true, &src, &params(1, 10)).unwrap_err();
        assert!(name(e).contains("gather.rays"));
        let other = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(4, 6, 8)).unwrap();
        let moved =
            CellSource::new(other, vec![Vec3::ZERO; other.point_count()], Vec3::NEG_Y).unwrap();
        let e = gather(&m, true, &moved, &Gather::LOW_SUN).unwrap_err();
        assert!(name(e).contains("source"));
        let big = CellSource::new(
            *m.desc(),
            vec![Vec3::splat(1e35); m.desc().point_count()],
            Vec3::NEG_Y,
        )
        .unwrap();
        let e = gather(&m, true, &big, &Gather::LOW_SUN).unwrap_err();
        assert!(name(e).contains("source.removed[0]"));
        // The largest source allowed gathers to finite light.
        let most = CellSource::new(
            *m.desc(),
            vec![Vec3::splat(1e30); m.desc().point_count()],
            Vec3::NEG_Y,
        )
        .unwrap();
        let g = gather(&m, true, &most, &params(4, 64)).unwrap();
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
