//! Time of day: a moved sun's direct light at once, its scattered light after.
//!
//! A grid's sun responses are two: the beam's transmittance, a march along the sun's
//! exact direction (cheap: 3 ms for the world grid, about 1 ms a node), and the
//! scattered light of its first collisions, a sweep (the world grid's takes 110–300 ms
//! on two cores). [`Hierarchy::set_sun`] of a new direction re-marches every grid's
//! transmittance at once ([`Hierarchy::march_suns`]): the direct sun, shadows
//! included, moves in the call; under a time budget the world grid's and the nodes'
//! nearest the last frame's camera first (those over the camera whatever the time)
//! until about half a frame's budget is spent, the rest in the frames after within their
//! budget, each a march alone while its scattered sun is current (meanwhile such a
//! node shows the coarser grids' sun). The scattered sun follows. The world grid's is swept
//! in `set_sun`, or under a time budget ([`HierarchyParams::budget_ms`]), with a
//! sweeper that forks, on a fork of the sweeper on a thread of its own (in a one-thread
//! rayon pool apart from the frames': in theirs, a frame waiting on its own jobs would
//! steal the sweep's long ones), and `set_sun` returns; the old direction's scattered
//! sun stays shown, whole, until a frame ([`Hierarchy::update`],
//! [`Hierarchy::refresh`]) finds the new one done and installs it
//! ([`FrameStats::sun_moved`]). The nodes' scattered sun is then swept again within the
//! budget, coarse and near first; until then a node shows its earlier direction's
//! beside its new transmittance. A sun set again while the sweep runs waits for it,
//! then is swept in its turn (only the last one asked for). Without a time budget, with
//! a sweeper that cannot fork (the GPU's: one queue), and for a first sun (none shown
//! yet), the world grid's sweep runs at once, in `set_sun`.
//!
//! With the sun swept with the sky ([`crate::HierarchyParams::sun_with_sky`]) the world
//! grid's sweep on the thread is its light, sky and sun's first collisions together;
//! until a frame installs it, the grids' sky sweeps take the sun the world grid's light
//! holds ([`Hierarchy::sky_sun`]), so a node built meanwhile agrees with the boundary
//! it reads, and every node is swept again after.
//!
//! Under a 30 ms frame budget, on the frame bench's forest path with 16-point nodes and
//! two cores, moving the sun 20° took `set_sun` 26–44 ms (50–90 ms of CPU time, 42
//! grids re-marched), the world grid's scattered sun landed 0.23–0.31 s later and every
//! node's 0.5–0.9 s later (`cargo xtask frame --budget-ms 30`; the repository's
//! `docs/measurements.md`, "The hierarchy frame by frame").
//!
//! [`HierarchyParams::budget_ms`]: crate::HierarchyParams::budget_ms
//! [`FrameStats::sun_moved`]: crate::FrameStats::sun_moved

use std::thread::JoinHandle;

use lightgrid_core::glam::Vec3;
use lightgrid_core::{
    BinLight, Boundary, Grid, MaterialGrid, SunBoundary, SweepError, SweepOptions, Sweeper,
};

use crate::{GridSun, Hierarchy, LodError, SunLight, shadow};

/// A moved sun's world-grid responses, being swept.
pub(crate) struct SunMove {
    /// The sun they are swept for.
    sun: SunLight,
    thread: JoinHandle<Result<Moved, SweepError>>,
    /// A sun set while they were swept: swept next (the last one asked for).
    next: Option<SunLight>,
}

/// What a moved sun's sweep on a thread gives the world grid.
enum Moved {
    /// Its scattered sun's responses, swept apart.
    Apart(GridSun),
    /// Its light, the sun's first collisions swept with the sky
    /// ([`crate::HierarchyParams::sun_with_sky`]).
    WithSky(lightgrid_core::SweepOutput),
}

impl Hierarchy {
    /// Whether a moved sun's scattered light is being swept for the world grid on a
    /// thread (its direct light has moved; the scattered light shown is the earlier
    /// direction's meanwhile: see [`Hierarchy::set_sun`]).
    pub fn sun_moving(&self) -> bool {
        self.sun_move.is_some()
    }

    /// The sun being moved to, if its world grid's scattered light is being swept: the
    /// sun shown ([`Hierarchy::sun`]), whose direct light has moved already.
    pub fn sun_moving_to(&self) -> Option<SunLight> {
        self.sun_move.as_ref().and(self.sun)
    }

    /// [`Hierarchy::set_sun`] of a new direction where a sun is shown: starts the
    /// world grid's sweep on a thread (or queues it behind the one running) and returns
    /// `true`, or returns `false` where the sweep must run at once (no time budget, a
    /// sweeper that cannot fork, no thread to be had).
    pub(crate) fn move_sun_in_background(&mut self, sun: SunLight) -> Result<bool, LodError> {
        // Apart, the scattered sun is for unit irradiance: its direction alone counts.
        let with_sky = self.params.sun_with_sky;
        let same = |a: SunLight, b: SunLight| a.to_sun == b.to_sun && (!with_sky || a == b);
        if let Some(m) = &mut self.sun_move {
            m.next = (!same(m.sun, sun)).then_some(sun);
            return Ok(true);
        }
        if self.params.budget_ms.is_none() || self.world_sun.is_none() {
            return Ok(false);
        }
        match self.spawn_world_sun(sun)? {
            Some(m) => {
                self.sun_move = Some(m);
                Ok(true)
            }
            None => Ok(false),
        }
    }

    /// The world grid's sweep for `sun` on a fork of the sweeper, on a thread
    /// (`None`: no fork or no thread): its scattered sun's responses, or with the sun
    /// swept with the sky its light.
    fn spawn_world_sun(&mut self, sun: SunLight) -> Result<Option<SunMove>, LodError> {
        let Some(mut sweeper) = self.sweeper.fork() else {
            return Ok(None);
        };
        let material: MaterialGrid = match &self.world_material {
            Some(m) if m.desc() == self.world.desc() => m.clone(),
            _ => self.compose(self.world.desc())?,
        };
        let options = self.node_options(true);
        let (sky, with_sky) = (self.sky, self.params.sun_with_sky);
        let thread = std::thread::Builder::new()
            .name("lightgrid world sun".into())
            .spawn(move || {
                let _span = tracing::debug_span!("world sun (background)").entered();
                let mut run = move || {
                    let s = sweeper.as_mut();
                    if with_sky {
                        world_sky(s, &material, sky, Some(sun), &options).map(Moved::WithSky)
                    } else {
                        world_grid_sun(s, &material, sun.to_sun, &options).map(Moved::Apart)
                    }
                };
                // A pool of its own (the module's docs).
                match rayon::ThreadPoolBuilder::new()
                    .num_threads(1)
                    .thread_name(|_| "lightgrid world sun".into())
                    .build()
                {
                    Ok(pool) => pool.install(run),
                    Err(_) => run(),
                }
            });
        Ok(thread.ok().map(|thread| SunMove {
            sun,
            thread,
            next: None,
        }))
    }

    /// Installs a moved sun whose world-grid responses are done (all of them, waiting
    /// for the sweep, with `wait`): the world grid's responses; the nodes' scattered
    /// light is then stale, for the budget to sweep again. Returns whether it installed
    /// one.
    pub(crate) fn poll_sun_move(&mut self, wait: bool) -> Result<bool, LodError> {
        loop {
            let Some(m) = self.sun_move.take() else {
                return Ok(false);
            };
            if !wait && !m.thread.is_finished() {
                self.sun_move = Some(m);
                return Ok(false);
            }
            let response = m.thread.join().map_err(|_| SweepError::Backend {
                backend: "world sun thread",
                message: "the thread sweeping the world grid's sun panicked".into(),
            })?;
            if let Some(next) = m.next {
                // Superseded: sweep the last sun asked for (at once if no thread).
                match self.spawn_world_sun(next)? {
                    Some(n) => {
                        self.sun_move = Some(n);
                        if !wait {
                            return Ok(false);
                        }
                        continue;
                    }
                    None => {
                        if self.params.sun_with_sky {
                            self.sweep_world()?;
                        }
                        self.sweep_world_sun()?;
                        return Ok(true);
                    }
                }
            }
            match response? {
                Moved::Apart(g) => self.world_sun = Some(g),
                Moved::WithSky(out) => self.install_world(out, Some(m.sun)),
            }
            return Ok(true);
        }
    }

    /// Drops every node's sun responses.
    pub(crate) fn drop_node_suns(&mut self) {
        for n in self.nodes.values_mut() {
            n.sun = None;
        }
    }

    /// Marches every grid's transmittance not marched for the sun shown (the world
    /// grid's and every node's with sun responses), nodes coarse first: a node's march
    /// beyond its box crosses coarser grids' materials only, as when it was swept
    /// ([`shadow`]), so each equals what a sweep of its sun responses would give. Under
    /// a time budget ([`crate::HierarchyParams::budget_ms`]) the world grid's and then
    /// the nodes' nearest the last frame's camera, until about half the budget is spent
    /// (as a frame composes: [`Hierarchy::composition_waits`]).
    pub(crate) fn march_suns(&mut self) -> Result<(), LodError> {
        let Some(sun) = self.sun else {
            return Ok(());
        };
        let _span = tracing::debug_span!("march suns").entered();
        let lent = crate::Lent(self.sweeper.carries_halo_paths());
        let mut sweeper = std::mem::replace(&mut self.sweeper, Box::new(lent));
        let r = self.march_all(sweeper.as_mut(), sun.to_sun);
        self.sweeper = sweeper;
        r
    }

    fn march_all(&mut self, sweeper: &mut dyn Sweeper, to_sun: Vec3) -> Result<(), LodError> {
        if self
            .world_sun
            .as_ref()
            .is_some_and(|w| w.marched_to != to_sun)
        {
            let composed;
            let material = match &self.world_material {
                Some(m) if m.desc() == self.world.desc() => m,
                _ => {
                    composed = self.compose(self.world.desc())?;
                    &composed
                }
            };
            let t = march(sweeper, material, to_sun, &|_| 1.0)?;
            if let Some(w) = &mut self.world_sun {
                w.transmittance = t;
                w.marched_to = to_sun;
            }
        }
        let mut keys: Vec<_> = self
            .nodes
            .iter()
            .filter(|(_, n)| n.sun.as_ref().is_some_and(|g| g.marched_to != to_sun))
            .map(|(k, _)| *k)
            .collect();
        keys.sort();
        // Under a time budget, nearest the last frame's camera first, for about half a
        // frame's budget (the nodes over the camera whatever the time): the nodes left
        // are marched by the frames after, within their budget (a march alone where
        // their scattered sun is current: `build.rs`), and show the coarser grids' sun
        // meanwhile.
        let allowance = self.params.budget_ms.map(|ms| {
            if let Some(cam) = self.camera {
                keys.sort_by(|a, b| {
                    self.distance(*a, cam)
                        .total_cmp(&self.distance(*b, cam))
                        .then(a.cmp(b))
                });
            }
            (std::time::Instant::now(), f64::from(ms) / 2e3)
        });
        // The sun's casters for the new direction first, unless a time budget is set:
        // then `set_sun` marches through the material held (composing every node's
        // casters at once took its CPU time at 10° from 60 to 240 ms), and each node's
        // transmittance is marched again with its casters when the budget sweeps its
        // scattered sun, which the move left stale.
        if self.params.budget_ms.is_none() {
            let lit: Vec<_> = keys
                .iter()
                .map(|k| (*k, self.marched_extent(&self.nodes[k].material)))
                .collect();
            self.compose_casters(&lit, &[to_sun], &[])?;
        }
        for key in keys {
            // (The nodes over the camera, at distance 0, whatever the time.)
            if let (Some((since, secs)), Some(cam)) = (allowance, self.camera)
                && since.elapsed().as_secs_f64() >= secs
                && self.distance(key, cam) > 0.0
            {
                break;
            }
            let n = &self.nodes[&key];
            let fresh = shadow::Fresh::default();
            let t = self.march_node(sweeper, key, &n.material, to_sun, &fresh)?;
            let ring = self.march_ring(sweeper, (key, &fresh), &n.material, to_sun)?;
            if let Some(g) = self.nodes.get_mut(&key).and_then(|n| n.sun.as_mut()) {
                g.transmittance = t;
                g.marched_to = to_sun;
                g.march_stale = false;
                g.ring = ring;
            }
        }
        Ok(())
    }
}

/// The world grid's light: `sky` over it, and with `sun` (swept with the sky:
/// [`crate::HierarchyParams::sun_with_sky`]) the sun's first collisions, the beam
/// entering through its faces with nothing lost before them.
pub(crate) fn world_sky(
    sweeper: &mut dyn Sweeper,
    material: &MaterialGrid,
    sky: BinLight,
    sun: Option<SunLight>,
    options: &SweepOptions,
) -> Result<lightgrid_core::SweepOutput, SweepError> {
    let boundary = Boundary::open_sky(sky);
    match sun {
        Some(sun) => sweeper.sweep_with_sun(
            material,
            &boundary,
            &lightgrid_core::SunBeam {
                to_sun: sun.to_sun,
                irradiance: sun.irradiance,
                outside: &|_| 1.0,
            },
            options,
        ),
        None => sweeper.sweep(material, &boundary, options),
    }
}

/// A grid's transmittance for `to_sun` alone, `outside` beyond its box (open sides, as
/// the world grid's and the nodes' sun sweeps have).
pub(crate) fn march(
    sweeper: &mut dyn Sweeper,
    material: &MaterialGrid,
    to_sun: Vec3,
    outside: &(dyn Fn(Vec3) -> f32 + Sync),
) -> Result<Grid<f32>, SweepError> {
    sweeper.sun_transmittance(
        material,
        &SunBoundary {
            to_sun,
            scattered: Boundary::open_sky(BinLight::ZERO),
            outside,
        },
    )
}

/// The world grid's sun responses for `to_sun`: the beam enters through its faces, no
/// scattered light does.
pub(crate) fn world_grid_sun(
    sweeper: &mut dyn Sweeper,
    material: &MaterialGrid,
    to_sun: Vec3,
    options: &SweepOptions,
) -> Result<GridSun, SweepError> {
    let boundary = SunBoundary {
        to_sun,
        scattered: Boundary::open_sky(BinLight::ZERO),
        outside: &|_| 1.0,
    };
    let r = sweeper.sweep_sun(material, &boundary, options)?;
    Ok(GridSun {
        scattered: Some(r.scattered),
        horizon: r.horizon,
        resident: r.resident,
        transmittance: r.transmittance,
        to_sun,
        marched_to: to_sun,
        with_sky: None,
        march_stale: false,
        ring: None,
    })
}
