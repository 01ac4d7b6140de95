//! Live lightgrid irradiance volumes in Bevy: volumes that follow the sun.
//!
//! Bevy lights meshes inside an [`IrradianceVolume`] from a 3D texture of ambient cubes.
//! `lightgrid bake` writes such textures once; this plugin keeps them in step with the
//! time of day. Give it a volume's material grid ([`LiveSource`]) and the sun and sky
//! ([`Daylight`], a resource); whenever `Daylight` changes, every [`LiveVolume`] is
//! swept again on Bevy's async compute pool (lightgrid's CPU sweeper, the indirect light
//! only: Bevy draws the sun itself with a `DirectionalLight`), and the finished volumes
//! replace their textures, at most [`LightgridPlugin::uploads_per_frame`] a frame, so a
//! sun move never stalls a frame on the sweeps. Baked volumes load too: a `lightgrid
//! bake` sidecar is an asset ([`BakedVolumes`], its KTX2 textures loaded with it), and an
//! entity with [`BakedProbes`] gets its light probes once all have loaded
//! ([`spawn_baked_volumes`] does the same from the sidecar's text, at once).
//!
//! ```no_run
//! use bevy::prelude::*;
//! use lightgrid_bevy::{Daylight, LightgridPlugin, LiveSource, spawn_live_volume};
//!
//! fn setup(mut commands: Commands, mut images: ResMut<Assets<Image>>, daylight: Res<Daylight>) {
//!     let material = lightgrid_bevy::flat_ground(16, 8, 1.0, 0.3).unwrap();
//!     let source = LiveSource::new(material, 1.0);
//!     spawn_live_volume(&mut commands, &mut images, source, &daylight).unwrap();
//! }
//!
//! // Time of day: move the sun and the volumes follow within a few frames.
//! fn sunset(time: Res<Time>, mut daylight: ResMut<Daylight>) {
//!     let elevation = 60.0 - 5.0 * time.elapsed_secs();
//!     if elevation > 5.0 {
//!         *daylight = Daylight::at(elevation, 40.0, Vec3::splat(3.0), Vec3::splat(0.3));
//!     }
//! }
//!
//! App::new()
//!     .add_plugins((DefaultPlugins, LightgridPlugin::default()))
//!     .insert_resource(Daylight::at(60.0, 40.0, Vec3::splat(3.0), Vec3::splat(0.3)))
//!     .add_systems(Startup, setup)
//!     .add_systems(Update, sunset)
//!     .run();
//! ```
//!
//! [`Daylight::clear`] is a clear day in physical units (the IES clear-sky sun and sky,
//! lux and cd/m², in the proportion measured skies keep at every elevation; scale them
//! into Bevy's with [`LiveSource::unit_scale`]): the natural input of a time-of-day
//! system.
//!
//! Where volumes overlap, Bevy 0.18 does not blend them: a fragment takes the first
//! volume whose box holds it in the view's list, nearest centre first
//! (`light_probe.wgsl`); the plugin keeps that rule and adds none of its own.
//! Units: a texel times the volume's intensity is irradiance / π in the grid's units
//! times [`LiveSource::unit_scale`] (Bevy's cd/m²); see `lightgrid_export::UNITS`.

use std::sync::Arc;

use bevy::asset::RenderAssetUsages;
use bevy::image::Image;
use bevy::light::{IrradianceVolume, LightProbe};
use bevy::prelude::*;
use bevy::render::render_resource::{Extent3d, TextureDimension, TextureFormat};
use bevy::tasks::{AsyncComputeTaskPool, Task, block_on, futures_lite::future};
use lightgrid_core::glam;
use lightgrid_core::{
    BinLight, Boundary, GridDesc, Material, MaterialGrid, SideBoundary, SweepOptions, TopBoundary,
};
use lightgrid_export::{BevyVolume, TexelFormat};

/// Errors of the plugin's functions, naming what was wrong.
#[derive(Debug, thiserror::Error)]
pub enum LiveError {
    /// A parameter is out of range.
    #[error("{field} = {value}: {reason}")]
    Invalid {
        /// Which parameter.
        field: &'static str,
        /// Its value.
        value: String,
        /// Why it is refused.
        reason: &'static str,
    },
    /// The grid, sky or sun were refused by lightgrid.
    #[error(transparent)]
    Grid(#[from] lightgrid_core::GridError),
    /// The sky model refused its parameters.
    #[error(transparent)]
    Sky(#[from] lightgrid_sky::SkyError),
    /// The export refused the volume.
    #[error(transparent)]
    Export(#[from] lightgrid_export::ExportError),
    /// A sidecar could not be read.
    #[error("sidecar: {0}")]
    Sidecar(String),
}

/// The sky of a [`Daylight`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Sky {
    /// Radiance uniform over the upper hemisphere (RGB, the grid's light units).
    Uniform(Vec3),
    /// lightgrid's clear daylight sky (Preetham's shape and colour, the IES clear-sky
    /// level, in cd/m²) of this turbidity (2 very clear, 3 clear, 6 hazy): its shape and
    /// brightness follow the sun (`lightgrid_sky::Daylight`).
    Clear {
        /// Haze, 1.7 to 10.
        turbidity: f32,
    },
}

/// The sun and sky the live volumes are swept under: the time of day. A resource;
/// changing it sweeps every [`LiveVolume`] again.
#[derive(Resource, Debug, Clone, Copy, PartialEq)]
pub struct Daylight {
    /// Unit vector towards the sun (y up).
    pub to_sun: Vec3,
    /// The sun's irradiance on a surface facing it (RGB, the grid's light units).
    pub sun: Vec3,
    /// The sky.
    pub sky: Sky,
}

impl Daylight {
    /// A sun `elevation` degrees above the horizon at `azimuth` degrees from `-Z`
    /// towards `+X` (lightgrid's convention), of irradiance `sun`, under a uniform sky of
    /// radiance `sky`.
    pub fn at(elevation: f32, azimuth: f32, sun: Vec3, sky: Vec3) -> Self {
        let s = lightgrid_sky::Sun::at(elevation.to_radians(), azimuth.to_radians(), lg(sun));
        Self {
            to_sun: Vec3::from_array(s.direction.to_array()),
            sun,
            sky: Sky::Uniform(sky),
        }
    }

    /// A clear day in physical units (lux and cd/m², to be scaled into Bevy's by
    /// [`LiveSource::unit_scale`]): the sun at `elevation` and `azimuth` degrees with the
    /// IES clear-sky illuminance for that elevation, under the clear sky of `turbidity`
    /// ([`Sky::Clear`]), the two in the proportion measured skies have at every
    /// elevation. Below the horizon both are dark.
    pub fn clear(elevation: f32, azimuth: f32, turbidity: f32) -> Self {
        let e = lightgrid_sky::ies_sun_illuminance(elevation.to_radians());
        let mut d = Self::at(elevation, azimuth, Vec3::splat(e), Vec3::ZERO);
        d.sky = Sky::Clear { turbidity };
        d
    }

    /// Checks every field (finite; light >= 0; a non-zero direction; a turbidity in
    /// `lightgrid_sky::TURBIDITY_RANGE`).
    pub fn validate(&self) -> Result<(), LiveError> {
        let bad = |field, value: String, reason| {
            Err(LiveError::Invalid {
                field,
                value,
                reason,
            })
        };
        if !self.to_sun.is_finite() || self.to_sun.length_squared() == 0.0 {
            return bad(
                "to_sun",
                format!("{:?}", self.to_sun),
                "must be finite and non-zero",
            );
        }
        let mut light = vec![("sun", self.sun)];
        match self.sky {
            Sky::Uniform(v) => light.push(("sky", v)),
            Sky::Clear { turbidity } => {
                if !lightgrid_sky::TURBIDITY_RANGE.contains(&turbidity) {
                    return bad(
                        "sky turbidity",
                        format!("{turbidity:?}"),
                        "must be in 1.7..=10",
                    );
                }
            }
        }
        for (field, v) in light {
            if !v.is_finite() || v.min_element() < 0.0 {
                return bad(field, format!("{v:?}"), "must be finite and >= 0");
            }
        }
        Ok(())
    }

    /// The sky's and the sun's light as the sweep takes them: (sky and sun together,
    /// the sun alone; `None` with the sun below the horizon or dark).
    fn boundaries(&self, sides: SideBoundary) -> Result<(Boundary, Option<Boundary>), LiveError> {
        self.validate()?;
        let to_sun = lg(self.to_sun.normalize());
        let sky = match self.sky {
            Sky::Uniform(v) => lightgrid_sky::SkySpec::Uniform(lg(v)),
            Sky::Clear { turbidity } => lightgrid_sky::SkySpec::Daylight(turbidity),
        }
        .bins(to_sun)?;
        let sun = lightgrid_sky::Sun {
            direction: to_sun,
            angular_radius: 0.00465,
            illuminance: lg(self.sun),
        };
        let sun_bins = if self.sun == Vec3::ZERO || self.to_sun.y <= 0.0 {
            BinLight::ZERO
        } else {
            sun.bins()?
        };
        let all = Boundary {
            top: TopBoundary::Uniform(Box::new(sky.top + sun_bins)),
            bottom: sky.bottom,
            sides: sides.clone(),
        };
        let alone = (sun_bins != BinLight::ZERO).then(|| Boundary {
            top: TopBoundary::Uniform(Box::new(sun_bins)),
            bottom: BinLight::ZERO,
            sides,
        });
        Ok((all, alone))
    }
}

impl Default for Daylight {
    /// A sun 45° up at azimuth 40° of irradiance 3 under a sky of radiance 0.3.
    fn default() -> Self {
        Self::at(45.0, 40.0, Vec3::splat(3.0), Vec3::splat(0.3))
    }
}

/// Bevy's vector as lightgrid's (the two depend on different `glam` releases).
fn lg(v: Vec3) -> glam::Vec3 {
    glam::Vec3::from_array(v.to_array())
}

/// What a live volume is swept from: its material grid and how.
#[derive(Debug, Clone)]
pub struct LiveSource {
    /// The volume's points and what fills their cells.
    pub material: MaterialGrid,
    /// Open sides (light from outside the box is the sky's) or periodic ones (the
    /// grid repeats: a tile of a larger world).
    pub sides: SideBoundary,
    /// The sweep's options (the 26 bins are always asked for).
    pub options: SweepOptions,
    /// The texels' format.
    pub format: TexelFormat,
    /// From the grid's light units to Bevy's (cd/m²), as `lightgrid bake --unit-scale`.
    pub unit_scale: f32,
}

impl LiveSource {
    /// A source of `material` with open sides, the multi-bounce sweep (4 passes at
    /// most), RGB9E5 texels and `unit_scale`.
    pub fn new(material: MaterialGrid, unit_scale: f32) -> Self {
        let mut options = SweepOptions::multi_bounce();
        options.max_passes = 4;
        Self {
            material,
            sides: SideBoundary::Open,
            options,
            format: TexelFormat::Rgb9e5,
            unit_scale,
        }
    }
}

/// A ground of `albedo`, `levels` cells deep at the bottom of a grid of `side × 8 ×
/// side` points `h` apart, air above: the plugin's smallest scene (its example and
/// test). `levels` is clamped into `1..=7`.
pub fn flat_ground(side: u32, levels: u32, h: f32, albedo: f32) -> Result<MaterialGrid, LiveError> {
    let desc = GridDesc::new(glam::Vec3::ZERO, h, glam::UVec3::new(side, 8, side))?;
    let ground = levels.clamp(1, 7);
    let cells = (0..desc.point_count())
        .map(|i| {
            if desc.coords(i).is_some_and(|c| c.y < ground) {
                Material {
                    reflectance: glam::Vec3::splat(albedo),
                    pass: 0.0,
                }
            } else {
                Material::EMPTY
            }
        })
        .collect();
    Ok(MaterialGrid::new(desc, cells)?)
}

/// Sweeps `source` under `daylight` and packs the indirect light (the sky and every
/// bounce; the direct sun left to Bevy's `DirectionalLight`) as an irradiance volume,
/// points inside geometry filled from their valid neighbours (what `lightgrid bake`
/// writes). Runs on the calling thread; [`LightgridPlugin`] calls it on the async
/// compute pool.
pub fn bake(source: &LiveSource, daylight: &Daylight) -> Result<BevyVolume, LiveError> {
    if !(source.unit_scale.is_finite() && source.unit_scale > 0.0) {
        return Err(LiveError::Invalid {
            field: "unit_scale",
            value: format!("{:?}", source.unit_scale),
            reason: "must be finite and > 0",
        });
    }
    let (all, sun) = daylight.boundaries(source.sides.clone())?;
    let mut o = source.options;
    o.outputs.bins = true;
    let light = lightgrid_export::indirect_light_split(
        &mut lightgrid_sweep_cpu::CpuSweeper::new(),
        &source.material,
        &all,
        sun.as_ref(),
        &o,
    )?;
    let valid = lightgrid_core::validity::valid_points(&source.material);
    Ok(BevyVolume::from_field_valid(
        &light,
        source.material.desc(),
        source.format,
        &valid,
    )?)
}

/// A volume's texture as a Bevy image (3D, `Rgb9e5Ufloat` or `Rg11b10Ufloat`).
pub fn image_of(volume: &BevyVolume) -> Image {
    let size = volume.texture_size();
    let format = match volume.format() {
        TexelFormat::Rgb9e5 => TextureFormat::Rgb9e5Ufloat,
        TexelFormat::Rg11b10 => TextureFormat::Rg11b10Ufloat,
    };
    let bytes = volume
        .texels()
        .iter()
        .flat_map(|t| t.to_le_bytes())
        .collect();
    Image::new(
        Extent3d {
            width: size.x,
            height: size.y,
            depth_or_array_layers: size.z,
        },
        TextureDimension::D3,
        bytes,
        format,
        RenderAssetUsages::default(),
    )
}

/// Bevy's transform of a volume's light probe (the unit cube onto its box).
pub fn transform_of(volume: &BevyVolume) -> Transform {
    let t = volume.transform();
    Transform {
        translation: Vec3::from_array(t.translation),
        rotation: Quat::from_array(t.rotation),
        scale: Vec3::from_array(t.scale),
    }
}

/// A volume that follows [`Daylight`]: swept again from its source whenever the
/// daylight differs from the one its texture holds.
#[derive(Component)]
pub struct LiveVolume {
    source: Arc<LiveSource>,
    /// The daylight the texture holds (`None`: not swept yet).
    shown: Option<Daylight>,
    /// The sweep under way and the daylight it is for.
    task: Option<(Daylight, Task<Result<BevyVolume, LiveError>>)>,
    /// The volume the texture holds.
    volume: Option<BevyVolume>,
    /// The daylight whose sweep failed (not tried again until the daylight changes).
    failed: Option<Daylight>,
}

impl LiveVolume {
    /// A volume of `source`, not swept yet (the plugin sweeps it under the current
    /// [`Daylight`]).
    pub fn new(source: LiveSource) -> Self {
        Self {
            source: Arc::new(source),
            shown: None,
            task: None,
            volume: None,
            failed: None,
        }
    }
    /// The daylight the texture holds, once swept.
    pub fn shown(&self) -> Option<Daylight> {
        self.shown
    }
    /// Whether a sweep is under way.
    pub fn sweeping(&self) -> bool {
        self.task.is_some()
    }
    /// The volume the texture holds (texels, intensity before the unit scale), once
    /// swept.
    pub fn volume(&self) -> Option<&BevyVolume> {
        self.volume.as_ref()
    }
    /// Its source.
    pub fn source(&self) -> &LiveSource {
        &self.source
    }
}

/// Sweeps `source` under `daylight` now, on this thread, and spawns its light probe: a
/// [`LightProbe`], an [`IrradianceVolume`] whose texture is the new image, its
/// transform and a [`LiveVolume`] that later daylight sweeps again.
pub fn spawn_live_volume(
    commands: &mut Commands,
    images: &mut Assets<Image>,
    source: LiveSource,
    daylight: &Daylight,
) -> Result<Entity, LiveError> {
    let volume = bake(&source, daylight)?;
    let handle = images.add(image_of(&volume));
    let intensity = volume.intensity() * source.unit_scale;
    let transform = transform_of(&volume);
    let mut live = LiveVolume::new(source);
    live.shown = Some(*daylight);
    live.volume = Some(volume);
    Ok(commands
        .spawn((
            LightProbe,
            IrradianceVolume {
                voxels: handle,
                intensity,
                affects_lightmapped_meshes: true,
            },
            transform,
            live,
        ))
        .id())
}

/// Spawns a light probe for every volume of a `lightgrid bake` sidecar (`json`: its
/// text; `dir`: its folder under the asset root, whose KTX2 files the asset server
/// loads, with Bevy's `ktx2` feature). Returns the entities; the volumes stay as baked.
pub fn spawn_baked_volumes(
    commands: &mut Commands,
    assets: &AssetServer,
    json: &str,
    dir: &str,
) -> Result<Vec<Entity>, LiveError> {
    let sidecar: lightgrid_export::Sidecar =
        serde_json::from_str(json).map_err(|e| LiveError::Sidecar(e.to_string()))?;
    Ok(sidecar
        .volumes
        .iter()
        .map(|v| {
            let path = if dir.is_empty() {
                v.ktx2.clone()
            } else {
                format!("{}/{}", dir.trim_end_matches('/'), v.ktx2)
            };
            commands.spawn(probe_of(v, assets.load(path))).id()
        })
        .collect())
}

/// A `lightgrid bake` sidecar loaded as an asset (`assets.load::<BakedVolumes>("x.json")`):
/// the sidecar and a handle to each of its volumes' KTX2 textures, loaded with it as
/// dependencies (file names relative to the sidecar's folder). Put a [`BakedProbes`]
/// holding the handle on an entity and the plugin spawns the light probes once
/// everything has loaded.
#[derive(Asset, TypePath, Debug)]
pub struct BakedVolumes {
    /// The sidecar as written.
    pub sidecar: lightgrid_export::Sidecar,
    /// One texture a volume, in the sidecar's order.
    pub textures: Vec<Handle<Image>>,
}

/// Loads `lightgrid bake` sidecars (`.json`) as [`BakedVolumes`].
#[derive(Default, TypePath)]
pub struct SidecarLoader;

impl bevy::asset::AssetLoader for SidecarLoader {
    type Asset = BakedVolumes;
    type Settings = ();
    type Error = LiveError;

    async fn load(
        &self,
        reader: &mut dyn bevy::asset::io::Reader,
        _settings: &(),
        load_context: &mut bevy::asset::LoadContext<'_>,
    ) -> Result<BakedVolumes, LiveError> {
        let mut bytes = Vec::new();
        reader
            .read_to_end(&mut bytes)
            .await
            .map_err(|e| LiveError::Sidecar(e.to_string()))?;
        let sidecar: lightgrid_export::Sidecar =
            serde_json::from_slice(&bytes).map_err(|e| LiveError::Sidecar(e.to_string()))?;
        let own = load_context.path().clone();
        let textures = sidecar
            .volumes
            .iter()
            .map(|v| {
                let path = own
                    .resolve_embed(&v.ktx2)
                    .map_err(|e| LiveError::Sidecar(format!("{}: {e}", v.ktx2)))?;
                Ok(load_context.load(path))
            })
            .collect::<Result<Vec<_>, LiveError>>()?;
        Ok(BakedVolumes { sidecar, textures })
    }

    fn extensions(&self) -> &[&str] {
        &["json"]
    }
}

/// A sidecar whose volumes the plugin turns into light probes once it and its
/// textures have loaded ([`BakedVolumes`]): each a child entity of this one with a
/// [`LightProbe`], an [`IrradianceVolume`] and the sidecar's transform (relative to this
/// entity's, the identity unless set: move the entity and its volumes move with it).
#[derive(Component, Debug, Clone)]
#[require(Transform, Visibility)]
pub struct BakedProbes(pub Handle<BakedVolumes>);

/// Marks a [`BakedProbes`] entity whose probes are spawned.
#[derive(Component)]
struct ProbesSpawned;

/// Spawns the probes of every [`BakedProbes`] whose sidecar and textures have loaded.
fn spawn_loaded_probes(
    mut commands: Commands,
    server: Res<AssetServer>,
    baked: Res<Assets<BakedVolumes>>,
    pending: Query<(Entity, &BakedProbes), Without<ProbesSpawned>>,
) {
    for (e, probes) in &pending {
        if !server.is_loaded_with_dependencies(&probes.0) {
            continue;
        }
        let Some(set) = baked.get(&probes.0) else {
            continue;
        };
        commands
            .entity(e)
            .insert(ProbesSpawned)
            .with_children(|parent| {
                for (v, texture) in set.sidecar.volumes.iter().zip(&set.textures) {
                    parent.spawn(probe_of(v, texture.clone()));
                }
            });
    }
}

/// The light probe of a sidecar's volume with its texture.
fn probe_of(
    v: &lightgrid_export::VolumeInfo,
    texture: Handle<Image>,
) -> (LightProbe, IrradianceVolume, Transform) {
    let t = &v.transform;
    (
        LightProbe,
        IrradianceVolume {
            voxels: texture,
            intensity: v.intensity,
            affects_lightmapped_meshes: true,
        },
        Transform {
            translation: Vec3::from_array(t.translation),
            rotation: Quat::from_array(t.rotation),
            scale: Vec3::from_array(t.scale),
        },
    )
}

/// The plugin: sweeps live volumes again when [`Daylight`] changes and replaces their
/// textures as the sweeps finish.
#[derive(Debug, Clone, Copy)]
pub struct LightgridPlugin {
    /// Most textures replaced in one frame (each upload copies a volume to the GPU).
    pub uploads_per_frame: usize,
    /// Most sweeps under way at once (the rest start as these finish).
    pub sweeps_at_once: usize,
}

impl Default for LightgridPlugin {
    fn default() -> Self {
        Self {
            uploads_per_frame: 1,
            sweeps_at_once: 2,
        }
    }
}

/// The plugin's settings, as a resource.
#[derive(Resource, Debug, Clone, Copy)]
struct Settings(LightgridPlugin);

/// What the plugin has done, for a summary or a test: sweeps started and finished,
/// textures replaced, sweeps that failed (each failure also logged).
#[derive(Resource, Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LiveStats {
    /// Sweeps started.
    pub started: u64,
    /// Textures replaced.
    pub uploaded: u64,
    /// Sweeps whose result was dropped: failed, or outdated by a later daylight.
    pub dropped: u64,
}

impl Plugin for LightgridPlugin {
    fn build(&self, app: &mut App) {
        app.insert_resource(Settings(*self))
            .init_resource::<Daylight>()
            .init_resource::<LiveStats>()
            .init_asset::<BakedVolumes>()
            .init_asset_loader::<SidecarLoader>()
            .add_systems(Update, (start_sweeps, finish_sweeps).chain())
            .add_systems(Update, spawn_loaded_probes);
    }
}

/// Starts a sweep for each live volume whose texture does not hold the current
/// daylight and that has none under way for it, up to the plugin's limit.
fn start_sweeps(
    daylight: Res<Daylight>,
    settings: Res<Settings>,
    mut stats: ResMut<LiveStats>,
    mut volumes: Query<&mut LiveVolume>,
) {
    let d = *daylight;
    let mut running = volumes.iter().filter(|v| v.task.is_some()).count();
    let pool = AsyncComputeTaskPool::get();
    for mut v in &mut volumes {
        if running >= settings.0.sweeps_at_once {
            break;
        }
        let wanted = v.shown != Some(d) && v.failed != Some(d);
        if !wanted || v.task.is_some() {
            continue;
        }
        let source = v.source.clone();
        v.task = Some((d, pool.spawn(async move { bake(&source, &d) })));
        stats.started += 1;
        running += 1;
    }
}

/// Replaces the textures of finished sweeps, at most the plugin's uploads a frame.
fn finish_sweeps(
    daylight: Res<Daylight>,
    settings: Res<Settings>,
    mut stats: ResMut<LiveStats>,
    mut images: ResMut<Assets<Image>>,
    mut volumes: Query<(&mut LiveVolume, &mut IrradianceVolume)>,
) {
    let mut uploads = 0;
    for (mut live, mut probe) in &mut volumes {
        if uploads >= settings.0.uploads_per_frame {
            break;
        }
        let Some((d, task)) = live.task.as_mut() else {
            continue;
        };
        let d = *d;
        let Some(result) = block_on(future::poll_once(task)) else {
            continue;
        };
        live.task = None;
        match result {
            // A sweep for a daylight since replaced is dropped: the next starts now.
            Ok(_) if d != *daylight => stats.dropped += 1,
            Ok(volume) => {
                let image = image_of(&volume);
                match images.get_mut(&probe.voxels) {
                    Some(old) => *old = image,
                    None => probe.voxels = images.add(image),
                }
                probe.intensity = volume.intensity() * live.source.unit_scale;
                live.shown = Some(d);
                live.volume = Some(volume);
                stats.uploaded += 1;
                uploads += 1;
            }
            Err(e) => {
                error!("lightgrid: sweeping a live volume failed: {e}");
                stats.dropped += 1;
                // Not tried again until the daylight changes; the texture keeps the
                // light it had.
                live.failed = Some(d);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn source() -> LiveSource {
        let mut s = LiveSource::new(flat_ground(6, 2, 1.0, 0.5).unwrap(), 1.0);
        s.sides = SideBoundary::Periodic;
        s
    }

    /// Over a flat ground of albedo a under a sky of radiance L and a sun of irradiance
    /// E at elevation θ, the ground reflects a (π L + E sin θ) / π: a face looking down
    /// well above it reads that (irradiance / π from a Lambertian half-space below),
    /// and moving the sun changes it by a E Δ(sin θ) / π.
    #[test]
    fn the_face_looking_down_follows_the_sun() {
        let s = source();
        let look_down = |elevation: f32| {
            let d = Daylight::at(elevation, 40.0, Vec3::splat(2.0), Vec3::splat(0.5));
            let v = bake(&s, &d).unwrap();
            v.texel(glam::UVec3::new(3, 6, 3), 3).x * v.intensity()
        };
        for e in [70.0f32, 20.0] {
            let exact = 0.5 * (std::f32::consts::PI * 0.5 + 2.0 * e.to_radians().sin())
                / std::f32::consts::PI;
            let got = look_down(e);
            assert!(
                (got / exact - 1.0).abs() < 0.02,
                "{e}°: {got} against {exact}"
            );
        }
    }

    /// The clear day's sky and sun keep the IES proportion: the face looking down reads
    /// `a (E_sky + E_sun sin θ) / π` with both illuminances from the IES clear-sky
    /// formulas, at a high and a low sun.
    #[test]
    fn a_clear_day_lights_the_ground_as_measured_skies_do() {
        let s = source();
        for e in [60.0f32, 15.0] {
            let d = Daylight::clear(e, 40.0, lightgrid_sky::DEFAULT_TURBIDITY);
            let v = bake(&s, &d).unwrap();
            let got = lightgrid_core::light::luminance(
                v.texel(glam::UVec3::new(3, 6, 3), 3) * v.intensity(),
            );
            let h = e.to_radians();
            let ground = lightgrid_sky::ies_sky_illuminance(h)
                + lightgrid_sky::ies_sun_illuminance(h) * h.sin();
            let exact = 0.5 * ground / std::f32::consts::PI;
            assert!(
                (got / exact - 1.0).abs() < 0.02,
                "{e}°: {got} against {exact}"
            );
        }
    }

    #[test]
    fn the_image_is_the_volume_texture() {
        let v = bake(&source(), &Daylight::default()).unwrap();
        let img = image_of(&v);
        let size = v.texture_size();
        assert_eq!(img.texture_descriptor.size.width, size.x);
        assert_eq!(img.texture_descriptor.size.height, size.y);
        assert_eq!(img.texture_descriptor.size.depth_or_array_layers, size.z);
        assert_eq!(img.texture_descriptor.format, TextureFormat::Rgb9e5Ufloat);
        let data = img.data.as_ref().unwrap();
        assert_eq!(data.len(), v.texels().len() * 4);
        assert_eq!(&data[..4], &v.texels()[0].to_le_bytes());
    }

    /// A `lightgrid bake` sidecar becomes one light probe a volume: its texture asked of
    /// the asset server under the folder given, its intensity and transform as written.
    #[test]
    fn a_baked_sidecar_becomes_light_probes() {
        use bevy::ecs::system::RunSystemOnce;
        let v = bake(&source(), &Daylight::default()).unwrap();
        let info = v
            .sidecar("tile", lightgrid_export::Content::Indirect, 2.0)
            .unwrap();
        let json = lightgrid_export::Sidecar::new(vec![info.clone(), info.clone()], None).to_json();
        let mut app = App::new();
        app.add_plugins((MinimalPlugins, AssetPlugin::default()))
            .init_asset::<Image>();
        let spawned = app
            .world_mut()
            .run_system_once(move |mut commands: Commands, assets: Res<AssetServer>| {
                spawn_baked_volumes(&mut commands, &assets, &json, "volumes/").unwrap()
            })
            .unwrap();
        assert_eq!(spawned.len(), 2);
        let world = app.world_mut();
        for e in spawned {
            let probe = world.get::<IrradianceVolume>(e).unwrap();
            assert_eq!(probe.intensity, info.intensity);
            assert_eq!(probe.intensity, v.intensity() * 2.0);
            let path = probe.voxels.path().unwrap().to_string();
            assert_eq!(path, "volumes/tile.ktx2");
            let t = world.get::<Transform>(e).unwrap();
            assert_eq!(t.translation.to_array(), info.transform.translation);
            assert_eq!(t.scale.to_array(), info.transform.scale);
            assert!(world.get::<LightProbe>(e).is_some());
        }
        let bad = world
            .run_system_once(|mut commands: Commands, assets: Res<AssetServer>| {
                spawn_baked_volumes(&mut commands, &assets, "{", "")
                    .unwrap_err()
                    .to_string()
            })
            .unwrap();
        assert!(bad.starts_with("sidecar:"), "{bad}");
    }

    /// The plugin in an app without a window: a live volume swept under one daylight is
    /// swept again when the resource changes, and its image and intensity become the
    /// new sweep's; unchanged daylight starts nothing.
    #[test]
    fn the_plugin_sweeps_again_when_the_daylight_changes() {
        use bevy::ecs::system::RunSystemOnce;
        let mut app = App::new();
        app.add_plugins((MinimalPlugins, AssetPlugin::default()))
            .init_asset::<Image>()
            .add_plugins(LightgridPlugin::default());
        let first = Daylight::at(70.0, 40.0, Vec3::splat(3.0), Vec3::splat(0.3));
        app.insert_resource(first);
        let e = app
            .world_mut()
            .run_system_once(
                move |mut commands: Commands, mut images: ResMut<Assets<Image>>| {
                    spawn_live_volume(&mut commands, &mut images, source(), &first).unwrap()
                },
            )
            .unwrap();
        let image_data = |app: &mut App| {
            let w = app.world();
            let h = w.get::<IrradianceVolume>(e).unwrap().voxels.clone();
            w.resource::<Assets<Image>>()
                .get(&h)
                .unwrap()
                .data
                .clone()
                .unwrap()
        };
        let before = image_data(&mut app);
        for _ in 0..5 {
            app.update();
        }
        assert_eq!(*app.world().resource::<LiveStats>(), LiveStats::default());
        let second = Daylight::at(12.0, 40.0, Vec3::splat(3.0), Vec3::splat(0.3));
        app.insert_resource(second);
        let mut frames = 0;
        while app.world().get::<LiveVolume>(e).unwrap().shown() != Some(second) {
            app.update();
            frames += 1;
            assert!(frames < 10_000, "not swept again");
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
        let stats = *app.world().resource::<LiveStats>();
        assert_eq!((stats.started, stats.uploaded, stats.dropped), (1, 1, 0));
        let after = image_data(&mut app);
        let expect = bake(&source(), &second).unwrap();
        assert_ne!(before, after);
        assert_eq!(after, image_of(&expect).data.unwrap());
        let probe = app.world().get::<IrradianceVolume>(e).unwrap();
        assert_eq!(probe.intensity, expect.intensity());
    }

    /// A sidecar loaded as an asset brings its KTX2 textures as dependencies, and a
    /// [`BakedProbes`] entity gets one probe child a volume once all have loaded: the
    /// sidecar's intensity and transform, the texture the volume's (size and format).
    #[test]
    fn a_sidecar_asset_spawns_its_probes_once_loaded() {
        use bevy::image::{CompressedImageFormats, ImageLoader};
        let dir = std::env::temp_dir().join(format!("lightgrid-bevy-test-{}", std::process::id()));
        let v = bake(&source(), &Daylight::default()).unwrap();
        lightgrid_export::write_volumes(
            &dir,
            "tile",
            &[v.clone(), v.clone()],
            lightgrid_export::Content::Indirect,
            1.0,
            None,
        )
        .unwrap();
        let mut app = App::new();
        app.add_plugins((
            MinimalPlugins,
            AssetPlugin {
                file_path: dir.to_string_lossy().into_owned(),
                ..default()
            },
            bevy::image::ImagePlugin::default(),
            LightgridPlugin::default(),
        ))
        // (The render plugin registers the image loader with the device's formats.)
        .register_asset_loader(ImageLoader::new(CompressedImageFormats::NONE));
        let handle: Handle<BakedVolumes> = app.world().resource::<AssetServer>().load("tile.json");
        let e = app.world_mut().spawn(BakedProbes(handle)).id();
        let mut frames = 0;
        while app.world().get::<Children>(e).is_none() {
            app.update();
            frames += 1;
            assert!(frames < 10_000, "the probes never came");
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
        let children: Vec<Entity> = app.world().get::<Children>(e).unwrap().to_vec();
        assert_eq!(children.len(), 2);
        let size = v.texture_size();
        for c in children {
            let w = app.world();
            let probe = w.get::<IrradianceVolume>(c).unwrap();
            assert_eq!(probe.intensity, v.intensity());
            let img = w.resource::<Assets<Image>>().get(&probe.voxels).unwrap();
            let d = img.texture_descriptor.size;
            assert_eq!(
                (d.width, d.height, d.depth_or_array_layers),
                (size.x, size.y, size.z)
            );
            assert_eq!(img.texture_descriptor.format, TextureFormat::Rgb9e5Ufloat);
            assert_eq!(*w.get::<Transform>(c).unwrap(), transform_of(&v));
        }
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn bad_daylight_and_scale_are_refused_by_name() {
        let mut d = Daylight {
            sky: Sky::Uniform(Vec3::new(f32::NAN, 0.0, 0.0)),
            ..Default::default()
        };
        assert!(bake(&source(), &d).unwrap_err().to_string().contains("sky"));
        d.sky = Sky::Clear { turbidity: 0.5 };
        let e = bake(&source(), &d).unwrap_err().to_string();
        assert!(e.contains("turbidity"), "{e}");
        d = Daylight::default();
        d.to_sun = Vec3::ZERO;
        assert!(
            bake(&source(), &d)
                .unwrap_err()
                .to_string()
                .contains("to_sun")
        );
        let mut s = source();
        s.unit_scale = 0.0;
        let e = bake(&s, &Daylight::default()).unwrap_err().to_string();
        assert!(e.contains("unit_scale"), "{e}");
    }
}
