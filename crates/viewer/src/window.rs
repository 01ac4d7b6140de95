//! `--window`: an interactive window (winit) with a flying camera. The grids are rebuilt
//! around the camera within the per-frame point budget while flying.
//!
//! Keys: W/S forward/back, A/D sideways, Q/E down/up, arrow keys turn, Shift faster;
//! `[` / `]` time of day −/+ 15 min, `,` / `.` sun azimuth −/+ 10°: with the sun kept
//! apart (`sun.split`, the default) the sun's responses are recomputed (the world grid's
//! at once, the nodes' coarse and near first within the frame budget; a clear sky is
//! swept again after them), else sky and sun are swept again; the console reports what
//! was recomputed and how long it took;
//! 1 lit, 2 without grids, 3 grid points, 4 material cells; with `[probes]` in the
//! scene, 5 lit by the light probes, 6 the probes and their surfels; Esc quits.
//!
//! `--frames N` (smoke tests, demos) flies forward on its own, moves the sun by 10° on
//! its 10th frame (as `.` does) and quits after `N` frames, printing the frames drawn
//! and the grids built while flying.

use std::collections::HashSet;
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context, Result};
use lightgrid_core::glam::Vec3;
use lightgrid_render::{Camera, Renderer};
use winit::application::ApplicationHandler;
use winit::event::{ElementState, KeyEvent, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::{Window, WindowId};

use crate::draw::{SceneMeshes, Shot, make_view};
use crate::scene::SceneFile;
use crate::world::{SweeperChoice, World};

/// What a window session did: printed by the viewer when the window closes.
#[derive(Debug, Clone, Default)]
pub struct WindowSummary {
    /// Frames drawn.
    pub frames_drawn: u32,
    /// Node grids built while flying.
    pub grids_built: u32,
    /// One line per finished sun move (what was recomputed, and how long it took).
    pub sun_moves: Vec<String>,
}

impl std::fmt::Display for WindowSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        for m in &self.sun_moves {
            writeln!(f, "sun moved: {m}")?;
        }
        write!(
            f,
            "frames drawn: {}, grids built while flying: {}",
            self.frames_drawn, self.grids_built
        )
    }
}

/// Opens the window and runs until it closes. Errors (with a hint) where no display
/// exists.
pub fn run(
    scene: SceneFile,
    sweeper: SweeperChoice,
    width: u32,
    height: u32,
    frames: Option<u32>,
) -> Result<WindowSummary> {
    let event_loop = EventLoop::new().context(
        "--window needs a display (X11 or Wayland); run without --window for headless images",
    )?;
    event_loop.set_control_flow(ControlFlow::Poll);
    // One device for the process: made before the window, on an instance that knows the
    // display, so that the grids are swept (and, by the GPU sweeper, kept) on the device
    // the window draws with. WGPU_BACKEND picks the backends.
    let ctx = lightgrid_gpu::GpuContext::with_instance(
        wgpu::InstanceDescriptor::new_with_display_handle(Box::new(
            event_loop.owned_display_handle(),
        ))
        .with_env(),
    )
    .with_context(|| {
        format!(
            "no GPU adapter for the window; {}",
            lightgrid_gpu::driver_hint()
        )
    })?;
    let ctx = Arc::new(ctx);
    tracing::info!(adapter = %ctx.info.name, device_type = ?ctx.info.device_type, "rendering");
    tracing::info!("building the scene (grids swept by the {sweeper:?} choice)");
    let world = World::build_on(scene, sweeper, Some(ctx.clone()))?;
    tracing::info!("grids swept by: {}", world.sweeper);
    let mut app = App {
        ctx,
        world,
        size: (width, height),
        state: None,
        error: None,
        keys: HashSet::new(),
        eye: Vec3::ZERO,
        yaw: 0.0,
        pitch: -0.2,
        shot: Shot::Lit,
        last: Instant::now(),
        last_relight: Instant::now(),
        dirty: true,
        sun_move: None,
        frames_left: frames,
        drawn: 0,
        built: 0,
        sun_moves: Vec::new(),
    };
    if frames.is_some() {
        app.keys.insert(KeyCode::KeyW);
    }
    let (eye, target) = app.world.view_points(0);
    app.eye = eye;
    let d = (target - eye).normalize();
    app.yaw = d.x.atan2(-d.z);
    app.pitch = d.y.asin();
    event_loop.run_app(&mut app).context("window event loop")?;
    if let Some(e) = app.error {
        return Err(e);
    }
    Ok(WindowSummary {
        frames_drawn: app.drawn,
        grids_built: app.built,
        sun_moves: app.sun_moves,
    })
}

struct GpuState {
    window: Arc<Window>,
    surface: wgpu::Surface<'static>,
    config: wgpu::SurfaceConfiguration,
    renderer: Renderer,
    meshes: SceneMeshes,
}

struct App {
    /// The process's one device: the world was swept on it, the window draws with it.
    ctx: Arc<lightgrid_gpu::GpuContext>,
    world: World,
    size: (u32, u32),
    state: Option<GpuState>,
    error: Option<anyhow::Error>,
    keys: HashSet<KeyCode>,
    eye: Vec3,
    yaw: f32,
    pitch: f32,
    shot: Shot,
    last: Instant,
    last_relight: Instant,
    dirty: bool,
    /// A sun move in progress: when it began, what it did at once, and the node sweeps
    /// (sky grids, sun responses) since.
    sun_move: Option<(Instant, crate::world::SunMove, u32, u32)>,
    frames_left: Option<u32>,
    drawn: u32,
    built: u32,
    sun_moves: Vec<String>,
}

impl App {
    fn init(&mut self, event_loop: &ActiveEventLoop) -> Result<GpuState> {
        let window = Arc::new(
            event_loop
                .create_window(
                    Window::default_attributes()
                        .with_title("lightgrid viewer")
                        .with_inner_size(winit::dpi::PhysicalSize::new(self.size.0, self.size.1)),
                )
                .context("creating the window")?,
        );
        let surface = self
            .ctx
            .create_surface(window.clone())
            .context("the window's surface")?;
        let adapter = self.ctx.adapter();
        let size = window.inner_size();
        let mut config = surface
            .get_default_config(adapter, size.width.max(1), size.height.max(1))
            .context("the surface does not work with this adapter")?;
        let caps = surface.get_capabilities(adapter);
        if let Some(f) = caps.formats.iter().find(|f| f.is_srgb()) {
            config.format = *f;
        }
        surface.configure(&self.ctx.device, &config);
        let mut renderer = Renderer::new(self.ctx.clone(), config.width, config.height)?;
        let meshes = SceneMeshes::new(&mut renderer, &self.world)?;
        Ok(GpuState {
            window,
            surface,
            config,
            renderer,
            meshes,
        })
    }

    fn forward(&self) -> Vec3 {
        Vec3::new(
            self.yaw.sin() * self.pitch.cos(),
            self.pitch.sin(),
            -self.yaw.cos() * self.pitch.cos(),
        )
    }

    /// Updates the grids and the camera and draws one frame; `Ok(false)` when the
    /// surface gave no texture this time (the next redraw tries again).
    fn frame(&mut self) -> Result<bool> {
        let dt = self.last.elapsed().as_secs_f32().min(0.2);
        self.last = Instant::now();
        let speed = if self.keys.contains(&KeyCode::ShiftLeft) {
            60.0
        } else {
            15.0
        } * dt;
        let f = self.forward();
        let side = f.cross(Vec3::Y).normalize_or_zero();
        for (k, v) in [
            (KeyCode::KeyW, f),
            (KeyCode::KeyS, -f),
            (KeyCode::KeyD, side),
            (KeyCode::KeyA, -side),
            (KeyCode::KeyE, Vec3::Y),
            (KeyCode::KeyQ, Vec3::NEG_Y),
        ] {
            if self.keys.contains(&k) {
                self.eye += v * speed;
            }
        }
        let turn = 1.2 * dt;
        for (k, dy, dp) in [
            (KeyCode::ArrowLeft, -turn, 0.0),
            (KeyCode::ArrowRight, turn, 0.0),
            (KeyCode::ArrowUp, 0.0, turn),
            (KeyCode::ArrowDown, 0.0, -turn),
        ] {
            if self.keys.contains(&k) {
                self.yaw += dy;
                self.pitch = (self.pitch + dp).clamp(-1.5, 1.5);
            }
        }
        // Rebuild grids around the camera within the budget; after a sun move, the ready
        // grids whose inputs changed first.
        let stats = match self.sun_move.as_mut() {
            Some((since, what, built, sun_built)) => {
                // Sky grids to sweep again: every ready node whose inputs changed;
                // the sun alone: the wanted nodes' sun responses (update does those).
                let s = if what.sky_reswept {
                    self.world.hierarchy.refresh(self.eye)?
                } else {
                    self.world.hierarchy.update(self.eye)?
                };
                *built += s.built;
                *sun_built += s.sun_built;
                if s.pending == 0 {
                    let line = format!(
                        "{what}; then {sun_built} node sun responses and {built} node sky grids in {:.2} s",
                        since.elapsed().as_secs_f64()
                    );
                    tracing::info!("sun moved: {line}");
                    self.sun_moves.push(line);
                    self.sun_move = None;
                }
                s
            }
            None => self.world.hierarchy.update(self.eye)?,
        };
        self.built += stats.built;
        if stats.built + stats.sun_built > 0 {
            self.dirty = true;
        }
        let camera = Camera::look_at(self.eye, self.eye + self.forward());
        let Some(state) = self.state.as_mut() else {
            return Ok(false);
        };
        // Resampling the light volume costs about a second on two cores: at most once a
        // second, and only after grids changed.
        if self.dirty && self.last_relight.elapsed().as_secs_f32() > 1.0 {
            if self.shot == Shot::Probes {
                state
                    .meshes
                    .relight_probes(&mut state.renderer, &self.world)?;
            } else {
                state.meshes.relight(&mut state.renderer, &self.world)?;
            }
            let grid = self.world.hierarchy.grid_at(self.eye).clone();
            state
                .meshes
                .set_debug(&mut state.renderer, &self.world, &grid)?;
            self.dirty = false;
            self.last_relight = Instant::now();
        }
        let view = make_view(&self.world, &state.meshes, camera, self.shot);
        let frame = match state.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t)
            | wgpu::CurrentSurfaceTexture::Suboptimal(t) => t,
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                state
                    .surface
                    .configure(&state.renderer.context().device, &state.config);
                return Ok(false);
            }
            _ => return Ok(false),
        };
        let target = frame.texture.create_view(&Default::default());
        state
            .renderer
            .render_to(&view, &target, state.config.format)?;
        state.renderer.context().queue.present(frame);
        self.drawn += 1;
        state.window.set_title(&format!(
            "lightgrid viewer: {:?} | {:.1} h | swept {} points, {} pending | {:.0} fps",
            self.shot,
            self.world.scene.sun.time_of_day.unwrap_or(f32::NAN),
            stats.points_swept,
            stats.pending,
            1.0 / dt.max(1e-3)
        ));
        Ok(true)
    }

    fn key(&mut self, code: KeyCode) -> Result<()> {
        match code {
            KeyCode::Digit1
            | KeyCode::Digit2
            | KeyCode::Digit3
            | KeyCode::Digit4
            | KeyCode::Digit5
            | KeyCode::Digit6 => {
                let next = match code {
                    KeyCode::Digit1 => Shot::Lit,
                    KeyCode::Digit2 => Shot::NoGrid,
                    KeyCode::Digit3 => Shot::Points,
                    KeyCode::Digit4 => Shot::Material,
                    _ if self.world.probes.is_none() => return Ok(()),
                    KeyCode::Digit5 => Shot::Probes,
                    _ => Shot::ProbesDebug,
                };
                // The light volume follows: the probes' for 5, the grids' otherwise.
                self.dirty |= (next == Shot::Probes) != (self.shot == Shot::Probes);
                self.shot = next;
            }
            KeyCode::BracketLeft | KeyCode::BracketRight => {
                let step = if code == KeyCode::BracketLeft {
                    -0.25
                } else {
                    0.25
                };
                let t = (self.world.scene.sun.time_of_day.unwrap_or(12.0) + step).clamp(5.0, 19.0);
                self.world.scene.sun.time_of_day = Some(t);
                self.new_sky()?;
            }
            KeyCode::Comma | KeyCode::Period => {
                let (e, a) = self.world.scene.sun.angles();
                let step = if code == KeyCode::Comma { -10.0 } else { 10.0 };
                let sun = &mut self.world.scene.sun;
                sun.time_of_day = None;
                sun.elevation_deg = e.to_degrees();
                sun.azimuth_deg = a.to_degrees() + step;
                self.new_sky()?;
            }
            _ => {}
        }
        Ok(())
    }

    /// The sun moved: its responses (or sky and sun) are recomputed, the world grid's at
    /// once, the nodes' progressively (reported when done).
    fn new_sky(&mut self) -> Result<()> {
        let what = self.world.move_sun()?;
        self.sun_move = Some((
            Instant::now() - std::time::Duration::from_secs_f64(what.seconds),
            what,
            0,
            0,
        ));
        self.dirty = true;
        Ok(())
    }

    fn fail(&mut self, event_loop: &ActiveEventLoop, e: anyhow::Error) {
        self.error = Some(e);
        event_loop.exit();
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.state.is_none() {
            match self.init(event_loop) {
                Ok(s) => {
                    s.window.request_redraw();
                    self.state = Some(s);
                }
                Err(e) => self.fail(event_loop, e),
            }
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        match event {
            WindowEvent::CloseRequested => event_loop.exit(),
            WindowEvent::Resized(size) => {
                if let Some(s) = self.state.as_mut()
                    && size.width > 0
                    && size.height > 0
                {
                    s.config.width = size.width;
                    s.config.height = size.height;
                    s.surface.configure(&s.renderer.context().device, &s.config);
                    if let Err(e) = s.renderer.resize(size.width, size.height) {
                        self.fail(event_loop, e.into());
                    }
                }
            }
            WindowEvent::KeyboardInput {
                event:
                    KeyEvent {
                        physical_key: PhysicalKey::Code(code),
                        state,
                        repeat,
                        ..
                    },
                ..
            } => {
                if state == ElementState::Pressed {
                    if code == KeyCode::Escape {
                        event_loop.exit();
                        return;
                    }
                    self.keys.insert(code);
                    if !repeat && let Err(e) = self.key(code) {
                        self.fail(event_loop, e);
                    }
                } else {
                    self.keys.remove(&code);
                }
            }
            WindowEvent::RedrawRequested => {
                let drawn = match self.frame() {
                    Ok(d) => d,
                    Err(e) => {
                        self.fail(event_loop, e);
                        return;
                    }
                };
                // Keep drawing, whether or not this frame got a surface texture.
                if let Some(s) = &self.state {
                    s.window.request_redraw();
                }
                if drawn && let Some(n) = self.frames_left.as_mut() {
                    *n = n.saturating_sub(1);
                    if *n == 0 {
                        event_loop.exit();
                    }
                    // The autopilot moves the sun once, on its 10th frame, as `.` does.
                    if self.drawn == 10
                        && let Err(e) = self.key(KeyCode::Period)
                    {
                        self.fail(event_loop, e);
                    }
                }
            }
            _ => {}
        }
    }
}
