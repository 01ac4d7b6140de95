//! The hierarchy's parameters ([`HierarchyParams`]) and the work it may skip
//! ([`LodSkips`]), with their checks and the layout they imply (cell sizes, node sizes,
//! the lattice of a depth's points).

use lightgrid_core::Heightmap;
use lightgrid_core::glam::{Vec2, Vec3};
use lightgrid_core::{GridError, SweepOptions};

use crate::MAX_DEPTHS;

/// Parameters of the hierarchy. Start from `default()` and change fields.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HierarchyParams {
    /// Cell size of the world grid, metres.
    pub world_cell: f32,
    /// Cell size of the finest node grids, metres (`world_cell / 2^k`).
    pub finest_cell: f32,
    /// Points across a node grid horizontally.
    pub node_points: u32,
    /// Cells a node's sky sweep reaches beyond the node on every side (its apron, at
    /// the node's own cell, composed from the scene; 0: none), its light kept only
    /// inside: the light entering the node's sides has crossed that much fine material
    /// instead of coming straight from a coarser grid's points. Each sky sweep sweeps
    /// `((node_points + 2 apron) / node_points)²` the points (and composes the apron's
    /// material), and the point budget counts them: at a given budget fewer fine nodes
    /// are built a frame. At most `node_points`. By default 6: with the default
    /// 32-point nodes, 1.89 times the sky sweep's points, which the default point
    /// budget ([`HierarchyParams::budget_points`]) counts in: two 48-level nodes a
    /// frame with their aprons. On the frame bench's forest (15° and 40°) every depth
    /// serving the camera then nests within 1.8 % RMSE and 0.6 % bias of one sweep at
    /// its own cell, for sky, sun and both; with 3 cells and a budget of two nodes
    /// without their aprons, the finest depth's sky 2.1 / 1.9 % and depth 2's sun
    /// 4.8 / 3.3 % (the repository's `docs/measurements.md`, "The sides, and an
    /// apron" and "An apron of 6 cells and a budget that counts it"). Smaller nodes pay more for the same cells (16-point
    /// nodes: 3.06 times); set it with `node_points`. With an apron, a sweeper that
    /// keeps its grids on a device (the GPU sweeper) has its widened grid's copy
    /// dropped: readers sample the node's grid kept on the CPU (set 0 to sample in
    /// place). With the sun kept apart, a node also keeps its transmittance marched one
    /// cell past its points, which a read beside a neighbour not built takes (its
    /// shadows where they fall there, not half a cell off), and the sun's casters are
    /// found one cell wider for those rays: on the frame bench's forest at 15°, 166
    /// casters over the path instead of 99 and a frame 6 % longer, for the finest
    /// depth's largest error of sky and sun over the local brightest 14.4 → 10.5 %.
    pub apron: u32,
    /// Cells of the apron ([`HierarchyParams::apron`]; a larger value is taken as the
    /// apron: [`HierarchyParams::sun_apron_cells`]) that a node's sun responses are
    /// swept and marched over too (default 3): the sun's light scattered beside the
    /// node then enters its sides having crossed fine material, as the sky's does.
    /// Each sun response sweeps `((node_points + 2 sun_apron) / node_points)²` the
    /// points, counted in the point budget. On the frame bench (`cargo xtask frame
    /// --node-points 32 --elevation 15 --elevation 40 --mc-probes 0 [--path edge]
    /// --sun-apron N`): with none, out of the forest depth 1's sun at 40°, whose probes
    /// lie beside a node's side, nests at −1.5 / 2.0 % (bias / RMSE), with 3 cells at
    /// −0.5 / 0.9 %; in the forest depth 2's sun at 15° 0.6 / 1.0 % with none, 0.2 /
    /// 0.4 % with 3 cells, but 1.0 / 2.2 % with 6 (its frame 0's nodes).
    pub sun_apron: u32,
    /// With the sun kept apart ([`Hierarchy::set_sun`](crate::Hierarchy::set_sun)),
    /// every grid sweeps the sun's first collisions with its sky in one sweep
    /// (`Sweeper::sweep_with_sun`) instead of a second sweep of its own: its bins hold
    /// sky and scattered sun together, its sun response the transmittance alone (the
    /// direct sun, marched exactly as ever; the scattered part zero). The light read
    /// is the same to the passes' convergence (the sweep is linear;
    /// `tests/sun_with_sky.rs`), for one sweep a node instead of two: on the frame bench
    /// at 30° a frame took 57 ms instead of 83 (`docs/measurements.md`, "The sun swept
    /// with the sky"). What it gives up: a new irradiance of the same sun, or a sky
    /// scale, sweeps every grid again where the split rescales them (so
    /// [`Hierarchy::set_sky_scale`](crate::Hierarchy::set_sky_scale) takes only 1), and
    /// the sky and scattered sun cannot be read apart. A moved sun sweeps every grid
    /// again either way: under a time budget ([`HierarchyParams::budget_ms`]) the
    /// world grid's sweep runs on a thread, as the split's scattered sun does (the
    /// grids' light stays until a frame installs it; nodes swept meanwhile take the sun
    /// the world grid's light holds), so `set_sun` only marches the direct sun (on the
    /// frame bench under a 30 ms budget, 18–20 ms instead of 94–104). Off by default;
    /// the viewer turns it on (its clear sky follows the sun: both are swept again
    /// whenever the sun moves).
    pub sun_with_sky: bool,
    /// A node's side halo reads the light of the nodes of its own depth before it in
    /// a fixed order where they are built (those at index `(x − 1, z)`, `(x, z − 1)`
    /// and `(x − 1, z − 1)`: lower `x + z`), sky and scattered sun, instead of the
    /// coarser grid's there; a node is provisional until those of them the camera
    /// wants are built and final, and a depth's nodes are swept in waves of equal
    /// `x + z` (`neighbours.rs`). The light crossing those sides then comes at the
    /// node's own cell. On the frame bench's forest (32-point nodes, an apron of 3
    /// cells, 15° and 40°) with a point budget of 393,216 (eight such nodes without
    /// their aprons), the sky's nesting at the finest depth went from 2.1 / 1.9 % RMSE
    /// to 1.8 / 1.7 % and the seams between its nodes from 2.8 to 2.2 %, every depth
    /// within 2 % (sky, sun and both within 1.8 % RMSE and 0.6 % bias, near the camera
    /// and 24–192 m from it); but the waves cost a third more frame time in a cold
    /// start, and under a budget of two nodes the camera's finest nodes wait for the
    /// nodes before them (the path's error against one 1 m sweep 5.9 → 10.6 % at
    /// 15°).
    /// Off by default: for a bake, or a budget that keeps up with the camera (the
    /// repository's `docs/measurements.md`, "The same depth's nodes in a fixed order").
    pub neighbour_halo: bool,
    /// A node's side halo reads the coarser grid at points near bare ground from a
    /// level clear of that grid's ground band ([`GROUND_LIFT`](crate::GROUND_LIFT)
    /// coarse cells above the ground): where a halo point lies less than that above
    /// the terrain (or less than a coarse cell below it) and the coarser grid's cells
    /// between its band and that height are empty in the four columns around the
    /// point, the point takes the coarser grid's light at that height. A composed
    /// ground is a band of partly covered cells, and the light a grid holds within a
    /// cell or so of it changes with the cell: 1 m above bare ground a 2 m grid's
    /// horizontal bins were 0.83 of a 1 m grid's (a 4 m grid's 0.59), while over bare
    /// ground the light of the lowest metres hardly changes with height. On the frame
    /// bench out of the forest (`cargo xtask frame --node-points 32 --elevation 15
    /// --elevation 40 --mc-probes 0 --path edge [--no-ground-lift]`) the sky of depths
    /// 3 and 4 then nests within 0.7 % bias (−1.2 / −1.1 % without), every depth's sky,
    /// sun and both within 0.7 % but depth 1's sun at 40° (−1.5 %, from −3.2 %, over
    /// its 174 probes), and the finest depth's upward horizontal light is 0.974 of the
    /// 1 m sweep's (0.937 without); in the forest, where the check finds the canopy,
    /// every figure stays within 0.2 % of what it was. Over flat bare ground the finest
    /// nodes' sideways light 1–2 m up nests within 2 % (4.5–6.5 % short without: the
    /// crate's `tests/ground_lift.rs`). What the check does not see: objects inside
    /// the band's own cell (low rocks and shrubs under a coarse cell's height). On by
    /// default (the repository's `docs/measurements.md`, "Halo points near bare
    /// ground").
    pub halo_ground_lift: bool,
    /// Where each node's sweeps take the material of their halo's cells from
    /// ([`SideBoundary::GivenHalves`](lightgrid_core::SideBoundary)'s `cells`; [`HaloCells`];
    /// `Coarser` by default). Given, a sweep carries each halo value (a coarser grid's
    /// light at the point, a cell's mean) through its cell and the halo's cells after
    /// it as it carries its own points' light ([`lightgrid_core::halo_carry`]), instead
    /// of taking it for the light leaving the point through empty space: taken as
    /// empty, a canopy's halo cells let the coarse grid's light into the node
    /// unstopped. On the frame bench `Coarser` takes the finest depth's largest sky
    /// error 9.9 / 8.4 → 8.5 / 7.1 % (15 / 40°) and depth 2's 3.1 / 2.5 → 2.6 / 2.0 %,
    /// the finest sky bias −0.4 → −0.7 %, for some 1.4 ms a fly-through frame
    /// (`docs/measurements.md`, "The halo's cells, carried").
    pub halo_cells: HaloCells,
    /// Height above a node's highest ground searched for objects (trees), metres, at
    /// least: where the world grid holds material higher over the node, the search
    /// reaches its top. The grid then ends one cell above the highest object found.
    pub margin: f32,
    /// A node is wanted while the camera is within `lod_factor × node size` of it.
    pub lod_factor: f32,
    /// A node is evicted once the camera is beyond `evict_factor × node size`.
    pub evict_factor: f32,
    /// Most points swept per frame (the world grid, built at load, is not counted; a
    /// node's sky sweep counts its apron's points). By default two 48-level nodes of
    /// the default size with their aprons, `(32 + 2 × 6)² × 48 × 2` = 185,856: set it
    /// with `node_points` and `apron`.
    pub budget_points: u64,
    /// A frame's time budget, milliseconds (`None`: only `budget_points` limits a
    /// frame). [`Hierarchy::update`] then takes a job while the jobs it has selected
    /// and this one, at the measured rate of the last frames' jobs (points a second
    /// from their selection to their end, sun casters composed and sweeps run), end
    /// within the time left, at most `budget_points` in all; in a process's first
    /// frame, at most the points 0.2 M/s gets through in the budget
    /// ([`FrameStats::budget_points`]). A frame's first node runs whatever it costs
    /// (so frames get on; a frame that spent over half its budget composing new
    /// nodes' materials leaves its first node to the next frame, which then builds it).
    /// It composes new nodes' materials a batch (one a thread) at a time and no further
    /// batch once it has spent half its budget; the rest waits for later frames.
    ///
    /// [`Hierarchy::update`]: crate::Hierarchy::update
    /// [`FrameStats::budget_points`]: crate::FrameStats::budget_points
    pub budget_ms: Option<f32>,
    /// Under a time budget, a new node whose sun job waits for the sun's casters (not
    /// all composed in the frame's time: [`LodSkips::sun_casters`]) still marches its direct
    /// sun in the frame it is built, through the casters held and coarser material
    /// beyond them, and marches it again once they are held; without it the node's
    /// points read the coarser grids' sun (2–8 m shadows) until its sun job runs. Off
    /// by default: on the frame bench at 10° under a 30 ms budget (`cargo xtask frame
    /// --budget-ms 30 --mc-probes 0 --elevation 10 [--march-before-casters]`, four
    /// interleaved pairs) every finest probe then reads its node's own direct sun
    /// (12–13 % RMSE against the 1 m sweep, against 35–36 % for the 73–94 % that read
    /// a coarser grid's without it) and the path's sun RMSE falls from 44–54 to 40–43 %,
    /// but the frame's rate against the kernel from 0.41–0.49 to 0.33–0.43 (the
    /// marches are time the frame does not sweep). Unused without `budget_ms`.
    pub march_before_casters: bool,
    /// Most nodes of a frame's next depth to build whose materials are composed while
    /// the depth before it sweeps (0: each depth composes its own first). Composition
    /// reads no light, so a depth's new materials need not wait for the coarser depths'
    /// sweeps: composed beside them, they fill the time a thread would wait on a depth's
    /// last node. The grids are the same bit for bit either way; a material composed
    /// for a node the budget then leaves for a later frame is kept for it. Not used
    /// under a time budget ([`budget_ms`](Self::budget_ms)), whose frames compose a
    /// batch at a time. Default 4 (16-point nodes along the fly-through: 4–11 % less
    /// time a frame, the medians of interleaved runs on two cores).
    pub compose_ahead: u32,
    /// Most levels of one node grid (taller spans are cut at the top).
    pub max_levels: u32,
    /// Sweep options for every grid (by default 4 passes at most, stopping once the
    /// light still waiting is under 1 % of the light entering: `tolerance` 0.01;
    /// `outputs.bins` is forced on: children read it;
    /// average and dominant are read from the bins and never kept). `outputs.horizon`
    /// (on by default) keeps every grid's horizon halves, sky and scattered sun, and the
    /// hierarchy's irradiance reads each horizontal bin in its two halves
    /// ([`lightgrid_core::LightField::horizon`]) instead of as even across the horizon:
    /// 8 more colours a point beside the 26 bins. `gather` (off by default, where
    /// `SweepOptions::multi_bounce` has `Gather::AUTO`) applies to the sun's first
    /// collisions in every grid (`SweepOptions::gather`): seconds a node, a bake's
    /// setting; a frame budget does not foresee it.
    pub sweep: SweepOptions,
    /// Work the hierarchy skips (see [`LodSkips`] for which are on by default).
    pub skip: LodSkips,
}

/// Work the hierarchy skips. Each is measured (time saved) and checked (light changed
/// within tolerance) by `cargo xtask bench`; the sun's casters, which need the sun kept
/// apart, by `cargo xtask frame --no-casters`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LodSkips {
    /// No finer grids under a node without objects (bare ground): its light is read
    /// from the coarser grid. Off by default: on a camera path out of the forest over
    /// bare ground (`cargo xtask frame --path edge [--bare-skip]`, 16-point nodes, sun
    /// at 30°) it cuts the frame time by a sixth (81 → 67 ms) but adds 3.4 points of
    /// RMSE against a full-resolution sweep (17.2 → 20.6 %) and 1.6 points of bias:
    /// more than the sweep's own error (1.6 % on the bench forest); `cargo xtask bench`
    /// sees 6.6 % RMS at the demo forest's edge.
    pub bare_children: bool,
    /// `refresh` does not sweep a node whose inputs (material, boundary, options) hash
    /// as before.
    pub unchanged: bool,
    /// Nodes without objects get a single downward pass: the upward pass over bare
    /// ground only carries ground bounce into empty air. Off by default: it changes
    /// the light by 1.3–1.6 % RMS at the demo forest's edge (`cargo xtask bench`).
    pub up_pass_over_bare: bool,
    /// No sun's casters: a node's direct sun is marched past the built nodes through
    /// the coarser grids' material, not through its own depth's nodes composed for the
    /// march (`casters.rs`). Off by default: on the frame bench at 10° (`cargo xtask
    /// frame --elevation 10 [--no-casters]`) the casters take the finest nodes' direct
    /// sun from 27.8 to 9.6 % RMSE against a full-resolution sweep (sky and sun 9.2 →
    /// 4.4 %) for about 12 nodes composed a frame (the same build, interleaved runs:
    /// 70–81 ms a frame skipping them, 82–94 with them); at 60° 4 a frame, 4.9 → 4.5 %.
    pub sun_casters: bool,
    /// The finest depth sweeps no scattered sun of its own: its nodes' scattered sun
    /// (bins and horizon halves) is the coarser grids' read at their points, their
    /// direct sun marched as always (exact). Off by default. On the frame bench's
    /// forest (`cargo xtask frame [--skip-finest-sun]`, 16-point nodes) a finest node's
    /// sun is then a march, not a march, a beam trace and a sweep: at 30° 67–70 ms a
    /// frame against 79–87 (three interleaved runs each), and under the same point
    /// budget 7 % more of the probes read the finest depth, so the whole path's error
    /// against the 1 m sweep falls by 0.1–0.3 points at suns of 10–60°. But the finest
    /// depth's sun nests worse against one 1 m sweep (RMSE 0.7–1.3 → 1.1–2.4 %, bias
    /// +0.2–0.7 → +0.5–1.4 %, the most at a high sun, where more of the sun is
    /// scattered), and surfaces facing down read 10–19 % more sun (+3–7 % swept): the
    /// coarser grids carry too much scattered sun upward near the ground
    /// (`docs/measurements.md`, "The finest depth's scattered sun").
    pub finest_scattered_sun: bool,
}

impl Default for LodSkips {
    fn default() -> Self {
        Self {
            bare_children: false,
            unchanged: true,
            up_pass_over_bare: false,
            sun_casters: false,
            finest_scattered_sun: false,
        }
    }
}

impl Default for HierarchyParams {
    fn default() -> Self {
        let mut sweep = SweepOptions::multi_bounce();
        sweep.max_passes = 4;
        // Passes stop once the light still waiting to be sent on is under 1 % of the
        // light that entered: in the frame bench's forest (green leaves of albedo up
        // to 0.3, ground 0.18-0.25) a node then stops after its downward and upward
        // passes, 15 % less time a frame with the error against Monte Carlo the same
        // to 0.1 points; brighter media run on to `max_passes` (`tests/passes.rs`).
        sweep.tolerance = 0.01;
        sweep.outputs.horizon = true;
        // A frame's sweeps do not gather, at any sun (seconds a node: a bake's setting).
        sweep.gather = lightgrid_core::Gather::OFF;
        // `sweep.halo_paths` stays off: on the frame bench it moved no finest-depth
        // figure and cost 5-15 % of a 32-point node's sweep with its apron, 30-60 % of
        // a 16-point one's (`docs/measurements.md`, "The halo's paths, traced").
        Self {
            world_cell: 16.0,
            finest_cell: 1.0,
            node_points: 32,
            apron: 6,
            sun_apron: 3,
            sun_with_sky: false,
            neighbour_halo: false,
            halo_ground_lift: true,
            halo_cells: HaloCells::Coarser,
            margin: 12.0,
            lod_factor: 1.0,
            evict_factor: 1.5,
            // Two 48-level nodes a frame with their aprons.
            budget_points: (32 + 2 * 6) * (32 + 2 * 6) * 48 * 2,
            budget_ms: None,
            march_before_casters: false,
            compose_ahead: 4,
            max_levels: 48,
            sweep,
            skip: LodSkips::default(),
        }
    }
}

impl HierarchyParams {
    /// Node depth count: levels below the world grid (`world_cell / finest_cell = 2^k`).
    pub fn depths(&self) -> u32 {
        (self.world_cell / self.finest_cell).log2().round() as u32
    }
    /// Cell size at node depth `d` (0 = world).
    pub fn cell(&self, d: u32) -> f32 {
        self.world_cell / (1u32 << d) as f32
    }
    /// [`Hierarchy::lattice`](crate::Hierarchy::lattice) of a hierarchy over `heightmap`
    /// with these parameters.
    pub fn lattice(&self, heightmap: &Heightmap, d: u32) -> Vec3 {
        self.lattice_over(heightmap.origin, self.world_bottom(heightmap), d)
    }
    /// [`HierarchyParams::lattice`] from the heightmap's origin and
    /// [`HierarchyParams::world_bottom`] (known: no pass over the heights).
    pub(crate) fn lattice_over(&self, origin: Vec2, world_bottom: f32, d: u32) -> Vec3 {
        let h = self.cell(d);
        let lo = origin + Vec2::splat(0.5 * h);
        Vec3::new(lo.x, world_bottom, lo.y)
    }
    /// The world grid's lowest level: two world cells below the lowest ground.
    pub(crate) fn world_bottom(&self, heightmap: &Heightmap) -> f32 {
        heightmap.range().0 - 2.0 * self.world_cell
    }
    /// Horizontal size of a node at depth `d >= 1`, metres.
    pub fn node_size(&self, d: u32) -> f32 {
        self.cell(d) * self.node_points as f32
    }

    /// Points of the largest node's sky sweep, `(node_points + 2 apron)² × max_levels`:
    /// [`HierarchyParams::budget_points`] must cover it, and `k` times it is a budget
    /// of `k` such nodes a frame (the default: 2).
    ///
    /// ```
    /// use lightgrid_terrain_lod::HierarchyParams;
    /// let p = HierarchyParams::default();
    /// assert_eq!(p.largest_node(), (32 + 2 * 6) * (32 + 2 * 6) * 48);
    /// assert_eq!(p.budget_points, 2 * p.largest_node());
    /// ```
    pub fn largest_node(&self) -> u64 {
        let across = (self.node_points + 2 * self.apron) as u64;
        across * across * self.max_levels as u64
    }

    /// Cells of the apron a node's sun responses are swept and marched over:
    /// [`HierarchyParams::sun_apron`], at most [`HierarchyParams::apron`].
    ///
    /// ```
    /// use lightgrid_terrain_lod::HierarchyParams;
    /// let p = HierarchyParams::default();
    /// assert_eq!((p.apron, p.sun_apron_cells()), (6, 3));
    /// let small = HierarchyParams { apron: 0, ..p };
    /// assert_eq!(small.sun_apron_cells(), 0);
    /// ```
    pub fn sun_apron_cells(&self) -> u32 {
        self.sun_apron.min(self.apron)
    }

    pub(crate) fn validate(&self) -> Result<(), GridError> {
        for (name, v) in [
            ("world_cell", self.world_cell),
            ("finest_cell", self.finest_cell),
            ("lod_factor", self.lod_factor),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(GridError::invalid(name, v, "must be finite and > 0"));
            }
        }
        let ratio = self.world_cell / self.finest_cell;
        if !(ratio >= 1.0 && (ratio.log2() - ratio.log2().round()).abs() < 1e-4) {
            return Err(GridError::invalid(
                "finest_cell",
                self.finest_cell,
                "world_cell / finest_cell must be a power of two",
            ));
        }
        if ratio > (1u32 << MAX_DEPTHS) as f32 {
            return Err(GridError::invalid(
                "finest_cell",
                self.finest_cell,
                "world_cell / finest_cell must be at most 2^16 (16 depths)",
            ));
        }
        if !(2..=1024).contains(&self.node_points) {
            return Err(GridError::invalid(
                "node_points",
                self.node_points,
                "must be in 2..=1024",
            ));
        }
        if self.apron > self.node_points {
            return Err(GridError::invalid(
                "apron",
                self.apron,
                "must be at most node_points",
            ));
        }
        if !(self.margin.is_finite() && self.margin >= 0.0) {
            return Err(GridError::invalid(
                "margin",
                self.margin,
                "must be finite and >= 0",
            ));
        }
        if !(self.evict_factor.is_finite() && self.evict_factor >= self.lod_factor) {
            return Err(GridError::invalid(
                "evict_factor",
                self.evict_factor,
                "must be finite and >= lod_factor",
            ));
        }
        if !(2..=4096).contains(&self.max_levels) {
            return Err(GridError::invalid(
                "max_levels",
                self.max_levels,
                "must be in 2..=4096",
            ));
        }
        if let Some(ms) = self.budget_ms
            && !(ms.is_finite() && ms > 0.0)
        {
            return Err(GridError::invalid(
                "budget_ms",
                ms,
                "must be finite and > 0 (or None)",
            ));
        }
        let largest = self.largest_node();
        if self.budget_points < largest {
            return Err(GridError::invalid(
                "budget_points",
                self.budget_points,
                "must cover the largest node ((node_points + 2 apron)² × max_levels), or it could never be built",
            ));
        }
        self.sweep.validate()
    }
}

/// Where a node's sweeps take the material of their halo's cells from
/// ([`HierarchyParams::halo_cells`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum HaloCells {
    /// Not given: the sweeps take them as empty space.
    Off,
    /// From the coarser depths' materials, already composed (each cell's from the
    /// finest coarser node built over it, else the world grid's): a coarser cell's
    /// pass-through taken to the finer cell's length. Near the ground (within one of
    /// the coarser grid's cells above the terrain, where its cell may hold the
    /// terrain's band) the node's own nearest cell at the same height above the
    /// terrain stands in, and a cell holding the terrain's surface is left empty: the
    /// carry's even source misplaces a surface's light, and where the ground lift
    /// applies ([`HierarchyParams::halo_ground_lift`]) the halo value there is light
    /// read clear of the band, not the cell's mean.
    #[default]
    Coarser,
    /// Composed at the node's own cell size: the node's material is composed
    /// [`HALO_WIDTH`](lightgrid_core::HALO_WIDTH) cells beyond its sky sweep's apron.
    Composed,
}
