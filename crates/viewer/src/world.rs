//! Builds a scene's world: heightmap, models and their material grids, instances, the
//! area composer, the sky and the light grid hierarchy.

use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use lightgrid_core::glam::{Quat, Vec2, Vec3};
use lightgrid_core::{BinLight, LightKind, MaterialGrid, Sweeper};
use lightgrid_material_voxelizer::compose::{
    AreaComposer, ComposeParams, GroundColour, Heightmap, Instance, Terrain,
};
use lightgrid_material_voxelizer::model::{Model, Texture};
use lightgrid_material_voxelizer::procedural::{TreeParams, bush, rock, tree};
use lightgrid_material_voxelizer::voxelize::{VoxelizeParams, voxelize};
use lightgrid_sky::{SkySpec, Sun};
use lightgrid_terrain_lod::bake::WorldBake;
use lightgrid_terrain_lod::{Hierarchy, HierarchyParams};

use crate::scene::{ProceduralModel, SceneFile, SkyKind};

/// Which sweeper computes the grids.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum SweeperChoice {
    /// The CPU sweeper, for now: the GPU's is latency-bound on the hierarchy's
    /// node-sized grids (a level costs an NVIDIA H200 about 0.2 ms whatever its size),
    /// and the demo took 4.9–5.4 s with it there against 2.1 s with 16 CPU cores' (3.1 s
    /// on two); see `docs/measurements.md`.
    Auto,
    /// The multithreaded CPU sweep.
    Cpu,
    /// The wgpu compute sweep (any adapter, lavapipe included).
    Gpu,
}

/// A model and the instances placed from the scene file.
pub struct ModelEntry {
    /// Name in the scene file.
    pub name: String,
    /// Its triangles and materials.
    pub model: Model,
    /// Leaves and bushes (alpha-masked or procedural foliage) are lit as foliage.
    pub foliage: bool,
}

/// Everything built from a scene file.
pub struct World {
    /// The scene.
    pub scene: SceneFile,
    /// Terrain heights.
    pub heightmap: Heightmap,
    /// Ground colour.
    pub ground: GroundColour,
    /// Models, in scene order.
    pub models: Vec<ModelEntry>,
    /// All instances (model = index into `models`).
    pub instances: Vec<Instance>,
    /// The material of any box (shared with the hierarchy).
    pub composer: Arc<AreaComposer>,
    /// The light grids.
    pub hierarchy: Hierarchy,
    /// The scene's sky, resolved once.
    pub sky: SkySpec,
    /// Sky light entering the top (without the sun).
    pub sky_top: BinLight,
    /// The way sunlight travels (unit), and its irradiance (zero below the horizon).
    pub sun: (Vec3, Vec3),
    /// Name of the sweeper used.
    pub sweeper: String,
    /// The GPU sweeps the grids (else the CPU).
    pub gpu_sweeps: bool,
    /// Seconds per stage.
    pub timings: Vec<(String, f64)>,
    /// Material grid bytes of the models.
    pub model_grid_bytes: u64,
    /// Dynamic lights and their culling grid (empty without `[dynamic_lights]`).
    pub dynamic: lightgrid_render::DynamicLights,
    /// The light probes (with `[probes]`).
    pub probes: Option<crate::probes::Probes>,
}

/// `f()`, its wall time pushed onto `timings` as `stage`.
fn timed<T>(
    timings: &mut Vec<(String, f64)>,
    stage: &str,
    f: impl FnOnce() -> Result<T>,
) -> Result<T> {
    let t = Instant::now();
    let out = f()?;
    timings.push((stage.to_string(), t.elapsed().as_secs_f64()));
    Ok(out)
}

/// The scene's terrain: its heights (a PNG heightmap or procedural) and ground colour.
fn load_terrain(scene: &SceneFile) -> Result<(Heightmap, GroundColour)> {
    let ts = &scene.terrain;
    let heightmap = match (&ts.heightmap, &ts.procedural) {
        (Some(path), _) => {
            let p = scene.resolve(path);
            lightgrid_material_voxelizer::compose::load_heightmap_png(
                &p,
                Vec2::ZERO,
                ts.spacing,
                ts.height_scale,
                0.0,
            )
            .with_context(|| format!("terrain.heightmap {}", p.display()))?
        }
        (None, Some(p)) => procedural_heightmap(p, ts.spacing)?,
        (None, None) => anyhow::bail!("terrain: no heightmap"),
    };
    let ground = match &ts.ground_texture {
        Some(path) => {
            let (w, d) = (
                (heightmap.width - 1) as f32 * heightmap.spacing,
                (heightmap.depth - 1) as f32 * heightmap.spacing,
            );
            GroundColour::Texture {
                texture: load_texture_png(&scene.resolve(path))
                    .context("terrain.ground_texture")?,
                origin: heightmap.origin,
                size: Vec2::new(w, d),
            }
        }
        None => GroundColour::Uniform(Vec3::from_array(ts.ground_colour)),
    };
    Ok((heightmap, ground))
}

/// The scene's models, loaded or made, and their material grids, in scene order.
fn voxelize_models(scene: &SceneFile) -> Result<(Vec<ModelEntry>, Vec<MaterialGrid>)> {
    let mut models = Vec::new();
    let mut grids: Vec<MaterialGrid> = Vec::new();
    let pb = bar(scene.models.len() as u64, "voxelizing models");
    for (i, m) in scene.models.iter().enumerate() {
        pb.set_message(format!("voxelizing {}", m.name));
        let (model, foliage) = model_of(scene, i)?;
        let (grid, _) = voxelize(&model, &VoxelizeParams::standard(m.voxel_size), &|_, _| {})
            .with_context(|| format!("voxelizing models[{i}] ({})", m.name))?;
        grids.push(grid);
        models.push(ModelEntry {
            name: m.name.clone(),
            model,
            foliage,
        });
        pb.inc(1);
    }
    pb.finish_and_clear();
    Ok((models, grids))
}

/// Model `i` of the scene (a glTF file or a procedural kind), and whether it is lit as
/// foliage (alpha-masked materials, procedural plants).
fn model_of(scene: &SceneFile, i: usize) -> Result<(Model, bool)> {
    let m = &scene.models[i];
    Ok(match (&m.gltf, m.procedural) {
        (Some(path), _) => {
            let p = scene.resolve(path);
            let model = Model::load_gltf(&p)
                .with_context(|| format!("models[{i}].gltf {}", p.display()))?;
            let foliage = model.materials.iter().any(|s| {
                !matches!(
                    s.alpha,
                    lightgrid_material_voxelizer::model::AlphaMode::Opaque
                )
            });
            (model, foliage)
        }
        (None, Some(ProceduralModel::Broadleaf)) => (tree(&TreeParams::broadleaf(m.seed))?, true),
        (None, Some(ProceduralModel::Young)) => (tree(&TreeParams::young(m.seed))?, true),
        (None, Some(ProceduralModel::Bush)) => (bush(m.seed, 1.2)?, true),
        (None, Some(ProceduralModel::Rock)) => (rock(m.seed, 1.0)?, false),
        (None, None) => anyhow::bail!("models[{i}]: no source"),
    })
}

/// The scene's instances on the terrain: those placed one by one, then each scatter's
/// (seeded, so the same scene gives the same forest).
fn place_instances(scene: &SceneFile, heightmap: &Heightmap) -> Vec<Instance> {
    let index = |name: &str| {
        scene
            .models
            .iter()
            .position(|m| m.name == name)
            .expect("validated") as u32
    };
    let mut instances = Vec::new();
    for inst in &scene.instances {
        let [x, z] = inst.position;
        instances.push(Instance {
            model: index(&inst.model),
            position: Vec3::new(x, heightmap.height_at(x, z) + inst.height, z),
            rotation: Quat::from_rotation_y(inst.rotation_deg.to_radians()),
            scale: inst.scale,
        });
    }
    for s in &scene.scatter {
        let mut rng = fastrand::Rng::with_seed(s.seed ^ ((index(&s.model) as u64 + 1) * 7919));
        let mut r = move || rng.f32();
        for _ in 0..s.count {
            let (a, d) = (r() * std::f32::consts::TAU, s.radius * r().sqrt());
            let (x, z) = (s.centre[0] + d * a.cos(), s.centre[1] + d * a.sin());
            instances.push(Instance {
                model: index(&s.model),
                // Sunk a little so slopes leave no gap under the trunk.
                position: Vec3::new(x, heightmap.height_at(x, z) - 0.2, z),
                rotation: Quat::from_rotation_y(r() * std::f32::consts::TAU),
                scale: s.scale[0] + r() * (s.scale[1] - s.scale[0]),
            });
        }
    }
    instances
}

/// The light grid hierarchy over the terrain, its world grid swept under the sky
/// (`sky_top`; with the sun in the bins, sky and sun together) by the chosen sweeper;
/// also the sweeper's name.
fn world_grid(
    scene: &SceneFile,
    heightmap: &Heightmap,
    composer: &Arc<AreaComposer>,
    sky_top: &BinLight,
    (sweeper, gpu): (SweeperChoice, &Option<Arc<lightgrid_gpu::GpuContext>>),
) -> Result<(Hierarchy, String)> {
    // With the sun kept apart the bins get the sky alone.
    let top = if scene.sun.split {
        *sky_top
    } else {
        boundary_light(sky_top, scene)?
    };
    let (sweeper, name) = choose_sweeper(sweeper, gpu)?;
    let mut params = hierarchy_params(scene, false);
    // The sun's first collisions swept with the sky, one sweep a grid (the same light;
    // a moved sun sweeps the clear sky's grids again anyway). Not on the GPU sweeper,
    // whose scattered sun the renderer's device sampling reads where it lies.
    params.sun_with_sky = scene.sun.split && !name.starts_with("gpu");
    let hierarchy = Hierarchy::new(heightmap, Box::new(composer.clone()), sweeper, top, params)
        .context("building the light grid hierarchy")?;
    Ok((hierarchy, name))
}

/// The hierarchy's parameters from the scene's `[grid]`, for a world bake (`bake`:
/// its gather left out is `Gather::AUTO`) or the viewer's frames (off).
fn hierarchy_params(scene: &SceneFile, bake: bool) -> HierarchyParams {
    let g = &scene.grid;
    let mut params = HierarchyParams {
        world_cell: g.world_cell,
        finest_cell: g.finest_cell,
        node_points: g.node_points,
        apron: g.apron,
        neighbour_halo: g.neighbour_halo,
        ..Default::default()
    };
    // Four of the largest nodes a frame.
    params.budget_points = 4 * params.largest_node();
    params.sweep.max_passes = g.passes;
    params.sweep.gather = g.gather(bake);
    params
}

/// What a world bake of the scene needs (`lightgrid bake world.toml`): the terrain, the
/// models and instances composed, the sky and sun (kept apart with `sun.split`) and the
/// grid settings, with the CPU sweeper; nothing swept yet. Also the sun as (direction
/// toward it, irradiance), for the volumes' sidecar.
pub fn world_bake(scene: &SceneFile) -> Result<(WorldBake, (Vec3, Vec3))> {
    let (heightmap, ground) = load_terrain(scene)?;
    let (_, grids) = voxelize_models(scene)?;
    let instances = place_instances(scene, &heightmap);
    let terrain = Terrain {
        heightmap: heightmap.clone(),
        colour: ground,
    };
    let composer = AreaComposer::new(grids, &instances, Some(terrain), ComposeParams::default())?;
    let (sky_top, sun) = sky_and_sun(scene, &sky_spec(scene)?)?;
    let (top, split) = if scene.sun.split {
        (sky_top, Some(sun_light(sun)))
    } else {
        (boundary_light(&sky_top, scene)?, None)
    };
    let bake = WorldBake::new(
        &heightmap,
        Box::new(composer),
        Box::new(lightgrid_sweep_cpu::CpuSweeper::new()),
        top,
        split,
        hierarchy_params(scene, true),
    )
    .context("laying out the world's grids")?;
    Ok((bake, (-sun.0, sun.1)))
}

fn bar(len: u64, what: &str) -> ProgressBar {
    let b = if std::env::var_os("LIGHTGRID_QUIET").is_some() {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(len)
    };
    b.set_style(
        ProgressStyle::with_template("{msg:28} [{bar:30}] {pos}/{len} {elapsed}")
            .expect("valid template")
            .progress_chars("=> "),
    );
    b.set_message(what.to_string());
    b
}

/// Most samples along one side of a procedural terrain (a 16384² heightmap is 1 GiB).
const MAX_TERRAIN_SAMPLES_PER_SIDE: f32 = 16384.0;

fn procedural_heightmap(p: &crate::scene::ProceduralTerrain, spacing: f32) -> Result<Heightmap> {
    use noise::{Fbm, MultiFractal, NoiseFn, Perlin};
    let fbm = Fbm::<Perlin>::new(p.seed)
        .set_octaves(5)
        .set_frequency(1.0 / p.feature_size as f64);
    let n = (p.size / spacing).round();
    if !(1.0..MAX_TERRAIN_SAMPLES_PER_SIDE).contains(&n) {
        anyhow::bail!(
            "terrain.procedural.size / terrain.spacing = {} / {spacing} = {n} samples a side: at most {}",
            p.size,
            MAX_TERRAIN_SAMPLES_PER_SIDE - 1.0
        );
    }
    let n = n as u32 + 1;
    Ok(Heightmap::from_fn(Vec2::ZERO, spacing, n, n, |x, z| {
        // fBm is roughly in [-1, 1]; map to [0, relief].
        let v = fbm.get([x as f64, z as f64]) as f32;
        (0.5 + 0.5 * v).clamp(0.0, 1.0) * p.relief
    })?)
}

fn load_texture_png(path: &std::path::Path) -> Result<Texture> {
    let bytes = lightgrid_core::limits::read_file(
        path,
        lightgrid_material_voxelizer::gltf_read::MAX_MODEL_BYTES,
    )?;
    lightgrid_material_voxelizer::gltf_read::decode_texture(&bytes)
        .map_err(|e| anyhow::anyhow!("decoding {}: {e}", path.display()))
}

/// The scene's sky, resolved once (an EXR map is read here, not again when the sun
/// moves).
pub fn sky_spec(scene: &SceneFile) -> Result<SkySpec> {
    Ok(match scene.sky.kind {
        SkyKind::Uniform => SkySpec::Uniform(Vec3::from_array(scene.sky.radiance)),
        SkyKind::Exr => {
            let f = scene.resolve(scene.sky.file.as_ref().context("sky.file")?);
            SkySpec::exr(&f).with_context(|| format!("sky.file {}", f.display()))?
        }
        SkyKind::Clear => SkySpec::Clear,
        SkyKind::Daylight => SkySpec::Daylight(scene.sky.turbidity),
    })
}

/// The sky's top boundary (sun excluded), and the sun.
pub fn sky_and_sun(scene: &SceneFile, spec: &SkySpec) -> Result<(BinLight, (Vec3, Vec3))> {
    let (elevation, azimuth) = scene.sun.angles();
    let illuminance = Vec3::from_array(scene.sun.illuminance);
    let sun = Sun::at(elevation, azimuth, illuminance);
    let sky = spec.bins(sun.direction)?.top.scaled(scene.sky.scale);
    let sun_light = if elevation > 0.0 {
        illuminance
    } else {
        Vec3::ZERO
    };
    Ok((sky, (-sun.direction.normalize(), sun_light)))
}

/// What [`World::move_sun`] recomputed at once (the world grid's part; the nodes follow
/// within the hierarchy's budget).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SunMove {
    /// The sun is kept apart: only its responses were recomputed for it.
    pub split: bool,
    /// The sky's grids are swept again too (sun in the bins, or a clear sky).
    pub sky_reswept: bool,
    /// The sun's first collisions are swept with the sky
    /// ([`lightgrid_terrain_lod::HierarchyParams::sun_with_sky`]): every grid is swept
    /// again, sky and scattered sun in one sweep.
    pub with_sky: bool,
    /// Seconds spent on the world grid.
    pub seconds: f64,
}

impl std::fmt::Display for SunMove {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match (self.split, self.sky_reswept) {
            (true, _) if self.with_sky => write!(
                f,
                "every grid's transmittance re-marched at once; the sun's first collisions are swept with the sky (one sweep a grid), so every grid is swept again, the world grid at once, the nodes after"
            ),
            (true, false) => write!(
                f,
                "sun responses recomputed (every grid's transmittance and the world grid's scattered sun at once, the nodes' scattered sun after), sky's grids kept"
            ),
            (true, true) => write!(
                f,
                "sun responses recomputed (every grid's transmittance and the world grid's scattered sun at once, the nodes' scattered sun after); the clear sky's shape follows the sun, so its grids are swept again too"
            ),
            (false, _) => write!(f, "sky and sun swept again (the sun is in the bins)"),
        }?;
        write!(f, "; world grid {:.2} s", self.seconds)
    }
}

/// The sweeper `choice` asks for, and its name for the summary. The GPU sweeper shares
/// the renderer's device `gpu` when one is given (one device per process); otherwise it
/// opens its own.
fn choose_sweeper(
    choice: SweeperChoice,
    gpu: &Option<Arc<lightgrid_gpu::GpuContext>>,
) -> Result<(Box<dyn Sweeper + Send + Sync>, String)> {
    let open = || -> Result<Arc<lightgrid_gpu::GpuContext>, lightgrid_gpu::GpuError> {
        match gpu {
            Some(c) => Ok(c.clone()),
            None => Ok(Arc::new(lightgrid_gpu::GpuContext::new()?)),
        }
    };
    // On the renderer's device the sweeper keeps its grids there, and the renderer
    // samples and draws them in place (SceneMeshes::relight).
    let gpu_sweeper = |c: Arc<lightgrid_gpu::GpuContext>| {
        let mut s = lightgrid_sweep_gpu::GpuSweeper::with_context(c);
        s.keep_resident(gpu.is_some());
        Box::new(s)
    };
    Ok(match choice {
        SweeperChoice::Cpu => (
            Box::new(lightgrid_sweep_cpu::CpuSweeper::new()),
            "cpu".into(),
        ),
        SweeperChoice::Auto => (
            Box::new(lightgrid_sweep_cpu::CpuSweeper::new()),
            "cpu (auto: the GPU sweeper is slower on the hierarchy's node-sized grids)".into(),
        ),
        SweeperChoice::Gpu => {
            let c = open().context("--sweeper gpu")?;
            let name = format!("gpu ({})", c.info.name);
            (gpu_sweeper(c), name)
        }
    })
}

/// The hierarchy's sun from [`sky_and_sun`]'s (travel direction, irradiance).
pub fn sun_light(sun: (Vec3, Vec3)) -> lightgrid_terrain_lod::SunLight {
    lightgrid_terrain_lod::SunLight {
        to_sun: -sun.0,
        irradiance: sun.1,
    }
}

/// The sky top boundary with the sun disc in it (what the sweep reads).
pub fn boundary_light(sky: &BinLight, scene: &SceneFile) -> Result<BinLight> {
    let (elevation, azimuth) = scene.sun.angles();
    let mut top = *sky;
    if elevation > 0.0 {
        let sun = Sun::at(elevation, azimuth, Vec3::from_array(scene.sun.illuminance)).bins()?;
        top += sun;
    }
    Ok(top)
}

/// The scene's dynamic lights, standing on the ground, with their culling grid.
fn dynamic_lights(scene: &SceneFile, hm: &Heightmap) -> Result<lightgrid_render::DynamicLights> {
    let Some(d) = &scene.dynamic_lights else {
        return Ok(lightgrid_render::DynamicLights::build(Vec::new(), 4.0)?);
    };
    let (c, r) = (Vec2::from_array(d.centre), d.radius);
    let mut lights = lightgrid_render::dynamic::scatter(
        d.count as usize,
        d.seed,
        Vec3::new(c.x - r, d.height[0], c.y - r),
        Vec3::new(c.x + r, d.height[1], c.y + r),
    );
    let lift = |p: Vec3| p + Vec3::Y * hm.height_at(p.x, p.z);
    // Stand every light on the ground (a line by the height at its first end).
    for l in &mut lights {
        match &mut l.kind {
            LightKind::Point { position } | LightKind::Spot { position, .. } => {
                *position = lift(*position);
            }
            LightKind::Line { a, b } => {
                let dy = Vec3::Y * hm.height_at(a.x, a.z);
                *a += dy;
                *b += dy;
            }
            LightKind::Area { centre, .. } => *centre = lift(*centre),
        }
    }
    Ok(lightgrid_render::DynamicLights::build(lights, 4.0)?)
}

impl World {
    /// Builds everything but the node grids (those follow the camera:
    /// [`World::prepare_view`]).
    pub fn build(scene: SceneFile, sweeper: SweeperChoice) -> Result<Self> {
        Self::build_on(scene, sweeper, None)
    }

    /// [`World::build`] with the GPU sweeper (if chosen) on the device `gpu`, the one the
    /// renderer draws with.
    pub fn build_on(
        scene: SceneFile,
        sweeper: SweeperChoice,
        gpu: Option<Arc<lightgrid_gpu::GpuContext>>,
    ) -> Result<Self> {
        Self::build_with(scene, sweeper, || Ok(gpu))
    }

    /// [`World::build_on`] with the device asked for (`gpu()`) only once the terrain,
    /// the models and their instances are ready, just before the world grid, whose
    /// sweeper may be the GPU's: a device made on another thread meanwhile costs the
    /// build no wait.
    pub fn build_with(
        scene: SceneFile,
        sweeper: SweeperChoice,
        gpu: impl FnOnce() -> Result<Option<Arc<lightgrid_gpu::GpuContext>>>,
    ) -> Result<Self> {
        let mut timings = Vec::new();
        let (heightmap, ground) = timed(&mut timings, "terrain", || load_terrain(&scene))?;
        let (models, grids) = timed(&mut timings, "voxelize models", || voxelize_models(&scene))?;
        let model_grid_bytes = grids.iter().map(|g| g.data().len() as u64 * 16).sum();
        let (instances, composer) = timed(&mut timings, "place instances", || {
            let instances = place_instances(&scene, &heightmap);
            let terrain = Terrain {
                heightmap: heightmap.clone(),
                colour: ground.clone(),
            };
            let composer =
                AreaComposer::new(grids, &instances, Some(terrain), ComposeParams::default())?;
            Ok((instances, Arc::new(composer)))
        })?;
        let gpu = gpu()?;
        let (sky, sky_top, sun, hierarchy, name) = timed(&mut timings, "world grid", || {
            let sky = sky_spec(&scene)?;
            let (sky_top, sun) = sky_and_sun(&scene, &sky)?;
            let (hierarchy, name) =
                world_grid(&scene, &heightmap, &composer, &sky_top, (sweeper, &gpu))?;
            Ok((sky, sky_top, sun, hierarchy, name))
        })?;
        let mut world = Self {
            dynamic: dynamic_lights(&scene, &heightmap)?,
            scene,
            heightmap,
            ground,
            models,
            instances,
            composer,
            hierarchy,
            sky,
            sky_top,
            sun,
            gpu_sweeps: name.starts_with("gpu"),
            sweeper: name,
            timings,
            model_grid_bytes,
            probes: None,
        };
        world.sun_and_probes()?;
        Ok(world)
    }

    /// The last stages of a build: the world grid's sun responses (with the sun kept
    /// apart) and the light probes (with `[probes]`).
    fn sun_and_probes(&mut self) -> Result<()> {
        if self.scene.sun.split {
            let sun = sun_light(self.sun);
            let hierarchy = &mut self.hierarchy;
            timed(&mut self.timings, "world grid sun", || {
                let set = hierarchy.set_sun(Some(sun));
                set.context("the sun's responses in the world grid")
            })?;
        }
        if self.scene.probes.is_some() {
            let t = Instant::now();
            let desc = crate::draw::volume_desc(self)?;
            self.probes = Some(crate::probes::Probes::build(self, desc)?);
            self.timings
                .push(("light probes".to_string(), t.elapsed().as_secs_f64()));
        }
        Ok(())
    }

    /// The scene's sun changed (angles, time of day or illuminance): with the sun kept
    /// apart, every grid's transmittance (the direct sun) and the world grid's
    /// scattered sun are recomputed now and the nodes' scattered sun waits for
    /// [`Hierarchy::refresh`] / [`Hierarchy::update`] (the sky's grids stay, unless a
    /// clear sky, whose shape follows the sun, changed: then it is swept again too);
    /// with the sun in the bins, the sky and sun are swept again together. Probes are
    /// relit (eight frames).
    pub fn move_sun(&mut self) -> Result<SunMove> {
        let t = Instant::now();
        let (sky, sun) = sky_and_sun(&self.scene, &self.sky)?;
        let sky_changed = sky != self.sky_top;
        self.sky_top = sky;
        self.sun = sun;
        if self.scene.sun.split {
            self.hierarchy.set_sun(Some(sun_light(sun)))?;
            if sky_changed {
                self.hierarchy.set_sky(sky)?;
            }
        } else {
            let top = boundary_light(&sky, &self.scene)?;
            self.hierarchy.set_sky(top)?;
        }
        if let Some(mut probes) = self.probes.take() {
            let relit = probes.relight(self, 8);
            self.probes = Some(probes);
            relit.context("relighting the probes")?;
        }
        Ok(SunMove {
            split: self.scene.sun.split,
            sky_reswept: sky_changed || !self.scene.sun.split,
            with_sky: self.hierarchy.params().sun_with_sky,
            seconds: t.elapsed().as_secs_f64(),
        })
    }

    /// Eye and target of view `i` in world space.
    pub fn view_points(&self, i: usize) -> (Vec3, Vec3) {
        let v = &self.scene.views[i];
        let at = |xz: [f32; 2], h: f32| {
            Vec3::new(xz[0], self.heightmap.height_at(xz[0], xz[1]) + h, xz[1])
        };
        (at(v.position, v.height), at(v.target, v.target_height))
    }

    /// Builds the grids the camera at `eye` wants (all of them: frames until none is
    /// pending), with progress. Returns frames run, points swept and the last stats.
    pub fn prepare_view(
        &mut self,
        eye: Vec3,
        label: &str,
    ) -> Result<(u32, u64, lightgrid_terrain_lod::FrameStats)> {
        settle_view(&mut self.hierarchy, eye, label)
    }

    /// What the renderer's meshes are made of ([`crate::draw::SceneMeshes::from_sources`]):
    /// borrowed apart from the hierarchy, which may build grids meanwhile.
    pub fn mesh_sources(&self) -> crate::draw::MeshSources<'_> {
        crate::draw::MeshSources {
            heightmap: &self.heightmap,
            ground: &self.ground,
            models: &self.models,
            instances: &self.instances,
            dynamic: &self.dynamic,
            far_detail: self.scene.render.impostors_beyond(),
        }
    }
}

/// [`World::prepare_view`] on the world's hierarchy alone.
pub(crate) fn settle_view(
    hierarchy: &mut Hierarchy,
    eye: Vec3,
    label: &str,
) -> Result<(u32, u64, lightgrid_terrain_lod::FrameStats)> {
    let pb = bar(0, label);
    let mut swept = 0;
    let mut frames = 0;
    // Drawn once settled: coarse to fine, each node swept once (`settle`).
    let s = hierarchy
        .settle(eye, 400, |s| {
            frames += 1;
            swept += s.points_swept;
            pb.set_length(frames as u64 + s.pending as u64);
            pb.set_position(frames as u64);
        })
        .context("updating the light grids")?;
    pb.finish_and_clear();
    Ok((frames, swept, s))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `auto` sweeps on the CPU without opening a device, and says why.
    #[test]
    fn auto_takes_the_cpu_sweeper() {
        let (_, name) = choose_sweeper(SweeperChoice::Auto, &None).unwrap();
        assert!(name.starts_with("cpu (auto:"), "{name}");
        let (_, name) = choose_sweeper(SweeperChoice::Cpu, &None).unwrap();
        assert_eq!(name, "cpu");
    }

    /// The scene's `[grid] gather` reaches every grid's sweeps (the viewer's and a
    /// world bake's hierarchy); left out, a bake gathers a low sun and a frame never.
    #[test]
    fn the_scene_s_gather_reaches_the_sweeps() {
        use lightgrid_core::Gather;
        let mut scene = SceneFile::demo().unwrap();
        assert_eq!(hierarchy_params(&scene, false).sweep.gather, Gather::OFF);
        assert_eq!(hierarchy_params(&scene, true).sweep.gather, Gather::AUTO);
        scene.grid.gather = Some(crate::scene::GatherSpec::Preset(
            crate::scene::GatherPreset::LowSun,
        ));
        for bake in [false, true] {
            assert_eq!(hierarchy_params(&scene, bake).sweep.gather, Gather::LOW_SUN);
        }
    }
}
