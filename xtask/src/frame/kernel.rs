//! The kernel alone on the path's own sweeps (issue 43: "the hierarchy's points per
//! second of frame time at least half of the kernel's rate for the same passes and
//! sweeps on the same nodes").
//!
//! A second hierarchy flies the same path with its sweeper wrapped in a [`Recording`]:
//! every sweep of the path's second half (sky sweeps, sun responses and marches, with
//! their materials, boundaries and options, and the sun's outside transmittance the
//! sweeper looked up) is kept. They are then made again one after another on one
//! sweeper with recycled memory, five rounds, and the points the hierarchy counted for
//! those frames are divided by the median round's time. The recording run's own frames are not timed (copying the
//! inputs costs time); the sweeps made again are the very calls the frames made.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use anyhow::Result;
use lightgrid_core::glam::Vec3;
use lightgrid_core::{
    BinLight, Boundary, Grid, MaterialGrid, SunBeam, SunBoundary, SunResponse, SweepError,
    SweepOptions, SweepOutput, Sweeper,
};
use lightgrid_terrain_lod::{Hierarchy, SunLight};

use super::{FrameConfig, Gpu, SUN_E, World, hierarchy_params, new_sweeper};

/// Most sweeps kept (whole frames are kept until this many are held): a 32-point node's
/// inputs are some 10 MB.
const MAX_RECORDED: usize = 64;

/// The outside transmittance a sun sweep looked up, by position (its bits).
type Outside = HashMap<[u32; 3], f32>;

/// One call to the sweeper, with what it was given.
enum Call {
    Sky {
        material: MaterialGrid,
        boundary: Boundary,
        options: SweepOptions,
    },
    Sun {
        material: MaterialGrid,
        to_sun: Vec3,
        scattered: Boundary,
        outside: Outside,
        /// `None`: a march alone ([`Sweeper::sun_transmittance`]).
        options: Option<SweepOptions>,
    },
    /// The sky and the sun's first collisions in one sweep ([`Sweeper::sweep_with_sun`]).
    SkyWithSun {
        material: MaterialGrid,
        boundary: Boundary,
        to_sun: Vec3,
        irradiance: Vec3,
        outside: Outside,
        options: SweepOptions,
    },
}

/// The calls kept, and whether calls are kept now.
#[derive(Default)]
struct Log {
    on: bool,
    calls: Vec<Call>,
}

/// A sweeper that forwards every call and, while its log is on, keeps what each call
/// was given (its forks share the log).
struct Recording {
    inner: Box<dyn Sweeper + Send + Sync>,
    log: Arc<Mutex<Log>>,
}

fn key(p: Vec3) -> [u32; 3] {
    p.to_array().map(f32::to_bits)
}

/// `outside`, each lookup kept in `seen` by position.
fn recorded<'a>(
    outside: &'a (dyn Fn(Vec3) -> f32 + Sync),
    seen: &'a Mutex<Outside>,
) -> impl Fn(Vec3) -> f32 + Sync + 'a {
    move |p: Vec3| {
        let v = outside(p);
        seen.lock()
            .unwrap_or_else(|e| e.into_inner())
            .insert(key(p), v);
        v
    }
}

impl Recording {
    fn on(&self) -> bool {
        self.log.lock().unwrap_or_else(|e| e.into_inner()).on
    }
    fn keep(&self, call: Call) {
        self.log
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .calls
            .push(call);
    }
    /// `sun` with its outside lookups kept (when the log is on), run through `f`.
    fn with_outside<T>(
        &mut self,
        material: &MaterialGrid,
        sun: &SunBoundary<'_>,
        options: Option<SweepOptions>,
        f: impl FnOnce(&mut dyn Sweeper, &SunBoundary<'_>) -> Result<T, SweepError>,
    ) -> Result<T, SweepError> {
        if !self.on() {
            return f(self.inner.as_mut(), sun);
        }
        let seen = Mutex::new(Outside::new());
        let outside = recorded(sun.outside, &seen);
        let boundary = SunBoundary {
            to_sun: sun.to_sun,
            scattered: sun.scattered.clone(),
            outside: &outside,
        };
        let r = f(self.inner.as_mut(), &boundary)?;
        self.keep(Call::Sun {
            material: material.clone(),
            to_sun: sun.to_sun,
            scattered: boundary.scattered,
            outside: std::mem::take(&mut *seen.lock().unwrap_or_else(|e| e.into_inner())),
            options,
        });
        Ok(r)
    }
}

impl Sweeper for Recording {
    fn name(&self) -> &'static str {
        self.inner.name()
    }
    fn fork(&self) -> Option<Box<dyn Sweeper + Send + Sync>> {
        Some(Box::new(Recording {
            inner: self.inner.fork()?,
            log: self.log.clone(),
        }))
    }
    fn sweep(
        &mut self,
        material: &MaterialGrid,
        boundary: &Boundary,
        options: &SweepOptions,
    ) -> Result<SweepOutput, SweepError> {
        let out = self.inner.sweep(material, boundary, options)?;
        if self.on() {
            self.keep(Call::Sky {
                material: material.clone(),
                boundary: boundary.clone(),
                options: *options,
            });
        }
        Ok(out)
    }
    fn sweep_with_sun(
        &mut self,
        material: &MaterialGrid,
        boundary: &Boundary,
        sun: &SunBeam<'_>,
        options: &SweepOptions,
    ) -> Result<SweepOutput, SweepError> {
        if !self.on() {
            return self.inner.sweep_with_sun(material, boundary, sun, options);
        }
        let seen = Mutex::new(Outside::new());
        let outside = recorded(sun.outside, &seen);
        let beam = SunBeam {
            outside: &outside,
            ..*sun
        };
        let out = self
            .inner
            .sweep_with_sun(material, boundary, &beam, options)?;
        self.keep(Call::SkyWithSun {
            material: material.clone(),
            boundary: boundary.clone(),
            to_sun: sun.to_sun,
            irradiance: sun.irradiance,
            outside: std::mem::take(&mut *seen.lock().unwrap_or_else(|e| e.into_inner())),
            options: *options,
        });
        Ok(out)
    }
    /// Forwarded, not kept: the hierarchy sweeps cell sources only inside `sweep_sun`
    /// and `sweep_with_sun`.
    fn sweep_with_source(
        &mut self,
        material: &MaterialGrid,
        boundary: &Boundary,
        source: &lightgrid_core::CellSource,
        options: &SweepOptions,
    ) -> Result<SweepOutput, SweepError> {
        self.inner
            .sweep_with_source(material, boundary, source, options)
    }
    fn sweep_sun(
        &mut self,
        material: &MaterialGrid,
        sun: &SunBoundary<'_>,
        options: &SweepOptions,
    ) -> Result<SunResponse, SweepError> {
        self.with_outside(material, sun, Some(*options), |s, b| {
            s.sweep_sun(material, b, options)
        })
    }
    fn sun_transmittance(
        &mut self,
        material: &MaterialGrid,
        sun: &SunBoundary<'_>,
    ) -> Result<Grid<f32>, SweepError> {
        self.with_outside(material, sun, None, |s, b| s.sun_transmittance(material, b))
    }
    fn crop_resident(
        &self,
        resident: &lightgrid_core::Resident,
        inner: &lightgrid_core::GridDesc,
        offset: lightgrid_core::glam::UVec3,
    ) -> Option<lightgrid_core::Resident> {
        self.inner.crop_resident(resident, inner, offset)
    }
}

/// The kernel's points per second on the path's own sweeps (the module docs): the
/// path flown again by a hierarchy of `cfg`'s parameters under the sun `to_sun` and
/// sky `sky`, the second half's sweeps made again on one sweeper.
pub(super) fn rate(
    world: &World,
    cfg: &FrameConfig,
    gpu: &Gpu,
    (to_sun, sky): (Vec3, BinLight),
) -> Result<f64> {
    let log = Arc::new(Mutex::new(Log::default()));
    let recording = Recording {
        inner: new_sweeper(gpu),
        log: log.clone(),
    };
    let mut h = Hierarchy::new(
        &world.hm,
        Box::new(world.composer()?),
        Box::new(recording),
        sky,
        hierarchy_params(cfg),
    )?;
    h.set_sun(Some(SunLight {
        to_sun,
        irradiance: SUN_E,
    }))?;
    let mut points = 0u64;
    for f in 0..cfg.frames {
        let keep = f >= cfg.frames / 2
            && log.lock().unwrap_or_else(|e| e.into_inner()).calls.len() < MAX_RECORDED;
        log.lock().unwrap_or_else(|e| e.into_inner()).on = keep;
        let s = h.update(world.camera(cfg, f))?;
        if keep {
            points += s.points_swept;
        }
    }
    drop(h);
    let calls = std::mem::take(&mut log.lock().unwrap_or_else(|e| e.into_inner()).calls);
    anyhow::ensure!(
        !calls.is_empty(),
        "the path's second half swept nothing to time the kernel on"
    );
    // The CPU sweeper takes its outputs' memory back (as a sweep after sweep does).
    let secs = if gpu.is_some() {
        let mut s = new_sweeper(gpu);
        time_all(&calls, &mut |c| replay(s.as_mut(), c).map(drop))?
    } else {
        let mut s = lightgrid_sweep_cpu::CpuSweeper::new();
        time_all(&calls, &mut |c| {
            if let Some(out) = replay(&mut s, c)? {
                s.recycle(out);
            }
            Ok(())
        })?
    };
    Ok(points as f64 / secs.max(1e-9))
}

/// Times the calls are made again ([`time_all`]); the median is the kernel's time.
const REPLAYS: usize = 5;

/// Seconds to make every call of `calls` again with `run`, after the first once
/// untimed (a process's first sweep of each kind makes its tables): the median of
/// [`REPLAYS`] rounds (on the 2-core VM one round's time varied 295–505 ms within one
/// run, the rate 0.38–0.72 M points a second between runs of the same path).
fn time_all(calls: &[Call], run: &mut dyn FnMut(&Call) -> Result<()>) -> Result<f64> {
    run(&calls[0])?;
    let mut secs = Vec::with_capacity(REPLAYS);
    for _ in 0..REPLAYS {
        let t = Instant::now();
        for c in calls {
            run(c)?;
        }
        secs.push(t.elapsed().as_secs_f64());
    }
    secs.sort_by(f64::total_cmp);
    Ok(secs[REPLAYS / 2])
}

/// `call` made again on `sweeper`, the sun's outside transmittance read from what the
/// call looked up; a sky sweep's output returned.
fn replay(sweeper: &mut dyn Sweeper, call: &Call) -> Result<Option<SweepOutput>> {
    match call {
        Call::Sky {
            material,
            boundary,
            options,
        } => Ok(Some(sweeper.sweep(material, boundary, options)?)),
        Call::SkyWithSun {
            material,
            boundary,
            to_sun,
            irradiance,
            outside,
            options,
        } => {
            let missed = std::sync::atomic::AtomicU64::new(0);
            let look = looked_up(outside, &missed);
            let beam = SunBeam {
                to_sun: *to_sun,
                irradiance: *irradiance,
                outside: &look,
            };
            let out = sweeper.sweep_with_sun(material, boundary, &beam, options)?;
            no_misses(&missed)?;
            Ok(Some(out))
        }
        Call::Sun {
            material,
            to_sun,
            scattered,
            outside,
            options,
        } => {
            let missed = std::sync::atomic::AtomicU64::new(0);
            let look = looked_up(outside, &missed);
            let sun = SunBoundary {
                to_sun: *to_sun,
                scattered: scattered.clone(),
                outside: &look,
            };
            match options {
                Some(o) => drop(std::hint::black_box(sweeper.sweep_sun(material, &sun, o)?)),
                None => drop(std::hint::black_box(
                    sweeper.sun_transmittance(material, &sun)?,
                )),
            }
            no_misses(&missed)?;
            Ok(None)
        }
    }
}

/// The outside transmittance a recorded call looked up, read back by position (1, and
/// counted in `missed`, where it looked up none).
fn looked_up<'a>(
    outside: &'a Outside,
    missed: &'a std::sync::atomic::AtomicU64,
) -> impl Fn(Vec3) -> f32 + Sync + 'a {
    move |p: Vec3| {
        outside.get(&key(p)).copied().unwrap_or_else(|| {
            missed.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            1.0
        })
    }
}

/// An error where a call made again looked up outside points the recorded one did not.
fn no_misses(missed: &std::sync::atomic::AtomicU64) -> Result<()> {
    let missed = missed.load(std::sync::atomic::Ordering::Relaxed);
    anyhow::ensure!(
        missed == 0,
        "a sun sweep made again looked up {missed} outside points the recorded one did not"
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use lightgrid_core::glam::UVec3;
    use lightgrid_core::{GridDesc, Material};
    use lightgrid_sweep_cpu::CpuSweeper;

    /// A small grid of random media over an opaque floor.
    fn material() -> MaterialGrid {
        let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(8, 6, 8)).unwrap();
        let mut rng = lightgrid_core::SeededRng::new(3);
        let cells = (0..desc.point_count())
            .map(|i| match desc.coords(i).unwrap().y {
                0 => Material::opaque(Vec3::splat(0.2)),
                _ if rng.f32() < 0.4 => Material {
                    reflectance: Vec3::new(0.1, 0.3, 0.1),
                    pass: 0.2 + 0.7 * rng.f32(),
                },
                _ => Material::EMPTY,
            })
            .collect();
        MaterialGrid::new(desc, cells).unwrap()
    }

    #[test]
    fn a_recorded_sweep_made_again_gives_the_same_light() {
        let m = material();
        let log = Arc::new(Mutex::new(Log {
            on: true,
            calls: Vec::new(),
        }));
        let mut rec = Recording {
            inner: Box::new(CpuSweeper::new()),
            log: log.clone(),
        };
        let mut o = SweepOptions::multi_bounce();
        o.max_passes = 2;
        let sky = BinLight::uniform(Vec3::new(0.6, 0.7, 1.0));
        let sky_out = rec.sweep(&m, &Boundary::open_sky(sky), &o).unwrap();
        // An outside transmittance that varies with the exit point.
        let outside = |p: Vec3| 0.5 + 0.05 * (p.x + p.z).rem_euclid(8.0);
        let sun = SunBoundary {
            to_sun: Vec3::new(0.8, 0.35, 0.3),
            scattered: Boundary::open_sky(BinLight::ZERO),
            outside: &outside,
        };
        let sun_out = rec.sweep_sun(&m, &sun, &o).unwrap();
        let march = rec.sun_transmittance(&m, &sun).unwrap();
        let calls = std::mem::take(&mut log.lock().unwrap().calls);
        assert_eq!(calls.len(), 3);
        // Made again on a fresh sweeper: bit for bit the light the recorded calls made.
        let mut again = CpuSweeper::new();
        let sky_again = replay(&mut again, &calls[0]).unwrap().unwrap();
        assert_eq!(sky_again.bins.unwrap().data(), sky_out.bins.unwrap().data());
        let Call::Sun { outside: seen, .. } = &calls[1] else {
            panic!("the second call is the sun's");
        };
        assert!(!seen.is_empty(), "the sun's sweep looked outside");
        assert!(replay(&mut again, &calls[1]).unwrap().is_none());
        let look = |p: Vec3| seen[&key(p)];
        let sun_again = again
            .sweep_sun(
                &m,
                &SunBoundary {
                    to_sun: sun.to_sun,
                    scattered: Boundary::open_sky(BinLight::ZERO),
                    outside: &look,
                },
                &o,
            )
            .unwrap();
        assert_eq!(sun_again.transmittance.data(), sun_out.transmittance.data());
        assert_eq!(sun_again.scattered.data(), sun_out.scattered.data());
        assert!(replay(&mut again, &calls[2]).unwrap().is_none());
        assert!(march.data().iter().any(|&t| t > 0.0 && t < 1.0));
        // Off: nothing is kept.
        log.lock().unwrap().on = false;
        rec.sweep(&m, &Boundary::open_sky(sky), &o).unwrap();
        assert!(log.lock().unwrap().calls.is_empty());
    }
}
