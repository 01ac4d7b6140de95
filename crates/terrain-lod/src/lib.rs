//! # terrain-lod
//!
//! The light grid hierarchy around a moving camera (seed 000, "Global illumination" and
//! "Performance"): one **world grid** over the whole terrain (16 m cells by default), and
//! **node grids** of a quadtree whose cell size halves per level down to the finest
//! (1 m), each `node_points × node_points` points across and as tall as the node's
//! ground-to-canopy span. Grids are built coarse to fine: a node's top and side
//! boundaries are interpolated from the coarser grids, then it is swept, so reading the
//! finest ready grid needs no blending at its edges.
//!
//! Each frame, [`Hierarchy::update`] decides from the camera which nodes should exist
//! (finer near the camera), evicts far ones, and builds missing or stale ones within a
//! budget of points swept (or of time, [`HierarchyParams::budget_ms`]: the points its
//! measured rate gets through): the camera's surroundings down to the finest depth first,
//! each part coarse and near first (`order`). A caller that draws only once everything
//! is built calls [`Hierarchy::settle`] instead: coarse to fine, each node swept once.
//! The nodes of one depth are built side by side, each node's sky sweep and sun
//! responses as two jobs, and the next depth's materials are composed beside those
//! sweeps ([`HierarchyParams::compose_ahead`]); a wanted node the budget leaves keeps
//! its composed material for the frame that builds it. A node whose inputs (material,
//! boundary light, options) hash as before is not swept again. With
//! [`LodSkips::bare_children`]
//! (off by default: it costs accuracy at forest edges) nodes with no objects above the
//! ground get no finer children.
//!
//! ## Node size: time and memory
//!
//! `cargo run --release -p lightgrid-terrain-lod --example flythrough`: 30 frames along a 300 m
//! path over the shipped DEM (4 m a pixel, heights × 0.05) with 4000 procedural 8 m
//! trees, world grid 16 m, nodes down to 1 m, budget `node_points² × 96` points a frame,
//! no apron, CPU sweeper (the default options: 4 passes at most, stopping at a
//! tolerance of 0.01), the 2-core Intel Xeon VM, three runs on 2026-12-04 (the frame's
//! mean includes building the world grid; the first run after a build took the 16-point
//! path 35.5 ms, `cargo xtask figures`' median of three 28.0 that morning and 31.1 in a
//! slower spell at noon). Memory is that of the
//! grids alive after the last frame, as stored (26 bins `f32`) and as the other
//! representations would take.
//!
//! | points a node | ms a frame | points swept | 26 bins `f32` | 26 bins R11G11B10 | average + dominant |
//! |--------------:|-----------:|-------------:|--------------:|------------------:|-------------------:|
//! | 16 | 30–31 | 0.56 M | 62 MB | 21 MB | 5 MB |
//! | 32 | 68–77 | 1.64 M | 203 MB | 68 MB | 16 MB |
//! | 64 | 204–218 | 4.85 M | 853 MB | 284 MB | 66 MB |
//!
//! On the CPU sweeper 16-point nodes win on both counts: smaller nodes overlap the
//! wanted area more tightly. Seed 000 chose 32 for GPU occupancy (one dispatch per
//! level); `sweep-gpu` will measure it there. `cargo bench -p lightgrid-terrain-lod` times an
//! 8-frame fly-through for 16 and 32.
//!
//! ## A frame as a user runs it
//!
//! [`FrameStats::times`] splits a frame's wall time by stage ([`StageTimes`]).
//! `cargo xtask frame` runs a camera path with the sun kept apart and measures the
//! light sampled against one full-resolution sweep of the region, and at the last
//! camera against Monte Carlo (the repository's `docs/measurements.md`, "The hierarchy
//! frame by frame", has its figures): with 16-point nodes 71, 59 and 57 ms a frame on
//! two cores at 10, 30 and 60° suns (`cargo xtask figures`, 2026-12-04); against the
//! single sweep the sky within about 1 % in bias at every depth,
//! sky and sun together 3–5 % RMSE in the finest nodes; against Monte Carlo, what the
//! renderer reads 6–10 % RMSE, most of it the single sweep's own error at points
//! (ARCHITECTURE.md, "Known defects").
//!
//! ## Across the horizon
//!
//! Every grid keeps the downward halves of its horizontal bins beside them, sky and
//! scattered sun ([`HierarchyParams::sweep`]'s `outputs.horizon`, on by default: 96
//! bytes a point each, [`BYTES_HORIZON`]), and the hierarchy's irradiance reads each
//! horizontal bin in its two halves ([`LightField::horizon`](lightgrid_core::LightField::horizon)): a surface facing down
//! over dark ground no longer sees half the sky through them (in the frame bench's
//! forest, against Monte Carlo, +64–75 % read even, −4 % through the halves).
//! [`Layer::horizon`] and [`LayerSun::horizon`] hand them to GPU renderers.
//!
//! ## The sun kept apart
//!
//! [`Hierarchy::set_sun`] keeps the sun out of the bins (issue 14): every grid then holds
//! the sky's bins (swept from the sky alone), the sun's scattered bins and its
//! transmittance along the exact direction, both for unit sun irradiance
//! (`Sweeper::sweep_sun`; 312 + 312 + 4 bytes a point as `f32`; every grid also keeps
//! the material it was swept with, [`BYTES_MATERIAL`] a point). Sky and sun colours
//! multiply ([`Hierarchy::set_sky_scale`], [`SunLight::irradiance`]); a new direction
//! recomputes the sun's responses only. Every grid's transmittance is marched again in
//! `set_sun` (the direct sun and its shadows move in the call: tens of milliseconds for
//! the whole hierarchy; under a time budget the grids over the camera and, nearest
//! first, those half the budget allows, the frames after the rest); the scattered sun
//! follows, the world grid's
//! at once and the nodes' coarse and near first within the budget (each costs a node's
//! points, and its parent's must be current; from the kept material, composed again for
//! nothing); meanwhile a node shows its earlier direction's scattered sun. A node's beam
//! is marched on beyond its box through its own depth's material wherever it may meet
//! some: the depth's neighbours, and the nodes not built that its rays cross, composed
//! for the march alone (the sun's casters, [`FrameStats::casters`]; at 10° on the
//! frame bench the finest nodes' direct sun against one 1 m sweep went from 28 to
//! 9.6 % RMSE with them); coarser grids beyond. A new node whose sun responses the
//! budget leaves for a later frame marches its transmittance with its sky sweep, so its
//! direct sun is its own at once (with the seams below, the finest nodes' direct sun
//! over the bench's flight is 0.5–0.8 % RMSE). The tests check that the transmittance marched in
//! `set_sun`, and everything once the nodes are swept again, equal a hierarchy built
//! under the new sun from the start. Between two nodes of one depth a point reads
//! both, each by its share of the lookup's corners (`lightgrid_core::seam`): one grid's
//! trilinear read across the seam. Under a time budget
//! ([`HierarchyParams::budget_ms`]) the world grid's scattered-sun sweep for a moved sun
//! (with [`HierarchyParams::sun_with_sky`], its light) runs on a thread while frames go
//! on with the old scattered sun ([`Hierarchy::sun_moving`]); `cargo xtask frame
//! --budget-ms 30` times it.
//!
//! ```
//! use lightgrid_core::glam::{Vec2, Vec3};
//! use lightgrid_core::{BinLight, LightField};
//! use lightgrid_material_voxelizer::compose::{AreaComposer, ComposeParams, GroundColour, Heightmap, Terrain};
//! use lightgrid_sweep_cpu::CpuSweeper;
//! use lightgrid_terrain_lod::{Hierarchy, HierarchyParams};
//!
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let hm = Heightmap::from_fn(Vec2::ZERO, 2.0, 129, 129, |x, z| 3.0 * (x * 0.02).sin() * (z * 0.03).cos())?;
//! let terrain = Terrain { heightmap: hm, colour: GroundColour::Uniform(Vec3::splat(0.3)) };
//! let composer = AreaComposer::new(vec![], &[], Some(terrain.clone()), ComposeParams::default())?;
//! let (sky, _) = BinLight::uniform(Vec3::ONE).split_vertical();
//! let mut params = HierarchyParams::default();
//! params.finest_cell = 4.0; // 16, 8, 4 m
//! let mut h = Hierarchy::new(&terrain.heightmap, Box::new(composer), Box::new(CpuSweeper::new()), sky, params)?;
//! let frame = h.update(Vec3::new(128.0, 10.0, 128.0))?;
//! assert!(frame.points_swept <= params.budget_points);
//! let e = h.irradiance(Vec3::new(128.0, 5.0, 128.0), Vec3::Y)?;
//! assert!(e.x > 0.0);
//! # Ok(())
//! # }
//! ```
//!
//! ## Map
//!
//! - `lib.rs`: [`Hierarchy`] (the world grid, the quadtree of node grids, the frame's
//!   update within its budget, the sun kept apart, the light field it serves), its
//!   parameters and statistics.
//! - `params`: [`HierarchyParams`] and [`LodSkips`], their checks and the layout they
//!   imply (cell and node sizes, a depth's lattice).
//! - `order`: the order a frame builds its wanted nodes in (the camera's surroundings
//!   first, nodes swept before a coarser node they read swept again; coarse to fine
//!   where everything fits the frame, and in [`Hierarchy::settle`]).
//! - `build`: a frame's nodes built a depth at a time, the nodes of one depth side by
//!   side (material, boundaries from coarser grids, sweeps).
//! - `refresh`: ready nodes swept again where their inputs changed
//!   ([`Hierarchy::refresh`]).
//! - `neighbours`: the side halo from the same depth's nodes before a node in a fixed
//!   order ([`HierarchyParams::neighbour_halo`], off by default), and the waves a
//!   depth is then swept in.
//! - `shadow`: the sun's beam beyond a node, marched through the finest material held
//!   at each place.
//! - `casters`: the nodes a low sun's rays cross beyond the built ones, composed for
//!   that march alone.
//! - `volume`: light volumes read fast (`LightField::volume_sampler`): every grid reduced
//!   once to its moments.
//! - [`bake`]: a whole world as a graph of tasks (the world grid, its tiles, every node
//!   of every depth from the coarser grids it reads), each a function of its inputs,
//!   for `lightgrid bake world.toml` in one process, one process per task or on Ray.

use std::collections::HashMap;
use std::hash::BuildHasherDefault;

mod apron;
pub mod bake;
mod boundary;
mod budget;
mod build;
mod casters;
mod depth;
mod neighbours;
mod order;
mod params;
mod read;
mod refresh;
mod shadow;
mod sun;
mod sun_move;
#[cfg(test)]
mod testing;
mod volume;

pub use depth::{DEPTH_BITS, quantized_pass};
pub use params::{HaloCells, HierarchyParams, LodSkips};

use lightgrid_core::Heightmap;
use lightgrid_core::glam::{IVec2, UVec3, Vec2, Vec3};
use lightgrid_core::{
    BinLight, Boundary, Grid, GridDesc, GridError, HorizonGrid, LightGrid, MaterialGrid,
    MaterialSource, Resident, SideBoundary, SunBoundary, SweepError, SweepOptions, Sweeper,
    TopBoundary,
};

/// Errors of the hierarchy.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LodError {
    /// A parameter or input is invalid (names the field).
    #[error(transparent)]
    Invalid(#[from] GridError),
    /// A sweep failed.
    #[error(transparent)]
    Sweep(#[from] SweepError),
}

/// Points a second a time budget assumes before the first frame has measured one
/// ([`HierarchyParams::budget_ms`]): the 16-point forest path's rate on two cores.
const FIRST_RATE: f64 = 200_000.0;

/// Hashes node keys for the hierarchy's map: every point sampled looks up a node per
/// depth, and std's SipHash (made for keys an attacker picks) took 3 % of the demo. A
/// multiply-rotate mix of the key's three words (no order of the map is relied on).
#[derive(Default)]
struct KeyHasher(u64);

impl std::hash::Hasher for KeyHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for b in bytes {
            self.write_u32(*b as u32);
        }
    }
    fn write_u32(&mut self, i: u32) {
        self.0 = (self.0.rotate_left(5) ^ i as u64).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
    fn write_i32(&mut self, i: i32) {
        self.write_u32(i as u32);
    }
}

/// A node of the quadtree: depth (1 = coarsest nodes) and index in its depth's lattice.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct NodeKey {
    /// Depth, 1 ..= `params.depths()`.
    pub depth: u32,
    /// Lattice index in x and z.
    pub index: IVec2,
}

impl Ord for NodeKey {
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        (self.depth, self.index.y, self.index.x).cmp(&(o.depth, o.index.y, o.index.x))
    }
}

impl PartialOrd for NodeKey {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}

/// A sun kept apart from the sky ([`Hierarchy::set_sun`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SunLight {
    /// Direction toward the sun (normalised when set; at or below the horizon the sun
    /// has no direct light and its scattered response is zero).
    pub to_sun: Vec3,
    /// The sun's irradiance on a surface facing it, RGB (multiplies the sun's responses:
    /// changing it sweeps nothing).
    pub irradiance: Vec3,
}

/// A grid's sun responses for unit sun irradiance: the scattered light swept for
/// `to_sun`, the transmittance marched for `marched_to` (the same but while a moved
/// sun's scattered light follows its direct light: the module `sun_move`; `to_sun`
/// zero while a new node's scattered light is the coarser grids', `interim_sun`).
struct GridSun {
    /// `None` where the grid's sky bins hold it ([`HierarchyParams::sun_with_sky`]).
    scattered: Option<LightGrid>,
    /// The downward halves of `scattered`'s horizontal bins, if kept.
    horizon: Option<HorizonGrid>,
    /// The sweeper's device copy of `scattered`, if it keeps one.
    resident: Option<Resident>,
    transmittance: Grid<f32>,
    to_sun: Vec3,
    marched_to: Vec3,
    /// With the sun swept with the sky ([`HierarchyParams::sun_with_sky`]): the
    /// irradiance the grid's sky sweep took the sun's first collisions with (toward
    /// `to_sun`); `None` where the scattered sun is swept apart.
    with_sky: Option<Vec3>,
    /// The transmittance was marched through a scene since changed
    /// ([`Hierarchy::refresh`]), or before the sun's casters it crosses were all
    /// composed (a new node's interim march under a time budget: [`crate::casters`]):
    /// shown until it is marched again, not current.
    march_stale: bool,
    /// A node's transmittance one cell beyond its points, marched over its apron's
    /// first ring ([`apron::SunRing`]): read in the strip beside a neighbour not built.
    /// `None` without an apron (or for the world grid); read only while marched for
    /// `marched_to`.
    ring: Option<apron::SunRing>,
}

/// The sun responses of one layer ([`Layer::sun`]), for unit sun irradiance.
#[derive(Debug, Clone, Copy)]
pub struct LayerSun<'a> {
    /// The sun's light after at least one scattering (26 bins); `None` where the
    /// layer's bins hold it ([`HierarchyParams::sun_with_sky`]: read them alone).
    pub scattered: Option<&'a LightGrid>,
    /// The downward halves of `scattered`'s horizontal bins, if kept.
    pub horizon: Option<&'a HorizonGrid>,
    /// The sun beam's transmittance per point.
    pub transmittance: &'a Grid<f32>,
    /// The sweeper's device copy of `scattered`, if it keeps one.
    pub resident: Option<&'a Resident>,
}

/// A node's composed material ([`Hierarchy::node_material`]).
#[derive(Clone)]
struct NodeMaterial {
    grid: MaterialGrid,
    /// With an apron ([`HierarchyParams::apron`]), the material of `grid` widened by it
    /// on every side (the same levels; `grid` is its inner points): what the node's
    /// sweeps and marches run on ([`crate::apron`]).
    widened: Option<MaterialGrid>,
    /// With [`HaloCells::Composed`], the material of `grid` widened by the apron
    /// and [`HALO_WIDTH`](lightgrid_core::HALO_WIDTH) more cells: its ring holds the
    /// cells of the halos of the node's sweeps (the sky's and the sun's).
    outer: Option<MaterialGrid>,
    /// Objects above the ground.
    has_objects: bool,
    /// Nothing lies above the grid in the node's column (its composed top was empty).
    open_above: bool,
}

struct Node {
    light: LightGrid,
    /// The downward halves of `light`'s horizontal bins, if kept
    /// (`HierarchyParams::sweep.outputs.horizon`).
    horizon: Option<HorizonGrid>,
    /// The material it was swept with (its sun responses are recomputed from it, and the
    /// sun's march beyond other nodes crosses it: [`shadow`]).
    material: NodeMaterial,
    /// The sun's responses for the current sun direction (`None`: not computed yet for
    /// it; the coarser grids' light the node's points meanwhile).
    sun: Option<GridSun>,
    /// The sweeper's device copy of `light`, if it keeps one.
    resident: Option<Resident>,
    /// Its light one cell beyond its grid, where its sky sweep had an apron and keeps
    /// its light on the CPU: read beside a neighbour not built ([`apron::Ring`]).
    ring: Option<apron::Ring>,
    /// Its light over its apron beyond its sides, while a finer node's boundary may read
    /// it there in place of a wanted neighbour not built ([`apron::Band`]).
    band: Option<apron::Band>,
    input_hash: u64,
    /// Built before a wanted coarser node its boundary reads, or over one such
    /// (`order.rs`): swept again once those are all built and final.
    provisional: bool,
}

/// Which points of space a [`Layer`] lights: those whose `(x, z)` fall in quadtree cell
/// `index` (`floor((p.xz - origin) / size) == index`) and whose height lies within its
/// grid's points' (the whole cell across, not a coarser grid: the half cell beside its
/// outermost points is read across the seam with the neighbouring nodes of its depth
/// where they are ready and reach the point's height, [`lightgrid_core::seam`], else at
/// its outermost points, clamped).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Owner {
    /// World `(x, z)` of the quadtree's corner.
    pub origin: Vec2,
    /// Side of a node at this depth, metres.
    pub size: f32,
    /// The node's cell.
    pub index: IVec2,
}

impl Owner {
    /// Whether the layer lights `p` (given its grid's descriptor).
    pub fn owns(&self, desc: &GridDesc, p: Vec3) -> bool {
        ((Vec2::new(p.x, p.z) - self.origin) / self.size)
            .floor()
            .as_ivec2()
            == self.index
            && within_levels(desc, p)
    }
}

/// Whether `p`'s height lies within the points of `desc` (a node serves its quadtree
/// cell's whole column between its lowest and highest level: [`Owner`]).
fn within_levels(desc: &GridDesc, p: Vec3) -> bool {
    let (lo, hi) = desc.point_bounds();
    p.y >= lo.y && p.y <= hi.y
}

/// One grid of the hierarchy as a renderer layers them: [`Hierarchy::layers`] lists the
/// world grid first (it lights every point), then the ready nodes coarse to fine; a point
/// takes its light from the last layer that owns it, which is [`Hierarchy::grid_at`]
/// (tested), and where its read falls between that node's points and a neighbour's of
/// the same depth, from both ([`Owner`], [`lightgrid_core::seam`]). GPU renderers
/// evaluate the same rule per layer (`lightgrid_render::GpuLightSampler::sample_layers`).
#[derive(Debug, Clone, Copy)]
pub struct Layer<'a> {
    /// The grid.
    pub grid: &'a LightGrid,
    /// The sweeper's device copy of it, if the sweeper keeps one.
    pub resident: Option<&'a Resident>,
    /// The downward halves of `grid`'s horizontal bins, if kept
    /// ([`HierarchyParams::sweep`]'s `outputs.horizon`); a point served by a layer with
    /// them reads each horizontal bin in its two halves ([`LightField::horizon`](lightgrid_core::LightField::horizon)).
    pub horizon: Option<&'a HorizonGrid>,
    /// Which points it lights; `None`: all (the world grid).
    pub owner: Option<Owner>,
    /// With the sun kept apart ([`Hierarchy::set_sun`]): the grid's sun responses for
    /// the current sun direction; `None` while they wait to be computed, and then the
    /// sun part of a point comes from the last *earlier* owning layer that has them
    /// (the world grid always has). `grid` then holds the sky's light alone (times
    /// [`Hierarchy::sky_scale`]).
    pub sun: Option<LayerSun<'a>>,
}

/// Per-frame report.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FrameStats {
    /// Points swept this frame.
    pub points_swept: u64,
    /// The points this frame's budget allowed at its start: `budget_points`, or under a
    /// time budget ([`HierarchyParams::budget_ms`]) what the last frames' rate of
    /// update time gets through in it (the frame itself takes jobs while their
    /// predicted time fits what is left, and its first node whatever it costs).
    pub budget_points: u64,
    /// Nodes built (swept) this frame.
    pub built: u32,
    /// New nodes whose material this frame composed (under a time budget a batch, one
    /// a thread, at a time: [`HierarchyParams::budget_ms`]).
    pub composed: u32,
    /// Materials composed this frame for the sun's march alone: nodes not built whose
    /// cells a low sun's rays from the nodes being lit cross (their time is in
    /// `times.material`).
    pub casters: u32,
    /// Bytes of the casters' materials held at the frame's end (kept while later
    /// frames' rays may cross them).
    pub caster_bytes: u64,
    /// Nodes whose inputs were unchanged: not swept again.
    pub skipped_unchanged: u32,
    /// Wanted nodes left for later frames (over budget or waiting for a parent).
    pub pending: u32,
    /// Nodes evicted.
    pub evicted: u32,
    /// Ready nodes a [`Hierarchy::refresh`] built anew at a new height: the scene
    /// changed their column (an object risen above their levels, or gone).
    pub regrown: u32,
    /// Wanted nodes not built because their parent has no objects above the ground.
    pub skipped_bare: u32,
    /// Ready nodes per depth (index 0: the world grid, 0 or 1).
    pub alive_per_depth: Vec<u32>,
    /// Points of the ready grids per depth (index 0: the world grid).
    pub points_per_depth: Vec<u64>,
    /// Node sun responses computed this frame (transmittance and scattered sun, or the
    /// transmittance alone where a moved sun's `set_sun` left it and the scattered sun
    /// is current), with the sun kept apart; their points count in `points_swept` (a
    /// transmittance alone a quarter of them).
    pub sun_built: u32,
    /// Ready nodes the camera wants still without a sun response for the current sun
    /// direction (lit by coarser grids' sun meanwhile). Ready nodes it no longer wants
    /// are not counted: no frame sweeps their sun (they are kept until evicted).
    pub sun_pending: u32,
    /// Ready nodes swept before a coarser node their boundary reads was built (or over
    /// such a node) at the frame's end: [`Hierarchy::update`] sweeps them again once
    /// those are built (they count in `pending` while they wait).
    pub provisional: u32,
    /// This frame installed a moved sun's scattered light, whose world grid was swept on
    /// a thread since [`Hierarchy::set_sun`] (the nodes' then follow within the budget;
    /// the direct sun moved in `set_sun`).
    pub sun_moved: bool,
    /// Where the frame's time went, by stage.
    pub times: StageTimes,
}

/// Time of a frame's stages ([`FrameStats::times`]), summed over the nodes: where the
/// nodes of a depth are built side by side (a sweeper that forks, on several threads)
/// the stages add up the threads' time and can sum past the frame's wall time. What is
/// not in a stage (deciding which nodes are wanted, eviction, bookkeeping) is the rest
/// of the frame.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StageTimes {
    /// Composing node materials from the scene (and sizing the grids).
    pub material: std::time::Duration,
    /// Node boundaries of the sky's light from the coarser grids, and the input hash.
    pub boundary: std::time::Duration,
    /// Sweeps of the sky's light (all light without the sun apart).
    pub sky_sweep: std::time::Duration,
    /// Sun boundaries from the coarser grids (scattered sun's halo and top).
    pub sun_boundary: std::time::Duration,
    /// Sun responses: the transmittance march, first collisions and the sweep of them.
    pub sun_sweep: std::time::Duration,
}

impl StageTimes {
    /// The sum of the stages.
    pub fn total(&self) -> std::time::Duration {
        self.material + self.boundary + self.sky_sweep + self.sun_boundary + self.sun_sweep
    }
    /// The time spent in the sweeper (sky and sun sweeps).
    pub fn sweeping(&self) -> std::time::Duration {
        self.sky_sweep + self.sun_sweep
    }
}

/// Adds the time `f` takes to `into`.
fn timed<R>(into: &mut std::time::Duration, f: impl FnOnce() -> R) -> R {
    let t = std::time::Instant::now();
    let r = f();
    *into += t.elapsed();
    r
}

impl FrameStats {
    /// Bytes per depth at `bytes_per_point` ([`BYTES_26_F32`] as stored,
    /// [`BYTES_26_PACKED`], or [`BYTES_AVG_DOM`]).
    pub fn bytes_per_depth(&self, bytes_per_point: u64) -> Vec<u64> {
        self.points_per_depth
            .iter()
            .map(|p| p * bytes_per_point)
            .collect()
    }
    /// Total bytes at `bytes_per_point`.
    pub fn bytes(&self, bytes_per_point: u64) -> u64 {
        self.points_per_depth.iter().sum::<u64>() * bytes_per_point
    }
}

/// Bytes per point of the representations the docs compare.
pub const BYTES_26_F32: u64 = 26 * 12;
/// The horizon halves kept beside a grid's bins (8 colours, `f32`:
/// [`HierarchyParams::sweep`]'s `outputs.horizon`).
pub const BYTES_HORIZON: u64 = 8 * 12;
/// 26 bins as R11G11B10.
pub const BYTES_26_PACKED: u64 = 26 * 4;
/// Average (RGB `f32`) and dominant direction (`f32` × 3).
pub const BYTES_AVG_DOM: u64 = 24;
/// The material every grid keeps beside its light (reflectance RGB and pass-through,
/// `f32`).
pub const BYTES_MATERIAL: u64 = std::mem::size_of::<lightgrid_core::Material>() as u64;

/// The light grid hierarchy.
pub struct Hierarchy {
    params: HierarchyParams,
    heightmap_lo: Vec2,
    heightmap_hi: Vec2,
    heights: Heightmap,
    /// `params.world_bottom(&heights)`, worked out once (a pass over the heights).
    world_bottom: f32,
    source: Box<dyn MaterialSource + Send + Sync>,
    sweeper: Box<dyn Sweeper + Send + Sync>,
    /// Forks of `sweeper` for nodes swept side by side, kept with their memory.
    forks: Vec<Box<dyn Sweeper + Send + Sync>>,
    sky: BinLight,
    world: LightGrid,
    /// The downward halves of `world`'s horizontal bins, if kept.
    world_horizon: Option<HorizonGrid>,
    world_resident: Option<Resident>,
    nodes: HashMap<NodeKey, Node, BuildHasherDefault<KeyHasher>>,
    /// Materials composed for wanted nodes that the budget left for a later frame,
    /// kept until the node is built or no longer wanted ([`Hierarchy::refresh`] drops
    /// them all: the scene may have changed).
    composed: HashMap<NodeKey, NodeMaterial, BuildHasherDefault<KeyHasher>>,
    /// Materials of nodes not built that the sun's march crosses ([`casters`]).
    casters: casters::Casters,
    /// Points swept per second of [`Hierarchy::update`]'s time, averaged over the frames
    /// that swept (for [`HierarchyParams::budget_ms`]).
    rate: Option<f64>,
    /// This frame's budget of points ([`FrameStats::budget_points`]).
    frame_budget: u64,
    /// Under a time budget, the points a second of a frame's depths' jobs from their
    /// selection to their end (sun casters composed, sweeps run), smoothed over the
    /// frames: what [`Hierarchy::over_budget`] predicts a job's time with.
    step_rate: Option<f64>,
    /// The frame's points counted when the jobs being selected began to be (those
    /// counted since are selected, not yet swept).
    step_swept: u64,
    /// This frame's depths' points and seconds from their jobs' selection to their end.
    steps_timed: (u64, f64),
    /// When this frame began ([`Hierarchy::update`], [`Hierarchy::refresh`]).
    frame_started: std::time::Instant,
    /// Whether the last frame swept anything (see [`Hierarchy::over_budget`]).
    last_frame_swept: bool,
    /// Whether a frame has warned that one job alone took over twice the time budget.
    warned_single_job: bool,
    /// The sun kept apart (`None`: whatever sun there is lies in `sky`'s bins).
    sun: Option<SunLight>,
    world_sun: Option<GridSun>,
    /// The world grid's material (the sun's march beyond the nodes crosses it).
    world_material: Option<MaterialGrid>,
    /// The top of `world_material`'s highest non-empty cell anywhere (the highest of
    /// `world_tops`; −∞ before it or without one): the sun's casters are bounded by it.
    world_top: f32,
    /// The top of each column's highest non-empty cell of `world_material` (x fastest;
    /// −∞ where none): what bounds the sun's march above
    /// ([`shadow::SkyMarch`]'s clear sky ahead).
    world_tops: Vec<f32>,
    /// A moved sun's world-grid responses being swept on a thread ([`sun_move`]).
    sun_move: Option<sun_move::SunMove>,
    sky_scale: Vec3,
    /// The camera of the last frame ([`Hierarchy::update`], [`Hierarchy::refresh`]):
    /// under a time budget a moved sun's direct light is marched nearest it first.
    camera: Option<Vec3>,
    /// The nodes this round of [`Hierarchy::refresh`] calls has checked (`refresh.rs`).
    checked: refresh::Checked,
    /// The nodes the camera of the frame under way wants ([`Hierarchy::update`],
    /// [`Hierarchy::refresh`]): a node's sun waits for those of them its boundary
    /// reads, not for built nodes no longer wanted, whose sun no frame brings current.
    pub(crate) wanted_now: order::Wanted,
    /// Materials a refresh round composed again for ready nodes its budget then left
    /// for a later frame of the round (`refresh.rs`).
    recomposed: refresh::Recomposed,
}

/// Stands in for the sweeper while a sun sweep borrows the hierarchy for its boundary
/// (with the sweeper's [`Sweeper::carries_halo_paths`], which the nodes' options read).
struct Lent(bool);

impl Sweeper for Lent {
    fn name(&self) -> &'static str {
        "lent"
    }
    fn carries_halo_paths(&self) -> bool {
        self.0
    }
    fn sweep(
        &mut self,
        _: &MaterialGrid,
        _: &Boundary,
        _: &SweepOptions,
    ) -> Result<lightgrid_core::SweepOutput, SweepError> {
        Err(SweepError::Backend {
            backend: "lent",
            message: "the hierarchy's sweeper is in use".into(),
        })
    }
}

/// Which of a grid's responses a boundary is taken from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Response {
    /// The sky's light (all light, without the sun apart).
    Sky,
    /// The sun's scattered light.
    Sun,
}

/// A node's inputs hashed, for [`Hierarchy::refresh`] to see what changed. Compared
/// only within the process, so the bulk (materials, boundary light: megabytes a node)
/// goes through foldhash's quality hasher with a fixed seed (96 bytes a round; std's
/// SipHash, 8 bytes a round, was 2.4 % of the 16-point flythrough) rather than the
/// stable [`ContentHash`](lightgrid_core::hash::ContentHash) (FNV-1a, a byte a round);
/// the descriptor and options through `ContentHash`.
fn hash_grid(m: &MaterialGrid, b: &Boundary, o: &SweepOptions) -> u64 {
    use std::hash::{BuildHasher, Hasher};
    let mut h = foldhash::quality::FixedState::with_seed(0x6c67_6e6f_6465_7632).build_hasher();
    h.write_u64(
        lightgrid_core::hash::ContentHash::new(b"terrain-lod-node-v2")
            .desc(m.desc())
            .options(o)
            .finish(),
    );
    h.write(bytemuck::cast_slice(m.data()));
    match &b.top {
        TopBoundary::Uniform(x) => {
            h.write_u8(0);
            h.write(bytemuck::cast_slice(&x.0));
        }
        TopBoundary::PerPoint(v) => {
            h.write_u8(1);
            h.write(bytemuck::cast_slice(v));
        }
    }
    h.write(bytemuck::cast_slice(&b.bottom.0));
    match &b.sides {
        SideBoundary::Open => h.write_u8(0),
        SideBoundary::Periodic => h.write_u8(1),
        SideBoundary::Given(v) => {
            h.write_u8(2);
            h.write(bytemuck::cast_slice(v));
        }
        SideBoundary::GivenHalves { light, down, cells } => {
            h.write_u8(3);
            h.write(bytemuck::cast_slice(light));
            h.write(bytemuck::cast_slice(down));
            if let Some(cells) = cells {
                h.write_u8(1);
                for m in cells {
                    h.write(bytemuck::cast_slice(&[m.pass]));
                    h.write(bytemuck::cast_slice(&m.reflectance.to_array()));
                }
            }
        }
    }
    h.finish()
}

/// Most node depths below the world grid (`world_cell / finest_cell <= 2^16`).
pub const MAX_DEPTHS: u32 = 16;

/// Cells of a coarser grid above the terrain at which a halo point nearer bare ground
/// reads it ([`HierarchyParams::halo_ground_lift`]): one and a half, the least height
/// whose trilinear read takes neither of its levels from the grid's ground band (the
/// band's points lie within half a cell of the terrain, so a point a cell and a half
/// above it has both levels around it above the band's).
pub const GROUND_LIFT: f32 = 1.5;

/// Bytes a world-grid point needs while it is built: its material (16), the sweep's
/// bins (312) and the stored grid (312).
const WORLD_BYTES_PER_POINT: u64 = 16 + 2 * 312;

impl Hierarchy {
    /// Builds the world grid over the heightmap's extent (at load; not budgeted).
    pub fn new(
        heightmap: &Heightmap,
        source: Box<dyn MaterialSource + Send + Sync>,
        sweeper: Box<dyn Sweeper + Send + Sync>,
        sky_top: BinLight,
        params: HierarchyParams,
    ) -> Result<Self, LodError> {
        let mut h = Self::unswept(heightmap, source, sweeper, sky_top, params)?;
        h.sweep_world()?;
        Ok(h)
    }

    /// [`Hierarchy::new`] with the world grid laid out and its memory checked, not swept
    /// (a bake sweeps it as a task of its own: [`bake`]).
    fn unswept(
        heightmap: &Heightmap,
        source: Box<dyn MaterialSource + Send + Sync>,
        sweeper: Box<dyn Sweeper + Send + Sync>,
        sky_top: BinLight,
        params: HierarchyParams,
    ) -> Result<Self, LodError> {
        params.validate()?;
        if !sky_top.is_valid() {
            return Err(
                GridError::invalid("sky_top", sky_top, "light must be finite and >= 0").into(),
            );
        }
        let lo = heightmap.origin;
        let hi = lo
            + Vec2::new((heightmap.width - 1) as f32, (heightmap.depth - 1) as f32)
                * heightmap.spacing;
        let ground = heightmap.range();
        let mut h = Self {
            params,
            heightmap_lo: lo,
            heightmap_hi: hi,
            heights: heightmap.clone(),
            world_bottom: params.world_bottom(heightmap),
            source,
            sweeper,
            forks: Vec::new(),
            sky: sky_top,
            world: LightGrid::filled(GridDesc::new(Vec3::ZERO, 1.0, UVec3::ONE)?, BinLight::ZERO)?,
            world_horizon: None,
            world_resident: None,
            nodes: HashMap::default(),
            composed: HashMap::default(),
            casters: Default::default(),
            rate: None,
            frame_budget: params.budget_points,
            step_rate: None,
            step_swept: 0,
            steps_timed: (0, 0.0),
            frame_started: std::time::Instant::now(),
            last_frame_swept: true,
            warned_single_job: false,
            sun: None,
            world_sun: None,
            world_material: None,
            world_top: f32::NEG_INFINITY,
            world_tops: Vec::new(),
            sun_move: None,
            camera: None,
            checked: Default::default(),
            wanted_now: Default::default(),
            recomposed: Default::default(),
            sky_scale: Vec3::ONE,
        };
        let w = params.world_cell;
        let dims_xz = ((hi - lo) / w).ceil().as_uvec2() + lightgrid_core::glam::UVec2::ONE;
        let bottom = h.world_bottom;
        let top = ground.1 + params.margin.max(w) + 2.0 * w;
        let ny = (((top - bottom) / w).ceil() as u32)
            .saturating_add(1)
            .max(2);
        let desc = GridDesc::new(
            Vec3::new(lo.x, bottom, lo.y),
            w,
            UVec3::new(dims_xz.x, ny, dims_xz.y),
        )?;
        // The world grid (26 f32 bins) and what sweeping it holds at once.
        lightgrid_core::limits::check_memory(
            &format!(
                "the world grid of {} points (world_cell = {w} m over the terrain)",
                desc.point_count()
            ),
            lightgrid_core::limits::checked_bytes(
                "world grid",
                &[desc.point_count() as u64, WORLD_BYTES_PER_POINT],
            )?,
        )?;
        // (Zeros the sweep replaces: a filled grid wrote 25 MB over the flythrough's DEM.)
        h.world = LightGrid::zeroed(desc)?;
        Ok(h)
    }

    fn sweep_world(&mut self) -> Result<(), LodError> {
        let desc = *self.world.desc();
        let material = self.compose(&desc)?;
        self.sweep_world_over(material)
    }

    /// [`Hierarchy::sweep_world`] over `material`, composed from the scene.
    pub(crate) fn sweep_world_over(&mut self, material: MaterialGrid) -> Result<(), LodError> {
        let o = self.node_options(true);
        let sun = self.sun_with_sky();
        let out = sun_move::world_sky(self.sweeper.as_mut(), &material, self.sky, sun, &o)?;
        self.install_world(out, sun);
        self.set_world_material(material);
        Ok(())
    }

    /// The world grid's light swept (its sky, and `sun`'s first collisions with it:
    /// [`HierarchyParams::sun_with_sky`]); with a sun, the sun its grids' sky sweeps
    /// take from now on ([`Hierarchy::sky_sun`]), a moved sun's sweep on a thread
    /// superseded.
    pub(crate) fn install_world(
        &mut self,
        out: lightgrid_core::SweepOutput,
        sun: Option<SunLight>,
    ) {
        self.world = out.bins.expect("bins asked for");
        self.world_horizon = out.horizon;
        self.world_resident = out.resident;
        if let (Some(sun), Some(w)) = (sun, self.world_sun.as_mut()) {
            w.to_sun = sun.to_sun;
            w.with_sky = Some(sun.irradiance);
            self.sun_move = None;
        }
    }

    /// Keeps `material` as the world grid's, with its top (`world_top`).
    pub(crate) fn set_world_material(&mut self, material: MaterialGrid) {
        self.world_tops = shadow::column_tops(&material);
        self.world_top = self
            .world_tops
            .iter()
            .fold(f32::NEG_INFINITY, |a, &b| a.max(b));
        self.world_material = Some(material);
    }

    /// Sweeps from now on with `sweeper`, and sweeps the world grid again with it (so
    /// that a sweeper keeping its grids on a device holds the base layer too); the nodes
    /// already built stay as they are. For moving the GPU sweeper onto the device a
    /// window draws with, once that device exists.
    pub fn set_sweeper(&mut self, sweeper: Box<dyn Sweeper + Send + Sync>) -> Result<(), LodError> {
        self.poll_sun_move(true)?;
        self.sweeper = sweeper;
        self.forks.clear();
        self.checked.clear();
        self.sweep_world()?;
        if self.sun.is_some() {
            self.sweep_world_sun()?;
        }
        Ok(())
    }

    /// Changes the sky: the world grid is swept again at once; ready nodes are rebuilt by
    /// [`Hierarchy::refresh`] (within the budget), each only if its inputs changed.
    pub fn set_sky(&mut self, sky_top: BinLight) -> Result<(), LodError> {
        if !sky_top.is_valid() {
            return Err(
                GridError::invalid("sky_top", sky_top, "light must be finite and >= 0").into(),
            );
        }
        self.sky = sky_top;
        self.checked.clear();
        self.sweep_world()
    }

    /// Keeps the sun apart from the sky (issue 14), or stops doing so (`None`). With a
    /// sun, every grid holds three responses: the sky's light (the bins swept from the
    /// sky given to [`Hierarchy::new`] / [`Hierarchy::set_sky`], which must then hold no
    /// sun), the sun's scattered light and its transmittance along the exact direction
    /// (both for unit irradiance, by `Sweeper::sweep_sun`); the light read is
    /// `sky × sky_scale + scattered × irradiance` and the direct sun
    /// `irradiance × T × max(0, n · s)` ([`LightField::sun_transmittance`](lightgrid_core::LightField::sun_transmittance),
    /// [`Hierarchy::sun`]).
    ///
    /// A new direction re-marches every grid's transmittance here, at once
    /// (`Sweeper::sun_transmittance`: the direct sun moves in the call), and recomputes
    /// the world grid's scattered sun; the nodes' scattered sun is swept again by
    /// [`Hierarchy::update`] or [`Hierarchy::refresh`], coarse and near first, within
    /// the budget (a node shows its earlier direction's meanwhile, beside its new
    /// transmittance); the sky's responses stay. Under a time budget
    /// ([`HierarchyParams::budget_ms`]) the transmittances re-marched here are the world
    /// grid's and the nodes' nearest the last frame's camera, for about half the budget
    /// (the nodes over the camera whatever the time; the frames after march the rest,
    /// which show the coarser grids' sun meanwhile), and the world grid's scattered sun
    /// is swept on a thread: the old one stays shown until a frame finds the new one
    /// done ([`Hierarchy::sun_moving`], [`FrameStats::sun_moved`]; the module
    /// `sun_move`); otherwise, and for a first sun, it is swept here, at once. The same
    /// direction with another irradiance sweeps nothing. With
    /// [`HierarchyParams::sun_with_sky`] the world grid's light is swept again instead
    /// (for a new irradiance too), the same way, and then every node's; `None` there
    /// sweeps the world grid's sky alone again at once, and [`Hierarchy::refresh`]
    /// the nodes' (as after [`Hierarchy::set_sky`]). The sweeper must take cell
    /// sources (the CPU and GPU sweepers do).
    ///
    /// ```no_run
    /// # fn f(h: &mut lightgrid_terrain_lod::Hierarchy, camera: lightgrid_core::glam::Vec3)
    /// # -> Result<(), lightgrid_terrain_lod::LodError> {
    /// use lightgrid_core::glam::Vec3;
    /// use lightgrid_terrain_lod::SunLight;
    /// h.set_sun(Some(SunLight { to_sun: Vec3::new(0.3, 0.5, 0.2), irradiance: Vec3::splat(3.0) }))?;
    /// while h.sun_moving() {
    ///     h.update(camera)?; // the new direct sun, the old scattered sun meanwhile
    /// }
    /// # Ok(())
    /// # }
    /// ```
    pub fn set_sun(&mut self, sun: Option<SunLight>) -> Result<(), LodError> {
        let Some(mut sun) = sun else {
            // A sweep under way finishes on its thread alone; its result is dropped.
            self.checked.clear();
            self.sun_move = None;
            let swept_with_sky = self.sun_with_sky().is_some();
            self.sun = None;
            self.world_sun = None;
            self.drop_node_suns();
            if swept_with_sky {
                // The grids' bins hold its scattered light: the world grid's sky alone
                // again at once, the nodes' by `refresh` (their inputs changed).
                self.sweep_world()?;
            }
            return Ok(());
        };
        sun.to_sun = lightgrid_core::light::check_sun(sun.to_sun, sun.irradiance)?;
        self.checked.clear();
        let Some(shown) = self.scattered_to() else {
            // A first sun: the world grid at once, the nodes within the budget.
            self.sun = Some(sun);
            self.drop_node_suns();
            if self.sun_with_sky().is_some() {
                self.sweep_world()?;
            }
            return self.sweep_world_sun();
        };
        self.sun = Some(sun);
        // The direct sun moves at once, first (on every core); the scattered sun
        // follows (the module `sun_move`).
        self.march_suns()?;
        if self.sun_with_sky().is_some() {
            // Every grid is swept again: the world grid's on a thread under a time
            // budget (its earlier light stays shown until a frame installs the new),
            // else at once.
            if self.sky_sun() == Some(sun) {
                self.sun_move = None;
                return Ok(());
            }
            if !self.move_sun_in_background(sun)? {
                self.sweep_world()?;
                return self.sweep_world_sun();
            }
            return Ok(());
        }
        if shown == sun.to_sun {
            // Back to the scattered sun shown (a move under way is dropped), or a new
            // irradiance.
            self.sun_move = None;
        } else if !self.move_sun_in_background(sun)? {
            self.sweep_world_sun()?;
        }
        Ok(())
    }

    /// The sun kept apart, if any ([`Hierarchy::set_sun`]).
    pub fn sun(&self) -> Option<SunLight> {
        self.sun
    }

    /// Multiplies the sky's light (RGB, finite and >= 0; 1 by default): its colour and
    /// intensity change with no sweep. Only with the sun kept apart is the sky's light
    /// alone in the bins; without, this scales all light.
    pub fn set_sky_scale(&mut self, scale: Vec3) -> Result<(), LodError> {
        if !scale.is_finite() || scale.min_element() < 0.0 {
            return Err(GridError::invalid("sky_scale", scale, "must be finite and >= 0").into());
        }
        if self.params.sun_with_sky && scale != Vec3::ONE {
            return Err(GridError::invalid(
                "sky_scale",
                scale,
                "must be 1 with HierarchyParams::sun_with_sky (the sky's bins hold the scattered sun)",
            )
            .into());
        }
        self.sky_scale = scale;
        Ok(())
    }

    /// The sky's multiplier ([`Hierarchy::set_sky_scale`]).
    pub fn sky_scale(&self) -> Vec3 {
        self.sky_scale
    }

    /// The parameters.
    pub fn params(&self) -> &HierarchyParams {
        &self.params
    }

    /// The world grid.
    pub fn world(&self) -> &LightGrid {
        &self.world
    }

    /// A ready node's light grid.
    pub fn node(&self, key: NodeKey) -> Option<&LightGrid> {
        self.nodes.get(&key).map(|n| &n.light)
    }

    /// Whether a ready node has objects above the ground (and so may get finer children).
    pub fn node_has_objects(&self, key: NodeKey) -> Option<bool> {
        self.nodes.get(&key).map(|n| n.material.has_objects)
    }

    /// The parent of a node (`None` at depth 1, whose parent is the world grid).
    pub fn parent_of(key: NodeKey) -> Option<NodeKey> {
        Self::parent(key)
    }

    /// Keys of the ready nodes, sorted ([`NodeKey`]'s order: by depth, then index);
    /// [`Hierarchy::layers`] follows the world grid with their grids in this order.
    pub fn ready_nodes(&self) -> Vec<NodeKey> {
        let mut v: Vec<NodeKey> = self.nodes.keys().copied().collect();
        v.sort();
        v
    }

    /// World `(x, z)` rectangle of a node.
    pub fn node_rect(&self, key: NodeKey) -> (Vec2, Vec2) {
        let s = self.params.node_size(key.depth);
        let lo = self.heightmap_lo + key.index.as_vec2() * s;
        (lo, lo + Vec2::splat(s))
    }

    fn node_at(&self, depth: u32, p: Vec2) -> NodeKey {
        let s = self.params.node_size(depth);
        NodeKey {
            depth,
            index: {
                let q = (p - self.heightmap_lo) / s;
                // (`floor` without a libm call a coordinate: the same integers.)
                IVec2::new(shadow::floor_i32(q.x), shadow::floor_i32(q.y))
            },
        }
    }

    fn distance(&self, key: NodeKey, cam: Vec3) -> f32 {
        let (lo, hi) = self.node_rect(key);
        let c = Vec2::new(cam.x, cam.z);
        (c - c.clamp(lo, hi)).length()
    }

    /// The nodes the camera wants, coarse first, nearest first within a depth.
    pub fn wanted(&self, cam: Vec3) -> Vec<NodeKey> {
        let mut out = Vec::new();
        for d in 1..=self.params.depths() {
            let s = self.params.node_size(d);
            let r = self.params.lod_factor * s;
            let c = Vec2::new(cam.x, cam.z);
            let lo = self.node_at(d, c - Vec2::splat(r)).index;
            let hi = self.node_at(d, c + Vec2::splat(r)).index;
            let mut level: Vec<(f32, NodeKey)> = Vec::new();
            for iz in lo.y..=hi.y {
                for ix in lo.x..=hi.x {
                    let key = NodeKey {
                        depth: d,
                        index: IVec2::new(ix, iz),
                    };
                    let (nlo, nhi) = self.node_rect(key);
                    // Inside the terrain, and within reach.
                    if nhi.cmple(self.heightmap_lo).any() || nlo.cmpge(self.heightmap_hi).any() {
                        continue;
                    }
                    let dist = self.distance(key, cam);
                    if dist <= r {
                        level.push((dist, key));
                    }
                }
            }
            level.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            out.extend(level.into_iter().map(|(_, k)| k));
        }
        out
    }

    fn parent(key: NodeKey) -> Option<NodeKey> {
        (key.depth > 1).then(|| NodeKey {
            depth: key.depth - 1,
            index: key.index.div_euclid(IVec2::splat(2)),
        })
    }

    /// The source's material over `desc`, every cell's depth of medium rounded
    /// ([`quantized_pass`]): what every grid of the hierarchy sweeps.
    fn compose(&self, desc: &GridDesc) -> Result<MaterialGrid, GridError> {
        Self::quantized(self.source.material(desc)?)
    }

    /// `m` with every cell's depth of medium rounded ([`depth::quantized`]).
    fn quantized(m: MaterialGrid) -> Result<MaterialGrid, GridError> {
        let d = *m.desc();
        MaterialGrid::new(d, depth::quantized(m.into_data()))
    }

    /// The node's material grid, `node_points` across and from below its lowest ground to
    /// two cells above its highest ground and one above its highest object, whichever is
    /// higher: tall where the forest is tall. Also whether it has objects above the
    /// ground.
    pub(crate) fn node_material(&self, key: NodeKey) -> Result<NodeMaterial, GridError> {
        let composed = self.compose_node(&self.node_desc(key)?)?;
        self.trimmed(composed)
    }

    /// The material of node `key` as a sun's caster holds it ([`casters`]): the source's
    /// [`MaterialSource::shadow_material`] (coarser where the source allows) over the
    /// node's grid alone (a march reads no apron), its levels as
    /// [`Hierarchy::node_material`] keeps them.
    pub(crate) fn caster_material(&self, key: NodeKey) -> Result<NodeMaterial, GridError> {
        let m = self.source.shadow_material(&self.node_desc(key)?)?;
        self.trimmed((Self::quantized(m)?, None, None))
    }

    /// `full` (and `wide`, its apron's widened grid) kept from the ground to two cells
    /// above the highest ground and one above the highest object ([`NodeMaterial`]).
    fn trimmed(&self, (full, wide, outer): apron::Composed) -> Result<NodeMaterial, GridError> {
        let d = *full.desc();
        let mut top_level = 0;
        // The highest level holding ground, and the highest holding an object (`None`:
        // bare ground).
        let mut top_ground = 0;
        let mut top_object: Option<u32> = None;
        for (i, c) in full.data().iter().enumerate() {
            if c.is_empty() {
                continue;
            }
            let q = d.coords(i).expect("index in range");
            let p = d.position(q);
            top_level = top_level.max(q.y);
            if p.y - d.h() > self.heights.height_at(p.x, p.z) {
                top_object = Some(top_object.map_or(q.y, |t| t.max(q.y)));
            } else {
                top_ground = top_ground.max(q.y);
            }
        }
        let has_objects = top_object.is_some();
        // Two empty levels above the ground, one above the highest object: the coarser
        // grid serves the air above. (Two above objects too cost the frame bench's
        // budget-held frames nodes and error: both RMSE 14.5 / 10.9 / 9.6 % at 10 / 30 /
        // 60° against 13.8 / 10.3 / 9.1 with one, the finest depth no worse. One above
        // bare ground too took the bench's edge path from 8.6 to 11.1 %.)
        let ny = (top_ground + 3)
            .max(top_object.map_or(0, |t| t + 2))
            .clamp(2, d.dims().y);
        // The composed column's top level empty: nothing above it (to `margin` above
        // the highest ground, where the search stops).
        let open_above = top_level + 1 < d.dims().y;
        Ok(NodeMaterial {
            grid: apron::lowest_levels(full, ny)?,
            widened: wide.map(|w| apron::lowest_levels(w, ny)).transpose()?,
            outer: outer.map(|w| apron::lowest_levels(w, ny)).transpose()?,
            has_objects,
            open_above,
        })
    }

    /// A point of the lattice every node grid of `depth` has its points on: they lie at
    /// `lattice(depth) + k × cell(depth)` for integer `k` (x, z: half a cell inside the
    /// quadtree's corner; y: from the world grid's bottom). A grid of the same spacing on
    /// this lattice (a full-resolution reference) has its points and cells where the
    /// nodes have theirs.
    pub fn lattice(&self, depth: u32) -> Vec3 {
        self.params
            .lattice_over(self.heights.origin, self.world_bottom, depth)
    }

    /// The node's tallest grid descriptor: `node_points` across, from its lowest ground
    /// to `margin` above its highest ground or to the world grid's highest material over
    /// its rectangle, whichever is higher (objects taller than `margin` are not cut
    /// off), at most `max_levels`. Its bottom level is
    /// the depth's last lattice level below the lowest ground in its rectangle
    /// ([`Heightmap::range_within`], exact): the ground's surface lies between two of
    /// its levels everywhere, and at most the bottom level lies wholly inside the
    /// ground (the levels below it would hold no light, and an opaque level costs a
    /// sweep more than an empty one).
    pub(crate) fn node_desc(&self, key: NodeKey) -> Result<GridDesc, GridError> {
        let (lo, hi) = self.node_rect(key);
        let h = self.params.cell(key.depth);
        let (ground_lo, ground_hi) = self.heights.range_within(lo, hi);
        // On the depth's lattice ([`Hierarchy::lattice`]): neighbours' levels line up,
        // and their voxels with them.
        let datum = self.lattice(key.depth).y;
        let bottom = datum + (((ground_lo - datum) / h).ceil() - 1.0) * h;
        // Trees taller than `margin` on the rectangle's highest ground: a column cut
        // below them left their tops to the world grid's 16 m cells, whose material
        // there also holds what lies below the cut (at depth 1 of the frame bench at 15°
        // the direct sun was 2.7 % RMSE off one sweep of its own cell, 0.0 with the
        // whole column). Before the world grid is composed (a bake's plan), its top:
        // no material lies above it.
        let material_top = match &self.world_material {
            Some(world) => {
                casters::material_top_over(world, lo, hi)
                    + casters::TOP_MARGIN * self.params.world_cell
            }
            None => {
                let w = self.world.desc();
                w.origin().y + (w.dims().y as f32 - 0.5) * w.h()
            }
        };
        let top = (ground_hi + self.params.margin.max(h)).max(material_top);
        let ny = (((top - bottom) / h).ceil() as u32 + 1).clamp(2, self.params.max_levels);
        GridDesc::new(
            Vec3::new(lo.x + 0.5 * h, bottom, lo.y + 0.5 * h),
            h,
            UVec3::new(self.params.node_points, ny, self.params.node_points),
        )
    }

    /// A frame's start ([`Hierarchy::update`], [`Hierarchy::refresh`]): the camera
    /// checked and kept, the clock started, a moved sun's sweep polled (installed if
    /// done), the frame's budget set; its stats so far.
    fn begin_frame(&mut self, camera: Vec3) -> Result<FrameStats, LodError> {
        if !camera.is_finite() {
            return Err(GridError::invalid("camera", camera, "must be finite").into());
        }
        self.frame_started = std::time::Instant::now();
        self.camera = Some(camera);
        let mut stats = FrameStats {
            sun_moved: self.poll_sun_move(false)?,
            ..FrameStats::default()
        };
        self.frame_budget = self.frame_budget_points();
        self.step_swept = 0;
        self.steps_timed = (0, 0.0);
        stats.budget_points = self.frame_budget;
        Ok(stats)
    }

    /// One frame: evict, then build wanted nodes within the budget: the camera's
    /// surroundings down to the finest depth and what their boundaries read first, then
    /// the rest, each coarse and near first (`order.rs`; a node swept before a coarser
    /// node its boundary reads is swept again once that one is built).
    ///
    /// For a moving camera, drawn every frame. To build everything a still camera wants
    /// before drawing, [`Hierarchy::settle`] sweeps fewer points.
    pub fn update(&mut self, camera: Vec3) -> Result<FrameStats, LodError> {
        self.frame(camera, true)
    }

    /// Frames until no wanted node is pending ([`FrameStats::pending`]) and no built
    /// node waits for its sun response ([`FrameStats::sun_pending`]), at most
    /// `max_frames`: what a renderer that draws only once the camera's grids are all
    /// built calls (a bake, a cut scene, a teleport behind a loading screen). Each frame
    /// is [`Hierarchy::update`]'s within the same budget, but builds every wanted node
    /// coarse and near first, so that no node is swept before a coarser node its
    /// boundary reads and none is swept twice. `each` sees every frame's stats (for
    /// progress); the last frame's are returned. The grids are those `update` frames
    /// settle on, bit for bit (`tests/order.rs`).
    ///
    /// ```no_run
    /// # fn demo(h: &mut lightgrid_terrain_lod::Hierarchy) -> Result<(), lightgrid_terrain_lod::LodError> {
    /// let eye = lightgrid_core::glam::Vec3::new(500.0, 320.0, 520.0);
    /// let (mut frames, mut swept) = (0, 0);
    /// let last = h.settle(eye, 400, |s| {
    ///     frames += 1;
    ///     swept += s.points_swept;
    /// })?;
    /// println!("{frames} frames, {swept} points; settled: {}", last.pending == 0);
    /// # Ok(()) }
    /// ```
    pub fn settle(
        &mut self,
        camera: Vec3,
        max_frames: u32,
        mut each: impl FnMut(&FrameStats),
    ) -> Result<FrameStats, LodError> {
        let mut last = None;
        for _ in 0..max_frames.max(1) {
            let s = self.frame(camera, false)?;
            each(&s);
            let done = s.pending == 0 && s.sun_pending == 0;
            last = Some(s);
            if done {
                break;
            }
        }
        Ok(last.expect("one frame at least"))
    }

    /// Ready nodes marked provisional ([`FrameStats::provisional`]).
    pub(crate) fn provisional_count(&self) -> u32 {
        self.nodes.values().filter(|n| n.provisional).count() as u32
    }

    /// One frame of [`Hierarchy::update`] (`near_first`) or [`Hierarchy::settle`].
    fn frame(&mut self, camera: Vec3, near_first: bool) -> Result<FrameStats, LodError> {
        let _frame = tracing::debug_span!("frame", camera = %camera).entered();
        let mut stats = self.begin_frame(camera)?;
        self.checked.clear();
        self.recomposed.clear();
        // Evict far nodes.
        let evict: Vec<NodeKey> = self
            .nodes
            .keys()
            .copied()
            .filter(|k| {
                self.distance(*k, camera)
                    > self.params.evict_factor * self.params.node_size(k.depth)
            })
            .collect();
        for k in evict {
            self.nodes.remove(&k);
            stats.evicted += 1;
        }
        // The finest depth's nodes and what they read first, then the rest
        // (`order.rs`); each a depth at a time, coarse to fine (`build`: the nodes of a
        // depth side by side).
        let wanted = self.wanted(camera);
        // Kept materials of nodes no longer wanted go.
        let wanted_set: order::Wanted = wanted.iter().copied().collect();
        self.wanted_now = wanted_set.clone();
        self.composed.retain(|k, _| wanted_set.contains(k));
        let [near, read, rest] = if near_first && !self.all_fit(&wanted) {
            self.build_order(&wanted, camera)
        } else {
            [Vec::new(), Vec::new(), wanted]
        };
        // Each depth's step composes the next step's materials beside its sweeps.
        let parts = [near, read, rest];
        let steps: Vec<(usize, &[NodeKey])> = parts
            .iter()
            .enumerate()
            .flat_map(|(i, part)| {
                part.chunk_by(|a, b| a.depth == b.depth)
                    .map(move |c| (i, c))
            })
            .collect();
        let mut step = 0;
        for i in 0..parts.len() {
            while let Some(&(part, depth)) = steps.get(step)
                && part == i
            {
                let next = steps.get(step + 1).map_or(&[][..], |s| s.1);
                // In waves where a node reads the nodes of its depth before it
                // (`neighbours.rs`; one wave otherwise), each wave's next the one after.
                let waves = neighbours::waves(depth, self.params.neighbour_halo);
                for (w, wave) in waves.iter().enumerate() {
                    let next = waves.get(w + 1).map_or(next, |n| &n[..]);
                    self.build_depth(wave, next, &wanted_set, &mut stats)?;
                }
                step += 1;
            }
            if i == 1 {
                // The nodes near the camera built before what their boundaries read.
                self.rebuild_provisional(camera, &wanted_set, &mut stats)?;
            }
        }
        stats.sun_pending = self.sun_pending();
        stats.provisional = self.provisional_count();
        self.casters.end_frame();
        stats.caster_bytes = self.casters.bytes();
        self.last_frame_swept = stats.points_swept > 0;
        self.warn_single_job(&stats);
        if let (p @ 1.., secs) = self.steps_timed
            && secs > 0.0
        {
            let now = p as f64 / secs;
            self.step_rate = Some(self.step_rate.map_or(now, |r| 0.5 * (r + now)));
        }
        if stats.points_swept > 0 {
            let secs = self.frame_started.elapsed().as_secs_f64().max(1e-6);
            let now = stats.points_swept as f64 / secs;
            self.rate = Some(self.rate.map_or(now, |r| 0.5 * (r + now)));
        }
        tracing::debug!(
            built = stats.built,
            sun_built = stats.sun_built,
            evicted = stats.evicted,
            pending = stats.pending,
            points_swept = stats.points_swept,
            "frame done"
        );
        self.drop_unread_bands();
        let depths = self.params.depths() as usize;
        stats.alive_per_depth = vec![0; depths + 1];
        stats.points_per_depth = vec![0; depths + 1];
        stats.alive_per_depth[0] = 1;
        stats.points_per_depth[0] = self.world.desc().point_count() as u64;
        for (k, n) in &self.nodes {
            stats.alive_per_depth[k.depth as usize] += 1;
            stats.points_per_depth[k.depth as usize] += n.light.desc().point_count() as u64
                + n.ring.as_ref().map_or(0, apron::Ring::points)
                + n.band.as_ref().map_or(0, apron::Band::points);
        }
        Ok(stats)
    }

    /// Ready nodes the frame's camera wants without a sun response for the current sun
    /// (0 without a sun).
    fn sun_pending(&self) -> u32 {
        if self.sun.is_none() {
            return 0;
        }
        (self.nodes.keys())
            .filter(|k| self.wanted_now.contains(*k) && !self.sun_current(**k))
            .count() as u32
    }

    /// The sweep options of a node: bins always on; one downward pass over bare ground
    /// when that skip is on.
    fn node_options(&self, has_objects: bool) -> SweepOptions {
        let mut o = self.params.sweep;
        // Asked of a sweeper that traces them alone.
        o.halo_paths &= self.sweeper.carries_halo_paths();
        // The grids keep the bins alone: average and dominant direction are read
        // from them.
        o.outputs = lightgrid_core::Outputs {
            bins: true,
            average: false,
            dominant: false,
            horizon: self.params.sweep.outputs.horizon,
        };
        if !has_objects && self.params.skip.up_pass_over_bare {
            o.max_passes = 1;
        }
        o
    }

    /// Whether the nearest ready ancestor of `key` (itself included) is bare ground.
    fn bare_ancestor(&self, key: NodeKey) -> bool {
        let mut k = Some(key);
        while let Some(key) = k {
            if let Some(n) = self.nodes.get(&key) {
                return !n.material.has_objects;
            }
            k = Self::parent(key);
        }
        false
    }
}
