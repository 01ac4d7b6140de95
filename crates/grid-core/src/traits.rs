//! The narrow traits that keep the layers apart, and the plain data they exchange.
//!
//! * [`Sweeper`]: material + boundary in, light grids out. `sweep-cpu` and `sweep-gpu`
//!   implement it; callers cannot tell which one runs.
//! * [`LightField`]: light at a point and normal. The grid hierarchy implements it;
//!   `render` consumes it.
//! * [`MaterialSource`]: the material grid of a box. The area composer implements it.

use glam::{UVec3, Vec3};

use crate::grid::{AverageGrid, DominantGrid, Grid, LightGrid, Material, MaterialGrid};
use crate::light::BinLight;
#[cfg(doc)]
use crate::{Acceleration, Outputs};
use crate::{GridDesc, GridError, HORIZONTAL_STEP, SweepOptions};

/// Light entering the grid through its faces.
///
/// Light travelling downward enters through the top, light travelling upward through the
/// bottom. A horizontal bin (which straddles the horizon symmetrically) is split into its
/// downward-travelling half, which belongs to the top, and its upward-travelling half,
/// which belongs to the bottom: in `top` the horizontal bins hold the downward halves and
/// the upward bins are ignored; in `bottom` the horizontal bins hold the upward halves and
/// the downward bins are ignored. [`BinLight::split_vertical`] makes both from
/// full-sphere bins.
#[derive(Debug, Clone, PartialEq)]
pub struct Boundary {
    /// Light arriving through the top face.
    pub top: TopBoundary,
    /// Light arriving through the bottom face (the same under every bottom point).
    pub bottom: BinLight,
    /// Light arriving through the four side faces.
    pub sides: SideBoundary,
}

impl Boundary {
    /// Open sky: `top` above every top point and beside every side (as if the world
    /// around the grid were empty), nothing from below.
    pub fn open_sky(top: BinLight) -> Self {
        Self {
            top: TopBoundary::Uniform(Box::new(top)),
            bottom: BinLight::ZERO,
            sides: SideBoundary::Open,
        }
    }

    /// The grid inside an empty world lit from every direction by `light` (full-sphere
    /// bins): the top gets its downward part, the bottom its upward part.
    pub fn surrounding(light: &BinLight) -> Self {
        let (top, bottom) = light.split_vertical();
        Self {
            top: TopBoundary::Uniform(Box::new(top)),
            bottom,
            sides: SideBoundary::Open,
        }
    }

    /// Checks every value against `desc` (finite, not negative, right lengths).
    pub fn validate(&self, desc: &GridDesc) -> Result<(), GridError> {
        self.validate_up_to(desc, f32::MAX)
    }

    /// [`Boundary::validate`], and every value of the light (top, bottom, the sides'
    /// halo; not the horizon halves, which a sweep clamps to their bins) at most
    /// [`MAX_LIGHT`](crate::MAX_LIGHT), as a sweep needs: an error naming the part
    /// (`top`, `bottom`, `sides`) otherwise. One pass over each part's values where a
    /// check and then a scale pass took two (a node's halo holds some 17,000 bins, read
    /// at every sweep).
    pub fn validate_for_sweep(&self, desc: &GridDesc) -> Result<(), GridError> {
        self.validate_up_to(desc, crate::MAX_LIGHT)
    }

    /// [`Boundary::validate`] with the light at most `max` (`f32::MAX`: no more than
    /// finite; else [`MAX_LIGHT`](crate::MAX_LIGHT)).
    fn validate_up_to(&self, desc: &GridDesc, max: f32) -> Result<(), GridError> {
        // The field is named only for a bad value (a node's halo holds thousands).
        let check = |field: &dyn Fn() -> String, b: &BinLight| {
            if !b.is_valid() {
                Err(GridError::invalid(
                    field(),
                    b,
                    "boundary light must be finite and >= 0",
                ))
            } else {
                Ok(())
            }
        };
        // (The message's figure is `MAX_LIGHT`'s, the one `max` below `f32::MAX`.)
        const _: () = assert!(crate::MAX_LIGHT.to_bits() == 1e30f32.to_bits());
        // A part over `max`, once every value of it is valid.
        let over = |part: &'static str, v: &[BinLight]| {
            if v.iter().any(|b| b.0.iter().any(|c| c.max_element() > max)) {
                Err(GridError::invalid(
                    part,
                    "a value over 1e30",
                    "boundary light must be <= 1e30",
                ))
            } else {
                Ok(())
            }
        };
        check(&|| "bottom".into(), &self.bottom)?;
        match &self.top {
            TopBoundary::Uniform(b) => check(&|| "top".into(), b.as_ref())?,
            TopBoundary::PerPoint(v) => {
                let columns = HaloLayout::new(desc.dims()).columns();
                if v.len() != desc.level_len() && v.len() != columns {
                    return Err(GridError::LengthMismatchEither {
                        field: "top",
                        expected: desc.level_len(),
                        or: columns,
                        found: v.len(),
                    });
                }
                if !BinLight::all_within(v, max) {
                    for (i, b) in v.iter().enumerate() {
                        check(&|| format!("top[{i}]"), b)?;
                    }
                }
            }
        }
        if let Some(down) = self.sides.halo_down() {
            let layout = HaloLayout::new(desc.dims());
            if down.len() != layout.len() {
                return Err(GridError::LengthMismatch {
                    field: "sides.down",
                    expected: layout.len(),
                    found: down.len(),
                });
            }
            // One pass over the values that vectorises; the bad one named only if any.
            let ok = bytemuck::cast_slice::<crate::HorizonLight, f32>(down)
                .iter()
                .fold(true, |ok, x| ok & (0.0..=f32::MAX).contains(x));
            for (i, d) in down.iter().enumerate().filter(|_| !ok) {
                if let Some(v) = d.0.iter().find(|v| !v.is_finite() || v.min_element() < 0.0) {
                    return Err(GridError::invalid(
                        "sides.down",
                        format!("[{i}] = {v}"),
                        "must be finite and >= 0",
                    ));
                }
            }
        }
        if let Some(cells) = self.sides.halo_cells() {
            let layout = HaloLayout::new(desc.dims());
            if cells.len() != layout.len() {
                return Err(GridError::LengthMismatch {
                    field: "sides.cells",
                    expected: layout.len(),
                    found: cells.len(),
                });
            }
            let unit = |v: f32| (0.0..=1.0).contains(&v);
            let valid =
                |m: &Material| unit(m.pass) && m.reflectance.to_array().into_iter().all(unit);
            if let Some((i, m)) = cells.iter().enumerate().find(|(_, m)| !valid(m)) {
                return Err(GridError::invalid(
                    "sides.cells",
                    format!("[{i}] = pass {}, reflectance {}", m.pass, m.reflectance),
                    "pass and reflectance must be in [0, 1]",
                ));
            }
        }
        if let Some(h) = self.sides.halo() {
            let layout = HaloLayout::new(desc.dims());
            if h.len() != layout.len() {
                return Err(GridError::LengthMismatch {
                    field: "sides",
                    expected: layout.len(),
                    found: h.len(),
                });
            }
            if !BinLight::all_within(h, max) {
                for (i, b) in h.iter().enumerate() {
                    check(&|| format!("sides[{i}]"), b)?;
                }
            }
        }
        // Every value is valid: the scale, in the order `top`, `bottom`, `sides`.
        match &self.top {
            TopBoundary::Uniform(b) => over("top", std::slice::from_ref(b.as_ref()))?,
            TopBoundary::PerPoint(v) if !BinLight::all_within(v, max) => over("top", v)?,
            TopBoundary::PerPoint(_) => {}
        }
        over("bottom", std::slice::from_ref(&self.bottom))?;
        if let Some(h) = self.sides.halo()
            && !BinLight::all_within(h, max)
        {
            over("sides", h)?;
        }
        Ok(())
    }
}

/// Light arriving through the top face, as the outgoing light of an imaginary level just
/// above the grid.
#[derive(Debug, Clone, PartialEq)]
pub enum TopBoundary {
    /// The same light above every point (an open sky).
    Uniform(Box<BinLight>),
    /// One value per top point, in level order (`i + nx * k`): a fine grid inside a coarser
    /// one. Or one per column of the grid and of its halo ring
    /// ([`HaloLayout::columns`] values, `(x + W) + (nx + 2W)(z + W)` for `x` in `-W ..
    /// nx + W` and `z` in `-W .. nz + W`, `W` = [`HALO_WIDTH`]): the light above the
    /// columns beyond the sides too, where paths from above the top start that reach the
    /// grid through a given side. With one value per top point those take the nearest
    /// top point's.
    PerPoint(Vec<BinLight>),
}

/// Light arriving through the side faces.
#[derive(Debug, Clone, PartialEq)]
pub enum SideBoundary {
    /// Outside the grid is empty space under the open sky: light from outside is the top
    /// boundary's (uniform) light.
    Open,
    /// The grid wraps around in x and z (a tileable scene).
    Periodic,
    /// Given values at the points outside the grid that sweep paths start from: a ring of
    /// width [`HALO_WIDTH`] around every level, laid out by [`HaloLayout`]. Each value
    /// is full-sphere light (as a coarser grid holds it): the downward pass takes its
    /// downward part, the upward pass its upward part, each horizontal bin split across
    /// the horizon by its neighbours ([`BinLight::split_vertical_by_neighbours`]). Paths
    /// that start above the top level (below the bottom one) beyond the sides take the
    /// top's (bottom's) light, at the nearest column, as those inside the sides do.
    Given(Vec<BinLight>),
    /// [`SideBoundary::Given`] with the downward halves of every value's horizontal bins
    /// beside it (`down[i]` for `light[i]`, as a coarser grid that kept them holds them:
    /// [`Outputs::horizon`]): the downward pass takes each horizontal bin's downward half
    /// as given (clamped to the bin), the upward pass the rest, instead of a split by the
    /// neighbours.
    GivenHalves {
        /// Full-sphere light at the halo's points, as in [`SideBoundary::Given`].
        light: Vec<BinLight>,
        /// The downward halves of `light`'s horizontal bins, point for point.
        down: Vec<crate::HorizonLight>,
        /// The material of the halo's cells, point for point, where the caller knows it
        /// (`None`: taken as empty space). A value of `light` is its cell's mean (as a
        /// grid's points hold it); with the cell's material known, a sweep carries it to
        /// where the point's paths leave the cell and through the halo's cells after it
        /// (a medium stops part of it and emits its albedo's share of the cell's mean
        /// light), as the paths of the grid's own points are carried
        /// ([`SideBoundary::halo_cells`]).
        cells: Option<Vec<Material>>,
    },
}

impl SideBoundary {
    /// The halo's light, if the sides are given ([`SideBoundary::Given`] or
    /// [`SideBoundary::GivenHalves`]).
    pub fn halo(&self) -> Option<&[BinLight]> {
        match self {
            SideBoundary::Given(h) | SideBoundary::GivenHalves { light: h, .. } => Some(h),
            SideBoundary::Open | SideBoundary::Periodic => None,
        }
    }

    /// The material of the halo's cells, if given ([`SideBoundary::GivenHalves`]'s
    /// `cells`).
    pub fn halo_cells(&self) -> Option<&[Material]> {
        match self {
            SideBoundary::GivenHalves { cells, .. } => cells.as_deref(),
            _ => None,
        }
    }

    /// The downward halves of the halo's horizontal bins, if given
    /// ([`SideBoundary::GivenHalves`]).
    pub fn halo_down(&self) -> Option<&[crate::HorizonLight]> {
        match self {
            SideBoundary::GivenHalves { down, .. } => Some(down),
            _ => None,
        }
    }
}

/// Width of the [`SideBoundary::Given`] halo: the farthest a sweep path's source point
/// lies outside the grid ([`HORIZONTAL_STEP`], plus one for the smoothing kernel).
pub const HALO_WIDTH: i32 = HORIZONTAL_STEP + 1;

/// Layout of the [`SideBoundary::Given`] halo: for each level `j` (0 = bottom), the points
/// `(x, z)` with `x` in `-W .. nx + W` and `z` in `-W .. nz + W` that lie outside the grid,
/// in z-major then x order, `W` = [`HALO_WIDTH`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HaloLayout {
    dims: UVec3,
}

impl HaloLayout {
    /// The halo around a grid of `dims` points.
    pub fn new(dims: UVec3) -> Self {
        Self { dims }
    }
    /// Halo points per level.
    pub fn per_level(&self) -> usize {
        let w = HALO_WIDTH as usize;
        let (nx, nz) = (self.dims.x as usize, self.dims.z as usize);
        (nx + 2 * w) * (nz + 2 * w) - nx * nz
    }
    /// Columns of the grid and of its ring, `(nx + 2W)(nz + 2W)`: what a
    /// [`TopBoundary::PerPoint`] that covers the ring holds.
    pub fn columns(&self) -> usize {
        let w = HALO_WIDTH as usize;
        (self.dims.x as usize + 2 * w) * (self.dims.z as usize + 2 * w)
    }
    /// Total halo points over all levels.
    pub fn len(&self) -> usize {
        self.per_level() * self.dims.y as usize
    }
    /// True when the halo has no points (never, for a valid grid).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Index of outside point `(x, j, z)`; `None` inside the grid or beyond the ring.
    #[inline]
    pub fn index(&self, x: i32, j: u32, z: i32) -> Option<usize> {
        let w = HALO_WIDTH;
        let (nx, nz) = (self.dims.x as i32, self.dims.z as i32);
        if j >= self.dims.y || x < -w || x >= nx + w || z < -w || z >= nz + w {
            return None;
        }
        if (0..nx).contains(&x) && (0..nz).contains(&z) {
            return None;
        }
        let width = (nx + 2 * w) as usize;
        let row = (z + w) as usize;
        let col = (x + w) as usize;
        // Rows above the grid's z range are full; rows inside it have 2W points.
        let before = if z < 0 {
            row * width + col
        } else if z < nz {
            w as usize * width
                + (z as usize) * 2 * w as usize
                + if x < 0 { col } else { col - nx as usize }
        } else {
            w as usize * width + nz as usize * 2 * w as usize + (z - nz) as usize * width + col
        };
        Some(j as usize * self.per_level() + before)
    }
}

/// What a sweep produced: the outputs asked for, and what it did.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepOutput {
    /// The 26-bin grid, if asked for.
    pub bins: Option<LightGrid>,
    /// The downward-travelling halves of the horizontal bins, if asked for
    /// ([`Outputs::horizon`]).
    pub horizon: Option<crate::HorizonGrid>,
    /// The average-light grid, if asked for.
    pub average: Option<AverageGrid>,
    /// The dominant-direction grid, if asked for.
    pub dominant: Option<DominantGrid>,
    /// Work counters.
    pub stats: SweepStats,
    /// The sweeper's own copy of the 26 bins, kept where it computed them, if it keeps
    /// one: the GPU sweeper (asked to) returns its device buffer here
    /// (`lightgrid_gpu::GpuLightGrid`), so a renderer on the same device samples and
    /// draws the grid without uploading it again. `None` from the CPU sweeper.
    pub resident: Option<Resident>,
}

/// A sweeper's handle to light it keeps outside the CPU's memory (a GPU buffer), opaque
/// to crates without the backend: downcast it with [`Resident::get`]. Cloning shares
/// it; two handles are equal when they share one buffer.
#[derive(Clone)]
pub struct Resident(pub std::sync::Arc<dyn std::any::Any + Send + Sync>);

impl Resident {
    /// The handle as `T`, if it is one.
    pub fn get<T: 'static>(&self) -> Option<&T> {
        self.0.downcast_ref()
    }
}

impl std::fmt::Debug for Resident {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Resident(..)")
    }
}

impl PartialEq for Resident {
    fn eq(&self, other: &Self) -> bool {
        std::sync::Arc::ptr_eq(&self.0, &other.0)
    }
}

/// Work a sweep did and skipped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SweepStats {
    /// Levels computed point by point.
    pub levels_computed: u64,
    /// Levels above all material whose light was copied from the boundary.
    pub levels_copied: u64,
    /// Sweeps run (downward and upward passes counted separately).
    pub passes: u32,
    /// Diffusion corrections applied between passes ([`Acceleration::Diffusion`]; 0
    /// where the sweeper ran without).
    pub corrections: u32,
}

/// Errors a sweeper returns.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SweepError {
    /// The material, boundary or options are invalid.
    #[error(transparent)]
    Invalid(#[from] GridError),
    /// The backend cannot run this sweep (no adapter, grid beyond a device limit, ...).
    #[error("{backend}: {message}")]
    Backend {
        /// Which sweeper.
        backend: &'static str,
        /// What went wrong, naming the limit or resource.
        message: String,
    },
}

/// Computes light grids from a material grid and its boundary light.
///
/// Implementations follow the semantics written in `sweep-cpu`'s docs and must validate
/// their inputs (returning [`SweepError::Invalid`]), never emitting NaN or infinity.
pub trait Sweeper {
    /// A short name for logs ("cpu", "gpu").
    fn name(&self) -> &'static str;
    /// An independent sweeper of the same kind, to sweep other grids at the same time
    /// on other threads (a hierarchy's nodes of one depth), with the same results as
    /// this one; `None` where grids cannot be swept side by side (the default: one GPU
    /// queue runs one sweep at a time).
    fn fork(&self) -> Option<Box<dyn Sweeper + Send + Sync>> {
        None
    }
    /// Whether this sweeper traces the halo's paths into the grid
    /// ([`SweepOptions::halo_paths`]); one that does not returns an error for options
    /// that ask for them with given sides (the default: it does not).
    fn carries_halo_paths(&self) -> bool {
        false
    }
    /// Sweeps `material` lit by `boundary`.
    fn sweep(
        &mut self,
        material: &MaterialGrid,
        boundary: &Boundary,
        options: &SweepOptions,
    ) -> Result<SweepOutput, SweepError>;
    /// Sweeps with light already deposited in cells (the sun's first collisions: see
    /// [`CellSource`]). Sweepers that cannot take one say so (the default).
    fn sweep_with_source(
        &mut self,
        material: &MaterialGrid,
        boundary: &Boundary,
        source: &CellSource,
        options: &SweepOptions,
    ) -> Result<SweepOutput, SweepError> {
        let _ = (material, boundary, source, options);
        Err(SweepError::Invalid(GridError::invalid(
            "source",
            self.name(),
            "this sweeper takes no cell sources",
        )))
    }
    /// The sun's responses in `material` (see [`SunResponse`]): the transmittance along
    /// the exact direction, and the light of the sun's first collisions swept into the
    /// bins with `sun.scattered` as boundary. Sweepers that cannot keep the sun apart say
    /// so (the default); `lightgrid_sweep_cpu::sun::sweep_sun` is the implementation the CPU and
    /// GPU sweepers share.
    fn sweep_sun(
        &mut self,
        material: &MaterialGrid,
        sun: &SunBoundary<'_>,
        options: &SweepOptions,
    ) -> Result<SunResponse, SweepError> {
        let _ = (material, sun, options);
        Err(SweepError::Invalid(GridError::invalid(
            "sun",
            self.name(),
            "this sweeper cannot keep the sun apart from the sky",
        )))
    }
    /// Sweeps `boundary`'s light and `sun`'s first collisions in one sweep: by the
    /// sweep's linearity the light of [`Sweeper::sweep`] with `boundary` plus
    /// `sun.irradiance` times the scattered light of [`Sweeper::sweep_sun`] with no
    /// scattered light entering (to the convergence of the passes), for half the sweeps
    /// where the two are never needed apart (the sun's transmittance is marched on its
    /// own: [`Sweeper::sun_transmittance`]). Periodic sides make the beam wrap. Sweepers
    /// that cannot take cell sources say so (the default);
    /// `lightgrid_sweep_cpu::sun::sweep_with_sun` is the implementation the CPU and GPU
    /// sweepers share.
    fn sweep_with_sun(
        &mut self,
        material: &MaterialGrid,
        boundary: &Boundary,
        sun: &SunBeam<'_>,
        options: &SweepOptions,
    ) -> Result<SweepOutput, SweepError> {
        let _ = (material, boundary, sun, options);
        Err(SweepError::Invalid(GridError::invalid(
            "sun",
            self.name(),
            "this sweeper cannot sweep the sun's first collisions",
        )))
    }
    /// The sun's transmittance alone: [`SunResponse::transmittance`] of
    /// [`Sweeper::sweep_sun`] for the same `material` and `sun` (bit for bit), without
    /// the scattered light's sweep (`sun.scattered` is read only for its sides:
    /// periodic sides make the march wrap). A moved sun's direct light is re-marched with
    /// it at once while its scattered light follows. The default runs the whole
    /// [`Sweeper::sweep_sun`] and keeps the transmittance; `lightgrid_sweep_cpu::sun::transmittance`
    /// is the march the CPU and GPU sweepers run instead.
    fn sun_transmittance(
        &mut self,
        material: &MaterialGrid,
        sun: &SunBoundary<'_>,
    ) -> Result<Grid<f32>, SweepError> {
        Ok(self
            .sweep_sun(material, sun, &SweepOptions::single_pass())?
            .transmittance)
    }
    /// The points of `inner` (a box of `resident`'s grid's points from point `offset`,
    /// the same cell size) kept on the device as a handle of their own, for a grid
    /// swept wider than the points it keeps (a hierarchy's node over its apron): the
    /// GPU sweeper copies them there (`lightgrid_gpu::GpuLightGrid::crop`). `None` where
    /// the sweeper keeps no device copies or `resident` is not one of its own (the
    /// default): the light is then on the CPU alone.
    fn crop_resident(
        &self,
        resident: &Resident,
        inner: &crate::GridDesc,
        offset: glam::UVec3,
    ) -> Option<Resident> {
        let _ = (resident, inner, offset);
        None
    }
}

/// What a sweeper needs to compute the sun's two responses in one grid
/// ([`Sweeper::sweep_sun`]; the sun kept apart from the sky, issue 14). All sun light is
/// for a sun of normal irradiance 1: colours multiply afterwards.
pub struct SunBoundary<'a> {
    /// Direction toward the sun (need not be unit; at or below the horizon there is no
    /// direct sun: transmittance 0 and no first collisions).
    pub to_sun: Vec3,
    /// Scattered sun light entering the grid (top, sides, bottom), per unit sun
    /// irradiance: none under open sky (`Boundary::open_sky(BinLight::ZERO)`); a fine
    /// grid of a hierarchy takes it from its coarser grid's sun response. Periodic sides
    /// also make the transmittance march wrap.
    pub scattered: Boundary,
    /// The sun's transmittance already lost where its ray leaves the grid's box toward
    /// the sun (world position of the exit): 1 under open sky, a coarser grid's
    /// transmittance in a hierarchy. Values are clamped to `[0, 1]` (NaN counts as 0).
    pub outside: &'a (dyn Fn(Vec3) -> f32 + Sync),
}

impl std::fmt::Debug for SunBoundary<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SunBoundary")
            .field("to_sun", &self.to_sun)
            .field("scattered", &self.scattered)
            .finish_non_exhaustive()
    }
}

/// A sun beam swept together with a grid's other light ([`Sweeper::sweep_with_sun`]):
/// its direction, its irradiance (RGB, normal to the beam) and what it has lost before
/// it reaches the grid's box (as [`SunBoundary::outside`]).
#[derive(Clone, Copy)]
pub struct SunBeam<'a> {
    /// Direction toward the sun (need not be unit; at or below the horizon: no beam).
    pub to_sun: Vec3,
    /// Irradiance normal to the beam, RGB, finite and `>= 0`.
    pub irradiance: Vec3,
    /// The transmittance where a ray leaves the box toward the sun (world position):
    /// 1 under open sky. Clamped to `[0, 1]` (NaN counts as 0).
    pub outside: &'a (dyn Fn(Vec3) -> f32 + Sync),
}

impl std::fmt::Debug for SunBeam<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SunBeam")
            .field("to_sun", &self.to_sun)
            .field("irradiance", &self.irradiance)
            .finish_non_exhaustive()
    }
}

/// The sun's two responses in one grid, for unit sun irradiance
/// ([`Sweeper::sweep_sun`]): its light after at least one scattering (26 bins) and its
/// uncollided beam's transmittance at every point (`[0, 1]`, along the exact sun
/// direction). The direct sun on a surface facing `n` at `p` is then
/// `E T(p) max(0, n · s)`.
#[derive(Debug, Clone, PartialEq)]
pub struct SunResponse {
    /// Scattered sun light (26 bins).
    pub scattered: LightGrid,
    /// The downward halves of `scattered`'s horizontal bins, where the sweep was asked
    /// for them ([`Outputs::horizon`] in its options).
    pub horizon: Option<crate::HorizonGrid>,
    /// The beam's transmittance per point (same grid; trilinear `sample`).
    pub transmittance: Grid<f32>,
    /// Work counters of the scattered-light sweep.
    pub stats: SweepStats,
    /// The sweeper's device copy of `scattered`, if it keeps one (as
    /// [`SweepOutput::resident`]).
    pub resident: Option<Resident>,
}

/// A sun response read as a light field, for unit sun irradiance: the scattered light's
/// bins, and the beam's transmittance as [`LightField::sun_transmittance`] (read like
/// the bins, clamped to `[0, 1]`).
impl LightField for SunResponse {
    fn light(&self, p: Vec3, n: Option<Vec3>) -> Result<BinLight, GridError> {
        self.scattered.light(p, n)
    }
    fn horizon(&self, p: Vec3, n: Option<Vec3>) -> Result<Option<crate::HorizonLight>, GridError> {
        self.horizon
            .as_ref()
            .map(|h| match n {
                Some(n) => h.sample_biased(p, n),
                None => h.sample(p),
            })
            .transpose()
    }
    fn sun_transmittance(&self, p: Vec3, n: Option<Vec3>) -> Result<f32, GridError> {
        let t = match n {
            Some(n) => self.transmittance.sample_biased(p, n)?,
            None => self.transmittance.sample(p)?,
        };
        // (Trilinear weights may sum to 1 + 1 ulp.)
        Ok(t.clamp(0.0, 1.0))
    }
}

/// Light a beam deposits in cells before a sweep's first pass (the first collisions of
/// the sun, `lightgrid_sweep_cpu::sun::first_collision`; [`Sweeper::sweep_with_source`]): per
/// cell the flux taken from the beam (RGB, per `h²`, the sweep's flux unit), and the beam's direction of travel. A sweep
/// absorbs `(1 - a)` of it and scatters the rest as if the cell had removed it from a
/// channel along that direction (sweep-cpu's steps 4-7), so only scattered sun light
/// enters the bins; the beam itself is the sun transmittance's.
#[derive(Debug, Clone, PartialEq)]
pub struct CellSource {
    desc: GridDesc,
    removed: Vec<Vec3>,
    dir: Vec3,
    heights: Option<Vec<[f32; 2]>>,
    across: Option<Vec<[f32; 2]>>,
}

impl CellSource {
    /// A source on the cells of `desc`: `removed` per cell (finite, >= 0), travelling
    /// along `dir` (normalised; non-zero and finite).
    pub fn new(desc: GridDesc, removed: Vec<Vec3>, dir: Vec3) -> Result<Self, GridError> {
        if removed.len() != desc.point_count() {
            return Err(GridError::LengthMismatch {
                field: "removed",
                expected: desc.point_count(),
                found: removed.len(),
            });
        }
        if let Some(i) = removed
            .iter()
            .position(|v| !v.is_finite() || v.min_element() < 0.0)
        {
            return Err(GridError::invalid(
                format!("removed[{i}]"),
                removed[i],
                "must be finite and >= 0",
            ));
        }
        if !dir.is_finite() || dir.length_squared() == 0.0 {
            return Err(GridError::invalid(
                "dir",
                dir,
                "must be finite and non-zero",
            ));
        }
        Ok(Self {
            desc,
            removed,
            dir: dir.normalize(),
            heights: None,
            across: None,
        })
    }

    /// [`CellSource::new`] with where in each cell's height the beam collides:
    /// `heights[i] = [C₁/C₀, C₂/C₀]`, the Legendre moments `Cₙ = ∫ Pₙ(y) dF` of the
    /// collisions over the cell's height `y ∈ [-1, 1]` (bottom to top) per unit of
    /// collided flux `C₀`; `|C₁/C₀| ≤ 1`, `-1/2 ≤ C₂/C₀ ≤ 1` (finite). A sweep's
    /// profile rule starts a medium cell's source from them; without them it assumes
    /// the beam entered through the top (or bottom) face.
    pub fn with_heights(
        desc: GridDesc,
        removed: Vec<Vec3>,
        heights: Vec<[f32; 2]>,
        dir: Vec3,
    ) -> Result<Self, GridError> {
        if heights.len() != desc.point_count() {
            return Err(GridError::LengthMismatch {
                field: "heights",
                expected: desc.point_count(),
                found: heights.len(),
            });
        }
        if let Some(i) = heights.iter().position(|h| {
            !(h[0].is_finite() && h[1].is_finite())
                || h[0].abs() > 1.0 + 1e-5
                || !(-0.5 - 1e-5..=1.0 + 1e-5).contains(&h[1])
        }) {
            return Err(GridError::invalid(
                format!("heights[{i}]"),
                format!("{:?}", heights[i]),
                "must be finite Legendre moments: |C1/C0| <= 1, -1/2 <= C2/C0 <= 1",
            ));
        }
        let mut s = Self::new(desc, removed, dir)?;
        s.heights = Some(heights);
        Ok(s)
    }

    /// The collisions' height moments per cell, where known
    /// ([`CellSource::with_heights`]).
    pub fn heights(&self) -> Option<&[[f32; 2]]> {
        self.heights.as_deref()
    }

    /// This source with where across each cell the beam collides: `across[i] = [x̄,
    /// z̄]`, the mean of the collisions' local x and z over the cell (`-1` at its low
    /// face, `1` at its high one; finite, `|x̄|, |z̄| ≤ 1`): the first Legendre
    /// moments across, as [`CellSource::with_heights`]' `C₁/C₀` in height. A gather of
    /// the first scatterings (`lightgrid_sweep_cpu::gather`) places a cell's emission
    /// by them (a low beam entering a cell through its side collides near that side);
    /// the sweeps do not read them.
    pub fn with_across(mut self, across: Vec<[f32; 2]>) -> Result<Self, GridError> {
        if across.len() != self.desc.point_count() {
            return Err(GridError::LengthMismatch {
                field: "across",
                expected: self.desc.point_count(),
                found: across.len(),
            });
        }
        if let Some(i) = across.iter().position(|a| {
            !(a[0].is_finite() && a[1].is_finite())
                || a[0].abs() > 1.0 + 1e-5
                || a[1].abs() > 1.0 + 1e-5
        }) {
            return Err(GridError::invalid(
                format!("across[{i}]"),
                format!("{:?}", across[i]),
                "must be finite first moments: |x|, |z| <= 1",
            ));
        }
        self.across = Some(across);
        Ok(self)
    }

    /// The collisions' first moments across each cell (x, z), where known
    /// ([`CellSource::with_across`]).
    pub fn across(&self) -> Option<&[[f32; 2]]> {
        self.across.as_deref()
    }

    /// Flux taken from the beam, per cell (grid order).
    pub fn removed(&self) -> &[Vec3] {
        &self.removed
    }

    /// The beam's direction of travel.
    pub fn dir(&self) -> Vec3 {
        self.dir
    }

    /// Where the cells are.
    pub fn desc(&self) -> &GridDesc {
        &self.desc
    }
}

/// Light at any point in space.
///
/// One required method, [`LightField::light`] (the 26 bins at a point); irradiance and
/// average light follow from it. Implemented by [`LightGrid`] and by the grid hierarchy
/// (`terrain-lod`); `render` consumes it.
pub trait LightField {
    /// The light in the 26 bins at `p`, trilinearly interpolated; with a normal `n`, read
    /// half a cell along it (the normal bias against leaks through walls). Errors on
    /// non-finite `p` or a zero or non-finite `n`.
    fn light(&self, p: Vec3, n: Option<Vec3>) -> Result<BinLight, GridError>;

    /// Irradiance on a surface at `p` facing normal `n` (sampled with the normal bias):
    /// each horizontal bin read in its two halves where the field keeps them
    /// ([`LightField::horizon`], [`BinLight::irradiance_split`]), else as even across
    /// the horizon.
    fn irradiance(&self, p: Vec3, n: Vec3) -> Result<Vec3, GridError> {
        let l = self.light(p, Some(n))?;
        Ok(match self.horizon(p, Some(n))? {
            Some(h) => l.irradiance_split(n, &h),
            None => l.irradiance(n),
        })
    }
    /// The downward-travelling halves of the horizontal bins at `p`
    /// ([`crate::HorizonLight`]), read like [`LightField::light`], for fields that keep
    /// them (a sweep's [`Outputs::horizon`], [`crate::SplitLightGrid`]); `None` (the
    /// default): the bins are read as even across the horizon.
    fn horizon(&self, p: Vec3, n: Option<Vec3>) -> Result<Option<crate::HorizonLight>, GridError> {
        let _ = (p, n);
        Ok(None)
    }
    /// Mean light over the sphere at `p`.
    fn average(&self, p: Vec3) -> Result<Vec3, GridError> {
        Ok(self.light(p, None)?.average())
    }
    /// The transmittance at `p` of a direct sun this field keeps apart from its bins
    /// (issue 14: the bins then hold sky and scattered sun light only, and the direct
    /// sun on a surface facing `n` is `E T(p) max(0, n · s)` with the field's own sun
    /// colour `E` and direction `s`), read like [`LightField::light`] (with a normal,
    /// half a cell along it). 0 for fields whose bins hold all their light (the
    /// default), so adding the direct term is always right.
    fn sun_transmittance(&self, p: Vec3, n: Option<Vec3>) -> Result<f32, GridError> {
        let _ = (p, n);
        Ok(0.0)
    }

    /// What a sampler reads at `p` in one call: [`LightField::light`], with a normal
    /// [`LightField::horizon`], and [`LightField::sun_transmittance`], equal to those
    /// three calls (the default makes them); fields that find their grids per point
    /// (a hierarchy) find them once.
    fn reading(&self, p: Vec3, n: Option<Vec3>) -> Result<Reading, GridError> {
        Ok(Reading {
            light: self.light(p, n)?,
            horizon: match n {
                Some(_) => self.horizon(p, n)?,
                None => None,
            },
            sun: self.sun_transmittance(p, n)?,
        })
    }

    /// A faster reader of what a light volume stores ([`VolumeSample`]) for fields that
    /// can prepare one (a hierarchy reduces every grid to its moments once, then reads 7
    /// numbers a corner instead of 26 bins), equal to [`VolumeSample::read`] up to
    /// rounding where a lookup's corners lie outside geometry (a reader may give grid
    /// points inside opaque cells their valid neighbours' light, [`crate::validity`], so
    /// that a surface reads the light above it); `None` (the default): read the field
    /// point by point.
    #[allow(clippy::type_complexity)]
    fn volume_sampler(
        &self,
    ) -> Option<Box<dyn Fn(Vec3) -> Result<VolumeSample, GridError> + Sync + '_>> {
        None
    }
}

/// What a sampler reads at a point ([`LightField::reading`]).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Reading {
    /// The bins ([`LightField::light`]).
    pub light: BinLight,
    /// With a normal, the horizon halves where the field keeps them
    /// ([`LightField::horizon`]); `None` without a normal.
    pub horizon: Option<crate::HorizonLight>,
    /// The sun's transmittance ([`LightField::sun_transmittance`]).
    pub sun: f32,
}

/// What a light volume holds at a point ([`LightField::volume_sampler`]).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct VolumeSample {
    /// Mean light over the sphere.
    pub average: Vec3,
    /// The dominant direction ([`BinLight::dominant`]).
    pub dominant: Vec3,
    /// The transmittance of the direct sun the field keeps apart (0 where none).
    pub sun: f32,
}

impl VolumeSample {
    /// The sample at `p` read through [`LightField::light`] and
    /// [`LightField::sun_transmittance`] (no normal bias).
    pub fn read<F: LightField + ?Sized>(field: &F, p: Vec3) -> Result<Self, GridError> {
        let bins = field.light(p, None)?;
        Ok(Self {
            average: bins.average(),
            dominant: bins.dominant(),
            sun: field.sun_transmittance(p, None)?,
        })
    }
}

impl LightField for LightGrid {
    fn light(&self, p: Vec3, n: Option<Vec3>) -> Result<BinLight, GridError> {
        match n {
            Some(n) => self.sample_biased(p, n),
            None => self.sample(p),
        }
    }
}

/// A light grid with its horizon halves ([`Outputs::horizon`]): a [`LightField`] whose
/// irradiance reads each horizontal bin in its two halves (exact across the horizon
/// where a bin's light is constant within each half: over a Lambertian ground, facing
/// down `a pi` where the bins read as even give `(1 + a) pi / 2`'s share more).
#[derive(Debug, Clone, PartialEq)]
pub struct SplitLightGrid {
    bins: LightGrid,
    halves: crate::HorizonGrid,
}

impl SplitLightGrid {
    /// The two grids, which must share one descriptor.
    pub fn new(bins: LightGrid, halves: crate::HorizonGrid) -> Result<Self, GridError> {
        if bins.desc() != halves.desc() {
            return Err(GridError::invalid(
                "halves.desc()",
                format!("{:?}", halves.desc()),
                "must equal the bins' descriptor",
            ));
        }
        Ok(Self { bins, halves })
    }
    /// The 26 bins.
    pub fn bins(&self) -> &LightGrid {
        &self.bins
    }
    /// The downward halves of the horizontal bins.
    pub fn halves(&self) -> &crate::HorizonGrid {
        &self.halves
    }
}

impl LightField for SplitLightGrid {
    fn light(&self, p: Vec3, n: Option<Vec3>) -> Result<BinLight, GridError> {
        self.bins.light(p, n)
    }
    fn horizon(&self, p: Vec3, n: Option<Vec3>) -> Result<Option<crate::HorizonLight>, GridError> {
        Ok(Some(match n {
            Some(n) => self.halves.sample_biased(p, n)?,
            None => self.halves.sample(p)?,
        }))
    }
}

/// Two light fields added: e.g. the sky and sun hierarchy plus local lights.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SumField<A, B>(pub A, pub B);

impl<A: LightField, B: LightField> LightField for SumField<A, B> {
    fn light(&self, p: Vec3, n: Option<Vec3>) -> Result<BinLight, GridError> {
        let (a, b) = (self.0.light(p, n)?, self.1.light(p, n)?);
        Ok(a + b)
    }
    /// The sum: the direct suns of both fields add (they must be the same sun).
    fn sun_transmittance(&self, p: Vec3, n: Option<Vec3>) -> Result<f32, GridError> {
        Ok(self.0.sun_transmittance(p, n)? + self.1.sun_transmittance(p, n)?)
    }
    /// The sum where either field keeps halves (the other's bins split evenly).
    fn horizon(&self, p: Vec3, n: Option<Vec3>) -> Result<Option<crate::HorizonLight>, GridError> {
        let (a, b) = (self.0.horizon(p, n)?, self.1.horizon(p, n)?);
        if a.is_none() && b.is_none() {
            return Ok(None);
        }
        let a = a.map_or_else(
            || self.0.light(p, n).map(|l| crate::HorizonLight::even(&l)),
            Ok,
        )?;
        let b = b.map_or_else(
            || self.1.light(p, n).map(|l| crate::HorizonLight::even(&l)),
            Ok,
        )?;
        Ok(Some(a + b))
    }
}

/// One light field minus another, clamped at zero per bin and colour: `B` is a part of
/// `A` (the direct sun within everything, say), so the difference is the rest (the
/// indirect light). The clamp only removes rounding below zero.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DifferenceField<A, B>(pub A, pub B);

impl<A: LightField, B: LightField> LightField for DifferenceField<A, B> {
    fn light(&self, p: Vec3, n: Option<Vec3>) -> Result<BinLight, GridError> {
        Ok(self.0.light(p, n)?.saturating_sub(&self.1.light(p, n)?))
    }
    /// The difference, clamped at zero (as the bins).
    fn sun_transmittance(&self, p: Vec3, n: Option<Vec3>) -> Result<f32, GridError> {
        Ok((self.0.sun_transmittance(p, n)? - self.1.sun_transmittance(p, n)?).max(0.0))
    }
    /// The difference where either field keeps halves (the other's bins split
    /// evenly), held within the difference's bins.
    fn horizon(&self, p: Vec3, n: Option<Vec3>) -> Result<Option<crate::HorizonLight>, GridError> {
        let (a, b) = (self.0.horizon(p, n)?, self.1.horizon(p, n)?);
        if a.is_none() && b.is_none() {
            return Ok(None);
        }
        let (la, lb) = (self.0.light(p, n)?, self.1.light(p, n)?);
        let a = a.unwrap_or_else(|| crate::HorizonLight::even(&la));
        let b = b.unwrap_or_else(|| crate::HorizonLight::even(&lb));
        Ok(Some((a + b * -1.0).within(&la.saturating_sub(&lb))))
    }
}

impl<T: LightField + ?Sized> LightField for &T {
    fn light(&self, p: Vec3, n: Option<Vec3>) -> Result<BinLight, GridError> {
        (**self).light(p, n)
    }
    fn irradiance(&self, p: Vec3, n: Vec3) -> Result<Vec3, GridError> {
        (**self).irradiance(p, n)
    }
    fn average(&self, p: Vec3) -> Result<Vec3, GridError> {
        (**self).average(p)
    }
    fn sun_transmittance(&self, p: Vec3, n: Option<Vec3>) -> Result<f32, GridError> {
        (**self).sun_transmittance(p, n)
    }
    fn horizon(&self, p: Vec3, n: Option<Vec3>) -> Result<Option<crate::HorizonLight>, GridError> {
        (**self).horizon(p, n)
    }
    #[allow(clippy::type_complexity)]
    fn volume_sampler(
        &self,
    ) -> Option<Box<dyn Fn(Vec3) -> Result<VolumeSample, GridError> + Sync + '_>> {
        (**self).volume_sampler()
    }
}

/// The material grid of any box.
pub trait MaterialSource {
    /// The material of every cell of `desc`.
    fn material(&self, desc: &GridDesc) -> Result<MaterialGrid, GridError>;

    /// The material of every cell of `desc` for the sun's shadows alone: what a march of
    /// the sun's transmittance crosses and nothing is swept on (the hierarchy's sun
    /// casters). A source may compose it more coarsely than [`MaterialSource::material`]
    /// (the area composer takes about half the samples a side, no fewer than two where
    /// the material takes two or more); by default it is that material.
    fn shadow_material(&self, desc: &GridDesc) -> Result<MaterialGrid, GridError> {
        self.material(desc)
    }
}

/// A shared source (one composer feeding the hierarchy and debug views).
impl<T: MaterialSource + ?Sized> MaterialSource for std::sync::Arc<T> {
    fn material(&self, desc: &GridDesc) -> Result<MaterialGrid, GridError> {
        (**self).material(desc)
    }
    fn shadow_material(&self, desc: &GridDesc) -> Result<MaterialGrid, GridError> {
        (**self).shadow_material(desc)
    }
}

/// A source with every reflectance set to zero: the same shadows and no scattered light.
/// Swept under the sun alone it gives the sun's direct (uncollided) light, which
/// [`DifferenceField`] removes from the full light to leave the indirect part.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoScatter<S>(pub S);

impl<S: MaterialSource> MaterialSource for NoScatter<S> {
    fn material(&self, desc: &GridDesc) -> Result<MaterialGrid, GridError> {
        Ok(Self::scatter_none(self.0.material(desc)?))
    }
    fn shadow_material(&self, desc: &GridDesc) -> Result<MaterialGrid, GridError> {
        Ok(Self::scatter_none(self.0.shadow_material(desc)?))
    }
}

impl<S> NoScatter<S> {
    /// `g` with every reflectance zero.
    fn scatter_none(mut g: MaterialGrid) -> MaterialGrid {
        for m in g.data_mut() {
            m.reflectance = Vec3::ZERO;
        }
        g
    }
}

/// A borrowed source.
impl<T: MaterialSource + ?Sized> MaterialSource for &T {
    fn material(&self, desc: &GridDesc) -> Result<MaterialGrid, GridError> {
        (**self).material(desc)
    }
    fn shadow_material(&self, desc: &GridDesc) -> Result<MaterialGrid, GridError> {
        (**self).shadow_material(desc)
    }
}

/// A material grid is the source of its own box (and of no other: a different `desc` is
/// an error, not a resampling).
impl MaterialSource for MaterialGrid {
    fn material(&self, desc: &GridDesc) -> Result<MaterialGrid, GridError> {
        if desc != self.desc() {
            return Err(GridError::invalid(
                "desc",
                desc,
                "a material grid is the source of its own box only",
            ));
        }
        Ok(self.clone())
    }
}

/// The same material everywhere (a fog, or empty space): the simplest source.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UniformMaterial(pub Material);

impl MaterialSource for UniformMaterial {
    fn material(&self, desc: &GridDesc) -> Result<MaterialGrid, GridError> {
        Grid::filled(*desc, self.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `validate_for_sweep` is `validate` and the scale check in one pass: each refusal
    /// names its part, a valid boundary over `MAX_LIGHT` passes `validate` alone, and a
    /// bad value is named before any scale.
    #[test]
    fn a_sweep_s_validation_names_the_bad_part() {
        let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(3, 2, 3)).unwrap();
        let halo = vec![BinLight::uniform(Vec3::ONE); HaloLayout::new(desc.dims()).len()];
        let given = |halo: Vec<BinLight>| Boundary {
            sides: SideBoundary::Given(halo),
            ..Boundary::open_sky(BinLight::uniform(Vec3::ONE))
        };
        let message = |b: &Boundary| b.validate_for_sweep(&desc).unwrap_err().to_string();
        assert!(given(halo.clone()).validate_for_sweep(&desc).is_ok());
        let mut big = halo.clone();
        big[7].0[3].y = 1e31;
        assert!(given(big.clone()).validate(&desc).is_ok());
        let e = message(&given(big.clone()));
        assert!(e.contains("sides") && e.contains("1e30"), "{e}");
        big[9].0[1].x = f32::NAN;
        let e = message(&given(big));
        assert!(e.contains("sides[9]") && e.contains("finite"), "{e}");
        let mut top = given(halo.clone());
        top.top = TopBoundary::PerPoint(vec![BinLight::single(2, Vec3::splat(2e30)); 9]);
        let e = message(&top);
        assert!(e.contains("top") && e.contains("1e30"), "{e}");
        let bottom = Boundary {
            bottom: BinLight::single(20, Vec3::splat(f32::MAX)),
            ..given(halo)
        };
        let e = message(&bottom);
        assert!(e.contains("bottom") && e.contains("1e30"), "{e}");
    }

    /// A grid of light that is `sky` above the horizon and `ground` below, with its
    /// halves: as a [`SplitLightGrid`] it reads irradiance exactly on every axis (a
    /// bare grid reads the horizontal bins as even); sums and differences with a field
    /// without halves keep them; halves on another descriptor are refused.
    #[test]
    fn a_split_light_grid_reads_irradiance_across_the_horizon() {
        let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(2, 3, 2)).unwrap();
        let w = crate::dirs::solid_angles();
        let (sky, ground) = (Vec3::ONE, Vec3::splat(0.3));
        let l = BinLight(std::array::from_fn(|d| match crate::dirs::dir_ivec(d).y {
            -1 => sky * w[d],
            1 => ground * w[d],
            _ => (sky + ground) * (0.5 * w[d]),
        }));
        let down = crate::HorizonLight(std::array::from_fn(|k| {
            sky * (0.5 * w[crate::dirs::FIRST_HORIZONTAL + k])
        }));
        let bins = LightGrid::filled(desc, l).unwrap();
        let halves = crate::HorizonGrid::filled(desc, down).unwrap();
        let split = SplitLightGrid::new(bins.clone(), halves.clone()).unwrap();
        let p = Vec3::new(0.5, 1.2, 0.7);
        let pi = std::f32::consts::PI;
        let facing_down = |f: &dyn LightField| f.irradiance(p, Vec3::NEG_Y).unwrap().x;
        assert!((facing_down(&split) - 0.3 * pi).abs() < 1e-4);
        assert!(
            (facing_down(&&split) - 0.3 * pi).abs() < 1e-4,
            "through a reference"
        );
        assert!(facing_down(&bins) > 1.1 * 0.3 * pi, "the even reading");
        assert!((split.irradiance(p, Vec3::Y).unwrap().x - pi).abs() < 1e-4);
        // Plus a field without halves (its bins split evenly): the halves add.
        let zero = LightGrid::filled(desc, BinLight::ZERO).unwrap();
        let sum = SumField(&split, &zero);
        assert!((facing_down(&sum) - 0.3 * pi).abs() < 1e-4);
        let twice = SumField(&split, &bins);
        let want = 0.3 * pi + facing_down(&bins);
        assert!((facing_down(&twice) - want).abs() < 1e-4);
        let diff = DifferenceField(&split, &zero);
        assert!((facing_down(&diff) - 0.3 * pi).abs() < 1e-4);
        assert!(SumField(&bins, &zero).horizon(p, None).unwrap().is_none());
        let other = GridDesc::new(Vec3::ONE, 1.0, UVec3::new(2, 3, 2)).unwrap();
        let e = SplitLightGrid::new(bins, crate::HorizonGrid::filled(other, down).unwrap())
            .unwrap_err();
        assert!(e.to_string().contains("halves.desc()"), "{e}");
    }

    #[test]
    fn a_sun_response_reads_as_a_light_field() {
        let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::splat(3)).unwrap();
        let bins = BinLight::uniform(Vec3::new(0.5, 1.0, 2.0));
        // Transmittance rising with height, 1 + 1 ulp at the top (what trilinear
        // weights can give): read clamped.
        let t: Vec<f32> = (0..desc.point_count())
            .map(|i| [0.0, 0.5, 1.0 + f32::EPSILON][desc.coords(i).unwrap().y as usize])
            .collect();
        let r = SunResponse {
            scattered: LightGrid::filled(desc, bins).unwrap(),
            horizon: None,
            transmittance: Grid::from_trusted(desc, t),
            stats: SweepStats::default(),
            resident: None,
        };
        let p = Vec3::new(1.0, 0.5, 1.0);
        assert_eq!(r.light(p, None).unwrap(), bins);
        assert!((r.sun_transmittance(p, None).unwrap() - 0.25).abs() < 1e-6);
        // With a normal, read half a cell along it, as the bins are.
        assert!((r.sun_transmittance(p, Some(Vec3::Y)).unwrap() - 0.5).abs() < 1e-6);
        assert_eq!(
            r.sun_transmittance(Vec3::new(1.0, 2.0, 1.0), None).unwrap(),
            1.0
        );
        assert!(r.sun_transmittance(Vec3::NAN, None).is_err());
    }

    #[test]
    fn halo_layout_is_a_bijection() {
        for dims in [
            UVec3::new(1, 2, 1),
            UVec3::new(3, 1, 5),
            UVec3::new(9, 2, 2),
        ] {
            let l = HaloLayout::new(dims);
            let mut seen = vec![false; l.len()];
            let w = HALO_WIDTH;
            for j in 0..dims.y {
                for z in -w..dims.z as i32 + w {
                    for x in -w..dims.x as i32 + w {
                        let inside =
                            (0..dims.x as i32).contains(&x) && (0..dims.z as i32).contains(&z);
                        match l.index(x, j, z) {
                            Some(i) => {
                                assert!(!inside && !seen[i], "{dims} ({x},{j},{z}) -> {i}");
                                seen[i] = true;
                            }
                            None => assert!(inside),
                        }
                    }
                }
            }
            assert!(seen.iter().all(|&s| s));
            assert_eq!(l.index(-w - 1, 0, 0), None);
        }
    }

    #[test]
    fn options_and_boundary_validation_name_fields() {
        let mut o = SweepOptions::single_pass();
        o.smoothing = 1.0;
        assert!(
            o.validate()
                .unwrap_err()
                .to_string()
                .contains("smoothing = 1.0")
        );
        let mut o = SweepOptions::multi_bounce();
        o.max_passes = 0;
        assert!(o.validate().unwrap_err().to_string().contains("max_passes"));
        assert!(SweepOptions::default().validate().is_ok());

        let d = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(2, 2, 2)).unwrap();
        let mut sky = BinLight::uniform(Vec3::ONE);
        assert!(Boundary::open_sky(sky).validate(&d).is_ok());
        sky.0[3].x = f32::INFINITY;
        assert!(
            Boundary::open_sky(sky)
                .validate(&d)
                .unwrap_err()
                .to_string()
                .contains("top")
        );
        let b = Boundary {
            top: TopBoundary::PerPoint(vec![BinLight::ZERO; 3]),
            bottom: BinLight::ZERO,
            sides: SideBoundary::Open,
        };
        assert!(
            b.validate(&d)
                .unwrap_err()
                .to_string()
                .contains("top has 3 elements, the descriptor needs 4 or 144")
        );
        // Given halves: as many as the halo's points, each finite and >= 0.
        let n = HaloLayout::new(d.dims()).len();
        let sides = |down: Vec<crate::HorizonLight>| Boundary {
            sides: SideBoundary::GivenHalves {
                light: vec![BinLight::ZERO; n],
                down,
                cells: None,
            },
            ..Boundary::open_sky(BinLight::ZERO)
        };
        assert!(
            sides(vec![crate::HorizonLight::default(); n])
                .validate(&d)
                .is_ok()
        );
        let short = sides(vec![crate::HorizonLight::default(); n - 1]).validate(&d);
        assert!(short.unwrap_err().to_string().contains("sides.down"));
        let mut bad = vec![crate::HorizonLight::default(); n];
        bad[5].0[2].y = -1.0;
        let e = sides(bad).validate(&d).unwrap_err().to_string();
        assert!(e.contains("sides.down") && e.contains("[5]"), "{e}");
        // Given cells: as many as the halo's points, pass-through and reflectance in
        // [0, 1].
        let with_cells = |cells: Vec<Material>| Boundary {
            sides: SideBoundary::GivenHalves {
                light: vec![BinLight::ZERO; n],
                down: vec![crate::HorizonLight::default(); n],
                cells: Some(cells),
            },
            ..Boundary::open_sky(BinLight::ZERO)
        };
        assert!(with_cells(vec![Material::EMPTY; n]).validate(&d).is_ok());
        let e = with_cells(vec![Material::EMPTY; n + 1])
            .validate(&d)
            .unwrap_err()
            .to_string();
        assert!(e.contains("sides.cells"), "{e}");
        for bad in [
            Material {
                reflectance: Vec3::ONE,
                pass: 1.5,
            },
            Material {
                reflectance: Vec3::ONE,
                pass: f32::NAN,
            },
            Material {
                reflectance: Vec3::new(0.5, -0.1, 0.5),
                pass: 0.5,
            },
            Material {
                reflectance: Vec3::new(0.5, 1.1, 0.5),
                pass: 0.5,
            },
            Material {
                reflectance: Vec3::new(0.5, f32::INFINITY, 0.5),
                pass: 0.5,
            },
        ] {
            let mut cells = vec![Material::EMPTY; n];
            cells[7] = bad;
            let e = with_cells(cells).validate(&d).unwrap_err().to_string();
            assert!(e.contains("sides.cells") && e.contains("[7]"), "{e}");
        }
    }

    #[test]
    fn light_grid_is_a_light_field() {
        let d = GridDesc::new(Vec3::ZERO, 2.0, UVec3::new(2, 2, 2)).unwrap();
        let g = LightGrid::filled(d, BinLight::uniform(Vec3::ONE)).unwrap();
        let e = g.irradiance(Vec3::ONE, Vec3::Y).unwrap();
        assert!((e - Vec3::splat(std::f32::consts::PI)).abs().max_element() < 1e-5);
        assert!(
            (g.average(Vec3::ONE).unwrap() - Vec3::ONE)
                .abs()
                .max_element()
                < 1e-6
        );
        assert!(g.irradiance(Vec3::ONE, Vec3::ZERO).is_err());
        let m = UniformMaterial(Material::EMPTY).material(&d).unwrap();
        assert_eq!(m.data().len(), 8);
    }

    #[test]
    fn difference_field_removes_a_part_and_clamps_rounding() {
        let d = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(3, 3, 3)).unwrap();
        let ramp = |k: f32| {
            let data = (0..d.point_count())
                .map(|i| BinLight(std::array::from_fn(|b| Vec3::splat(k * (i + b) as f32))))
                .collect();
            LightGrid::new(d, data).unwrap()
        };
        let (a, b) = (ramp(1.0), ramp(0.5));
        let sum = SumField(&a, &b);
        for p in [Vec3::ZERO, Vec3::new(0.3, 1.7, 1.2), Vec3::splat(2.0)] {
            // (a + b) - b = a, within f32 rounding.
            let got = DifferenceField(&sum, &b).light(p, None).unwrap();
            let want = a.light(p, None).unwrap();
            for k in 0..26 {
                assert!((got.0[k] - want.0[k]).abs().max_element() < 1e-4);
            }
            // A part larger than the whole clamps to zero, never negative.
            let neg = DifferenceField(&b, &sum).light(p, None).unwrap();
            assert!(neg.0.iter().all(|v| *v == Vec3::ZERO));
        }
    }

    #[test]
    fn no_scatter_keeps_pass_through_and_drops_reflectance() {
        let d = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(2, 2, 2)).unwrap();
        let m = Material {
            reflectance: Vec3::new(0.2, 0.5, 0.9),
            pass: 0.3,
        };
        let g = NoScatter(UniformMaterial(m)).material(&d).unwrap();
        assert!(
            g.data()
                .iter()
                .all(|c| c.reflectance == Vec3::ZERO && c.pass == 0.3)
        );
        // A grid is the source of its own box, and of no other.
        let own = MaterialGrid::filled(d, m).unwrap();
        assert_eq!(own.material(&d).unwrap(), own);
        let other = GridDesc::new(Vec3::ONE, 1.0, UVec3::new(2, 2, 2)).unwrap();
        let e = own.material(&other).unwrap_err().to_string();
        assert!(e.contains("desc"), "{e}");
        assert_eq!(NoScatter(&own).material(&d).unwrap().data()[0].pass, 0.3);
    }
}
