//! # render
//!
//! Light for what the camera sees, from the light grids.
//!
//! - **Light sampling buffers** ([`sample_points`] on the CPU from any
//!   [`lightgrid_core::LightField`], [`GpuLightSampler`] as one wgpu compute dispatch per grid):
//!   a batch of points, with or without normals, in; irradiance (from the 26 bins) or
//!   average light, plus the dominant direction, out. This is how the seed lights the
//!   vertices of a terrain node once, when the node is prepared.
//! - **Shading** ([`shading`]): irradiance from average + dominant direction for moving
//!   objects, a cheap specular term from the dominant direction, the seed's ground blend,
//!   underwater attenuation, tone mapping. The CPU functions are the specification; the
//!   WGSL in `shaders/common.wgsl` implements the same formulas.
//! - **Rasteriser** ([`Renderer`]): terrain and instanced meshes (base colour texture,
//!   alpha mask; billboards turned to face the eye, for markers: [`MeshMaterial::billboard`])
//!   into a linear HDR target, tone-mapped to sRGB; headless images or any
//!   texture view (a window). Instances wholly outside a view are left out of its draw
//!   ([`cull`]: bounding spheres against the frustum; the image is the same). Views
//!   recorded one after another go to the device in one submission and come back
//!   together ([`Renderer::record`], [`Renderer::send`], [`Renderer::finish`]).
//!
//! - **Many dynamic lights** ([`dynamic`]): point, spot and line lights culled through a
//!   world-space grid of light-index ranges (3DWorld's grid bag), in the mesh shader.
//! - **Grids stay on the device** ([`GpuLightGrid`], from `lightgrid-gpu`): the GPU
//!   sweeper's output is sampled where it lies ([`GpuLightSampler::sample_layers`]: a
//!   grid hierarchy as layers, one dispatch each, the finest owning layer winning) and
//!   the samples are drawn where they lie ([`Renderer::set_light_volume_samples`],
//!   [`Renderer::set_vertex_light_samples`], [`Renderer::set_ground_light_samples`]);
//!   CPU grids are uploaded once and updated only in a changed box
//!   ([`GpuLightGrid::upload_region`], local lights toggling).
//!
//! Every WGSL struct shared with Rust is generated from the Rust declaration
//! (`lightgrid_gpu::gpu_struct!`); every shader validates with naga in a plain `cargo test`.
//!
//! ```
//! use lightgrid_core::glam::{UVec3, Vec3};
//! use lightgrid_core::{BinLight, Grid, GridDesc, LightGrid};
//! use lightgrid_render::{SamplePoints, sample_points};
//!
//! // A grid lit by a uniform sky of radiance 1.
//! let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::splat(4))?;
//! let grid: LightGrid = Grid::filled(desc, BinLight::uniform(Vec3::ONE))?;
//! let positions = [Vec3::splat(1.5), Vec3::new(0.5, 2.0, 2.5)];
//! let normals = [Vec3::Y, Vec3::X];
//! let lit = sample_points(&grid, SamplePoints { positions: &positions, normals: Some(&normals) })?;
//! // A uniform sky gives irradiance π on every normal.
//! for s in &lit {
//!     assert!((s.light.x - std::f32::consts::PI).abs() < 1e-3);
//! }
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod cull;
pub mod dynamic;
pub mod impostor;
pub mod passes;
pub mod raster;
pub mod sampling;
pub mod shading;
pub mod wgsl;

pub use dynamic::{DynamicLight, DynamicLights, DynamicShade};
pub use lightgrid_core::LightKind;
pub use lightgrid_gpu::GpuLightGrid;
pub use passes::dynamic::GpuDynamicShader;
pub use passes::sample::{
    GpuHorizon, GpuLayerSun, GpuLightSampler, GpuPoints, GpuSampleLayer, GpuSamples, LayerLight,
    LayerOwner, transmittance_buffer,
};
pub use raster::{
    Camera, GroundLight, HDR_FALLBACK_FORMAT, HDR_FORMAT, Image, Lighting, LightingMode, MeshId,
    MeshInstance, MeshMaterial, PendingImages, Renderer, TextureRgba8, Vertex, View, Water,
    hdr_format, renderable,
};
pub use sampling::{IrradianceTable, LightVolume, SamplePoints, SampledLight, sample_points};

/// Errors of rendering and sampling.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RenderError {
    /// Invalid input (names the field and value).
    #[error(transparent)]
    Grid(#[from] lightgrid_core::GridError),
    /// The GPU failed or is missing.
    #[error(transparent)]
    Gpu(#[from] lightgrid_gpu::GpuError),
}
