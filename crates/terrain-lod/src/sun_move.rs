//! Time of day under a time budget: a moved sun's world-grid responses swept on a
//! thread of their own.
//!
//! The world grid's sun responses are the one job a moved sun cannot leave to the
//! budget: every node's sun reads them, and they are one sweep of the whole world grid
//! (110–300 ms on two cores), several times a frame's budget. Under a time budget
//! ([`HierarchyParams::budget_ms`](crate::HierarchyParams::budget_ms)), with a sweeper
//! that forks, [`Hierarchy::set_sun`] starts that sweep on a fork of the sweeper on a
//! thread of its own (in a one-thread rayon pool apart from the frames': in theirs, a
//! frame waiting on its own jobs would steal the sweep's long ones) and returns; the
//! old sun stays shown, whole (its world grid and nodes), until a frame
//! ([`Hierarchy::update`], [`Hierarchy::refresh`]) finds the new responses done. That
//! frame installs them and drops the nodes' old ones, which the budget then recomputes
//! coarse and near first, as a sun set at once would. A sun set again while the sweep
//! runs waits for it, then is swept in its turn (only the last one asked for). Without
//! a time budget, with a sweeper that cannot fork (the GPU's: one queue), and for a
//! first sun (none shown yet), the sweep runs at once, in `set_sun`.

use std::thread::JoinHandle;

use lightgrid_core::glam::Vec3;
use lightgrid_core::{
    BinLight, Boundary, MaterialGrid, SunBoundary, SweepError, SweepOptions, Sweeper,
};

use crate::{GridSun, Hierarchy, LodError, SunLight};

/// A moved sun's world-grid responses, being swept.
pub(crate) struct SunMove {
    /// The sun they are swept for.
    sun: SunLight,
    thread: JoinHandle<Result<GridSun, SweepError>>,
    /// A sun set while they were swept: swept next (the last one asked for).
    next: Option<SunLight>,
}

impl Hierarchy {
    /// Whether a moved sun's world-grid responses are being swept (the old sun is shown
    /// meanwhile; see [`Hierarchy::set_sun`]).
    pub fn sun_moving(&self) -> bool {
        self.sun_move.is_some()
    }

    /// The sun being moved to, if its world-grid responses are being swept.
    pub fn sun_moving_to(&self) -> Option<SunLight> {
        self.sun_move.as_ref().map(|m| m.next.unwrap_or(m.sun))
    }

    /// [`Hierarchy::set_sun`] of a new direction where a sun is shown: starts the
    /// world grid's sweep on a thread (or queues it behind the one running) and returns
    /// `true`, or returns `false` where the sweep must run at once (no time budget, a
    /// sweeper that cannot fork, no thread to be had).
    pub(crate) fn move_sun_in_background(&mut self, sun: SunLight) -> Result<bool, LodError> {
        if let Some(m) = &mut self.sun_move {
            if m.sun.to_sun == sun.to_sun {
                m.sun = sun;
                m.next = None;
            } else {
                m.next = Some(sun);
            }
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

    /// The world grid's sweep for `sun` on a fork of the sweeper, on a thread (`None`:
    /// no fork or no thread).
    fn spawn_world_sun(&mut self, sun: SunLight) -> Result<Option<SunMove>, LodError> {
        let Some(mut sweeper) = self.sweeper.fork() else {
            return Ok(None);
        };
        let material: MaterialGrid = match &self.world_material {
            Some(m) if m.desc() == self.world.desc() => m.clone(),
            _ => self.source.material(self.world.desc())?,
        };
        let options = self.node_options(true);
        let to_sun = sun.to_sun;
        let thread = std::thread::Builder::new()
            .name("lightgrid world sun".into())
            .spawn(move || {
                let _span = tracing::debug_span!("world sun (background)").entered();
                let mut run = move || world_grid_sun(sweeper.as_mut(), &material, to_sun, &options);
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
    /// for the sweep, with `wait`): the sun, the world grid's responses, and every
    /// node's dropped for the budget to recompute. Returns whether it installed one.
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
                        self.sun = Some(next);
                        self.drop_node_suns();
                        self.sweep_world_sun()?;
                        return Ok(true);
                    }
                }
            }
            self.world_sun = Some(response?);
            self.sun = Some(m.sun);
            self.drop_node_suns();
            return Ok(true);
        }
    }

    /// Drops every node's sun responses (a new sun direction).
    pub(crate) fn drop_node_suns(&mut self) {
        for n in self.nodes.values_mut() {
            n.sun = None;
        }
    }
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
        scattered: r.scattered,
        resident: r.resident,
        transmittance: r.transmittance,
        to_sun,
    })
}
