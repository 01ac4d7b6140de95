//! Scene files (TOML): terrain, sky and sun, models, instances and scatter rules, grid
//! settings and views. The demo scene is `scenes/demo.toml`, embedded in the binary;
//! relative paths resolve against the scene file's folder.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use serde::Deserialize;

/// Largest scene file read: 16 MiB.
pub const MAX_SCENE_BYTES: u64 = 16 << 20;

/// The demo scene shipped with the viewer (the README's main command renders it).
pub const DEMO: &str = include_str!("../scenes/demo.toml");

/// A whole scene.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// Terrain.
    pub terrain: TerrainSpec,
    /// Sky.
    #[serde(default)]
    pub sky: SkySpec,
    /// Sun.
    #[serde(default)]
    pub sun: SunSpec,
    /// Light grid settings.
    #[serde(default)]
    pub grid: GridSpec,
    /// Models, by name.
    #[serde(default)]
    pub models: Vec<ModelSpec>,
    /// Single placed instances.
    #[serde(default)]
    pub instances: Vec<InstanceSpec>,
    /// Scatter rules.
    #[serde(default)]
    pub scatter: Vec<ScatterSpec>,
    /// Drawing settings.
    #[serde(default)]
    pub render: RenderSpec,
    /// Views to render.
    pub views: Vec<ViewSpec>,
    /// Many small dynamic lights (fireflies, lamps), scattered at random.
    pub dynamic_lights: Option<DynamicLightsSpec>,
    /// Relightable light probes (The Division's way) as a second light beside the
    /// sweep's: each view is also rendered lit by them (`<view>-probes.png`), with a
    /// debug view of probes and surfels (`<view>-probes-debug.png`).
    pub probes: Option<ProbesSpec>,
    /// Folder relative paths resolve against (not in the file).
    #[serde(skip)]
    pub base: PathBuf,
}

/// Terrain: a heightmap PNG or procedural hills, and the ground's colour.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TerrainSpec {
    /// A 16-bit (or 8-bit) grey PNG heightmap.
    pub heightmap: Option<PathBuf>,
    /// Procedural hills (fBm Perlin noise), when no heightmap is given.
    pub procedural: Option<ProceduralTerrain>,
    /// Metres between heightmap samples.
    #[serde(default = "default_spacing")]
    pub spacing: f32,
    /// Metres per heightmap unit (PNG: per grey level).
    #[serde(default = "one")]
    pub height_scale: f32,
    /// Linear RGB of the ground.
    #[serde(default = "default_ground")]
    pub ground_colour: [f32; 3],
    /// Optional ground texture (PNG, sRGB) stretched over the whole terrain.
    pub ground_texture: Option<PathBuf>,
}

/// Procedural hills.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProceduralTerrain {
    /// Side of the square terrain, metres.
    pub size: f32,
    /// Height range, metres.
    pub relief: f32,
    /// Size of the largest hills, metres.
    #[serde(default = "default_feature")]
    pub feature_size: f32,
    /// Noise seed.
    #[serde(default)]
    pub seed: u32,
}

/// The sky.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SkySpec {
    /// `"clear"` (analytic blue sky around the sun), `"uniform"`, `"exr"` or
    /// `"daylight"` (cd/m², with `turbidity`).
    #[serde(default)]
    pub kind: SkyKind,
    /// Radiance of a uniform sky.
    #[serde(default = "default_radiance")]
    pub radiance: [f32; 3],
    /// Equirectangular EXR environment map (kind = "exr").
    pub file: Option<PathBuf>,
    /// Multiplies the sky.
    #[serde(default = "one")]
    pub scale: f32,
    /// Haze of the daylight sky: 2 very clear, 3 clear, 6 hazy (1.7 to 10).
    #[serde(default = "default_turbidity")]
    pub turbidity: f32,
}

fn default_turbidity() -> f32 {
    lightgrid_sky::DEFAULT_TURBIDITY
}

impl Default for SkySpec {
    fn default() -> Self {
        Self {
            kind: SkyKind::Clear,
            radiance: default_radiance(),
            file: None,
            scale: 1.0,
            turbidity: default_turbidity(),
        }
    }
}

/// The sun: angles or a time of day.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SunSpec {
    /// Hours (6 = sunrise in the east, 12 = highest, 18 = sunset in the west); overrides
    /// the angles when given.
    pub time_of_day: Option<f32>,
    /// Degrees above the horizon.
    #[serde(default = "default_elevation")]
    pub elevation_deg: f32,
    /// Degrees from -Z towards +X.
    #[serde(default = "default_azimuth")]
    pub azimuth_deg: f32,
    /// Irradiance on a surface facing the sun (linear RGB).
    #[serde(default = "default_sun")]
    pub illuminance: [f32; 3],
    /// Keeps the sun apart from the sky's 26 bins (the default): its beam follows its
    /// exact direction (transmittance per grid point, direct light per pixel), only its
    /// scattered light enters the bins, and moving it recomputes the sun's responses
    /// without sweeping the sky again (a clear sky, whose shape follows the sun, is
    /// swept again after them). `false` puts the sun into the bins as the seed does.
    #[serde(default = "yes")]
    pub split: bool,
}

fn yes() -> bool {
    true
}

impl Default for SunSpec {
    fn default() -> Self {
        Self {
            time_of_day: None,
            elevation_deg: default_elevation(),
            azimuth_deg: default_azimuth(),
            illuminance: default_sun(),
            split: true,
        }
    }
}

impl SunSpec {
    /// Elevation and azimuth in radians (from the time of day when given): the sun rises
    /// at 6 h in the east (+X), is highest at 12 h in the south (-Z, 60°), sets at 18 h.
    pub fn angles(&self) -> (f32, f32) {
        match self.time_of_day {
            Some(t) => {
                let phase = (t - 6.0) / 12.0 * std::f32::consts::PI;
                let elevation = 60f32.to_radians() * phase.sin();
                let azimuth = std::f32::consts::FRAC_PI_2 + phase;
                (elevation, azimuth)
            }
            None => (
                self.elevation_deg.to_radians(),
                self.azimuth_deg.to_radians(),
            ),
        }
    }
}

/// Light grid settings (see `lightgrid_terrain_lod::HierarchyParams`).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GridSpec {
    /// World grid cell size, metres.
    #[serde(default = "default_world_cell")]
    pub world_cell: f32,
    /// Finest node grid cell size, metres.
    #[serde(default = "one")]
    pub finest_cell: f32,
    /// Points across a node grid.
    #[serde(default = "default_node_points")]
    pub node_points: u32,
    /// Down/up passes of each sweep (1 = the seed's single downward pass).
    #[serde(default = "default_passes")]
    pub passes: u32,
    /// Cells a node's sky sweep reaches beyond the node on every side
    /// (`HierarchyParams::apron`; left out: none, where the library's default is 6 for
    /// its 32-point nodes: at a point budget an apron builds fewer nodes a frame). With
    /// either sweeper the grids are sampled where they were swept.
    #[serde(default)]
    pub apron: u32,
    /// Side halos read the nodes of their depth before them where built
    /// (`HierarchyParams::neighbour_halo`; left out: off): closer to one fine sweep at
    /// every depth once every node is built (a bake, the headless views), for sweeps
    /// in waves.
    #[serde(default)]
    pub neighbour_halo: bool,
    /// How the sun's first scatterings reach the cells around the ones it lights
    /// (`SweepOptions::gather`, with `sun.split`): `"off"` (swept with the rest),
    /// `"low_sun"` (`Gather::LOW_SUN`: a low sun in a patchy canopy within 5 % of Monte
    /// Carlo in every cell, where the sweep alone leaves cells 16 % off, for about 10
    /// times each sun response's time), `"auto"` (`Gather::AUTO`: `low_sun` for a sun
    /// at or below 30°, off above), or `{ orders = 2, rays = 2048 }` (and
    /// `max_elevation_deg = 30`, left out 90). Left out: off in the viewer's frames,
    /// `"auto"` in a world bake ([`GridSpec::gather`]).
    #[serde(default)]
    pub gather: Option<GatherSpec>,
}

impl GridSpec {
    /// The gather the scene's grids sweep with: `[grid] gather`, or where it is left
    /// out `Gather::AUTO` for a bake (`lightgrid bake world.toml`, which takes seconds
    /// anyway) and `Gather::OFF` for the viewer's frames (a frame budget does not
    /// foresee it).
    pub fn gather(&self, bake: bool) -> lightgrid_core::Gather {
        match self.gather {
            Some(g) => g.gather(),
            None if bake => lightgrid_core::Gather::AUTO,
            None => lightgrid_core::Gather::OFF,
        }
    }
}

/// `[grid] gather`: a preset's name or the gather's own numbers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(untagged)]
pub enum GatherSpec {
    /// `"off"`, `"low_sun"` or `"auto"`.
    Preset(GatherPreset),
    /// Scatterings gathered (0–4), directions for the first (64–65,536) and the
    /// highest sun gathered.
    Rays(GatherRays),
}

/// A named gather ([`GatherSpec::Preset`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GatherPreset {
    /// `Gather::OFF`.
    #[default]
    Off,
    /// `Gather::LOW_SUN`.
    LowSun,
    /// `Gather::AUTO`.
    Auto,
}

/// A gather's numbers ([`GatherSpec::Rays`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GatherRays {
    /// Scatterings gathered.
    pub orders: u32,
    /// Rays a cell for the first.
    pub rays: u32,
    /// The highest sun gathered, degrees (left out: 90, every sun).
    #[serde(default = "every_sun")]
    pub max_elevation_deg: u32,
}

fn every_sun() -> u32 {
    90
}

impl Default for GatherSpec {
    fn default() -> Self {
        Self::Preset(GatherPreset::Off)
    }
}

impl GatherSpec {
    /// The sweep's gather (checked by [`SceneFile::validate`]).
    pub fn gather(&self) -> lightgrid_core::Gather {
        match *self {
            Self::Preset(GatherPreset::Off) => lightgrid_core::Gather::OFF,
            Self::Preset(GatherPreset::LowSun) => lightgrid_core::Gather::LOW_SUN,
            Self::Preset(GatherPreset::Auto) => lightgrid_core::Gather::AUTO,
            Self::Rays(GatherRays {
                orders,
                rays,
                max_elevation_deg,
            }) => lightgrid_core::Gather {
                orders,
                rays,
                max_elevation_deg,
            },
        }
    }
}

impl Default for GridSpec {
    fn default() -> Self {
        Self {
            world_cell: default_world_cell(),
            finest_cell: 1.0,
            node_points: default_node_points(),
            passes: default_passes(),
            apron: 0,
            neighbour_halo: false,
            gather: None,
        }
    }
}

/// Drawing settings.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RenderSpec {
    /// Metres from the eye beyond which a model's instances are drawn as its impostor,
    /// one picture of the model turned to face the eye (`lightgrid_render::impostor`),
    /// lit by the light volume as its foliage is; 0 draws every instance whole. Left
    /// out: 120 (the demo's overview then draws 0.4 s faster on lavapipe).
    #[serde(default = "default_far_detail")]
    pub far_detail: f32,
}

impl RenderSpec {
    /// Metres from the eye beyond which foliage is drawn as impostors, `None` for
    /// never (`far_detail` 0).
    pub fn impostors_beyond(&self) -> Option<f32> {
        (self.far_detail > 0.0).then_some(self.far_detail)
    }
}

impl Default for RenderSpec {
    fn default() -> Self {
        Self {
            far_detail: default_far_detail(),
        }
    }
}

fn default_far_detail() -> f32 {
    120.0
}

/// A model: a glTF file or a procedural one.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelSpec {
    /// Name instances refer to.
    pub name: String,
    /// A .glb / .gltf file.
    pub gltf: Option<PathBuf>,
    /// `"broadleaf"`, `"young"`, `"bush"` or `"rock"`.
    pub procedural: Option<ProceduralModel>,
    /// Seed of a procedural model.
    #[serde(default)]
    pub seed: u64,
    /// Material grid cell size, metres.
    #[serde(default = "default_voxel")]
    pub voxel_size: f32,
}

/// One placed instance.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InstanceSpec {
    /// Model name.
    pub model: String,
    /// World x, z.
    pub position: [f32; 2],
    /// Height above the ground (metres; default 0, standing on it).
    #[serde(default)]
    pub height: f32,
    /// Turn about +Y, degrees.
    #[serde(default)]
    pub rotation_deg: f32,
    /// Uniform scale.
    #[serde(default = "one")]
    pub scale: f32,
}

/// Scatter `count` instances in a disc.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScatterSpec {
    /// Model name.
    pub model: String,
    /// How many.
    pub count: u32,
    /// Disc centre, world x, z.
    pub centre: [f32; 2],
    /// Disc radius, metres.
    pub radius: f32,
    /// Scale range.
    #[serde(default = "default_scale")]
    pub scale: [f32; 2],
    /// Random seed.
    #[serde(default)]
    pub seed: u64,
}

/// Dynamic lights scattered over a disc, at heights above the ground (points, spots
/// and short lines in turn; `lightgrid_render::dynamic::scatter`).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DynamicLightsSpec {
    /// How many (at most 10 000).
    pub count: u32,
    /// Disc centre, world x, z.
    pub centre: [f32; 2],
    /// Disc radius, metres.
    pub radius: f32,
    /// Height range above the ground, metres.
    #[serde(default = "default_light_heights")]
    pub height: [f32; 2],
    /// Random seed.
    #[serde(default)]
    pub seed: u64,
}

/// Light probes over a region of the scene (`lightgrid_light_probes`).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProbesSpec {
    /// `"preview"`, `"standard"` (The Division's 4 m) or `"fine"`.
    #[serde(default)]
    pub preset: ProbePreset,
    /// Probe spacing, metres (overrides the preset's).
    pub spacing: Option<f32>,
    /// The region probed, world `[x0, z0, x1, z1]`; by default the instances' extent and
    /// a spacing around it (the whole terrain without instances).
    pub region: Option<[f32; 4]>,
    /// Extra probes along walls (the preset's distance from them); `false`: columns only.
    #[serde(default = "yes")]
    pub walls: bool,
    /// How surfels see the sun: `"rays"` (a shadow ray each, alpha-tested leaves opaque
    /// or not) or `"sweep"` (the sweep's sun transmittance, partial through foliage).
    #[serde(default)]
    pub sun: ProbeSun,
}

/// A sky kind (`sky.kind`), parsed once with the scene file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SkyKind {
    /// The analytic clear sky around the sun.
    #[default]
    Clear,
    /// A uniform sky of `sky.radiance`.
    Uniform,
    /// An equirectangular EXR environment map (`sky.file`).
    Exr,
    /// A clear daylight sky in cd/m² (`sky.turbidity`; `lightgrid_sky::Daylight`): give
    /// the sun in lux to match it (about 92,000 at 40°:
    /// `lightgrid_sky::ies_sun_illuminance`).
    Daylight,
}

/// A procedural model (`models[i].procedural`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ProceduralModel {
    /// A broadleaf tree.
    Broadleaf,
    /// A young tree.
    Young,
    /// A bush.
    Bush,
    /// A rock.
    Rock,
}

/// The probes' bake preset (`probes.preset`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ProbePreset {
    /// Coarse and quick.
    Preview,
    /// The Division's 4 m probes.
    #[default]
    Standard,
    /// Finer probes.
    Fine,
}

/// How the probes' surfels see the sun (`probes.sun`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ProbeSun {
    /// A shadow ray each.
    #[default]
    Rays,
    /// The sweep's sun transmittance.
    Sweep,
}

impl ProbesSpec {
    /// The bake parameters.
    pub fn params(&self) -> lightgrid_light_probes::ProbeParams {
        let mut p = match self.preset {
            ProbePreset::Preview => lightgrid_light_probes::ProbeParams::preview(),
            ProbePreset::Fine => lightgrid_light_probes::ProbeParams::fine(),
            ProbePreset::Standard => lightgrid_light_probes::ProbeParams::standard(),
        };
        if let Some(s) = self.spacing {
            p.spacing = s;
        }
        if !self.walls {
            p.wall_offset = 0.0;
        }
        p
    }
}

fn default_light_heights() -> [f32; 2] {
    [0.5, 4.0]
}

/// A camera.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ViewSpec {
    /// File name stem of the images.
    pub name: String,
    /// Eye x, z.
    pub position: [f32; 2],
    /// Eye height above the ground, metres.
    pub height: f32,
    /// Target x, z.
    pub target: [f32; 2],
    /// Target height above the ground.
    #[serde(default = "default_target_height")]
    pub target_height: f32,
    /// Vertical field of view, degrees.
    #[serde(default = "default_fov")]
    pub fov_deg: f32,
}

fn one() -> f32 {
    1.0
}
fn default_spacing() -> f32 {
    2.0
}
fn default_ground() -> [f32; 3] {
    [0.22, 0.2, 0.14]
}
fn default_feature() -> f32 {
    200.0
}
fn default_radiance() -> [f32; 3] {
    [0.5, 0.6, 0.8]
}
fn default_elevation() -> f32 {
    35.0
}
fn default_azimuth() -> f32 {
    150.0
}
fn default_sun() -> [f32; 3] {
    [8.0, 7.6, 6.8]
}
fn default_world_cell() -> f32 {
    16.0
}
fn default_node_points() -> u32 {
    32
}
fn default_passes() -> u32 {
    2
}

fn default_voxel() -> f32 {
    0.5
}
fn default_scale() -> [f32; 2] {
    [0.8, 1.2]
}
fn default_target_height() -> f32 {
    2.0
}
fn default_fov() -> f32 {
    60.0
}

impl SceneFile {
    /// Parses `text` (named `origin` in errors) and checks it; relative paths resolve
    /// against `base`.
    pub fn parse(text: &str, origin: &str, base: &Path) -> Result<Self> {
        let mut s: SceneFile =
            toml::from_str(text).with_context(|| format!("scene file {origin}"))?;
        s.base = base.to_path_buf();
        s.validate()
            .with_context(|| format!("scene file {origin}"))?;
        Ok(s)
    }

    /// Reads and checks a scene file.
    pub fn load(path: &Path) -> Result<Self> {
        let text = lightgrid_core::limits::read_text(path, MAX_SCENE_BYTES)
            .with_context(|| format!("reading scene file {}", path.display()))?;
        let base = path.parent().unwrap_or(Path::new("."));
        Self::parse(&text, &path.display().to_string(), base)
    }

    /// The embedded demo scene.
    pub fn demo() -> Result<Self> {
        Self::parse(
            DEMO,
            "scenes/demo.toml (embedded)",
            Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("scenes")
                .as_path(),
        )
    }

    /// A hash of what the scene's light depends on: terrain, sky, sun, grid settings,
    /// models, instances and scatter rules as parsed (not views, probes or dynamic
    /// lights, nor comments), and the bytes of every file they name. Equal scenes hash
    /// equal on any machine (`lightgrid bake` names its tasks' outputs by it).
    pub fn light_hash(&self) -> Result<u64> {
        let mut h = lightgrid_core::hash::ContentHash::new(b"lightgrid-scene-light-v1");
        let parts = format!(
            "{:?}{:?}{:?}{:?}{:?}{:?}{:?}",
            self.terrain, self.sky, self.sun, self.grid, self.models, self.instances, self.scatter
        );
        h.bytes(parts.as_bytes());
        let files = [
            &self.terrain.heightmap,
            &self.terrain.ground_texture,
            &self.sky.file,
        ]
        .into_iter()
        .chain(self.models.iter().map(|m| &m.gltf))
        .flatten();
        for f in files {
            let p = self.resolve(f);
            let bytes = lightgrid_core::limits::read_file(&p, u64::MAX)
                .with_context(|| format!("reading {}", p.display()))?;
            h.u64(bytes.len() as u64).bytes(&bytes);
        }
        Ok(h.finish())
    }

    /// A path from the file, resolved against its folder.
    pub fn resolve(&self, p: &Path) -> PathBuf {
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            self.base.join(p)
        }
    }

    /// Semantic checks the TOML types cannot express; errors name the field and value.
    pub fn validate(&self) -> Result<()> {
        let t = &self.terrain;
        match (&t.heightmap, &t.procedural) {
            (None, None) => bail!("terrain: give `heightmap` or `procedural`"),
            (Some(_), Some(_)) => bail!("terrain: give `heightmap` or `procedural`, not both"),
            _ => {}
        }
        positive("terrain.spacing", t.spacing)?;
        positive("terrain.height_scale", t.height_scale)?;
        if let Some(p) = &t.procedural {
            // Ranges that keep the noise's coordinates (position / feature size, up to
            // 16 times finer over the octaves) far inside what it can floor.
            in_range("terrain.procedural.size", p.size, 0.0, 1e6, "metres")?;
            in_range(
                "terrain.procedural.feature_size",
                p.feature_size,
                1e-3,
                1e7,
                "metres",
            )?;
            if !(p.relief.is_finite() && p.relief >= 0.0) {
                bail!("terrain.procedural.relief = {}: must be >= 0", p.relief);
            }
        }
        colour("terrain.ground_colour", t.ground_colour, Some(1.0))?;
        if self.sky.kind == SkyKind::Daylight
            && !lightgrid_sky::TURBIDITY_RANGE.contains(&self.sky.turbidity)
        {
            bail!(
                "sky.turbidity = {}: must be in 1.7..=10 (2 very clear, 3 clear, 6 hazy)",
                self.sky.turbidity
            );
        }
        if self.sky.kind == SkyKind::Exr && self.sky.file.is_none() {
            bail!("sky.kind = \"exr\" needs sky.file");
        }
        colour("sky.radiance", self.sky.radiance, None)?;
        if !(self.sky.scale.is_finite() && self.sky.scale >= 0.0) {
            bail!("sky.scale = {}: must be >= 0", self.sky.scale);
        }
        colour("sun.illuminance", self.sun.illuminance, None)?;
        if let Some(t) = self.sun.time_of_day
            && !(0.0..=24.0).contains(&t)
        {
            bail!("sun.time_of_day = {t}: must be in 0..=24 hours");
        }
        for (f, v) in [
            ("sun.elevation_deg", self.sun.elevation_deg),
            ("sun.azimuth_deg", self.sun.azimuth_deg),
        ] {
            if !v.is_finite() {
                bail!("{f} = {v}: must be finite");
            }
        }
        let g = &self.grid;
        positive("grid.world_cell", g.world_cell)?;
        positive("grid.finest_cell", g.finest_cell)?;
        if !(4..=128).contains(&g.node_points) {
            bail!("grid.node_points = {}: must be in 4..=128", g.node_points);
        }
        if !(1..=16).contains(&g.passes) {
            bail!("grid.passes = {}: must be in 1..=16", g.passes);
        }
        if let Err(e) = g.gather(false).validate() {
            bail!("grid.gather: {e}");
        }
        if g.apron > g.node_points {
            bail!(
                "grid.apron = {}: must be at most grid.node_points ({})",
                g.apron,
                g.node_points
            );
        }
        let far = self.render.far_detail;
        if !(far.is_finite() && far >= 0.0) {
            bail!("render.far_detail = {far}: must be finite and >= 0 (0: no impostors)");
        }
        for (i, m) in self.models.iter().enumerate() {
            match (&m.gltf, m.procedural) {
                (Some(_), None) | (None, Some(_)) => {}
                _ => bail!(
                    "models[{i}] ({}): give `gltf` or `procedural`, exactly one",
                    m.name
                ),
            }
            positive(&format!("models[{i}].voxel_size"), m.voxel_size)?;
            if self.models[..i].iter().any(|o| o.name == m.name) {
                bail!("models[{i}].name = {:?}: used twice", m.name);
            }
        }
        let known = |field: String, name: &str| -> Result<()> {
            if self.models.iter().any(|m| m.name == name) {
                Ok(())
            } else {
                bail!("{field} = {name:?}: no model of that name")
            }
        };
        for (i, inst) in self.instances.iter().enumerate() {
            known(format!("instances[{i}].model"), &inst.model)?;
            positive(&format!("instances[{i}].scale"), inst.scale)?;
            finite2(&format!("instances[{i}].position"), inst.position)?;
            finite2(
                &format!("instances[{i}].height, rotation_deg"),
                [inst.height, inst.rotation_deg],
            )?;
        }
        for (i, s) in self.scatter.iter().enumerate() {
            known(format!("scatter[{i}].model"), &s.model)?;
            positive(&format!("scatter[{i}].radius"), s.radius)?;
            finite2(&format!("scatter[{i}].centre"), s.centre)?;
            if !(s.scale[0] > 0.0 && s.scale[1] >= s.scale[0] && s.scale[1].is_finite()) {
                bail!("scatter[{i}].scale = {:?}: need 0 < min <= max", s.scale);
            }
            if s.count > 100_000 {
                bail!("scatter[{i}].count = {}: at most 100000", s.count);
            }
        }
        if let Some(d) = &self.dynamic_lights {
            if d.count > 10_000 {
                bail!("dynamic_lights.count = {}: at most 10000", d.count);
            }
            positive("dynamic_lights.radius", d.radius)?;
            finite2("dynamic_lights.centre", d.centre)?;
            if !(d.height[0].is_finite() && d.height[1].is_finite() && d.height[0] <= d.height[1]) {
                bail!(
                    "dynamic_lights.height = {:?}: need finite min <= max",
                    d.height
                );
            }
        }
        if let Some(p) = &self.probes {
            if let Some(s) = p.spacing {
                positive("probes.spacing", s)?;
            }
            if let Some(r) = p.region
                && !(r.iter().all(|v| v.is_finite()) && r[0] < r[2] && r[1] < r[3])
            {
                bail!("probes.region = {r:?}: need finite x0 < x1 and z0 < z1");
            }
            if !self.sun.split {
                bail!(
                    "probes: need sun.split = true (the probes hold no direct sun; its shadow comes from the sweep's transmittance)"
                );
            }
        }
        self.validate_tables()?;
        self.validate_views()
    }

    /// The repeated tables within their caps.
    fn validate_tables(&self) -> Result<()> {
        for (table, n, most) in [
            ("views", self.views.len(), MAX_VIEWS),
            ("models", self.models.len(), MAX_MODELS),
            ("instances", self.instances.len(), MAX_INSTANCES),
            ("scatter", self.scatter.len(), MAX_SCATTERS),
        ] {
            if n > most {
                bail!("{table}: {n} entries, at most {most}");
            }
        }
        Ok(())
    }

    /// Every view: finite, named, looking somewhere.
    fn validate_views(&self) -> Result<()> {
        if self.views.is_empty() {
            bail!("views: give at least one [[views]]");
        }
        for (i, v) in self.views.iter().enumerate() {
            finite2(&format!("views[{i}].position"), v.position)?;
            finite2(&format!("views[{i}].target"), v.target)?;
            finite2(
                &format!("views[{i}].height, target_height"),
                [v.height, v.target_height],
            )?;
            if !(v.fov_deg > 1.0 && v.fov_deg < 170.0) {
                bail!("views[{i}].fov_deg = {}: must be in (1, 170)", v.fov_deg);
            }
            if v.name.is_empty()
                || !v
                    .name
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
            {
                bail!(
                    "views[{i}].name = {:?}: letters, digits, - and _ only",
                    v.name
                );
            }
            if v.position == v.target && v.height == v.target_height {
                bail!("views[{i}]: position and target are the same point");
            }
        }
        Ok(())
    }
}

/// Most `[[views]]` of a scene (each renders several images).
pub const MAX_VIEWS: usize = 64;
/// Most `[[models]]` of a scene (each is voxelized).
pub const MAX_MODELS: usize = 256;
/// Most `[[instances]]` placed one by one.
pub const MAX_INSTANCES: usize = 100_000;
/// Most `[[scatter]]` tables (each up to 100,000 instances).
pub const MAX_SCATTERS: usize = 64;

/// `v` within `lo..=hi` where `lo > 0`, within `(lo, hi]` where `lo <= 0`; finite.
fn in_range(field: &str, v: f32, lo: f32, hi: f32, unit: &str) -> Result<()> {
    let ok = v.is_finite() && v <= hi && if lo > 0.0 { v >= lo } else { v > lo };
    if ok {
        Ok(())
    } else if lo > 0.0 {
        bail!("{field} = {v}: must be in {lo}..={hi} {unit}")
    } else {
        bail!("{field} = {v}: must be > {lo} and at most {hi} {unit}")
    }
}

fn positive(field: &str, v: f32) -> Result<()> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        bail!("{field} = {v}: must be finite and > 0")
    }
}

fn finite2(field: &str, v: [f32; 2]) -> Result<()> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        bail!("{field} = {v:?}: must be finite")
    }
}

fn colour(field: &str, c: [f32; 3], max: Option<f32>) -> Result<()> {
    let ok = c
        .iter()
        .all(|x| x.is_finite() && *x >= 0.0 && max.is_none_or(|m| *x <= m));
    if ok {
        Ok(())
    } else {
        bail!(
            "{field} = {c:?}: must be finite, >= 0{}",
            max.map(|m| format!(" and <= {m}")).unwrap_or_default()
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_demo_scene_parses() {
        let s = SceneFile::demo().unwrap();
        assert!(!s.views.is_empty() && !s.models.is_empty());
    }

    #[test]
    fn type_errors_name_the_file_line_and_field() {
        let text = DEMO.replacen("relief = 28.0", "relief = \"high\"", 1);
        let e = format!(
            "{:#}",
            SceneFile::parse(&text, "my.toml", Path::new(".")).unwrap_err()
        );
        assert!(e.contains("my.toml"), "{e}");
        assert!(e.contains("line"), "{e}");
        assert!(e.contains("relief"), "{e}");
    }

    #[test]
    fn unknown_fields_and_bad_values_are_named() {
        let text = DEMO.replacen("[sun]", "[sun]\nelevaton_deg = 3", 1);
        let e = format!(
            "{:#}",
            SceneFile::parse(&text, "a.toml", Path::new(".")).unwrap_err()
        );
        assert!(e.contains("elevaton_deg") && e.contains("a.toml"), "{e}");
        let text = DEMO.replacen("node_points = ", "node_points = 1000 #", 1);
        let e = format!(
            "{:#}",
            SceneFile::parse(&text, "b.toml", Path::new(".")).unwrap_err()
        );
        assert!(e.contains("grid.node_points = 1000"), "{e}");
        let text = DEMO.replacen("apron = 0", "apron = 33", 1);
        let e = format!(
            "{:#}",
            SceneFile::parse(&text, "d.toml", Path::new(".")).unwrap_err()
        );
        assert!(e.contains("grid.apron = 33") && e.contains("(32)"), "{e}");
        assert_eq!(
            SceneFile::parse(
                &DEMO.replacen("apron = 0", "apron = 2", 1),
                "e.toml",
                Path::new(".")
            )
            .unwrap()
            .grid
            .apron,
            2
        );
        // Left out: off.
        assert!(
            !SceneFile::parse(DEMO, "g.toml", Path::new("."))
                .unwrap()
                .grid
                .neighbour_halo
        );
        assert!(
            SceneFile::parse(
                &DEMO.replacen("apron = 0", "apron = 0\nneighbour_halo = true", 1),
                "h.toml",
                Path::new(".")
            )
            .unwrap()
            .grid
            .neighbour_halo
        );
        // Left out: none (the GPU sweeper's grids stay on the device).
        assert_eq!(
            SceneFile::parse(
                &DEMO.replacen("apron = 0", "# apron", 1),
                "f.toml",
                Path::new(".")
            )
            .unwrap()
            .grid
            .apron,
            0
        );
        let text = DEMO.replacen("model = \"oak\"", "model = \"pine\"", 1);
        let e = format!(
            "{:#}",
            SceneFile::parse(&text, "c.toml", Path::new(".")).unwrap_err()
        );
        assert!(e.contains("\"pine\"") && e.contains("no model"), "{e}");
    }

    /// `[grid] gather`: left out off; a preset by name or the numbers; a bad value
    /// named with the field.
    #[test]
    fn the_gather_is_a_preset_or_its_numbers() {
        use lightgrid_core::Gather;
        let parse = |line: &str| {
            SceneFile::parse(
                &DEMO.replacen("apron = 0", &format!("apron = 0\n{line}"), 1),
                "g.toml",
                Path::new("."),
            )
        };
        let gather = |line: &str| parse(line).unwrap().grid.gather(false);
        let baked = |line: &str| parse(line).unwrap().grid.gather(true);
        assert_eq!(gather(""), Gather::OFF);
        assert_eq!(baked(""), Gather::AUTO);
        assert_eq!(gather("gather = \"off\""), Gather::OFF);
        assert_eq!(baked("gather = \"off\""), Gather::OFF);
        assert_eq!(gather("gather = \"low_sun\""), Gather::LOW_SUN);
        assert_eq!(gather("gather = \"auto\""), Gather::AUTO);
        assert_eq!(
            gather("gather = { orders = 1, rays = 1024 }"),
            Gather {
                orders: 1,
                rays: 1024,
                max_elevation_deg: 90,
            }
        );
        assert_eq!(
            baked("gather = { orders = 2, rays = 512, max_elevation_deg = 20 }"),
            Gather {
                orders: 2,
                rays: 512,
                max_elevation_deg: 20,
            }
        );
        for (line, want) in [
            ("gather = { orders = 2, rays = 10 }", "gather.rays = 10"),
            ("gather = { orders = 9, rays = 4096 }", "gather.orders = 9"),
            (
                "gather = { orders = 2, rays = 4096, max_elevation_deg = 91 }",
                "gather.max_elevation_deg = 91",
            ),
        ] {
            let e = format!("{:#}", parse(line).unwrap_err());
            assert!(e.contains("grid.gather") && e.contains(want), "{line}: {e}");
        }
        for line in [
            "gather = \"lowsun\"",
            "gather = { orders = 2 }",
            "gather = 2",
        ] {
            let e = format!("{:#}", parse(line).unwrap_err());
            assert!(e.contains("gather") && e.contains("g.toml"), "{line}: {e}");
        }
    }

    #[test]
    fn time_of_day_moves_the_sun_east_to_west() {
        let mut s = SunSpec {
            time_of_day: Some(6.0),
            ..Default::default()
        };
        let (e, a) = s.angles();
        assert!(e.abs() < 1e-6 && (a - std::f32::consts::FRAC_PI_2).abs() < 1e-6);
        s.time_of_day = Some(12.0);
        let (e, _) = s.angles();
        assert!((e - 60f32.to_radians()).abs() < 1e-6);
    }
}
