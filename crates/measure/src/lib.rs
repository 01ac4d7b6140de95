//! # measure
//!
//! What lightgrid's sweeps are measured against, apart from the sweeps themselves (the
//! specification is `lightgrid-sweep-cpu`'s front page; this crate shares none of its
//! code paths except where it runs the sweep to report its error):
//!
//! * [`mod@reference`]: the Monte Carlo reference, the same physical problem solved by
//!   tracing light paths (track-length estimator, deterministic per seed on any number
//!   of threads), with a collimated sun kept apart when asked.
//! * [`scenes`]: the five canonical scenes (empty, fog, dense block, two canopies) and
//!   the error measures used to compare a sweep with the reference.
//! * [`exact`]: transport problems with exact answers that share none of the sweep's
//!   assumptions: the white furnace, the infinite Lambertian ground, Chandrasekhar's
//!   half-space albedo under a beam and under a uniform sky.
//! * [`points`]: the same problem solved backward from points (a terrain vertex, a
//!   light-volume probe): the irradiance on a normal there, for the total error of what a
//!   renderer reads.
//! * [`sun_measure`]: the sun split against the sun in the bins, both against the
//!   reference with a collimated sun.
//!
//! The crate's tests hold the CPU sweep to these answers (`tests/exact.rs`,
//! `tests/reference.rs`, the sun's split, stress and dispatch tests), its examples print
//! the tables the sweep's docs quote, and `cargo bench -p lightgrid-measure` times the
//! sweep on the canonical scenes.
//!
//! ## Example
//!
//! ```
//! use lightgrid_core::SweepOptions;
//! use lightgrid_measure::reference::{ReferenceOptions, trace};
//! use lightgrid_measure::scenes::{Scene, compare};
//!
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! // The canopy at 8³: the sweep against 20 000 reference paths.
//! let (material, boundary) = Scene::Canopy.build(8);
//! let swept = lightgrid_sweep_cpu::run(&material, &boundary, &SweepOptions::multi_bounce())?;
//! let options = ReferenceOptions { paths: 20_000, ..Default::default() };
//! let reference = trace(&material, &boundary, &options, &|_, _| {})?;
//! let e = compare(swept.output.bins.as_ref().unwrap(), &reference.light, &material);
//! assert!(e.average.is_finite() && e.points > 0);
//! # Ok(())
//! # }
//! ```

pub mod exact;
pub mod points;
pub mod reference;
pub mod scenes;
pub mod sun_measure;
