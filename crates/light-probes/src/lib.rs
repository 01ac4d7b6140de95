//! # light-probes
//!
//! Relightable light probes, the way The Division lights its cities (seed 004): what
//! each probe sees is precomputed once — the surfaces (**surfels**, grouped in
//! **bricks**) and the sky — and every frame the probes are relit from the sun, the sky
//! and their own last frame, so time of day and weather change the bounce light of
//! streets and walls without baking again. It complements the sweep: the sweep suits
//! foliage and open terrain (light through media); probes suit buildings and streets
//! (opaque surfaces bouncing light).
//!
//! ```text
//! glTF meshes --RayScene (obvhs BVH)--> probe positions (place: a ray down each column)
//! probes --rays (Fibonacci sphere)--> hits: surfels per 1 m cell and normal axis,
//!                                      bricks of 4³ cells; misses: sky visibility
//! per frame: surfels <- sun (shadow rays) + last frame's probes (ambient cube)
//!            bricks  <- mean of their surfels
//!            probes  <- Σ brick factors × brick light + sky visibility × sky bins
//! ```
//!
//! Each probe stores irradiance in the Half-Life 2 ambient-cube basis (six axes,
//! [`lightgrid_core::AmbientCube`]): The Division tried 2nd-order SH (loses opposite
//! strong lights) and 8 directions (too dark without ±Y) before settling on it.
//!
//! ## Example
//!
//! ```
//! use lightgrid_core::glam::{Vec2, Vec3, Vec4};
//! use lightgrid_core::BinLight;
//! use lightgrid_light_probes::{Lighting, ProbeLight, ProbeParams, ProbeSet};
//! use lightgrid_material_voxelizer::model::{Model, SurfaceMaterial, Triangle};
//! use lightgrid_material_voxelizer::voxelize::RayScene;
//!
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! // A 100 m ground of albedo 0.5 under a uniform sky of radiance 1.
//! let q = |a: [f32; 3], b: [f32; 3], c: [f32; 3]| Triangle {
//!     positions: [a.into(), b.into(), c.into()],
//!     uvs: [Vec2::ZERO; 3],
//!     material: 0,
//!     part: 0,
//! };
//! let model = Model {
//!     triangles: vec![
//!         q([-50.0, 0.0, -50.0], [50.0, 0.0, 50.0], [50.0, 0.0, -50.0]),
//!         q([-50.0, 0.0, -50.0], [-50.0, 0.0, 50.0], [50.0, 0.0, 50.0]),
//!     ],
//!     materials: vec![SurfaceMaterial {
//!         base_colour: Vec4::new(0.5, 0.5, 0.5, 1.0),
//!         ..Default::default()
//!     }],
//!     textures: vec![],
//! };
//! let scene = RayScene::new(&model, obvhs::BvhBuildParams::fast_build());
//! let params = ProbeParams::preview();
//! let set = ProbeSet::bake(&scene, &[Vec3::new(0.0, 2.0, 0.0)], &params, &|_, _| {})?;
//! let mut light = ProbeLight::new(&set);
//! let lighting = Lighting { sky: BinLight::uniform(Vec3::ONE), sun: None };
//! let visible = set.sun_visibility(&scene, Vec3::Y);
//! for _ in 0..3 {
//!     light.frame(&set, &lighting, &visible)?;
//! }
//! let up = light.probe(0).unwrap().irradiance(Vec3::Y);
//! assert!((up.x - std::f32::consts::PI).abs() < 0.05); // the open sky: π L
//! # Ok(())
//! # }
//! ```
//!
//! ## Memory
//!
//! Per probe `6 × 26 × 4 + 12 + 8` bytes of sky visibility, position and factor range, plus 28 bytes per
//! brick it sees; per surfel 40 bytes, plus 8 per probe link; per brick member 4 bytes
//! ([`ProbeSet::bytes`]). The Division's choice of bricks (4³ cells) keeps the factor
//! count per probe near the number of bricks in view instead of the number of surfels.
//!
//! | layout | per probe | relight cost | why |
//! |--------|-----------|--------------|-----|
//! | surfels per probe (brick = 1) | 28 B × surfels seen | one multiply-add per surfel seen | exact to the surfel |
//! | bricks of 4³ cells (default) | 28 B × bricks seen | one per brick seen | 5–20× fewer factors; a brick's light is its surfels' mean |
//! | sky visibility, 26 bins × 6 axes | 624 B | 156 multiply-adds | any sky the bins hold (clear, EXR), exact for light constant per bin |
//!
//! ## Known answers (tests)
//!
//! `tests/known_answers.rs`: an infinite Lambertian ground under a uniform sky and a sun
//! (up `π L`, down `a (π L + E cos θ)`, sideways the mean of the two halves); a closed
//! box stays dark; relighting is linear in sky and sun; baking is deterministic.
//!
//! ## Measured (Kenney town, 2-core VM)
//!
//! `cargo run --release -p lightgrid-light-probes --example town_probes`: 100 probes (4 m), 4 099
//! surfels; bake 0.02 s; relight 0.1–0.6 ms a frame; 5.5 KB a probe with bricks of 4,
//! 10 KB with brick 1; relative RMSE of probe irradiance against [`mod@reference`] 0.026–0.033
//! (bricks of 4) and 0.014–0.016 (brick 1), reference noise 0.003–0.004, suns at 15°,
//! 40°, 65°. `tests/town.rs` guards it. On the GPU (`lightgrid_render::probes`, the same
//! three stages as compute kernels; `cargo run --release -p lightgrid-render --example
//! probes_town`): equal to the CPU (largest difference 0 on lavapipe), 1 600 probes at
//! 1 m spacing in 0.65 ms a frame on the CPU (0.41 ms per 1 000 probes) and 5.3 ms on
//! lavapipe (3.3 ms per 1 000).
//!
//! ## Walls, rooms and the merged volume
//!
//! - [`place_walls`]: The Division's second placement rule, extra probes a
//!   [`ProbeParams::wall_offset`] in front of walls, storey by storey.
//! - Interior volumes: [`InteriorBox`] and [`ProbeSet::bake_interior`]: a room's own
//!   probes; surfaces they see through its openings are lit by the exterior probes
//!   ([`ProbeLight::frame_interior`]).
//! - [`ProbeVolume`]: probes merged into a regular volume (The Division's camera-based
//!   volume map) with a visibility ray per probe and point (no light through walls),
//!   rooms blended at their faces; [`ResolvedVolume`] is one frame of it, a
//!   [`lightgrid_core::LightField`].
//!
//! Measured (`tests/interior.rs`, `examples/town_probes.rs`): in a 6 × 3 × 6 m room
//! with a window (walls of albedo 0.7, a low sun through the window) the merged volume
//! with the room's probes is off the reference by a relative RMSE of 0.23, with the
//! exterior probes alone by 2.2 (street light through the window); surfels are lit by
//! probe cubes evaluated where the probes are, which near a window overestimates (the
//! remaining error). In the town the merged volume half a metre in front of walls is
//! off by 0.131 with column probes, 0.128 with probes along walls too. The viewer's
//! `[probes]` scene option renders a scene lit by probes beside the sweep
//! (`scenes/town.toml`).
//!
//! - On the GPU (feature `gpu`): `GpuProbeRelight` relights exterior
//!   and interior sets as `ProbeLight` does, to 1e-4 (`gpu` module, `tests/gpu.rs`,
//!   `examples/gpu_town.rs`). Without the feature (the default) the crate needs no
//!   GPU stack.
//!
//! Not here: [`Sectors`] of interior sets.
//!
//! ## Map
//!
//! - `params` ([`ProbeParams`]), `bake` (placement, [`ProbeSet::bake`]: surfels, bricks,
//!   sky visibility), `interior` ([`InteriorBox`]), `relight` ([`ProbeLight`], the CPU
//!   specification), `volume` ([`ProbeVolume`], [`ResolvedVolume`]), `sectors`
//!   ([`Sectors`]), [`mod@reference`] (the Monte Carlo reference), `gpu` (feature `gpu`:
//!   `GpuProbeRelight`).

mod bake;
#[cfg(feature = "gpu")]
pub mod gpu;
mod interior;
mod params;
pub mod reference;
mod relight;
mod sectors;
mod volume;

pub use bake::{BrickFactor, Probe, ProbeSet, Surfel, fibonacci, place, place_walls};
pub use interior::{InteriorBox, MAX_INTERIOR_PROBES};
pub use params::ProbeParams;
pub use relight::{Lighting, ProbeLight};
pub use sectors::{LoadedSector, SectorStats, Sectors};
pub use volume::{ProbeVolume, ResolvedVolume, cube_to_bins};

#[cfg(feature = "gpu")]
pub use gpu::GpuProbeRelight;

/// Errors of baking and relighting.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ProbeError {
    /// A parameter or input is invalid (names the field).
    #[error(transparent)]
    Invalid(#[from] lightgrid_core::GridError),
}
