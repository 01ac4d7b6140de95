//! `cargo xtask frame`: the hierarchy as a user runs it, frame by frame along a camera
//! path, timed by stage and measured against one full-resolution sweep of the region the
//! path sees (issue 43).
//!
//! **The world**: the shipped Jacksboro DEM (4 m a pixel, heights × 0.05) with a forest
//! of procedural broadleaf trees (0.5 m voxels) scattered over a 500 m square, under the
//! analytic clear sky ([`ClearSky::blue`]) with the sun kept apart
//! ([`Hierarchy::set_sun`]), at each sun elevation asked for (azimuth 40°).
//!
//! **The path**: the camera flies 20 m above the ground, `step` metres a frame along a
//! diagonal over the forest. Each frame runs [`Hierarchy::update`] (the library's
//! defaults but the node size; budget `node_points² × 96` points) and then samples the
//! light the renderer reads: *vertex points*, a 40 × 40 lattice of 1 m on the ground
//! around the camera (irradiance on the ground's normal, read with the normal bias), and
//! *volume points*, a 20 × 20 × 6 lattice of 2 m from 1 to 11 m above the ground
//! (irradiance on the six axes). Sky and sun are sampled apart (the sun's part with its
//! direct beam `E T max(0, n·s)`), and their sum is "both".
//!
//! **The reference**: one sweep at the finest cell size (1 m) of the region every frame's
//! points lie in, widened by `margin` metres (its open sides see the sky; the margin of
//! forest keeps that from the points) and toward the lowest sun as far as its rays
//! climb 16 m (beyond the region nothing shades them: with 40 m alone the coarse
//! depths' direct sun at 10° was 20–23 % RMSE off what one sweep of their own cell
//! gives over the wider region, 0.0 % with it), with the same sweeper options, read the
//! same way.
//! The error of a frame is the relative bias `Σ(h − r) / Σ r` and the relative RMSE
//! `√mean((h − r)²) / mean(r)` of the luminance over its points, for sky, sun and both,
//! and over the whole path per depth of the grid that serves the point. This is the
//! *nesting* error (the hierarchy against a single sweep of the same world). A coarse
//! depth's error against the 1 m sweep is mostly its cell size's; per depth it is also
//! measured against one sweep of the region at that depth's own cell, on its nodes'
//! lattice (`frame/reference.rs`): the nesting's own part. Those probes lie within some
//! 20 m of the camera, where the finest nodes serve once built, so a coarser depth
//! serves them only in the cold start (`frame/served.rs`); *far probes*, volume points
//! 24–192 m from the camera, measure each coarser depth where it serves along the path,
//! against its own-cell sweep, whose region reaches them (`frame/far.rs`; with 32-point
//! nodes at 15° and 40° the process then holds some 11 GB at its peak). At the last camera, once its
//! nodes are all built, the finest depth's probes are split by whether their read
//! falls within a node's points or across the seam between two nodes'
//! (`frame/seams.rs`).
//!
//! **The total error** ([`MonteCarlo`], `frame/mc.rs`): at the last camera, once its nodes are all built, the
//! hierarchy's read and the single sweep's against a Monte Carlo reference of the same
//! world at a subset of the probes (`--mc-probes`, `--mc-paths` paths each; backward
//! paths from each point, `lightgrid_measure::points`), for sky, sun and both: the
//! total error, the sweep's own, and the nesting error at the same probes.
//!
//! **Speed**: per frame the wall time of each stage ([`StageTimes`]: material, sky
//! boundaries, sky sweeps, sun boundaries, sun responses), the rest of `update`, the
//! sampling, points swept, and points per second of frame time beside points per
//! second of sweeping time. After the path the sun moves by 20° and the next frame is
//! timed: the world grid's new sun response, then the nodes re-lit within the budget.
//!
//! Writes `frame.txt`, `frame.json` and `frame.png` (frame time and error along the
//! path) into `--out` (default `target/bench`).

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use lightgrid_core::glam::{Vec2, Vec3};
use lightgrid_core::{BinLight, LightField, SeededRng, Sweeper};
use lightgrid_material_voxelizer::compose::{
    AreaComposer, ComposeParams, GroundBand, GroundColour, Heightmap, Instance, Terrain,
    load_heightmap_png,
};
use lightgrid_material_voxelizer::procedural::{TreeParams, tree};
use lightgrid_material_voxelizer::voxelize::{VoxelizeParams, voxelize};
use lightgrid_render::sampling::{SamplePoints, SampledLight, sample_points};
use lightgrid_sky::ClearSky;
use lightgrid_terrain_lod::{FrameStats, Hierarchy, HierarchyParams, StageTimes, SunLight};
use serde::Serialize;

mod bins;
mod far;
mod host;
mod kernel;
mod mc;
mod peaks;
mod places;
mod reference;
mod seams;
mod served;
mod sun_move;
mod text;
pub use far::Far;
pub use host::Interference;
use host::{Clocks, process_cpu_ms};
pub use mc::MonteCarlo;
pub use peaks::Peaks;
use reference::{Reference, reference_desc};
pub use seams::Seams;
pub use served::Served;
use text::run_line;
pub use text::text;

/// What `cargo xtask frame` runs.
#[derive(Debug, Clone)]
pub struct FrameConfig {
    /// Points across a node grid.
    pub node_points: u32,
    /// Frames along the path.
    pub frames: u32,
    /// Metres the camera moves per frame.
    pub step: f32,
    /// Sun elevations, degrees (one hierarchy each).
    pub elevations: Vec<f32>,
    /// Trees in the forest.
    pub trees: usize,
    /// Sweep with the GPU sweeper (the reference stays on the CPU).
    pub gpu: bool,
    /// No finer grids over bare ground (`LodSkips::bare_children`, off by default).
    pub bare_skip: bool,
    /// No sun's casters (`LodSkips::sun_casters`, off by default).
    pub no_casters: bool,
    /// The finest depth's scattered sun read from the coarser grids, not swept
    /// (`LodSkips::finest_scattered_sun`, off by default).
    pub skip_finest_sun: bool,
    /// Every grid sweeps the sun's first collisions with its sky
    /// (`HierarchyParams::sun_with_sky`, off by default): the sky and sun columns then
    /// hold the bins' light (sky and scattered sun) and the direct sun.
    pub sun_with_sky: bool,
    /// Keep no horizon halves (`HierarchyParams::sweep.outputs.horizon` off, in the
    /// hierarchy and the reference sweep): horizontal bins read as even.
    pub even: bool,
    /// A frame's time budget, milliseconds (`HierarchyParams::budget_ms`; `None`: the
    /// points budget alone).
    pub budget_ms: Option<f32>,
    /// Points a frame may sweep (`HierarchyParams::budget_points`; `None`: the node's
    /// points across with its apron squared times 96, two nodes of 48 levels).
    pub budget_points: Option<u64>,
    /// Side halos read the nodes of their depth before them
    /// (`HierarchyParams::neighbour_halo`).
    pub neighbour_halo: bool,
    /// The halo's paths traced through the nodes' edge cells
    /// (`SweepOptions::halo_paths` in `HierarchyParams::sweep`).
    pub halo_paths: bool,
    /// Halo points near bare ground read the coarser grid where they are, not clear of
    /// its ground band (`HierarchyParams::halo_ground_lift` off).
    pub no_ground_lift: bool,
    /// Where the nodes' sweeps take their halo's cells from
    /// (`HierarchyParams::halo_cells`).
    pub halo_cells: lightgrid_terrain_lod::HaloCells,
    /// Under a time budget a new node whose casters wait marches its direct sun
    /// at once (`HierarchyParams::march_before_casters`).
    pub march_before_casters: bool,
    /// The ground's partly covered cells composed with its colour as their albedo
    /// (`ComposeParams::band_albedo = GroundBand::Colour`, the composition before
    /// `GroundBand::Reflecting`, the default), in the hierarchy and in every reference.
    pub colour_band: bool,
    /// Most passes a sweep runs (`HierarchyParams::sweep.max_passes`, in the hierarchy
    /// and the reference sweep; `None`: the hierarchy's default, 4).
    pub passes: Option<u32>,
    /// Cells of a node's sky sweep beyond the node (`HierarchyParams::apron`; `None`:
    /// the hierarchy's default, 6, for nodes of 32 points or more, none for smaller
    /// ones: the 16-point nodes issue 43 times its speed with, which the default would
    /// cost 3.06 times the sky sweep's points).
    pub apron: Option<u32>,
    /// Cells of the apron the sun's responses are swept over too
    /// (`HierarchyParams::sun_apron`; `None`: the hierarchy's).
    pub sun_apron: Option<u32>,
    /// The sweeps' convergence tolerance (`HierarchyParams::sweep.tolerance`, in the
    /// hierarchy and the reference sweep; `None`: the hierarchy's default, 0.01).
    pub tolerance: Option<f32>,
    /// The flat source rule (`MediumEmission::Source`) instead of the hierarchy's
    /// default (`Profile`), in the hierarchy and the reference sweep.
    pub flat_source: bool,
    /// The sun's first two scatterings gathered by rays (`Gather::LOW_SUN`), in the
    /// hierarchy and the reference sweep.
    pub gather: bool,
    /// Where the camera flies.
    pub path: CameraPath,
    /// Metres of world around the sampled region in the reference sweep.
    pub margin: f32,
    /// Probes of the last camera measured against Monte Carlo (about; 0: none).
    pub mc_probes: usize,
    /// Monte Carlo paths per probe.
    pub mc_paths: u32,
    /// Output folder.
    pub out: PathBuf,
    /// The repository's `assets/`.
    pub assets: PathBuf,
}

impl FrameConfig {
    /// The defaults: 16-point nodes, 24 frames of 7.5 m, suns at 10, 30 and 60°.
    pub fn new(root: &Path) -> Self {
        Self {
            node_points: 16,
            frames: 24,
            step: 7.5,
            elevations: vec![10.0, 30.0, 60.0],
            trees: 4000,
            gpu: false,
            bare_skip: false,
            no_casters: false,
            skip_finest_sun: false,
            sun_with_sky: false,
            even: false,
            budget_ms: None,
            budget_points: None,
            neighbour_halo: false,
            halo_paths: false,
            no_ground_lift: false,
            halo_cells: lightgrid_terrain_lod::HierarchyParams::default().halo_cells,
            march_before_casters: false,
            colour_band: false,
            passes: None,
            apron: None,
            sun_apron: None,
            tolerance: None,
            flat_source: false,
            gather: false,
            path: CameraPath::Forest,
            margin: 40.0,
            mc_probes: 1000,
            mc_paths: 16384,
            out: root.join("target/bench"),
            assets: root.join("assets"),
        }
    }
}

/// The camera's path: `step` metres a frame, 20 m above the ground.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CameraPath {
    /// Diagonally inside the forest (from (520, 540) towards +x +z).
    Forest,
    /// Out of the forest over bare ground (from (840, 600) towards +x; the forest ends
    /// at x = 900): where the bare-ground skip acts.
    Edge,
}

impl std::str::FromStr for CameraPath {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "forest" => Ok(Self::Forest),
            "edge" => Ok(Self::Edge),
            _ => Err(format!("no path {s:?} (forest, edge)")),
        }
    }
}

/// Relative errors of one light component over a set of points.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct Error {
    /// `Σ(h − r) / Σ r`.
    pub bias: f64,
    /// `√mean((h − r)²) / mean(r)`.
    pub rmse: f64,
    /// Points.
    pub n: usize,
}

/// The errors of sky, sun and both.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct Errors {
    /// The sky alone.
    pub sky: Error,
    /// The sun alone (scattered and direct).
    pub sun: Error,
    /// Both.
    pub both: Error,
    /// The sun's direct part alone, `E T max(0, n·s)`: how well a node's transmittance
    /// agrees with the full-resolution march.
    pub direct: Error,
}

/// One frame.
#[derive(Debug, Clone, Serialize)]
pub struct FrameRow {
    /// Frame index.
    pub frame: u32,
    /// Milliseconds: material, sky boundary, sky sweep, sun boundary, sun sweep, the
    /// rest of `update`, sampling; and the whole frame.
    pub ms: StageMs,
    /// Points swept.
    pub points_swept: u64,
    /// Nodes built and sun responses computed.
    pub built: u32,
    /// Sun responses computed.
    pub sun_built: u32,
    /// Work left for later frames.
    pub pending: u32,
    /// Materials composed for the sun's march alone (the sun's casters).
    pub casters: u32,
    /// Bytes of the casters' materials held after the frame.
    pub caster_bytes: u64,
    /// Against the reference, over this frame's points.
    pub error: Errors,
    /// Against the reference, over this frame's points the finest depth serves (its
    /// nesting error: the finest depth's own-cell reference is the 1 m sweep).
    pub finest_error: Errors,
    /// Nodes provisional after the frame (swept before a coarser node their boundaries
    /// read, to be swept again: `FrameStats::provisional`).
    pub provisional: u32,
    /// What the machine took from the frame (steal, waits for a core).
    pub host: Interference,
}

/// Milliseconds per stage of a frame.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct StageMs {
    /// Node materials.
    pub material: f64,
    /// Sky boundaries and hashes.
    pub boundary: f64,
    /// Sky sweeps.
    pub sky_sweep: f64,
    /// Sun boundaries.
    pub sun_boundary: f64,
    /// Sun responses.
    pub sun_sweep: f64,
    /// The rest of `update`.
    pub other: f64,
    /// Sampling the vertex and volume points.
    pub sampling: f64,
    /// The whole frame.
    pub total: f64,
}

impl StageMs {
    fn of(t: &StageTimes, update: Duration, sampling: Duration) -> Self {
        let ms = |d: Duration| d.as_secs_f64() * 1e3;
        Self {
            material: ms(t.material),
            boundary: ms(t.boundary),
            sky_sweep: ms(t.sky_sweep),
            sun_boundary: ms(t.sun_boundary),
            sun_sweep: ms(t.sun_sweep),
            other: ms(update.saturating_sub(t.total())),
            sampling: ms(sampling),
            total: ms(update + sampling),
        }
    }
}

/// One sun elevation's run.
#[derive(Debug, Clone, Serialize)]
pub struct Run {
    /// Sun elevation, degrees.
    pub elevation: f32,
    /// Seconds to build the world grid and its sun response (at load).
    pub load_s: f64,
    /// The frames.
    pub frames: Vec<FrameRow>,
    /// Over every frame's points.
    pub error: Errors,
    /// Over every frame's points, by the depth of the grid serving the point (0: world).
    pub error_by_depth: Vec<Errors>,
    /// The same against one sweep of the region at the serving depth's own cell, on
    /// its nodes' lattice (the finest depth's is the 1 m sweep; none for the world
    /// grid): the nesting's own part of a coarse depth's error, its cell size's part
    /// left out.
    pub error_by_depth_own: Vec<Errors>,
    /// By depth, which frames its probes came from: a coarse depth serves the probes
    /// near the camera only while the finer nodes there are still to come, so its
    /// figures may be one frame's.
    pub served: Vec<Served>,
    /// The far probes (`frame/far.rs`): the coarser depths where they serve once the
    /// path is under way, against their own-cell sweeps.
    pub far: Far,
    /// By depth, the worst errors against that depth's own-cell reference relative to
    /// the local brightest value, shadow edges apart (`frame/peaks.rs`).
    pub peaks: Vec<Peaks>,
    /// [`Run::peaks`] over the path's second half alone (frames `frames / 2` on): the
    /// cold start's first frames, whose nodes near the camera are swept before coarser
    /// nodes their boundaries read and wait to be swept again, left out.
    pub peaks_second_half: Vec<Peaks>,
    /// The finest depth's probes over the path against the 1 m sweep: those whose node
    /// showed its own sun response, and those whose node's was still to come (they
    /// read a coarser grid's sun).
    pub finest_sun: [Errors; 2],
    /// The finest depth's probes over the path against the 1 m sweep by where they
    /// read: the way they face and their distance from their node's side.
    pub finest_places: places::Places,
    /// The finest depth's sky by the way it travels (`frame/bins.rs`).
    pub finest_bins: bins::BinGroups,
    /// Mean frame, milliseconds.
    pub mean_ms: f64,
    /// Slowest frame, milliseconds.
    pub max_ms: f64,
    /// Frames over twice the time budget (`None`: no time budget).
    pub over_budget: Option<usize>,
    /// Of those, the frames still over twice the budget with the hypervisor's steal
    /// taken out (its share of one core: the steal over all cores over their count;
    /// [`Interference`]).
    pub over_budget_own: Option<usize>,
    /// Steal over the path's frames, all cores (ms; `None` where not known).
    pub steal_ms: Option<f64>,
    /// Points swept per second of frame time (update and sampling).
    pub points_per_s_frame: f64,
    /// Points swept per second of sweeping time.
    pub points_per_s_sweeping: f64,
    /// The kernel alone on the path's own sweeps: the sweeps of the path's second half
    /// (sky sweeps, sun responses and marches, recorded in a second run of the path)
    /// made again one after another on one sweeper with recycled memory; the points the
    /// hierarchy counted for those frames per second of it (`frame/kernel.rs`).
    pub points_per_s_kernel: f64,
    /// The sun moved 20° up after the path: `Hierarchy::set_sun`'s time (ms), which
    /// re-marches every grid's transmittance (the direct sun) and sweeps the world
    /// grid's new scattered sun unless a time budget sends that to a thread.
    pub sun_move_world_ms: f64,
    /// Grids that show the new direct sun when `set_sun` returns (world grid and nodes).
    pub sun_move_marched: usize,
    /// `set_sun`'s CPU time, every thread of the process (ms, to the kernel's 10 ms
    /// ticks; Linux only: `None` elsewhere). Under a time budget the scattered-sun
    /// thread starts as `set_sun` returns.
    pub sun_move_cpu_ms: Option<f64>,
    /// Under a time budget: frames (at the budget's pace) that showed the old sun while
    /// the world grid's new response was swept on its thread.
    pub sun_move_wait_frames: u32,
    /// The longest of those frames (ms).
    pub sun_move_wait_max_ms: f64,
    /// From `set_sun` to the frame that found the new sun's world grid done (ms).
    pub sun_move_landed_ms: f64,
    /// The frame that installed the new sun (ms), and the sun responses it computed
    /// and left.
    pub sun_move_frame_ms: f64,
    /// Sun responses computed in that frame.
    pub sun_move_built: u32,
    /// Sun responses left for later frames.
    pub sun_move_pending: u32,
    /// From `set_sun` to the first frame with nothing left to sweep: every wanted
    /// node's sun response the new sun's (ms; frames at the budget's pace).
    pub sun_move_settled_ms: f64,
    /// Frames from `set_sun` until then.
    pub sun_move_settled_frames: u32,
    /// At the path's last camera (its nodes all built under the old sun first), against
    /// the reference swept for the new sun: the hierarchy's light as `set_sun` returns.
    pub sun_move_error_at_once: Errors,
    /// The same once every node's sun response is the new sun's.
    pub sun_move_error_settled: Errors,
    /// At the last camera once its nodes are all built (before the sun moves), the
    /// finest depth's probes against the 1 m sweep by where they read.
    pub seams: Seams,
    /// At the last camera (before the sun moves), against Monte Carlo (`None`: not
    /// asked for).
    pub monte_carlo: Option<MonteCarlo>,
}

/// Everything `cargo xtask frame` measured.
#[derive(Debug, Clone, Serialize)]
pub struct FrameReport {
    /// The sweeper: "cpu" or the GPU adapter.
    pub sweeper: String,
    /// Node points.
    pub node_points: u32,
    /// The camera path ("forest" or "edge").
    pub path: String,
    /// Whether the bare-ground skip was on.
    pub bare_skip: bool,
    /// Whether the sun's casters were skipped.
    pub no_casters: bool,
    /// Whether the finest depth read the coarser grids' scattered sun.
    pub skip_finest_sun: bool,
    /// Whether every grid swept the sun's first collisions with its sky.
    pub sun_with_sky: bool,
    /// Whether the grids kept their horizon halves (and were read through them).
    pub horizon: bool,
    /// Whether side halos read the nodes of their depth before them
    /// (`HierarchyParams::neighbour_halo`).
    pub neighbour_halo: bool,
    /// Whether the nodes' sweeps traced the halo's paths (`SweepOptions::halo_paths`).
    pub halo_paths: bool,
    /// Whether halo points near bare ground read the coarser grid clear of its ground
    /// band (`HierarchyParams::halo_ground_lift`).
    pub ground_lift: bool,
    /// Where the nodes' sweeps took their halo's cells from
    /// (`HierarchyParams::halo_cells`: off, coarser or composed).
    pub halo_cells: String,
    /// Whether a new node whose casters waited marched its direct sun at once
    /// (`HierarchyParams::march_before_casters`).
    pub march_before_casters: bool,
    /// Whether the ground's partly covered cells took its colour as their albedo
    /// (`GroundBand::Colour`; else `GroundBand::Reflecting`, the default).
    pub colour_band: bool,
    /// The frames' time budget, milliseconds (`None`: none).
    pub budget_ms: Option<f32>,
    /// The frames' point budget (`HierarchyParams::budget_points`).
    pub budget_points: u64,
    /// Cells of a node's sky sweep beyond the node (`HierarchyParams::apron`).
    pub apron: u32,
    /// Cells of it the sun's responses are swept over too (`HierarchyParams::sun_apron`).
    pub sun_apron: u32,
    /// Most passes a sweep ran (the hierarchy's and the reference's).
    pub passes: u32,
    /// The sweeps' convergence tolerance.
    pub tolerance: f32,
    /// The medium rule of every sweep (the hierarchy's and the reference's).
    pub medium: String,
    /// Whether every sweep gathers the sun's first scatterings by rays.
    pub gather: bool,
    /// The reference region, points.
    pub reference_points: u64,
    /// Seconds of the reference's sky sweep.
    pub reference_sky_s: f64,
    /// One run per elevation.
    pub runs: Vec<Run>,
}

/// The world: heightmap, trees, and a composer for it.
struct World {
    hm: Heightmap,
    terrain: Terrain,
    tree: lightgrid_core::MaterialGrid,
    instances: Vec<Instance>,
    compose: ComposeParams,
}

impl World {
    fn load(cfg: &FrameConfig) -> Result<Self> {
        let png = cfg.assets.join("dem-jacksboro/jacksboro_fault_dem_u16.png");
        let hm = load_heightmap_png(&png, Vec2::ZERO, 4.0, 0.05, 0.0)
            .with_context(|| format!("reading {}", png.display()))?;
        let (tree, _) = voxelize(
            &tree(&TreeParams::broadleaf(3))?,
            &VoxelizeParams::standard(0.5),
            &|_, _| {},
        )?;
        let mut rng = SeededRng::new(7);
        let instances = (0..cfg.trees)
            .map(|_| {
                let (x, z) = (rng.range(400.0, 900.0), rng.range(400.0, 900.0));
                Instance {
                    model: 0,
                    position: Vec3::new(x, hm.height_at(x, z) - 0.3, z),
                    rotation: lightgrid_core::glam::Quat::from_rotation_y(
                        rng.range(0.0, std::f32::consts::TAU),
                    ),
                    scale: rng.range(0.8, 1.3),
                }
            })
            .collect();
        let terrain = Terrain {
            heightmap: hm.clone(),
            colour: GroundColour::Uniform(Vec3::new(0.25, 0.22, 0.18)),
        };
        let band_albedo = if cfg.colour_band {
            GroundBand::Colour
        } else {
            GroundBand::Reflecting
        };
        Ok(Self {
            hm,
            terrain,
            tree,
            instances,
            compose: ComposeParams {
                band_albedo,
                ..ComposeParams::default()
            },
        })
    }

    fn composer(&self) -> Result<AreaComposer> {
        Ok(AreaComposer::new(
            vec![self.tree.clone()],
            &self.instances,
            Some(self.terrain.clone()),
            self.compose,
        )?)
    }

    fn camera(&self, cfg: &FrameConfig, f: u32) -> Vec3 {
        let (start, dir) = match cfg.path {
            CameraPath::Forest => (Vec2::new(520.0, 540.0), Vec2::new(0.8, 0.6)),
            CameraPath::Edge => (Vec2::new(840.0, 600.0), Vec2::X),
        };
        let Vec2 { x, y: z } = start + dir * cfg.step * f as f32;
        Vec3::new(x, self.hm.height_at(x, z) + 20.0, z)
    }

    /// The ground's unit normal at `(x, z)` (central differences over 1 m).
    fn normal(&self, x: f32, z: f32) -> Vec3 {
        let h = |x: f32, z: f32| self.hm.height_at(x, z);
        Vec3::new(
            h(x - 0.5, z) - h(x + 0.5, z),
            1.0,
            h(x, z - 0.5) - h(x, z + 0.5),
        )
        .normalize()
    }
}

/// A point the renderer samples and the normal it reads the light on.
#[derive(Debug, Clone, Copy)]
struct Probe {
    p: Vec3,
    n: Vec3,
    /// A terrain vertex (else a volume point).
    vertex: bool,
}

/// Terrain vertices a side of [`probes`]' lattice, 1 m apart.
const VERTEX_SIDE: usize = 40;
/// Volume points a side of [`probes`]' lattice, 2 m apart, at each of
/// [`VOLUME_LEVELS`] heights, six axes each.
const VOLUME_SIDE: usize = 20;
/// Heights of the volume points: 1 to 11 m above the ground, 2 m apart.
const VOLUME_LEVELS: usize = 6;
/// Metres from the camera along x and z within which [`probes`] lie (the vertices'
/// 19.5, the volume points' 19).
const NEAR_REACH: f32 = 20.0;

/// The vertex and volume points around camera `cam`: `VERTEX_SIDE²` vertices (x
/// major), then `VOLUME_SIDE² × VOLUME_LEVELS` volume points (x major, then z, then
/// height) on six axes each.
fn probes(world: &World, cam: Vec3) -> Vec<Probe> {
    let mut out = Vec::with_capacity(
        VERTEX_SIDE * VERTEX_SIDE + VOLUME_SIDE * VOLUME_SIDE * VOLUME_LEVELS * 6,
    );
    for i in 0..VERTEX_SIDE {
        for k in 0..VERTEX_SIDE {
            let (x, z) = (cam.x - 19.5 + i as f32, cam.z - 19.5 + k as f32);
            let n = world.normal(x, z);
            out.push(Probe {
                p: Vec3::new(x, world.hm.height_at(x, z), z),
                n,
                vertex: true,
            });
        }
    }
    let axes = [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z];
    for i in 0..VOLUME_SIDE {
        for k in 0..VOLUME_SIDE {
            let (x, z) = (cam.x - 19.0 + 2.0 * i as f32, cam.z - 19.0 + 2.0 * k as f32);
            let g = world.hm.height_at(x, z);
            for j in 0..VOLUME_LEVELS {
                let p = Vec3::new(x, g + 1.0 + 2.0 * j as f32, z);
                out.extend(axes.iter().map(|&n| Probe {
                    p,
                    n,
                    vertex: false,
                }));
            }
        }
    }
    out
}

/// The luminance of a probe's light in parts.
#[derive(Debug, Clone, Copy, Default)]
struct Parts {
    /// The sky alone.
    sky: f32,
    /// The sun alone, scattered and direct.
    sun: f32,
    /// The sun's direct part.
    direct: f32,
}

impl Parts {
    /// From one read with the sky and the sun swept together
    /// ([`FrameConfig::sun_with_sky`]): `sky` the bins' light (sky and scattered sun),
    /// `sun` the direct sun alone; their sum is all the light, as the split's.
    fn together(lit: &SampledLight, p: &Probe, to_sun: Vec3) -> Self {
        let direct = lightgrid_core::light::luminance(SUN_E * (lit.sun * p.n.dot(to_sun).max(0.0)));
        Self {
            sky: shaded(lit, p, Vec3::ZERO, to_sun),
            sun: direct,
            direct,
        }
    }

    /// From a read with the sun off (`sky`) and one with the sky off (`sun`).
    fn of(sky: &SampledLight, sun: &SampledLight, p: &Probe, to_sun: Vec3) -> Self {
        Self {
            sky: shaded(sky, p, Vec3::ZERO, to_sun),
            sun: shaded(sun, p, SUN_E, to_sun),
            direct: lightgrid_core::light::luminance(SUN_E * (sun.sun * p.n.dot(to_sun).max(0.0))),
        }
    }
}

/// Sky radiance scale and sun irradiance of the runs.
const SUN_E: Vec3 = Vec3::new(3.0, 2.9, 2.7);

pub(super) fn sun_dir(elevation_deg: f32) -> Vec3 {
    let s = lightgrid_sky::Sun::at(elevation_deg.to_radians(), 40f32.to_radians(), SUN_E);
    s.direction
}

fn sky_bins(to_sun: Vec3) -> Result<BinLight> {
    Ok(ClearSky::blue(to_sun).bins()?.top)
}

/// The process's one GPU device, with `--gpu`.
type Gpu = Option<std::sync::Arc<lightgrid_sweep_gpu::GpuContext>>;

/// A sweeper on the CPU, or on the process's GPU device.
fn new_sweeper(gpu: &Gpu) -> Box<dyn Sweeper + Send + Sync> {
    match gpu {
        Some(c) => Box::new(lightgrid_sweep_gpu::GpuSweeper::with_context(c.clone())),
        None => Box::new(lightgrid_sweep_cpu::CpuSweeper::new()),
    }
}

/// Accumulates the luminance pairs of one component.
#[derive(Default, Clone)]
struct Acc {
    d: f64,
    d2: f64,
    r: f64,
    n: usize,
}

impl Acc {
    fn add(&mut self, h: f32, r: f32) {
        let (h, r) = (h as f64, r as f64);
        self.d += h - r;
        self.d2 += (h - r) * (h - r);
        self.r += r;
        self.n += 1;
    }
    fn error(&self) -> Error {
        if self.n == 0 || self.r <= 0.0 {
            return Error::default();
        }
        let mean = self.r / self.n as f64;
        Error {
            bias: self.d / self.r,
            rmse: (self.d2 / self.n as f64).sqrt() / mean,
            n: self.n,
        }
    }
}

/// Sky, sun and both accumulators.
#[derive(Default, Clone)]
struct Acc3([Acc; 4]);

impl Acc3 {
    fn add(&mut self, h: Parts, r: Parts) {
        self.0[0].add(h.sky, r.sky);
        self.0[1].add(h.sun, r.sun);
        self.0[2].add(h.sky + h.sun, r.sky + r.sun);
        self.0[3].add(h.direct, r.direct);
    }
    fn errors(&self) -> Errors {
        Errors {
            sky: self.0[0].error(),
            sun: self.0[1].error(),
            both: self.0[2].error(),
            direct: self.0[3].error(),
        }
    }
}

/// A path's errors: over all points and by the depth serving them, against the 1 m
/// sweep, and by depth against the sweep at that depth's own cell.
#[derive(Default)]
struct Tally {
    all: Acc3,
    by_depth: Vec<Acc3>,
    by_depth_own: Vec<Acc3>,
    /// By depth, the probes it served in each frame.
    served: Vec<Vec<u64>>,
    /// The far probes ([`far`]).
    far: far::FarTally,
    /// The finest depth's probes against the 1 m sweep: those whose node shows its own
    /// sun response, and those whose node's is still to come (a coarser grid's read).
    finest_sun: [Acc3; 2],
    /// The finest depth's probes by where they read ([`places`]).
    finest_places: places::PlaceTally,
    /// By depth, the worst errors against the local brightest value ([`peaks`]).
    peaks: peaks::PeakTally,
    /// The same over the path's second half ([`Run::peaks_second_half`]).
    peaks_second_half: peaks::PeakTally,
    /// The finest depth's volume points' sky by bins (`frame/bins.rs`).
    finest_bins: bins::BinTally,
}

/// The renderer's read of `field` at the probes: `lightgrid_render`'s sampler
/// (irradiance from its table on the probe's normal, read with the normal bias, and the
/// sun's transmittance).
fn read<F: LightField + Sync + ?Sized>(field: &F, probes: &[Probe]) -> Result<Vec<SampledLight>> {
    let positions: Vec<Vec3> = probes.iter().map(|p| p.p).collect();
    let normals: Vec<Vec3> = probes.iter().map(|p| p.n).collect();
    Ok(sample_points(
        field,
        SamplePoints {
            positions: &positions,
            normals: Some(&normals),
        },
    )?)
}

/// The luminance a renderer shades from a read: the bins' irradiance plus the direct
/// sun `E T max(0, n·s)`.
fn shaded(s: &SampledLight, p: &Probe, e: Vec3, to_sun: Vec3) -> f32 {
    lightgrid_core::light::luminance(s.light + e * (s.sun * p.n.dot(to_sun).max(0.0)))
}

/// The hierarchy's sky and sun luminance at every probe (the sky's scale toggled:
/// nothing is swept or marched), restored at the end. The sun's irradiance is
/// [`SUN_E`].
fn sample_parts(h: &mut Hierarchy, probes: &[Probe], to_sun: Vec3) -> Result<Vec<Parts>> {
    if h.params().sun_with_sky {
        // The bins hold sky and scattered sun together: read once, apart only from the
        // direct sun (toggling the irradiance would make every grid stale).
        let lit = read(h, probes)?;
        return Ok(probes
            .iter()
            .zip(&lit)
            .map(|(p, s)| Parts::together(s, p, to_sun))
            .collect());
    }
    // The sky's scale toggled alone: `set_sun` (an irradiance of 0, then back) would
    // also march the grids a moved sun left for the frames, outside their time.
    debug_assert_eq!(h.sun().map(|s| s.irradiance), Some(SUN_E));
    let lit = read(h, probes)?;
    h.set_sky_scale(Vec3::ZERO)?;
    let sun = read(h, probes)?;
    h.set_sky_scale(Vec3::ONE)?;
    Ok(probes
        .iter()
        .zip(lit.iter().zip(&sun))
        .map(|(p, (l, s))| {
            let sky = SampledLight {
                light: l.light - s.light,
                ..*l
            };
            Parts::of(&sky, s, p, to_sun)
        })
        .collect())
}

/// The renderer's read of every probe with sky and sun on (what the sampling stage
/// times), shaded.
fn sample_all(h: &Hierarchy, probes: &[Probe], to_sun: Vec3) -> Result<f64> {
    let lit = read(h, probes)?;
    Ok(probes
        .iter()
        .zip(&lit)
        .map(|(p, s)| shaded(s, p, SUN_E, to_sun) as f64)
        .sum())
}

/// Frame `f`'s far probes around `cam` ([`far`]) read and tallied against each coarser
/// depth's own-cell sweep.
fn far_probes(
    h: &mut Hierarchy,
    world: &World,
    (f, cam, to_sun): (u32, Vec3, Vec3),
    refs: &Refs,
    tally: &mut far::FarTally,
) -> Result<()> {
    let probes = far::probes(world, cam);
    let parts = sample_parts(h, &probes, to_sun)?;
    let own = refs
        .coarse
        .iter()
        .map(|r| r.sky_and_sun(&probes))
        .collect::<Result<Vec<_>>>()?;
    let depths: Vec<usize> = probes.iter().map(|p| depth_at(h, p.p)).collect();
    // None for the world grid and the finest depth (the 1 m sweep stops short).
    let own_refs: Vec<Option<&[Parts]>> = (0..=h.params().depths() as usize)
        .map(|d| d.checked_sub(1).and_then(|k| own.get(k)).map(|v| &v[..]))
        .collect();
    tally.add(f, &depths, &parts, &own_refs);
    Ok(())
}

/// Depth of the grid serving `p` (0: the world grid).
fn depth_at(h: &Hierarchy, p: Vec3) -> usize {
    let cell = h.grid_at(p).desc().h();
    (h.params().world_cell / cell).log2().round().max(0.0) as usize
}

fn hierarchy_params(cfg: &FrameConfig) -> HierarchyParams {
    let mut p = HierarchyParams {
        node_points: cfg.node_points,
        finest_cell: 1.0,
        ..Default::default()
    };
    p.skip.bare_children = cfg.bare_skip;
    p.skip.sun_casters = cfg.no_casters;
    p.skip.finest_scattered_sun = cfg.skip_finest_sun;
    p.sun_with_sky = cfg.sun_with_sky;
    p.sweep.outputs.horizon = !cfg.even;
    p.budget_ms = cfg.budget_ms;
    p.neighbour_halo = cfg.neighbour_halo;
    p.sweep.halo_paths = cfg.halo_paths;
    p.halo_ground_lift = !cfg.no_ground_lift;
    p.halo_cells = cfg.halo_cells;
    p.march_before_casters = cfg.march_before_casters;
    if let Some(n) = cfg.passes {
        p.sweep.max_passes = n;
    }
    p.apron = match cfg.apron {
        Some(a) => a,
        None if cfg.node_points < 32 => 0,
        None => p.apron,
    };
    if let Some(k) = cfg.sun_apron {
        p.sun_apron = k;
    }
    // Two of the largest nodes a frame with their aprons (the library's default budget).
    p.budget_points = cfg.budget_points.unwrap_or(2 * p.largest_node());
    if let Some(t) = cfg.tolerance {
        p.sweep.tolerance = t;
    }
    if cfg.flat_source {
        p.sweep.medium = lightgrid_core::MediumEmission::Source;
    }
    if cfg.gather {
        p.sweep.gather = lightgrid_core::Gather::LOW_SUN;
    }
    p
}

/// The single sweeps of the region: at 1 m, and at each coarser node depth's cell.
struct Refs {
    /// At the finest cell (1 m): every figure's reference.
    full: Reference,
    /// At depth `d`'s cell for `d` in `1..depths`, in that order.
    coarse: Vec<Reference>,
}

/// One frame: update, sample (timed), and the error of the frame's probes.
fn frame(
    h: &mut Hierarchy,
    world: &World,
    cfg: &FrameConfig,
    f: u32,
    (to_sun, refs): (Vec3, &Refs),
    tally: &mut Tally,
) -> Result<FrameRow> {
    let cam = world.camera(cfg, f);
    let clocks = Clocks::now();
    let t = Instant::now();
    let stats: FrameStats = h.update(cam)?;
    let update = t.elapsed();
    let probes = probes(world, cam);
    let t = Instant::now();
    std::hint::black_box(sample_all(h, &probes, to_sun)?);
    let sampling = t.elapsed();
    let host = clocks.since(&Clocks::now());
    let parts = sample_parts(h, &probes, to_sun)?;
    let full = refs.full.sky_and_sun(&probes)?;
    let own = refs
        .coarse
        .iter()
        .map(|r| r.sky_and_sun(&probes))
        .collect::<Result<Vec<_>>>()?;
    // Which grids show a sun response of their own (a node's may follow its sky sweep).
    let own_sun: std::collections::HashSet<*const lightgrid_core::LightGrid> = h
        .layers()
        .iter()
        .filter(|l| l.sun.is_some())
        .map(|l| l.grid as *const _)
        .collect();
    let finest = h.params().depths() as usize;
    let depths: Vec<usize> = probes.iter().map(|p| depth_at(h, p.p)).collect();
    // Each depth's own-cell reference: none for the world grid, the 1 m sweep's at the
    // finest depth.
    let own_refs: Vec<Option<&[Parts]>> = (0..=finest)
        .map(|d| match d {
            0 => None,
            d if d > own.len() => Some(&full[..]),
            d => Some(&own[d - 1][..]),
        })
        .collect();
    far_probes(h, world, (f, cam, to_sun), refs, &mut tally.far)?;
    // The finest depth's volume points, each once (its six probes share it).
    let volume_points: Vec<Vec3> = (VERTEX_SIDE * VERTEX_SIDE..probes.len())
        .step_by(6)
        .filter(|&i| depths[i] == finest)
        .map(|i| probes[i].p)
        .collect();
    let coarser = finest.checked_sub(2).and_then(|k| refs.coarse.get(k));
    bins::tally(
        &mut tally.finest_bins,
        h,
        &volume_points,
        (&refs.full, coarser),
    )?;
    let side_of = |i: usize| places::nearest_side(h.grid_at(probes[i].p).desc(), probes[i].p);
    let at = peaks::Frame {
        frame: f,
        probes: &probes,
        side_of: &side_of,
    };
    tally.peaks.add(&at, &depths, &parts, &own_refs);
    if f >= cfg.frames / 2 {
        tally.peaks_second_half.add(&at, &depths, &parts, &own_refs);
    }
    let mut acc = Acc3::default();
    let mut finest_acc = Acc3::default();
    for (i, (p, (hp, r))) in probes
        .iter()
        .zip(parts.iter().copied().zip(full.iter().copied()))
        .enumerate()
    {
        acc.add(hp, r);
        tally.all.add(hp, r);
        let d = depths[i];
        if tally.by_depth.len() <= d {
            tally.by_depth.resize(d + 1, Acc3::default());
            tally.by_depth_own.resize(d + 1, Acc3::default());
        }
        tally.by_depth[d].add(hp, r);
        served::count(&mut tally.served, d, f);
        if d == finest {
            finest_acc.add(hp, r);
            let shown = own_sun.contains(&(h.grid_at(p.p) as *const _));
            tally.finest_sun[usize::from(!shown)].add(hp, r);
            tally.finest_places.add(h.grid_at(p.p).desc(), p, hp, r);
        }
        let own_r = own_refs.get(d).copied().flatten().map(|r| r[i]);
        if let Some(own_r) = own_r {
            tally.by_depth_own[d].add(hp, own_r);
        }
    }
    Ok(FrameRow {
        frame: f,
        ms: StageMs::of(&stats.times, update, sampling),
        points_swept: stats.points_swept,
        built: stats.built,
        sun_built: stats.sun_built,
        pending: stats.pending,
        casters: stats.casters,
        caster_bytes: stats.caster_bytes,
        error: acc.errors(),
        finest_error: finest_acc.errors(),
        provisional: stats.provisional,
        host,
    })
}

/// The path under a sun at `elevation` degrees.
fn run_elevation(
    world: &World,
    cfg: &FrameConfig,
    gpu: &Gpu,
    elevation: f32,
    refs: &mut Refs,
) -> Result<Run> {
    let params = hierarchy_params(cfg);
    let to_sun = sun_dir(elevation);
    for r in std::iter::once(&mut refs.full).chain(&mut refs.coarse) {
        r.sweep_sun(&params, to_sun)?;
    }
    let sweeper = new_sweeper(gpu);
    let t = Instant::now();
    let mut h = Hierarchy::new(
        &world.hm,
        Box::new(world.composer()?),
        sweeper,
        sky_bins(to_sun)?,
        params,
    )?;
    h.set_sun(Some(SunLight {
        to_sun,
        irradiance: SUN_E,
    }))?;
    let load_s = t.elapsed().as_secs_f64();
    let mut tally = Tally::default();
    let bar =
        indicatif::ProgressBar::new(cfg.frames as u64).with_message(format!("sun {elevation}°"));
    let mut frames = Vec::new();
    for f in 0..cfg.frames {
        frames.push(frame(&mut h, world, cfg, f, (to_sun, refs), &mut tally)?);
        bar.inc(1);
    }
    bar.finish_and_clear();
    let reference = &mut refs.full;
    // Time of day: the sun 20° higher (the sky kept: its glow moves little), once the
    // last camera's nodes are all built (the move's own effect, not the path's).
    let cam = world.camera(cfg, cfg.frames - 1);
    let pace = Duration::from_secs_f64(cfg.budget_ms.unwrap_or(0.0) as f64 / 1e3);
    settle(&mut h, cam, pace)?;
    let end_probes = probes(world, cam);
    let hier = sample_parts(&mut h, &end_probes, to_sun)?;
    let sweep = reference.sky_and_sun(&end_probes)?;
    let seams = seams::measure(&h, &end_probes, &hier, &sweep);
    let monte_carlo = if cfg.mc_probes > 0 {
        let which = mc::pick(&end_probes, cfg.mc_probes);
        Some(mc::measure(
            reference,
            &end_probes,
            &which,
            (&hier, &sweep),
            to_sun,
            cfg.mc_paths,
        )?)
    } else {
        None
    };
    let moved = sun_move::measure(
        &mut h,
        reference,
        &params,
        &end_probes,
        (elevation, cam, pace),
    )?;
    let points_per_s_kernel = kernel::rate(world, cfg, gpu, (to_sun, sky_bins(to_sun)?))?;
    let n = frames.len().max(1) as f64;
    let total_s: f64 = frames.iter().map(|r| r.ms.total).sum::<f64>() / 1e3;
    let sweep_s: f64 = frames
        .iter()
        .map(|r| r.ms.sky_sweep + r.ms.sun_sweep)
        .sum::<f64>()
        / 1e3;
    let points: u64 = frames.iter().map(|r| r.points_swept).sum();
    Ok(Run {
        elevation,
        load_s,
        mean_ms: total_s * 1e3 / n,
        max_ms: frames.iter().map(|r| r.ms.total).fold(0.0, f64::max),
        over_budget: cfg.budget_ms.map(|b| over_twice(&frames, b, None)),
        over_budget_own: cfg.budget_ms.map(|b| {
            let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
            over_twice(&frames, b, Some(cores))
        }),
        steal_ms: frames.iter().map(|r| r.host.steal_ms).sum(),
        points_per_s_frame: points as f64 / total_s.max(1e-9),
        points_per_s_sweeping: points as f64 / sweep_s.max(1e-9),
        points_per_s_kernel,
        frames,
        error: tally.all.errors(),
        error_by_depth: tally.by_depth.iter().map(Acc3::errors).collect(),
        error_by_depth_own: tally.by_depth_own.iter().map(Acc3::errors).collect(),
        served: tally.served.iter().map(|v| Served::of(v)).collect(),
        far: tally.far.far(),
        finest_sun: tally.finest_sun.each_ref().map(Acc3::errors),
        finest_places: tally.finest_places.places(),
        finest_bins: tally.finest_bins.groups(),
        peaks: tally.peaks.peaks(),
        peaks_second_half: tally.peaks_second_half.peaks(),
        sun_move_world_ms: moved.world_ms,
        sun_move_wait_frames: moved.wait_frames,
        sun_move_wait_max_ms: moved.wait_max_ms,
        sun_move_landed_ms: moved.landed_ms,
        sun_move_frame_ms: moved.frame_ms,
        sun_move_built: moved.built,
        sun_move_pending: moved.pending,
        sun_move_marched: moved.marched,
        sun_move_cpu_ms: moved.cpu_ms,
        sun_move_settled_ms: moved.settled_ms,
        sun_move_settled_frames: moved.settled_frames,
        sun_move_error_at_once: moved.error_at_once,
        sun_move_error_settled: moved.error_settled,
        seams,
        monte_carlo,
    })
}

/// How many `frames` took over twice `budget_ms`; with the machine's `cores`, counting
/// each frame's time less one core's share of the hypervisor's steal in it.
fn over_twice(frames: &[FrameRow], budget_ms: f32, cores: Option<usize>) -> usize {
    frames
        .iter()
        .filter(|r| {
            let stolen = cores.map_or(0.0, |c| r.host.steal_ms.unwrap_or(0.0) / c.max(1) as f64);
            r.ms.total - stolen > 2.0 * budget_ms as f64
        })
        .count()
}

/// Frames at `cam`, `pace` apart, until one finds nothing left to sweep (every wanted
/// node built, its sun response the current sun's; ready nodes the camera no longer
/// wants are left as they are). Returns the frames run; an error once
/// [`STALLED_FRAMES`] frames in a row did nothing while work was pending (a hierarchy
/// that waits for itself: the bench once ran on for hours so).
fn settle(h: &mut Hierarchy, cam: Vec3, pace: Duration) -> Result<u32> {
    let (mut frames, mut stalled) = (0u32, 0u32);
    loop {
        let f = Instant::now();
        let s = h.update(cam)?;
        frames += 1;
        if s.points_swept == 0 && s.pending == 0 && !h.sun_moving() {
            return Ok(frames);
        }
        let idle = s.points_swept == 0 && s.composed == 0 && s.casters == 0 && !h.sun_moving();
        stalled = if idle { stalled + 1 } else { 0 };
        anyhow::ensure!(
            stalled < STALLED_FRAMES,
            "the hierarchy made no progress in {stalled} frames at {cam} with work pending: {s:?}"
        );
        std::thread::sleep(pace.saturating_sub(f.elapsed()));
    }
}

/// Frames in a row that sweep and compose nothing, with work pending, before
/// [`settle`] gives up.
const STALLED_FRAMES: u32 = 100;

/// Runs the measurement and writes `frame.txt`, `frame.json` and `frame.png`.
pub fn run(cfg: &FrameConfig) -> Result<FrameReport> {
    anyhow::ensure!(cfg.frames >= 1, "--frames must be at least 1");
    anyhow::ensure!(
        cfg.step.is_finite() && (0.0..=100.0).contains(&cfg.step),
        "--step must be in 0..=100 m (got {})",
        cfg.step
    );
    anyhow::ensure!(
        cfg.margin.is_finite() && (0.0..=1000.0).contains(&cfg.margin),
        "--margin must be in 0..=1000 m (got {})",
        cfg.margin
    );
    for &e in &cfg.elevations {
        anyhow::ensure!(
            e.is_finite() && (1.0..=90.0).contains(&e),
            "--elevation must be in 1..=90 degrees (got {e})"
        );
    }
    std::fs::create_dir_all(&cfg.out).with_context(|| format!("creating {}", cfg.out.display()))?;
    let world = World::load(cfg)?;
    let params = hierarchy_params(cfg);
    let desc = reference_desc(&world, cfg, &params, params.depths())?;
    println!(
        "reference: one {} m sweep of {} x {} x {} points ({:.1} M)",
        desc.h(),
        desc.dims().x,
        desc.dims().y,
        desc.dims().z,
        desc.point_count() as f64 / 1e6
    );
    let gpu: Gpu = if cfg.gpu {
        Some(std::sync::Arc::new(lightgrid_sweep_gpu::GpuContext::new()?))
    } else {
        None
    };
    let sweeper = gpu.as_ref().map_or("cpu".into(), |c| {
        format!("gpu: {} ({:?})", c.info.name, c.info.device_type)
    });
    let mut runs = Vec::new();
    let mut reference_sky_s = 0.0;
    let mut refs = Refs {
        full: Reference::new(&world, desc)?,
        coarse: (1..params.depths())
            .map(|d| Reference::new(&world, reference_desc(&world, cfg, &params, d)?))
            .collect::<Result<_>>()?,
    };
    for &e in &cfg.elevations {
        // The clear sky's glow follows the sun: a reference sky per elevation.
        let sky = sky_bins(sun_dir(e))?;
        reference_sky_s = refs.full.sweep_sky(&params, sky)?;
        for r in &mut refs.coarse {
            r.sweep_sky(&params, sky)?;
        }
        let run = run_elevation(&world, cfg, &gpu, e, &mut refs)?;
        println!("{}", run_line(&run));
        runs.push(run);
    }
    let report = FrameReport {
        sweeper,
        node_points: cfg.node_points,
        path: format!("{:?}", cfg.path).to_lowercase(),
        bare_skip: cfg.bare_skip,
        no_casters: cfg.no_casters,
        skip_finest_sun: cfg.skip_finest_sun,
        sun_with_sky: cfg.sun_with_sky,
        horizon: !cfg.even,
        budget_ms: cfg.budget_ms,
        budget_points: hierarchy_params(cfg).budget_points,
        neighbour_halo: cfg.neighbour_halo,
        halo_paths: cfg.halo_paths,
        ground_lift: !cfg.no_ground_lift,
        halo_cells: format!("{:?}", cfg.halo_cells).to_lowercase(),
        march_before_casters: cfg.march_before_casters,
        colour_band: cfg.colour_band,
        apron: hierarchy_params(cfg).apron,
        sun_apron: hierarchy_params(cfg).sun_apron_cells(),
        passes: hierarchy_params(cfg).sweep.max_passes,
        tolerance: hierarchy_params(cfg).sweep.tolerance,
        medium: format!("{:?}", hierarchy_params(cfg).sweep.medium).to_lowercase(),
        gather: cfg.gather,
        reference_points: desc.point_count() as u64,
        reference_sky_s,
        runs,
    };
    write(cfg, &report)?;
    Ok(report)
}

/// Writes the three files, each whole or not at all.
fn write(cfg: &FrameConfig, report: &FrameReport) -> Result<()> {
    let put = |name: &str, bytes: &[u8]| -> Result<()> {
        let path = cfg.out.join(name);
        let tmp = cfg.out.join(format!(".{name}.partial"));
        std::fs::write(&tmp, bytes).with_context(|| format!("writing {}", tmp.display()))?;
        std::fs::rename(&tmp, &path).with_context(|| format!("writing {}", path.display()))
    };
    let txt = text(report);
    put("frame.txt", txt.as_bytes())?;
    put(
        "frame.json",
        serde_json::to_string_pretty(report)?.as_bytes(),
    )?;
    let png = cfg.out.join(".frame.partial.png");
    plot(report, &png)?;
    std::fs::rename(&png, cfg.out.join("frame.png")).context("writing frame.png")?;
    println!("wrote {}/frame.{{txt,json,png}}", cfg.out.display());
    Ok(())
}

/// `frame.png`: frame time (left) and the RMSE of sky and sun together (right) along
/// the path, one line per sun elevation.
fn plot(report: &FrameReport, path: &Path) -> Result<()> {
    use crate::bench::plot::{err, legend, line_with_points, register_font, save_rgb};
    use plotters::prelude::*;
    let text = register_font();
    let (w, h) = (1200u32, 420u32);
    let mut buf = vec![0u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(err)?;
        let panels = root.split_evenly((1, 2));
        let frames = report.runs.first().map_or(1, |r| r.frames.len()) as f64;
        type Series = (&'static str, fn(&FrameRow) -> f64);
        let series: [Series; 2] = [
            ("frame time (ms)", |r| r.ms.total),
            ("RMSE of sky + sun (%)", |r| r.error.both.rmse * 100.0),
        ];
        for ((label, value), area) in series.iter().zip(panels.iter()) {
            let top = report
                .runs
                .iter()
                .flat_map(|r| r.frames.iter().map(value))
                .fold(1e-3, f64::max);
            let mut chart = ChartBuilder::on(area);
            chart.margin(12);
            if text {
                chart
                    .caption(*label, ("sans-serif", 20))
                    .x_label_area_size(32)
                    .y_label_area_size(48);
            }
            let mut chart = chart
                .build_cartesian_2d(0.0..frames, 0.0..top * 1.1)
                .map_err(err)?;
            if text {
                chart
                    .configure_mesh()
                    .x_desc("frame")
                    .light_line_style(WHITE)
                    .label_style(("sans-serif", 13))
                    .draw()
                    .map_err(err)?;
            }
            for (i, r) in report.runs.iter().enumerate() {
                let colour = Palette99::pick(i).to_rgba();
                let pts: Vec<(f64, f64)> = r
                    .frames
                    .iter()
                    .map(|f| (f.frame as f64, value(f)))
                    .collect();
                let name = text.then(|| format!("sun {:.0}°", r.elevation));
                line_with_points(&mut chart, &pts, colour.stroke_width(2), name)?;
            }
            if text {
                legend(&mut chart)?;
            }
        }
        root.present().map_err(err)?;
    }
    save_rgb(&buf, (w, h), path)
}

#[cfg(test)]
impl FrameRow {
    /// A frame of `total` ms that swept `points_swept` points with `steal_ms` of steal.
    pub(crate) fn for_test(points_swept: u64, total: f64, steal_ms: Option<f64>) -> Self {
        FrameRow {
            frame: 0,
            ms: StageMs {
                total,
                ..StageMs::default()
            },
            points_swept,
            built: 0,
            sun_built: 0,
            pending: 0,
            casters: 0,
            caster_bytes: 0,
            error: Errors::default(),
            finest_error: Errors::default(),
            provisional: 0,
            host: Interference {
                steal_ms,
                ..Interference::default()
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lightgrid_core::GridDesc;

    /// A frame over twice the budget stays over with the steal taken out unless one
    /// core's share of the steal brings it under.
    #[test]
    fn frames_over_twice_the_budget_with_and_without_the_steal() {
        let row = |total, steal_ms| FrameRow::for_test(0, total, steal_ms);
        // Budget 30 ms: over at 60.
        let frames = [
            row(59.0, Some(0.0)),
            row(83.0, Some(50.0)), // 83 - 50 / 2 = 58: the host's
            row(83.0, Some(40.0)), // 83 - 20 = 63: its own
            row(70.0, None),       // steal unknown: its own
        ];
        assert_eq!(over_twice(&frames, 30.0, None), 3);
        assert_eq!(over_twice(&frames, 30.0, Some(2)), 2);
        assert_eq!(over_twice(&frames, 30.0, Some(1)), 1);
        assert_eq!(over_twice(&[], 30.0, Some(2)), 0);
    }

    #[test]
    fn errors_have_known_answers() {
        let mut a = Acc::default();
        // h = 1.1 r everywhere: bias +10 %, RMSE 10 % of the mean.
        for r in [1.0f32, 1.0, 1.0, 1.0] {
            a.add(1.1 * r, r);
        }
        let e = a.error();
        assert!(
            (e.bias - 0.1).abs() < 1e-6 && (e.rmse - 0.1).abs() < 1e-6,
            "{e:?}"
        );
        // +1 and -1 on a mean of 2: no bias, RMSE 50 %.
        let mut b = Acc::default();
        b.add(3.0, 2.0);
        b.add(1.0, 2.0);
        let e = b.error();
        assert!(
            e.bias.abs() < 1e-12 && (e.rmse - 0.5).abs() < 1e-12,
            "{e:?}"
        );
        assert_eq!(Acc::default().error().n, 0);
    }

    #[test]
    fn both_is_the_sum_of_sky_and_sun() {
        let mut a = Acc3::default();
        let parts = |sky, sun, direct| Parts { sky, sun, direct };
        a.add(parts(1.0, 3.0, 2.0), parts(1.0, 1.0, 0.5));
        let e = a.errors();
        assert!((e.sky.bias).abs() < 1e-12);
        assert!((e.sun.bias - 2.0).abs() < 1e-12);
        assert!((e.both.bias - 1.0).abs() < 1e-12);
        assert!((e.direct.bias - 3.0).abs() < 1e-12);
    }

    #[test]
    fn probes_lie_on_and_above_the_ground_around_the_camera() {
        let hm = Heightmap::from_fn(Vec2::ZERO, 1.0, 65, 65, |x, z| 0.1 * x + 0.05 * z).unwrap();
        let world = World {
            terrain: Terrain {
                heightmap: hm.clone(),
                colour: GroundColour::Uniform(Vec3::splat(0.3)),
            },
            hm,
            tree: lightgrid_core::MaterialGrid::new(
                GridDesc::new(Vec3::ZERO, 1.0, lightgrid_core::glam::UVec3::ONE).unwrap(),
                vec![lightgrid_core::Material::EMPTY],
            )
            .unwrap(),
            instances: vec![],
            compose: ComposeParams::default(),
        };
        let cam = Vec3::new(32.0, 10.0, 32.0);
        let p = probes(&world, cam);
        assert_eq!(p.len(), 40 * 40 + 20 * 20 * 6 * 6);
        for q in &p {
            assert!((q.n.length() - 1.0).abs() < 1e-5);
            assert!((q.p.x - cam.x).abs() <= NEAR_REACH && (q.p.z - cam.z).abs() <= NEAR_REACH);
            assert!(q.p.y >= world.hm.height_at(q.p.x, q.p.z) - 1e-4);
        }
        // The slope's normal leans against the gradient.
        let n = world.normal(32.0, 32.0);
        assert!(n.x < 0.0 && n.z < 0.0 && n.y > 0.9, "{n}");
    }
}
