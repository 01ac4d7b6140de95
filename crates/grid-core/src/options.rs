//! The options of a sweep: which outputs it computes ([`Outputs`]), how its passes
//! run and converge ([`SweepOptions`], [`Acceleration`], [`MediumEmission`]) and
//! whether a cell source's first scatterings are gathered by rays ([`Gather`]).

use crate::GridError;

/// Which outputs a sweep computes. Nothing that is not asked for is computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Outputs {
    /// The full 26-bin light grid.
    pub bins: bool,
    /// The average-light grid.
    pub average: bool,
    /// The dominant-direction grid.
    pub dominant: bool,
    /// Beside the bins (it needs them), the downward-travelling halves of the 8
    /// horizontal bins ([`crate::HorizonLight`], 8 RGB values a point: a third more
    /// memory than the bins), for irradiance exact across the horizon
    /// ([`crate::BinLight::irradiance_split`]).
    pub horizon: bool,
}

impl Outputs {
    /// The 26 bins, the average and the dominant direction (the horizon halves are
    /// asked for apart: [`Outputs::with_horizon`]).
    pub const ALL: Self = Self {
        bins: true,
        average: true,
        dominant: true,
        horizon: false,
    };
    /// Average and dominant direction only (per-frame lighting).
    pub const AVERAGE_DOMINANT: Self = Self {
        bins: false,
        average: true,
        dominant: true,
        horizon: false,
    };
    /// These outputs and the horizon halves (which need the bins: asked for too).
    pub const fn with_horizon(self) -> Self {
        Self {
            bins: true,
            horizon: true,
            ..self
        }
    }
}

/// Options of a sweep. Start from a preset and change fields.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct SweepOptions {
    /// Outputs to compute.
    pub outputs: Outputs,
    /// Weight in `[0, 1)` of the smoothing kernel over a source point's neighbours
    /// (0 = off): softens the sharp shadows of a few directions. The presets' 0.5 had
    /// the least error against Monte Carlo of 0, 0.25, 0.35, 0.5 and 0.6 on the bench
    /// forest (16³ and 24³, 4 passes), and less than 0.25 on every bench scene whose
    /// light smoothing changes (`sweep-cpu`'s crate docs, "Smoothing").
    pub smoothing: f32,
    /// Most sweeps, alternating downward and upward, starting downward (1 = the seed's
    /// single downward pass: no light travels upward).
    pub max_passes: u32,
    /// Stop repeating passes when a pass changes the light by less than this fraction
    /// (0: every pass up to `max_passes` runs).
    pub tolerance: f32,
    /// Copy, instead of computing, the levels above all material in a downward pass
    /// under a laterally uniform boundary, and carry the light of all upward passes
    /// through those levels once (the same result up to rounding; on by default; off
    /// only to measure what the skips save). GPU sweepers may compute them regardless.
    pub skip_empty_levels: bool,
    /// How a medium cell emits the light it scatters (step 5 of the sweep's
    /// specification, the `sweep-cpu` docs).
    pub medium: MediumEmission,
    /// How the passes converge: plain repetition ([`Acceleration::Off`]) or with a
    /// diffusion correction between passes ([`Acceleration::Diffusion`]).
    pub acceleration: Acceleration,
    /// How a cell source's first scatterings (the sun's) travel: swept with the rest
    /// ([`Gather::OFF`], [`SweepOptions::single_pass`]) or gathered by rays
    /// ([`Gather::LOW_SUN`]; [`Gather::AUTO`], [`SweepOptions::multi_bounce`]'s, for a
    /// sun at or below 30°).
    pub gather: Gather,
    /// With given sides ([`crate::SideBoundary::Given`]): the paths of the halo's points
    /// nearest the sides, which a sweep of the whole world traces through one or two of
    /// the grid's own cells of their level, are traced here too. A path entering the
    /// grid starts from the halo's light at its point and crosses the grid's cells
    /// after the point's centre: they stop its light and collect what they stop, and
    /// what they emit into it is carried on to the next level, which gathers the path's
    /// light instead of the halo point's mean. A path leaving the grid gathers as the
    /// grid's points do and crosses the grid's cells before its point: they collect
    /// what they stop of it. A grid's opaque cells do not stop an entering path: beyond
    /// an opaque cell at a given side the world goes on as it is there (as the sweep's
    /// exposure rule has it), so the halo's light there is a surface's, which leaves
    /// over its level-mates. A crop of a sweep of fog handed that sweep's own light at
    /// its halo is then exact in one pass (7 % off without). Off in the presets (the
    /// hand-over of the specification); the CPU sweeper traces them, a sweeper that does
    /// not returns an error ([`crate::Sweeper::carries_halo_paths`]).
    pub halo_paths: bool,
}

/// Whether a cell source's first scatterings are gathered by rays instead of swept
/// ([`SweepOptions::gather`]; `lightgrid_sweep_cpu::gather`, for the CPU and GPU
/// sweepers' `sweep_with_source` and the sun's entry points built on it).
///
/// The 26 bins carry light from a cell to its neighbours along 26 directions only: the
/// light a low sun scatters off lit patches of a canopy reaches cells between those
/// directions too little, and cells along them too much (ray effects). Gathered, each
/// cell's light of the first `orders` scatterings is its mean over `rays` directions (a
/// low-discrepancy set), each carried across the grid by parallel rays that integrate
/// what the cells along them emit, attenuated by the exact transmittance; the sweep
/// carries what those scatterings collide with further (the beam's first scattering
/// placed across each cell where it collided: [`crate::CellSource::across`]). A gather
/// costs about `rays ×` the grid's cells a scattering (a 16 × 10 × 16 canopy: 0.19 s
/// against the sweep's 19 ms on two cores): made for a bake, not a frame.
///
/// The sun's entry points (`Sweeper::sweep_sun`, `Sweeper::sweep_with_sun`) gather only
/// for a sun at most [`Gather::max_elevation_deg`] above the horizon ([`Gather::for_sun`];
/// a source given alone only with `max_elevation_deg` 90, [`Gather::for_source`]):
/// [`SweepOptions::multi_bounce`] gathers a sun at or below 30° ([`Gather::AUTO`]), where
/// the sweep alone leaves a patchy canopy's cells up to 17 % off, and sweeps a higher one
/// at the sweep's own cost.
///
/// ```
/// use lightgrid_core::{Gather, SweepOptions, glam::Vec3};
///
/// let auto = SweepOptions::multi_bounce().gather;
/// assert_eq!(auto, Gather::AUTO);
/// let at = |deg: f32| Vec3::new(deg.to_radians().cos(), deg.to_radians().sin(), 0.0);
/// assert_eq!(auto.for_sun(at(10.0)), Gather::LOW_SUN); // a low sun: gathered
/// assert_eq!(auto.for_sun(at(45.0)), Gather::OFF); // a high one: swept
/// assert_eq!(Gather::LOW_SUN.for_sun(at(60.0)), Gather::LOW_SUN); // every sun
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Gather {
    /// Scatterings gathered (0: none, the sweep carries them all; at most 4).
    pub orders: u32,
    /// Directions for the first scattering (64 to 65,536), each crossing every cell
    /// about once; later ones take a quarter as many (at least 64): their light is
    /// smoother.
    pub rays: u32,
    /// The highest sun the sun's entry points gather, degrees above the horizon (0 to
    /// 90; 90: every sun). A cell source given alone (`Sweeper::sweep_with_source`) is
    /// gathered only at 90 ([`Gather::for_source`]).
    pub max_elevation_deg: u32,
}

impl Gather {
    /// Nothing gathered: the sweep carries every scattering.
    pub const OFF: Self = Self {
        orders: 0,
        rays: 4096,
        max_elevation_deg: 90,
    };
    /// Two scatterings gathered over 2,048 and 512 directions, at every sun elevation
    /// (`max_elevation_deg` 90): a patchy canopy under a 10°, 20° or 30° sun within
    /// 3.5 % of Monte Carlo in every cell (8 M paths; `lightgrid-measure`'s `beam_cells`
    /// example, `--gather`; 4,096 directions: 3.3 % for twice the time, 1,024: 5.5 %).
    pub const LOW_SUN: Self = Self {
        orders: 2,
        rays: 2048,
        max_elevation_deg: 90,
    };
    /// [`Gather::LOW_SUN`] for a sun at or below 30°, nothing gathered for a higher one
    /// ([`SweepOptions::multi_bounce`]'s): the sweep alone leaves 87 of a patchy canopy's
    /// 407 cells over 5 % off Monte Carlo at 10°, 39 at 20° and 22 at 30°, worst
    /// 17 / 11 / 10 %, and 6 at 60° (7 %); gathered none at any of them (one of 408
    /// at 25°, 5.4 %; `docs/measurements.md`, "The first scatterings gathered").
    pub const AUTO: Self = Self {
        max_elevation_deg: 30,
        ..Self::LOW_SUN
    };
    /// Whether anything is gathered.
    pub const fn is_on(&self) -> bool {
        self.orders > 0
    }
    /// The gather for a sun toward `to_sun` (any length; y up), as the sun's entry
    /// points apply it before sweeping the beam's first collisions as a cell source:
    /// where the sun is at most [`Gather::max_elevation_deg`] above the horizon (to
    /// within 0.001°), this one for every source (`max_elevation_deg` 90); above it,
    /// [`Gather::OFF`]. A direction that is not finite and nonzero is left to the
    /// sweep's own checks: the gather comes back unchanged.
    pub fn for_sun(&self, to_sun: glam::Vec3) -> Self {
        let len = to_sun.length();
        if !(len.is_finite() && len > 0.0) {
            return *self;
        }
        let elevation = (to_sun.y / len).clamp(-1.0, 1.0).asin().to_degrees();
        if self.max_elevation_deg >= 90 || elevation <= self.max_elevation_deg as f32 + 1e-3 {
            Self {
                max_elevation_deg: 90,
                ..*self
            }
        } else {
            Self::OFF
        }
    }
    /// The gather a cell source given alone takes (`Sweeper::sweep_with_source`,
    /// `lightgrid_sweep_cpu::run_with_source`), whose sun, if any, is unknown: this one
    /// where it gathers at every sun (`max_elevation_deg` 90), else [`Gather::OFF`]. So
    /// [`Gather::AUTO`] (the `multi_bounce` preset's) gathers only through the sun's
    /// entry points, which know the sun ([`Gather::for_sun`]).
    pub const fn for_source(&self) -> Self {
        if self.max_elevation_deg >= 90 {
            *self
        } else {
            Self::OFF
        }
    }
    /// Checks every field; errors name it.
    pub fn validate(&self) -> Result<(), GridError> {
        if self.orders > 4 {
            return Err(GridError::invalid(
                "gather.orders",
                self.orders,
                "must be in 0..=4",
            ));
        }
        if !(64..=65_536).contains(&self.rays) {
            return Err(GridError::invalid(
                "gather.rays",
                self.rays,
                "must be in 64..=65536",
            ));
        }
        if self.max_elevation_deg > 90 {
            return Err(GridError::invalid(
                "gather.max_elevation_deg",
                self.max_elevation_deg,
                "must be in 0..=90",
            ));
        }
        Ok(())
    }
}

impl Default for Gather {
    fn default() -> Self {
        Self::OFF
    }
}

/// How a sweep's repeated passes converge ([`SweepOptions::acceleration`]).
///
/// The passes are source iteration: each sends on the light scattered in the one
/// before, so light that scatters many times (albedo near 1 in thick media: snow, dense
/// white cloud, fog banks) takes many passes. Measured by `cargo xtask exact`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub enum Acceleration {
    /// Every pass sends on what the one before scattered.
    #[default]
    Off,
    /// Diffusion synthetic acceleration (the CPU sweep, `lightgrid_sweep_cpu::accel`): after each
    /// downward and upward pair, the scattered light still waiting in media cells is
    /// spread by a diffusion solve over the media, which estimates every later
    /// generation of its scattering; the next passes send that on at once and take it
    /// back as they go, so the converged light is the same and the passes to a
    /// tolerance hardly grow with optical depth and albedo. Applies to media under
    /// [`MediumEmission::Source`] and [`MediumEmission::Profile`]; sweepers that do not
    /// implement it run as with `Off` (`SweepStats` says which ran).
    Diffusion,
}

/// How a medium cell (`0 < p < 1`) sends on the light it scatters (step 5 of the
/// sweep's specification, the `sweep-cpu` crate docs). Measured against exact answers in
/// `lightgrid_measure::exact` (`cargo xtask exact`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub enum MediumEmission {
    /// The scattered light is a flat, isotropic source inside the cell, and every path
    /// segment through the cell emits what such a source sends along it, attenuated by
    /// the segments after it (`lightgrid_sweep_cpu::medium`); thick cells lit from above send more
    /// of it back up. A white furnace is exact in any medium (random media of
    /// pass-through 0.02 to 1: within 1e-6), Chandrasekhar's half-space albedo within 2 %
    /// for cells of optical depth up to 0.7 (thick dark cells reflect too little: −23 %
    /// at depth 3, albedo 0.1; [`MediumEmission::Profile`], the default, fixes that).
    /// Kept as an option: measured the same or slightly better on the bench forest lit by
    /// the sky alone (where the sweep's angular error dominates), and up to twice as fast
    /// on the CPU in scenes made mostly of media.
    Source,
    /// `ω_b / 4π · (A S − B u_b · M)` into bin `b` (`M` the first moment of the light's
    /// incoming directions) with a slab's exact escape probabilities for light scattered
    /// out of a vertical beam: `A − B = τ p / (1 − p)` straight on (`τ = −ln p`), `A + B =
    /// (1 + p)/2` straight back (`lightgrid_sweep_cpu::sweep::medium_emission`). Fails the white
    /// furnace (horizontal bins too bright: +60 % at pass-through 0.5); kept because it
    /// is closer than the flat source on thick dark cells (half-space −3 % at optical
    /// depth 3, albedo 0.1, against −23 %; the default is +0.8 %) and the fastest rule
    /// on the CPU (no third phase: uniform fog 12³ in 20 ms, against 24 ms flat and
    /// 36 ms for the default).
    /// (The seed's rule, `A = (1 + p)/2`, `B = (1 − p)/2`, was removed: it reflected far
    /// too much from dense media, +59 % at optical depth 3, and measured worse than the
    /// source rule on every canonical scene.)
    Escape,
    /// [`MediumEmission::Source`] with each cell's source a **quadratic in height**
    /// instead of flat (`lightgrid_sweep_cpu::profile`, issue 13): a cell tallies the height
    /// moments of where light collides in it, and each batch of scattered light becomes
    /// an isotropic source whose Legendre coefficients in height solve the cell's 3 × 3
    /// balance with its own re-collisions; each pass's segments emit what that source
    /// sends along them. Still exact in a white furnace and linear in the light; on a
    /// laterally uniform half-space it is within the channels' own angular error at
    /// every cell depth (model: `cargo run --release -p lightgrid-measure --example
    /// profile_slab`); Chandrasekhar's half-space albedo within 2 % at every albedo and
    /// cell depth from 0.05 to 3. Cells thinner than optical depth 0.3
    /// (`lightgrid_sweep_cpu::medium::PROFILE_MIN_DEPTH`), whose collisions fall nearly
    /// evenly over their height, emit the flat source of [`MediumEmission::Source`]
    /// instead, which is as close to the exact answers there and cheaper. Both sweepers
    /// run it, with diffusion acceleration when asked. The default: a 64³ canopy sweeps
    /// at the flat rule's speed; on the CPU the bench forest takes 1.6 times the flat
    /// rule's time and scenes made mostly of media up to twice it (three source
    /// coefficients a thick cell instead of one).
    #[default]
    Profile,
}

/// Most passes one sweep may run ([`SweepOptions::max_passes`]): bounds the run time of
/// a sweep whose tolerance is never reached.
pub const MAX_PASSES: u32 = 4096;

impl SweepOptions {
    /// One downward pass, light smoothing, every output: the seed's sweep.
    pub const fn single_pass() -> Self {
        Self {
            outputs: Outputs::ALL,
            smoothing: 0.5,
            max_passes: 1,
            tolerance: 0.0,
            skip_empty_levels: true,
            medium: MediumEmission::Profile,
            acceleration: Acceleration::Off,
            gather: Gather::OFF,
            halo_paths: false,
        }
    }
    /// Repeated down/up passes for multiple bounces, until the light still to be
    /// transported is under 0.1 % of the input; a sun at or below 30° has its first
    /// scatterings gathered ([`Gather::AUTO`]: about ten times a sun sweep's time there).
    pub const fn multi_bounce() -> Self {
        Self {
            outputs: Outputs::ALL,
            smoothing: 0.5,
            max_passes: 16,
            tolerance: 1e-3,
            skip_empty_levels: true,
            medium: MediumEmission::Profile,
            acceleration: Acceleration::Off,
            gather: Gather::AUTO,
            halo_paths: false,
        }
    }
    /// Checks every field; errors name it.
    pub fn validate(&self) -> Result<(), GridError> {
        if !(self.smoothing.is_finite() && (0.0..1.0).contains(&self.smoothing)) {
            return Err(GridError::invalid(
                "smoothing",
                self.smoothing,
                "must be in [0, 1)",
            ));
        }
        if self.max_passes == 0 || self.max_passes > MAX_PASSES {
            return Err(GridError::invalid(
                "max_passes",
                self.max_passes,
                "must be in 1..=4096",
            ));
        }
        if !(self.tolerance.is_finite() && self.tolerance >= 0.0) {
            return Err(GridError::invalid(
                "tolerance",
                self.tolerance,
                "must be finite and >= 0",
            ));
        }
        self.gather.validate()?;
        if self.outputs.horizon && !self.outputs.bins {
            return Err(GridError::invalid(
                "outputs.horizon",
                self.outputs.horizon,
                "needs outputs.bins (the halves split the bins)",
            ));
        }
        if !(self.outputs.bins || self.outputs.average || self.outputs.dominant) {
            return Err(GridError::invalid(
                "outputs",
                self.outputs,
                "asks for nothing",
            ));
        }
        Ok(())
    }
}

impl Default for SweepOptions {
    fn default() -> Self {
        Self::single_pass()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn at(deg: f32) -> Vec3 {
        let r = deg.to_radians();
        Vec3::new(r.cos() * 0.6, r.sin(), r.cos() * 0.8) * 3.0
    }

    /// `Gather::for_sun` gathers up to its elevation, its own limit included, at any
    /// length of the direction, and never above it.
    #[test]
    fn a_gather_applies_up_to_its_elevation() {
        for deg in [0.5, 2.0, 10.0, 29.9, 30.0] {
            assert_eq!(Gather::AUTO.for_sun(at(deg)), Gather::LOW_SUN, "{deg}°");
        }
        for deg in [30.1, 45.0, 89.0, 90.0] {
            assert_eq!(Gather::AUTO.for_sun(at(deg)), Gather::OFF, "{deg}°");
            assert_eq!(Gather::LOW_SUN.for_sun(at(deg)), Gather::LOW_SUN, "{deg}°");
        }
        let never = Gather {
            max_elevation_deg: 0,
            ..Gather::LOW_SUN
        };
        assert_eq!(never.for_sun(at(1.0)), Gather::OFF);
        // A sun below the horizon: as low suns (it has no beam to gather); a direction
        // the sweep refuses: unchanged.
        assert_eq!(Gather::AUTO.for_sun(at(-10.0)), Gather::LOW_SUN);
        for bad in [Vec3::ZERO, Vec3::NAN, Vec3::new(f32::INFINITY, 1.0, 0.0)] {
            assert_eq!(Gather::AUTO.for_sun(bad), Gather::AUTO);
        }
        // A source alone: gathered only by a gather for every sun.
        assert_eq!(Gather::AUTO.for_source(), Gather::OFF);
        assert_eq!(Gather::LOW_SUN.for_source(), Gather::LOW_SUN);
        assert_eq!(Gather::OFF.for_source(), Gather::OFF);
    }

    /// The presets validate; a gather's elevation over 90 is refused by name.
    #[test]
    fn the_presets_validate_and_a_bad_elevation_is_named() {
        for o in [SweepOptions::single_pass(), SweepOptions::multi_bounce()] {
            o.validate().unwrap();
        }
        assert_eq!(SweepOptions::multi_bounce().gather, Gather::AUTO);
        assert_eq!(SweepOptions::single_pass().gather, Gather::OFF);
        let mut o = SweepOptions::multi_bounce();
        o.gather.max_elevation_deg = 91;
        let e = o.validate().unwrap_err().to_string();
        assert!(
            e.contains("gather.max_elevation_deg") && e.contains("91"),
            "{e}"
        );
    }
}
