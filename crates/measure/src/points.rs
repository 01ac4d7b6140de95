//! Monte Carlo irradiance at points: the physical problem of [`crate::reference`]
//! (the same cells, surfaces, boundary and sun), solved backward from each point.
//!
//! [`crate::reference`] traces paths forward from the light and tallies every cell,
//! which is what a sweep's grid is compared with. A renderer reads light at points
//! (a terrain vertex, a light-volume probe) on a surface facing some normal; how close
//! that read comes to the physical light there is its *total* error. Tracing forward
//! over a region of millions of cells to reach 1 % noise at a few thousand points
//! would take days; tracing from the points takes seconds.
//!
//! **The estimator.** For a point `x` and unit normal `n`, the irradiance of the
//! light arriving there, `E(n) = ∫ L(x, ω) max(0, n·ω) dω`, is `π L(x, ω)` averaged
//! over directions `ω` drawn with density `max(0, n·ω) / π`. `L` is estimated by
//! following `ω` backward through the cells (exact segment-in-cell lengths, the same
//! DDA as the forward reference):
//!
//! - in a medium (extinction `σ = -ln(p)` per cell, isotropic scattering, albedo =
//!   reflectance) a collision is drawn by its free-flight density; it adds the sun's
//!   single scattering there, `a E T_sun / 4π` (the exact transmittance toward the
//!   sun, marched), and the path goes on in a uniform direction with weight × `a`;
//! - on the face of an opaque cell (a Lambertian surface of albedo = reflectance, as
//!   in the forward reference) it adds the sun's reflection `a E T_sun max(0, m·s) / π`
//!   and goes on cosine-distributed about the face's normal `m`, weight × `a`;
//! - leaving the grid it adds the boundary's radiance for the direction the light
//!   travels: the top's where it travels down (through the top or open sides), the
//!   bottom's where it travels up, each constant within a bin (the top's within the
//!   downward half of a horizontal bin), as the forward reference emits it. Periodic
//!   sides wrap the path around.
//!
//! Paths end by Russian roulette once their weight falls below 1/20 (unbiased), or
//! after [`PointOptions::max_events`] events. The sky (boundary) and the scattered sun
//! are kept apart; the sun's uncollided light at the point, `E T max(0, n·s)`, is
//! marched exactly, with no noise.
//!
//! **Determinism.** Each point draws from its own random stream (seed, point index):
//! the same seed gives the same answer on any number of threads.
//!
//! The estimator is checked against exact answers (an infinite Lambertian ground
//! under a uniform sky and under a sun, facing up and down) and against the forward
//! reference's six-axis irradiance on canopies (`tests/points.rs`).
//!
//! ## Example
//!
//! ```
//! use lightgrid_core::glam::Vec3;
//! use lightgrid_core::{BinLight, Boundary, SideBoundary};
//! use lightgrid_measure::exact::ground_material;
//! use lightgrid_measure::points::{PointOptions, PointProbe, trace_points};
//!
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! // An infinite ground of albedo 0.3 under a uniform sky of radiance 1.
//! let ground = ground_material(1, 0.3)?;
//! let boundary = Boundary {
//!     sides: SideBoundary::Periodic,
//!     ..Boundary::open_sky(BinLight::uniform(Vec3::ONE).split_vertical().0)
//! };
//! let up = PointProbe { position: Vec3::new(3.2, 4.0, 2.7), normal: Vec3::Y };
//! let options = PointOptions { paths: 2000, ..Default::default() };
//! let e = trace_points(&ground, &boundary, None, &[up], &options)?;
//! let sky = e[0].expect("the point lies in the air").sky.x;
//! assert!((sky - std::f32::consts::PI).abs() < 1e-3); // facing up: all sky, exactly π
//! # Ok(())
//! # }
//! ```

use lightgrid_core::dda;
use lightgrid_core::dirs::{self, NUM_DIRS};
use lightgrid_core::glam::{DVec3, IVec3, Vec3};
use lightgrid_core::light::luminance;
use lightgrid_core::{Boundary, GridError, MaterialGrid, SideBoundary, SweepError, TopBoundary};
use rayon::prelude::*;

use crate::reference::{CollimatedSun, isotropic, lambertian};

/// A point where light is read, and the normal of the surface reading it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointProbe {
    /// World position (metres, the material grid's frame).
    pub position: Vec3,
    /// Normal of the surface (any non-zero length).
    pub normal: Vec3,
}

/// Options of [`trace_points`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointOptions {
    /// Paths per point. The standard error falls as one over its square root.
    pub paths: u32,
    /// Random seed.
    pub seed: u64,
    /// Most scattering events of one path before it ends (its remaining light is lost;
    /// with roulette at weight 1/20 paths rarely get near the default).
    pub max_events: u32,
}

impl Default for PointOptions {
    fn default() -> Self {
        Self {
            paths: 1024,
            seed: 1,
            max_events: 1000,
        }
    }
}

/// Most paths per point (2^24).
pub const MAX_POINT_PATHS: u32 = 1 << 24;

impl PointOptions {
    /// Checks the options: `paths` in 2..=[`MAX_POINT_PATHS`] (two at least, for the
    /// standard error), `max_events` at least 1. Errors name the field.
    pub fn validate(&self) -> Result<(), GridError> {
        if !(2..=MAX_POINT_PATHS).contains(&self.paths) {
            return Err(GridError::invalid(
                "paths",
                self.paths,
                "must be in 2..=2^24",
            ));
        }
        if self.max_events == 0 {
            return Err(GridError::invalid("max_events", 0, "must be at least 1"));
        }
        Ok(())
    }
}

/// The light at one point, on its normal (RGB, the boundary's and the sun's units).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PointIrradiance {
    /// Irradiance of the boundary's (the sky's) light.
    pub sky: Vec3,
    /// Irradiance of the sun's light scattered at least once.
    pub sun_scattered: Vec3,
    /// The sun's uncollided irradiance, `E T max(0, n·s)` (exact).
    pub sun_direct: Vec3,
    /// The sun's transmittance from the point (exact; 0 without a sun).
    pub transmittance: f32,
    /// Standard error of the luminance of `sky`.
    pub sky_se: f32,
    /// Standard error of the luminance of `sun_scattered`.
    pub sun_se: f32,
    /// Standard error of the luminance of `sky + sun_scattered`.
    pub both_se: f32,
}

/// The light on each probe's normal at its position: `None` for a probe outside the
/// grid's cells or inside an opaque cell.
///
/// The boundary must have a uniform top and open or periodic sides (as
/// [`crate::reference::trace`]); `sun`, if given, enters unshadowed through the grid's
/// faces (the top, and open sides). Errors: an invalid boundary, sun, options or probe
/// (a non-finite position or a zero normal; the field is named).
pub fn trace_points(
    material: &MaterialGrid,
    boundary: &Boundary,
    sun: Option<&CollimatedSun>,
    probes: &[PointProbe],
    options: &PointOptions,
) -> Result<Vec<Option<PointIrradiance>>, SweepError> {
    let desc = *material.desc();
    boundary.validate(&desc)?;
    lightgrid_sweep_cpu::sweep::check_boundary_scale(boundary)?;
    options.validate()?;
    let top = match &boundary.top {
        TopBoundary::Uniform(b) => **b,
        TopBoundary::PerPoint(_) => {
            return Err(GridError::invalid(
                "top",
                "PerPoint",
                "the point reference supports a uniform top only",
            )
            .into());
        }
    };
    let periodic = match boundary.sides {
        SideBoundary::Periodic => true,
        SideBoundary::Open => false,
        SideBoundary::Given(_) | SideBoundary::GivenHalves { .. } => {
            return Err(GridError::invalid(
                "sides",
                "Given",
                "the point reference supports open and periodic sides only",
            )
            .into());
        }
    };
    let sun = match sun {
        Some(s) => {
            if !s.irradiance.is_finite() || s.irradiance.min_element() < 0.0 {
                return Err(GridError::invalid(
                    "sun.irradiance",
                    s.irradiance,
                    "must be finite and >= 0",
                )
                .into());
            }
            lightgrid_sweep_cpu::sun::sun_direction(s.to_sun)?.map(|d| (d, s.irradiance))
        }
        None => None,
    };
    for (i, p) in probes.iter().enumerate() {
        if !p.position.is_finite() {
            return Err(GridError::invalid(
                format!("probes[{i}].position"),
                p.position,
                "must be finite",
            )
            .into());
        }
        if !p.normal.is_finite() || p.normal.length_squared() == 0.0 {
            return Err(GridError::invalid(
                format!("probes[{i}].normal"),
                p.normal,
                "must be finite and non-zero",
            )
            .into());
        }
    }
    let scene = Scene::new(material, &top, &boundary.bottom, periodic, sun);
    Ok(probes
        .par_iter()
        .enumerate()
        .map(|(i, p)| {
            let g = desc.to_grid(p.position);
            scene.point(g, p.normal.normalize(), i as u64, options)
        })
        .collect())
}

/// The cells, the boundary's radiance per bin, the sun: what a path reads.
struct Scene {
    dims: IVec3,
    /// Extinction per cell length; infinity for an opaque cell.
    sigma: Vec<f32>,
    albedo: Vec<Vec3>,
    periodic: bool,
    /// Radiance of light travelling in each bin's direction, from the top (travelling
    /// down) and from the bottom (travelling up).
    from_top: [Vec3; NUM_DIRS],
    from_bottom: [Vec3; NUM_DIRS],
    /// Unit direction toward the sun and its irradiance.
    sun: Option<(Vec3, Vec3)>,
}

/// Weight below which a path plays Russian roulette.
const ROULETTE: f32 = 0.05;
/// Optical depth past which the sun's march stops with transmittance 0 (`e^-40`).
const TAU_OPAQUE: f32 = 40.0;
/// Most cells one path or march crosses (a ray grazing periodic layers may wrap for
/// ever): past it the path ends, the march gives 0.
const MAX_STEPS: u32 = 1 << 20;

impl Scene {
    fn new(
        material: &MaterialGrid,
        top: &lightgrid_core::BinLight,
        bottom: &lightgrid_core::BinLight,
        periodic: bool,
        sun: Option<(Vec3, Vec3)>,
    ) -> Self {
        // A boundary's bin `d` holds radiance × the solid angle of the half of the bin
        // it carries (the forward reference's `sources`).
        let radiance = |light: &lightgrid_core::BinLight, vertical: DVec3| {
            std::array::from_fn(|d| {
                let v = light.0[d];
                if v == Vec3::ZERO || dirs::dir_ivec(d).y as f64 * vertical.y < 0.0 {
                    return Vec3::ZERO;
                }
                let (omega, _) = dirs::bin_region(d, &[vertical]);
                if omega > 0.0 {
                    v / omega as f32
                } else {
                    Vec3::ZERO
                }
            })
        };
        Self {
            dims: material.desc().dims().as_ivec3(),
            sigma: crate::reference::extinction(material),
            albedo: material.data().iter().map(|m| m.reflectance).collect(),
            periodic,
            from_top: radiance(top, DVec3::NEG_Y),
            from_bottom: radiance(bottom, DVec3::Y),
            sun,
        }
    }

    fn index(&self, c: IVec3) -> usize {
        (c.x + self.dims.x * (c.z + self.dims.z * c.y)) as usize
    }

    fn inside(&self, c: IVec3) -> bool {
        c.cmpge(IVec3::ZERO).all() && c.cmplt(self.dims).all()
    }

    /// After a step of `step` along `axis` into `cell`: true when the path left the
    /// grid (through the top or bottom, or an open side); periodic sides wrap.
    fn left(&self, cell: &mut IVec3, pos: &mut Vec3, axis: usize, step: i32) -> bool {
        if cell[axis] >= 0 && cell[axis] < self.dims[axis] {
            return false;
        }
        if axis == 1 || !self.periodic {
            return true;
        }
        let n = self.dims[axis];
        cell[axis] = cell[axis].rem_euclid(n);
        pos[axis] += if step > 0 { -(n as f32) } else { n as f32 };
        false
    }

    /// Radiance arriving from the boundary along `-dir` (the light travels along `dir`).
    fn boundary(&self, travel: Vec3) -> Vec3 {
        if travel.y < 0.0 {
            self.from_top[dirs::nearest_dir(travel)]
        } else if travel.y > 0.0 {
            self.from_bottom[dirs::nearest_dir(travel)]
        } else {
            Vec3::ZERO
        }
    }

    /// The sun's transmittance from `pos` in `cell` (not opaque) along `s`, out of the
    /// grid (the beam enters unshadowed; periodic sides wrap it).
    fn transmittance(&self, mut cell: IVec3, mut pos: Vec3, s: Vec3) -> f32 {
        let mut tau = 0.0f32;
        for _ in 0..MAX_STEPS {
            let sigma = self.sigma[self.index(cell)];
            if sigma == f32::INFINITY {
                return 0.0;
            }
            let (len, axis) = dda::exit(cell, pos, s);
            tau += sigma * len;
            if tau > TAU_OPAQUE {
                return 0.0;
            }
            pos += s * len;
            let step = dda::cross(&mut cell, &mut pos, axis, s);
            if self.left(&mut cell, &mut pos, axis, step) {
                return (-tau).exp();
            }
        }
        0.0
    }

    /// The light on normal `n` at grid coordinates `g`.
    fn point(&self, g: Vec3, n: Vec3, index: u64, o: &PointOptions) -> Option<PointIrradiance> {
        let cell = (g + Vec3::splat(0.5)).floor().as_ivec3();
        if !self.inside(cell) || self.sigma[self.index(cell)] == f32::INFINITY {
            return None;
        }
        let mut rng = fastrand::Rng::with_seed(o.seed ^ index.wrapping_mul(0x9E37_79B9_7F4A_7C15));
        let (mut sky, mut sun) = (Vec3::ZERO, Vec3::ZERO);
        // Luminance sums and sums of squares: sky, sun, both.
        let mut sums = [[0.0f64; 2]; 3];
        for _ in 0..o.paths {
            let (a, b) = self.path(cell, g, lambertian(&mut rng, n), &mut rng, o.max_events);
            let (a, b) = (a * std::f32::consts::PI, b * std::f32::consts::PI);
            sky += a;
            sun += b;
            for (k, v) in [luminance(a), luminance(b), luminance(a + b)]
                .into_iter()
                .enumerate()
            {
                sums[k][0] += v as f64;
                sums[k][1] += (v as f64) * (v as f64);
            }
        }
        let paths = o.paths as f64;
        let se = |[s, s2]: [f64; 2]| {
            let var = ((s2 - s * s / paths) / (paths - 1.0)).max(0.0);
            (var / paths).sqrt() as f32
        };
        let (transmittance, direct) = match self.sun {
            Some((s, e)) => {
                let t = self.transmittance(cell, g, s);
                (t, e * (t * n.dot(s).max(0.0)))
            }
            None => (0.0, Vec3::ZERO),
        };
        Some(PointIrradiance {
            sky: sky / o.paths as f32,
            sun_scattered: sun / o.paths as f32,
            sun_direct: direct,
            transmittance,
            sky_se: se(sums[0]),
            sun_se: se(sums[1]),
            both_se: se(sums[2]),
        })
    }

    /// One backward path from `pos` in `cell` along `dir`: the radiance it brings back
    /// from the boundary and from the sun.
    fn path(
        &self,
        mut cell: IVec3,
        mut pos: Vec3,
        mut dir: Vec3,
        rng: &mut fastrand::Rng,
        max_events: u32,
    ) -> (Vec3, Vec3) {
        let (mut sky, mut sun) = (Vec3::ZERO, Vec3::ZERO);
        let mut w = Vec3::ONE;
        let mut tau = -(1.0 - rng.f32()).ln();
        let mut events = 0u32;
        for _ in 0..MAX_STEPS {
            let ci = self.index(cell);
            let sigma = self.sigma[ci];
            let (s_exit, axis) = dda::exit(cell, pos, dir);
            if sigma > 0.0 && sigma * s_exit >= tau {
                // A collision in the medium.
                pos += dir * (tau / sigma);
                let a = self.albedo[ci];
                if let Some((s, e)) = self.sun {
                    let t = self.transmittance(cell, pos, s);
                    sun += w * a * e * (t / (4.0 * std::f32::consts::PI));
                }
                w *= a;
                dir = isotropic(rng);
            } else {
                tau -= sigma * s_exit;
                pos += dir * s_exit;
                let step = dda::cross(&mut cell, &mut pos, axis, dir);
                if self.left(&mut cell, &mut pos, axis, step) {
                    sky += w * self.boundary(-dir);
                    return (sky, sun);
                }
                let ci = self.index(cell);
                if self.sigma[ci] != f32::INFINITY {
                    continue;
                }
                // The face of an opaque cell: a Lambertian surface facing back.
                let a = self.albedo[ci];
                let mut m = Vec3::ZERO;
                m[axis] = -step as f32;
                cell[axis] -= step;
                if !self.inside(cell) {
                    // Came in across a periodic side: step back across it.
                    let n = self.dims[axis];
                    cell[axis] = cell[axis].rem_euclid(n);
                    pos[axis] += if step > 0 { n as f32 } else { -(n as f32) };
                }
                if let Some((s, e)) = self.sun {
                    let c = m.dot(s);
                    if c > 0.0 {
                        let t = self.transmittance(cell, pos, s);
                        sun += w * a * e * (t * c / std::f32::consts::PI);
                    }
                }
                w *= a;
                dir = lambertian(rng, m);
            }
            events += 1;
            tau = -(1.0 - rng.f32()).ln();
            let m = w.max_element();
            if events >= max_events || m <= 0.0 {
                return (sky, sun);
            }
            if m < ROULETTE {
                let survive = m / ROULETTE;
                if rng.f32() >= survive {
                    return (sky, sun);
                }
                w /= survive;
            }
        }
        (sky, sun)
    }
}
