//! # viewer
//!
//! The program people run. With no arguments it builds the embedded demo scene
//! (`scenes/demo.toml`: procedural hills and forest), computes its light grids around
//! each view (GPU if a real GPU exists, else CPU; said in the output), renders every view
//! headless and writes into `out/`:
//!
//! - `<view>.png`: the scene lit by the grids; `<view>-no-grid.png`: the same with the
//!   unshadowed sun and a flat sky instead; `<view>-grid-points.png`: the light grid
//!   points as lit balls; `<view>-material.png`: the material cells as cubes sized by
//!   density (as in the seed's figures);
//! - `<first view>.exr`: the lit view in linear HDR;
//! - `<last view>-sun-moved.png`: with the sun kept apart (`sun.split`, the default),
//!   the last view again after the sun moved [`SUN_MOVE_DEG`] in azimuth, through the
//!   path the window's sun keys take (the summary says what was recomputed, and how
//!   long it took);
//! - with `[probes]` in the scene: `<view>-probes.png`, each view lit by the light
//!   probes instead of the grids (the direct sun's shadow still from the sweep), and
//!   `<view>-probes-debug.png`, the probes as balls and their surfels as glowing cubes
//!   (`scenes/town.toml` is such a scene);
//! - `summary.txt` and `summary.json`: timings per stage, grids per depth, memory.
//!
//! `--scene file.toml` renders a user's scene, `--window` opens an interactive window.
//! The library half ([`run`]) is what the binary and the image tests call.

pub mod bevy;
pub mod draw;
pub mod probes;
pub mod scene;
pub mod window;
pub mod world;

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context, Result};
use lightgrid_render::{Camera, Renderer};
use lightgrid_terrain_lod::{BYTES_26_F32, BYTES_26_PACKED, BYTES_AVG_DOM};
use serde::Serialize;

pub use scene::SceneFile;
pub use world::{SweeperChoice, World};

/// Largest image width or height rendered.
pub const MAX_IMAGE_SIDE: u32 = 8192;

/// Options of a headless run.
#[derive(Debug, Clone)]
pub struct Options {
    /// Output folder (created).
    pub out: PathBuf,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Which sweeper builds the grids.
    pub sweeper: SweeperChoice,
    /// Also write the EXR of the first view.
    pub exr: bool,
    /// Also write each view's light as Bevy irradiance volumes into `out/bevy/`
    /// (indirect light; see [`bevy`]).
    pub bevy: bool,
}

/// What a run did and measured.
#[derive(Debug, Clone, Serialize)]
pub struct Summary {
    /// The sweeper used.
    pub sweeper: String,
    /// The GPU adapter that rendered.
    pub renderer: String,
    /// Seconds per stage.
    pub timings: Vec<(String, f64)>,
    /// Per view: frames until every wanted grid was ready, points swept.
    pub views: Vec<ViewSummary>,
    /// Instances in the scene.
    pub instances: usize,
    /// Metres from the eye beyond which foliage is drawn as impostors (`None`: never).
    pub far_detail: Option<f32>,
    /// Dynamic lights, and the entries of their culling grid.
    pub dynamic_lights: (usize, usize),
    /// Bytes of the model material grids.
    pub model_grid_bytes: u64,
    /// How the sun is lit: kept apart from the sky's bins or in them.
    pub sun: String,
    /// With the sun kept apart: the sun moved by [`SUN_MOVE_DEG`] in azimuth after the
    /// last view, what was recomputed and how long it took.
    pub sun_move: Option<String>,
    /// With `[probes]`: the probes' figures (count, surfels, bytes, bake, relight).
    pub probes: Option<String>,
    /// Files written.
    pub files: Vec<PathBuf>,
}

/// The headless run's sun move (degrees of azimuth), shown as `<view>-sun-moved.png`.
pub const SUN_MOVE_DEG: f32 = 20.0;

/// One view's figures.
#[derive(Debug, Clone, Serialize)]
pub struct ViewSummary {
    /// View name.
    pub name: String,
    /// Hierarchy frames until nothing was pending.
    pub frames: u32,
    /// Points swept for this view.
    pub points_swept: u64,
    /// Node grids alive per depth (1 = coarsest node level) after it.
    pub grids_per_depth: Vec<u32>,
    /// Grid points per depth.
    pub points_per_depth: Vec<u64>,
    /// Grid memory: 26 bins in f32, packed R11G11B10, average + dominant only.
    pub grid_bytes: [u64; 3],
    /// Light volume bytes for per-pixel lighting.
    pub volume_bytes: u64,
    /// Points of the light volume.
    pub volume_points: u64,
    /// Seconds sampling the light volume took.
    pub volume_seconds: f64,
    /// With the sun kept apart: the sun's responses beside the sky's grids (scattered
    /// bins as 26 `f32` bins, and the transmittance, 4 bytes a point); 0 otherwise.
    pub sun_bytes: u64,
    /// The horizon halves kept beside the sky's bins and the sun's scattered bins
    /// (`lightgrid_terrain_lod::BYTES_HORIZON` a point each); 0 where none are kept.
    pub horizon_bytes: u64,
    /// The materials the grids keep (for the sun's responses and its march beyond a
    /// node: `lightgrid_terrain_lod::BYTES_MATERIAL` a point).
    pub material_bytes: u64,
    /// Where the light was sampled: `"device"` (from the grids the GPU sweeper left on
    /// the renderer's device: nothing copied through the CPU) or `"cpu"`.
    pub sampled_on: String,
    /// Balls and cubes in the debug views.
    pub debug_instances: (usize, usize),
}

impl Summary {
    /// The human-readable report (also `summary.txt`).
    pub fn text(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "lightgrid viewer summary");
        let _ = writeln!(s, "  grids swept by: {}", self.sweeper);
        let _ = writeln!(s, "  rendered on:    {}", self.renderer);
        let _ = match self.far_detail {
            Some(d) => writeln!(
                s,
                "  instances:      {} (foliage beyond {d} m from the eye drawn as impostors)",
                self.instances
            ),
            None => writeln!(s, "  instances:      {}", self.instances),
        };
        let _ = writeln!(s, "  sun:            {}", self.sun);
        if let Some(m) = &self.sun_move {
            let _ = writeln!(s, "  sun moved:      {m}");
        }
        if let Some(p) = &self.probes {
            let _ = writeln!(s, "  light probes:   {p}");
        }
        if self.dynamic_lights.0 > 0 {
            let _ = writeln!(
                s,
                "  dynamic lights: {} ({} entries in their culling grid)",
                self.dynamic_lights.0, self.dynamic_lights.1
            );
        }
        let _ = writeln!(
            s,
            "  model material grids: {:.1} MB",
            self.model_grid_bytes as f64 / 1e6
        );
        let _ = writeln!(
            s,
            "stages (seconds; the GPU device is made beside the terrain and models, the meshes uploaded beside the first view's grids, and a view's images read back and written beside the next stage: the stages add up to more than the total):"
        );
        for (name, t) in &self.timings {
            let _ = writeln!(s, "  {name:32} {t:8.2}");
        }
        for v in &self.views {
            let _ = writeln!(
                s,
                "view {}: {} frames, {} points swept",
                v.name, v.frames, v.points_swept
            );
            let _ = writeln!(
                s,
                "  grids per depth {:?}, points per depth {:?}",
                v.grids_per_depth, v.points_per_depth
            );
            let _ = writeln!(
                s,
                "  grid memory: {:.1} MB as 26 f32 bins, {:.1} MB packed, {:.1} MB average+dominant; light volume {:.1} MB",
                v.grid_bytes[0] as f64 / 1e6,
                v.grid_bytes[1] as f64 / 1e6,
                v.grid_bytes[2] as f64 / 1e6,
                v.volume_bytes as f64 / 1e6
            );
            if v.sun_bytes > 0 {
                let _ = writeln!(
                    s,
                    "  sun responses (scattered bins and transmittance, or with the sun swept with the sky the transmittance alone): {:.1} MB beside the grids",
                    v.sun_bytes as f64 / 1e6
                );
            }
            if v.horizon_bytes > 0 {
                let _ = writeln!(
                    s,
                    "  horizon halves (sky, scattered sun): {:.1} MB beside the grids",
                    v.horizon_bytes as f64 / 1e6
                );
            }
            let _ = writeln!(
                s,
                "  materials kept with the grids: {:.1} MB",
                v.material_bytes as f64 / 1e6
            );
            let _ = writeln!(
                s,
                "  light sampled on: {}; light volume {} points in {:.3} s",
                v.sampled_on, v.volume_points, v.volume_seconds
            );
            let _ = writeln!(
                s,
                "  debug views: {} grid points, {} material cells",
                v.debug_instances.0, v.debug_instances.1
            );
        }
        let _ = writeln!(s, "files:");
        for f in &self.files {
            let _ = writeln!(s, "  {}", f.display());
        }
        s
    }
}

/// Writes an sRGB RGBA8 image as PNG (encoded in memory, then written atomically).
pub fn write_png(path: &Path, img: &lightgrid_render::Image) -> Result<()> {
    let buf: Vec<u8> = img.srgb.iter().flatten().copied().collect();
    let mut png = Vec::new();
    image::write_buffer_with_format(
        &mut std::io::Cursor::new(&mut png),
        &buf,
        img.width,
        img.height,
        image::ColorType::Rgba8,
        image::ImageFormat::Png,
    )
    .with_context(|| format!("encoding {}", path.display()))?;
    lightgrid_core::file::write_atomic(path, &png)
        .with_context(|| format!("writing {}", path.display()))
}

/// Writes the linear HDR image as EXR (encoded in memory, then written atomically).
pub fn write_exr(path: &Path, img: &lightgrid_render::Image) -> Result<()> {
    use exr::prelude::*;
    let w = img.width as usize;
    let pixels = SpecificChannels::rgb(|p: Vec2<usize>| {
        let v = img.hdr[p.y() * w + p.x()];
        (v[0], v[1], v[2])
    });
    let image = Image::from_channels((w, img.height as usize), pixels);
    let mut bytes = Vec::new();
    image
        .write()
        .to_buffered(std::io::Cursor::new(&mut bytes))
        .with_context(|| format!("encoding {}", path.display()))?;
    lightgrid_core::file::write_atomic(path, &bytes)
        .with_context(|| format!("writing {}", path.display()))
}

/// Sends the libraries' `tracing` logs to stderr, at the levels `RUST_LOG` sets (`debug`,
/// `lightgrid_terrain_lod=trace,info`; a bare level is the default), `info` without it.
/// The viewer's and xtask's `main` call it once.
pub fn init_logs() {
    use tracing_subscriber::{filter::Targets, layer::SubscriberExt, util::SubscriberInitExt};
    let filter = std::env::var("RUST_LOG")
        .ok()
        .and_then(|s| s.parse::<Targets>().ok());
    let filter = filter.unwrap_or_else(|| Targets::new().with_default(tracing::Level::INFO));
    let fmt = tracing_subscriber::fmt::layer().with_writer(std::io::stderr);
    tracing_subscriber::registry().with(fmt).with(filter).init();
}

/// The GPU context for rendering (any adapter, lavapipe included).
pub fn render_context() -> Result<Arc<lightgrid_gpu::GpuContext>> {
    Ok(Arc::new(
        lightgrid_gpu::GpuContext::new().context("rendering needs a GPU adapter")?,
    ))
}

/// Builds `scene`, computes the grids around every view and writes the images and
/// summary into `opts.out`.
pub fn run(scene: SceneFile, opts: &Options) -> Result<Summary> {
    for (name, v) in [("width", opts.width), ("height", opts.height)] {
        if !(1..=MAX_IMAGE_SIDE).contains(&v) {
            anyhow::bail!("{name} = {v}: must be in 1..={MAX_IMAGE_SIDE}");
        }
    }
    std::fs::create_dir_all(&opts.out)
        .with_context(|| format!("creating {}", opts.out.display()))?;
    let total = Instant::now();
    // One device for sweeping (when the GPU sweeps) and drawing, made on a thread of its
    // own while the terrain and the models are built (mostly one core's wait on the
    // driver).
    let (mut world, (ctx, device_time)) = std::thread::scope(|s| {
        let device = s.spawn(|| {
            let t = Instant::now();
            render_context().map(|ctx| (ctx, t.elapsed().as_secs_f64()))
        });
        let mut made = None;
        let world = World::build_with(scene, opts.sweeper, || {
            let (ctx, seconds) = device
                .join()
                .map_err(|_| anyhow::anyhow!("making the GPU device panicked"))??;
            made = Some((ctx.clone(), seconds));
            Ok(Some(ctx))
        })?;
        let made = made.context("the world was built without asking for its device")?;
        anyhow::Ok((world, made))
    })?;
    let mut rec = Record {
        timings: vec![("GPU device".to_string(), device_time)],
        files: Vec::new(),
    };
    rec.timings.extend(world.timings.iter().cloned());
    let renderer_name = format!("{} ({:?})", ctx.info.name, ctx.info.device_type);
    let (mut r, meshes, mut first) = upload_beside_first_view(&mut world, ctx, opts, &mut rec)?;
    let mut views = Vec::new();
    // A view's images are read back and written while the next view's grids are built
    // (or the sun moves): lavapipe's drawing and the sweeps share the cores.
    let mut drawn: Option<Drawn> = None;
    for vi in 0..world.scene.views.len() {
        let (view, next) = render_view(
            &mut world,
            (&mut r, &meshes),
            (vi, drawn.take(), first.take()),
            opts,
            &mut rec,
        )?;
        views.push(view);
        drawn = next;
    }
    let sun_move = move_sun(&mut world, (&mut r, &meshes), drawn, opts, &mut rec)?;
    rec.timings
        .push(("total".into(), total.elapsed().as_secs_f64()));
    let summary = Summary {
        sun: if world.hierarchy.sun().is_some() {
            let with_sky = if world.hierarchy.params().sun_with_sky {
                "; its first collisions swept with the sky, one sweep a grid"
            } else {
                "; its scattered light swept apart"
            };
            format!(
                "kept apart from the sky's bins (exact direction: transmittance per grid point, direct light per pixel{with_sky})"
            )
        } else {
            "in the sky's bins (sun.split = false)".into()
        },
        sun_move,
        sweeper: world.sweeper.clone(),
        renderer: renderer_name,
        timings: rec.timings,
        views,
        instances: world.instances.len(),
        far_detail: world.scene.render.impostors_beyond(),
        dynamic_lights: (world.dynamic.lights.len(), world.dynamic.indices.len()),
        model_grid_bytes: world.model_grid_bytes,
        probes: world.probes.as_ref().map(|p| p.summary()),
        files: rec.files,
    };
    write_summary(summary, opts)
}

/// What a run records as it goes: its stages' wall times and the files it writes.
struct Record {
    timings: Vec<(String, f64)>,
    files: Vec<PathBuf>,
}

impl Record {
    /// `f()`, its wall time recorded as `stage`.
    fn time<T>(&mut self, stage: String, f: impl FnOnce(&mut Self) -> Result<T>) -> Result<T> {
        let t = Instant::now();
        let out = f(self)?;
        self.timings.push((stage, t.elapsed().as_secs_f64()));
        Ok(out)
    }

    /// Draws `shots` of the view `view` from `camera`, in one submission (a
    /// [`draw::Shot::Lit`] followed by [`draw::Shot::NoGrid`] as a pair,
    /// [`Renderer::record_pair`]: the geometry once), and writes each as
    /// `<view><suffix>.png` in `out` (the first as `<view>.exr` too with `exr`).
    fn shots(
        &mut self,
        (r, meshes): (&mut Renderer, &draw::SceneMeshes),
        world: &World,
        (camera, shots): (Camera, &[draw::Shot]),
        to: (&Path, &str, bool),
    ) -> Result<()> {
        let drawn = Drawn::record((r, meshes), world, (camera, shots), to)?;
        self.files.extend(drawn.write(r)?);
        Ok(())
    }

    /// Writes the images `drawn` holds (`drawn.stage` timed: its recording and this),
    /// on a thread of its own, while `f` runs here.
    fn beside<T>(
        &mut self,
        r: &Renderer,
        drawn: Option<Drawn>,
        f: impl FnOnce() -> Result<T>,
    ) -> Result<T> {
        let Some(drawn) = drawn else { return f() };
        let (written, out) = std::thread::scope(|s| {
            let writer = s.spawn(|| {
                let t = Instant::now();
                let stage = (drawn.stage.clone(), drawn.record_s);
                drawn
                    .write(r)
                    .map(|files| (files, stage, t.elapsed().as_secs_f64()))
            });
            let out = f();
            let written = writer
                .join()
                .map_err(|_| anyhow::anyhow!("the thread writing the images panicked"))
                .and_then(|w| w);
            (written, out)
        });
        let (files, (stage, record_s), write_s) = written?;
        self.files.extend(files);
        self.timings.push((stage, record_s + write_s));
        out
    }
}

/// Images recorded and not yet read back: [`Drawn::write`] sends them, reads them
/// back and writes them.
struct Drawn {
    pending: lightgrid_render::PendingImages,
    /// Where each image goes, in order.
    paths: Vec<PathBuf>,
    /// The first image's EXR, if asked.
    exr: Option<PathBuf>,
    /// The stage (`render <view>`) and the seconds its recording took.
    stage: String,
    record_s: f64,
}

impl Drawn {
    /// Records `shots` of the view `view` (see [`Record::shots`]).
    fn record(
        (r, meshes): (&mut Renderer, &draw::SceneMeshes),
        world: &World,
        (camera, shots): (Camera, &[draw::Shot]),
        (out, view, exr): (&Path, &str, bool),
    ) -> Result<Self> {
        let t = Instant::now();
        let mut pending = lightgrid_render::PendingImages::default();
        let mut rest = shots;
        if let [draw::Shot::Lit, draw::Shot::NoGrid, tail @ ..] = shots {
            let lit = draw::make_view(world, meshes, camera, draw::Shot::Lit);
            pending.append(r.record_pair(&lit)?);
            rest = tail;
        }
        for &shot in rest {
            pending.append(r.record(&draw::make_view(world, meshes, camera, shot))?);
        }
        Ok(Self {
            pending,
            paths: (shots.iter())
                .map(|shot| out.join(format!("{view}{}.png", shot.suffix())))
                .collect(),
            exr: exr.then(|| out.join(format!("{view}.exr"))),
            stage: format!("render {view}"),
            record_s: t.elapsed().as_secs_f64(),
        })
    }

    /// Sends the images, reads them back and writes them; the files written.
    fn write(self, r: &Renderer) -> Result<Vec<PathBuf>> {
        let images = r.finish(self.pending)?;
        let mut files = Vec::new();
        for (img, path) in images.iter().zip(self.paths) {
            write_png(&path, img)?;
            files.push(path);
        }
        if let (Some(path), Some(img)) = (self.exr, images.first()) {
            write_exr(&path, img)?;
            files.push(path);
        }
        Ok(files)
    }
}

/// View `vi` of the scene: its light grids built around its eye, exported for Bevy
/// if asked, sampled onto the meshes and rendered (every shot, the probes' too).
/// A view's grids built ([`World::prepare_view`]'s frames, points swept and last
/// stats) and the seconds they took.
type Prepared = ((u32, u64, lightgrid_terrain_lod::FrameStats), f64);

/// The progress label of a view's grids.
fn grids_label(view: &str) -> String {
    format!("light grids for {view}")
}

/// The renderer made and the world's meshes uploaded on a thread of their own while
/// the first view's grids are built (the upload is mostly one core's work, the sweeps
/// leave a little of two); the first view's grids, built, with them.
fn upload_beside_first_view(
    world: &mut World,
    ctx: Arc<lightgrid_gpu::GpuContext>,
    opts: &Options,
    rec: &mut Record,
) -> Result<(Renderer, draw::SceneMeshes, Option<Prepared>)> {
    let first = (!world.scene.views.is_empty()).then(|| {
        let eye = world.view_points(0).0;
        (eye, grids_label(&world.scene.views[0].name))
    });
    // The hierarchy builds while the meshes are made of the world's other parts.
    let World {
        hierarchy,
        heightmap,
        ground,
        models,
        instances,
        dynamic,
        scene,
        ..
    } = world;
    let sources = draw::MeshSources {
        heightmap,
        ground,
        models,
        instances,
        dynamic,
        far_detail: scene.render.impostors_beyond(),
    };
    let (uploaded, prepared) = std::thread::scope(|s| {
        let upload = s.spawn(|| {
            let t = Instant::now();
            let mut r = Renderer::new(ctx, opts.width, opts.height)?;
            let meshes = draw::SceneMeshes::from_sources(&mut r, sources)?;
            anyhow::Ok((r, meshes, t.elapsed().as_secs_f64()))
        });
        let prepared = first.map(|(eye, label)| {
            let t = Instant::now();
            world::settle_view(hierarchy, eye, &label).map(|out| (out, t.elapsed().as_secs_f64()))
        });
        let uploaded = upload
            .join()
            .map_err(|_| anyhow::anyhow!("uploading the meshes panicked"));
        (uploaded, prepared)
    });
    let (r, meshes, upload_s) = uploaded??;
    rec.timings.push(("upload meshes".into(), upload_s));
    let prepared = prepared.transpose()?;
    Ok((r, meshes, prepared))
}

fn render_view(
    world: &mut World,
    (r, meshes): (&mut Renderer, &draw::SceneMeshes),
    (vi, before, prepared): (usize, Option<Drawn>, Option<Prepared>),
    opts: &Options,
    rec: &mut Record,
) -> Result<(ViewSummary, Option<Drawn>)> {
    let spec = world.scene.views[vi].clone();
    let name = &spec.name;
    let (eye, target) = world.view_points(vi);
    let ((frames, swept, stats), seconds) = match prepared {
        Some(p) => p,
        None => rec.beside(r, before, || {
            let t = Instant::now();
            let out = world.prepare_view(eye, &grids_label(name))?;
            Ok((out, t.elapsed().as_secs_f64()))
        })?,
    };
    rec.timings.push((format!("grids for {name}"), seconds));
    if opts.bevy {
        rec.time(format!("bevy volumes for {name}"), |rec| {
            let dir = opts.out.join("bevy");
            let files = bevy::export(world, eye, &dir, name, false)
                .with_context(|| format!("exporting {name} for Bevy"))?;
            rec.files.extend(files);
            Ok(())
        })?;
    }
    let (relit, debug) = rec.time(format!("sample light for {name}"), |_| {
        let relit = meshes.relight(r, world)?;
        let grid = world.hierarchy.grid_at(target).clone();
        Ok((relit, meshes.set_debug(r, world, &grid)?))
    })?;
    let mut camera = Camera::look_at(eye, target);
    camera.fov_y = spec.fov_deg.to_radians();
    let to = (opts.out.as_path(), name.as_str(), vi == 0 && opts.exr);
    let drawn = Drawn::record((r, meshes), world, (camera, &draw::Shot::ALL), to)?;
    // The probes relight the meshes: the grids' images are written first.
    let drawn = if world.probes.is_some() {
        rec.beside(r, Some(drawn), || Ok(()))?;
        None
    } else {
        Some(drawn)
    };
    if meshes.relight_probes(r, world)?.is_some() {
        // The same view lit by the probes, and the probes' debug view; the next view
        // samples the grids again.
        rec.time(format!("probes for {name}"), |rec| {
            let shots = [draw::Shot::Probes, draw::Shot::ProbesDebug];
            rec.shots(
                (r, meshes),
                world,
                (camera, &shots),
                (&opts.out, name, false),
            )
        })?;
    }
    let with_sky = world.hierarchy.params().sun_with_sky;
    let summary = ViewSummary {
        name: spec.name.clone(),
        frames,
        points_swept: swept,
        grids_per_depth: stats.alive_per_depth.clone(),
        points_per_depth: stats.points_per_depth.clone(),
        grid_bytes: [
            stats.bytes(BYTES_26_F32),
            stats.bytes(BYTES_26_PACKED),
            stats.bytes(BYTES_AVG_DOM),
        ],
        volume_bytes: relit.volume_bytes,
        volume_points: relit.volume_points,
        volume_seconds: relit.volume_seconds,
        // With the sun swept with the sky a response is its transmittance alone: the
        // sky's bins and halves hold the scattered sun.
        sun_bytes: stats.bytes(if with_sky { 4 } else { BYTES_26_F32 + 4 })
            * world.hierarchy.sun().is_some() as u64,
        horizon_bytes: stats.bytes(lightgrid_terrain_lod::BYTES_HORIZON)
            * world.hierarchy.params().sweep.outputs.horizon as u64
            * (1 + (world.hierarchy.sun().is_some() && !with_sky) as u64),
        material_bytes: stats.bytes(lightgrid_terrain_lod::BYTES_MATERIAL),
        sampled_on: if relit.on_device {
            format!("device ({} grids in place)", relit.grids)
        } else {
            format!("cpu ({} grids)", relit.grids)
        },
        debug_instances: debug,
    };
    Ok((summary, drawn))
}

/// With the sun kept apart: the sun moves [`SUN_MOVE_DEG`] in azimuth, what it changes
/// is recomputed around the last view's eye, and that view is rendered again; what was
/// done, for the summary.
fn move_sun(
    world: &mut World,
    (r, meshes): (&mut Renderer, &draw::SceneMeshes),
    before: Option<Drawn>,
    opts: &Options,
    rec: &mut Record,
) -> Result<Option<String>> {
    let (Some(_), Some(spec)) = (world.hierarchy.sun(), world.scene.views.last().cloned()) else {
        rec.beside(r, before, || Ok(()))?;
        return Ok(None);
    };
    let (eye, target) = world.view_points(world.scene.views.len() - 1);
    let (e, a) = world.scene.sun.angles();
    let sun = &mut world.scene.sun;
    sun.time_of_day = None;
    sun.elevation_deg = e.to_degrees();
    sun.azimuth_deg = a.to_degrees() + SUN_MOVE_DEG;
    let (what, sun_built, built, points, seconds) = rec.beside(r, before, || {
        let t = Instant::now();
        let what = world.move_sun().context("moving the sun")?;
        let (mut sun_built, mut built, mut points) = (0, 0, 0);
        for _ in 0..400 {
            let s = if what.sky_reswept {
                world.hierarchy.refresh(eye)
            } else {
                world.hierarchy.update(eye)
            }
            .context("recomputing the grids for the moved sun")?;
            (sun_built, built, points) = (
                sun_built + s.sun_built,
                built + s.built,
                points + s.points_swept,
            );
            if s.pending == 0 {
                break;
            }
        }
        Ok((what, sun_built, built, points, t.elapsed().as_secs_f64()))
    })?;
    rec.timings.push(("sun move".into(), seconds));
    meshes.relight(r, world)?;
    let mut camera = Camera::look_at(eye, target);
    camera.fov_y = spec.fov_deg.to_radians();
    let view = format!("{}-sun-moved", spec.name);
    rec.shots(
        (r, meshes),
        world,
        (camera, &[draw::Shot::Lit]),
        (&opts.out, &view, false),
    )?;
    Ok(Some(format!(
        "{SUN_MOVE_DEG} deg in azimuth: {what}; then {sun_built} node sun responses and {built} node sky grids ({points} points) for view {}; {seconds:.2} s in all",
        spec.name
    )))
}

/// Writes `summary.txt` and `summary.json` in the output folder (listed in the
/// summary's files) and returns the summary.
fn write_summary(mut summary: Summary, opts: &Options) -> Result<Summary> {
    let txt = opts.out.join("summary.txt");
    let json = opts.out.join("summary.json");
    summary.files.push(txt.clone());
    summary.files.push(json.clone());
    lightgrid_core::file::write_atomic(&txt, summary.text().as_bytes())
        .with_context(|| format!("writing {}", txt.display()))?;
    lightgrid_core::file::write_atomic(&json, serde_json::to_string_pretty(&summary)?.as_bytes())
        .with_context(|| format!("writing {}", json.display()))?;
    Ok(summary)
}
