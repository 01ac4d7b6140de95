//! # grid-core
//!
//! The shared vocabulary of lightgrid: volumetric **light grids** whose points hold the HDR
//! light arriving from 26 directions, the **material grids** that light flows through, and
//! everything needed to store, pack and read them. No GPU code lives here; every other
//! crate of the workspace depends on this one.
//!
//! ## Example: build a grid, write light, pack it, sample it
//!
//! ```
//! use lightgrid_core::{BinLight, GridDesc, GridFile, LightField, LightGrid};
//! use glam::{UVec3, Vec3};
//!
//! # fn main() -> Result<(), lightgrid_core::GridError> {
//! // 8 x 4 x 8 points, 1 m apart, starting at (-4, 0, -4).
//! let desc = GridDesc::new(Vec3::new(-4.0, 0.0, -4.0), 1.0, UVec3::new(8, 4, 8))?;
//! // Every point sees a uniform blue-ish sky of radiance (0.5, 0.7, 1.0)...
//! let mut grid = LightGrid::filled(desc, BinLight::uniform(Vec3::new(0.5, 0.7, 1.0)))?;
//! // ...and the top level also gets a bright sun shining straight down (bin 4).
//! for x in 0..8 {
//!     for z in 0..8 {
//!         let mut light = BinLight::uniform(Vec3::new(0.5, 0.7, 1.0));
//!         light.0[lightgrid_core::dirs::DOWN] += Vec3::splat(5000.0);
//!         grid.set(UVec3::new(x, 3, z), light)?;
//!     }
//! }
//! // Pack to R11G11B10 (104 bytes a point): the exposure keeps the sun in range.
//! let packed = grid.pack();
//! let restored = packed.unpack();
//!
//! // Irradiance on an upward-facing surface halfway up, read through the normal bias.
//! let e = restored.irradiance(Vec3::new(0.3, 2.5, -1.2), Vec3::Y)?;
//! let sky_only = std::f32::consts::PI * 0.5;
//! assert!(e.x > sky_only); // half a cell up the normal reads the sunlit top level
//!
//! // Files are versioned, checksummed and written atomically.
//! let path = std::env::temp_dir().join("grid-core-doc-example.lgrid");
//! GridFile::PackedLight(packed).save(&path)?;
//! let back = GridFile::load(&path)?.into_packed_light()?;
//! assert_eq!(back.unpack(), restored);
//! # std::fs::remove_file(&path).ok();
//! # Ok(())
//! # }
//! ```
//!
//! ## Memory layout
//!
//! A grid of dims `(nx, ny, nz)` stores point `(i, j, k)` (world position
//! `origin + h (i, j, k)`) at index `i + nx (k + nz j)`: x fastest, then z, then y, so each
//! horizontal level is one contiguous block (the sweep works one level at a time). Within
//! a point of a light grid, bins follow the canonical direction order of [`dirs`], RGB
//! within a bin.
//!
//! ## Why these formats
//!
//! | representation | bytes per point | directional detail | exact irradiance on any normal? |
//! |----------------|----------------:|--------------------|---------------------------|
//! | 26 bins `f32` ([`LightGrid`]) | 312 | 26 bins | yes, for light constant per bin |
//! | 26 bins R11G11B10 ([`PackedLightGrid`]) | 104 | 26 bins | same, within 2^-6 relative |
//! | 26 bins and horizon halves ([`SplitLightGrid`]) | 312 + 96 | 26 bins, each horizontal one in two halves | yes, for light constant per bin and per half (across the horizon: over a ground) |
//! | SH L2 RGB `f32` ([`Sh2`]) | 108 | smooth, ringing on the sun | no (band-limited) |
//! | SH L1 RGB `f32` ([`Sh1`]) | 48 | one lobe | no |
//! | ambient cube RGB `f32` ([`AmbientCube`]) | 72 (24 as R11G11B10) | 6 axes | on the axes only |
//! | average + dominant ([`AverageGrid`], [`DominantGrid`]) | 24 (16 packed) | one direction | no; cheap per-frame |
//!
//! The 26-bin grid is the sweep's native output (each bin is one of the directions light
//! flows along), so it loses nothing; R11G11B10 cuts it to a third at under 1.6 % error
//! with one exposure per grid so sun light of 1e5 and shade of 1e-2 both fit. The
//! projections are derived on demand for renderers that want fewer bytes.
//!
//! ## Conventions
//!
//! Right-handed, Y up, metres; linear HDR RGB in `f32`. A bin's value is the light
//! travelling *along* its direction, integrated over its solid angle (see [`light`]).
//! No public function returns NaN or infinity: invalid input is a [`GridError`] naming the
//! field and value.
//!
//! ## Map
//!
//! - Grids: `desc` ([`GridDesc`]: placement and index math), `grid` ([`Grid`] and the
//!   value types), `sample` (trilinear reads, the normal bias), [`validity`] (points
//!   inside geometry and the light they are given), [`mod@file`] (one versioned file format),
//!   [`pack`] (R11G11B10, RGB9E5).
//! - Light: [`dirs`] (the 26 directions, their exact bins, the 17 sweep directions),
//!   [`light`] ([`BinLight`] and its projections), [`lights`] (local light shapes).
//! - Between the layers: `traits` ([`Sweeper`], [`LightField`], [`MaterialSource`] and
//!   the data they exchange), `error` ([`GridError`]).
//! - Helpers every crate shares: [`dda`] (exact segment walks), [`terrain`]
//!   ([`Heightmap`]), [`rng`] (seeded content), [`hash`] (content hashes), [`limits`]
//!   (memory and size limits on user input), [`extremes`] (values for property tests).

pub mod dda;
mod desc;
pub mod dirs;
mod error;
pub mod extremes;
pub mod file;
mod grid;
pub mod halo_carry;
pub mod hash;
pub mod light;
pub mod lights;
pub mod limits;
mod options;
pub mod pack;
pub mod rng;
mod sample;
pub mod seam;
pub mod terrain;
mod traits;
pub mod validity;

pub use desc::{CELL_SIZE_RANGE, GridDesc, MAX_POINTS, WORLD_LIMIT};

/// Largest boundary light value accepted (skies, suns, sweep boundaries): leaves room for
/// path-length factors (≤ √33) and sums over a grid without overflowing `f32`.
pub const MAX_LIGHT: f32 = 1e30;
pub use dirs::{HORIZONTAL_STEP, NUM_DIRS, NUM_SWEEP_DIRS, SweepDir};
pub use error::{FileErrorKind, GridError};
pub use file::{GridFile, GridKind};
pub use grid::{
    AverageGrid, AverageLight, CodedBins, CodedLightGrid, DominantDir, DominantGrid, Grid,
    GridValue, HorizonGrid, LightGrid, Material, MaterialGrid, PackedBins, PackedLightGrid,
};
pub use light::{AmbientCube, BinLight, HorizonLight, LUMA, Sh1, Sh2, luminance, unit};
pub use lights::LightKind;
pub use options::{Acceleration, Gather, MAX_PASSES, MediumEmission, Outputs, SweepOptions};
pub use rng::SeededRng;
pub use sample::{Blend, trilinear_base, trilinear_corners, trilinear_frame, trilinear_indices};
pub use terrain::Heightmap;
pub use traits::{
    Boundary, CellSource, DifferenceField, HALO_WIDTH, HaloLayout, LightField, MaterialSource,
    NoScatter, Reading, Resident, SideBoundary, SplitLightGrid, SumField, SunBeam, SunBoundary,
    SunResponse, SweepError, SweepOutput, SweepStats, Sweeper, TopBoundary, UniformMaterial,
    VolumeSample,
};

/// The README's examples, compiled and run as doc tests.
#[cfg(doctest)]
#[doc = include_str!("../../../README.md")]
pub struct ReadmeDoctests;

/// Re-export of the `glam` version used in the public API.
pub use glam;
