//! # material-voxelizer
//!
//! Turns glTF models into model material grids (reflectance and pass-through per cell)
//! by ray queries against an obvhs BVH, offline.
//!
//! ```
//! use lightgrid_core::glam::{Vec2, Vec3, Vec4};
//! use lightgrid_material_voxelizer::model::{Model, SurfaceMaterial, Triangle};
//! use lightgrid_material_voxelizer::voxelize::{VoxelizeParams, voxelize};
//!
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! // A red square, 1 m on a side, lying flat at y = 0.
//! let corners = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 1.0), Vec3::new(0.0, 0.0, 1.0)];
//! let tri = |a: usize, b: usize, c: usize| Triangle {
//!     positions: [corners[a], corners[b], corners[c]],
//!     uvs: [Vec2::ZERO; 3],
//!     material: 0,
//!     part: 0,
//! };
//! let model = Model {
//!     triangles: vec![tri(0, 1, 2), tri(0, 2, 3)],
//!     materials: vec![SurfaceMaterial { base_colour: Vec4::new(0.8, 0.1, 0.1, 1.0), ..Default::default() }],
//!     textures: vec![],
//! };
//! let (grid, stats) = voxelize(&model, &VoxelizeParams::preview(0.25), &|_, _| {})?;
//! assert_eq!(stats.cells, 16); // 4 x 1 x 4 cells
//! let cell = grid.data()[5];
//! assert!(cell.pass < 1.0 && cell.reflectance.x > 0.7);
//! # Ok(())
//! # }
//! ```
//!
//! Load real models with [`model::Model::load_gltf`] (`.gltf` with embedded or external
//! buffers, `.glb`; base colour factor and texture with `KHR_texture_transform`; alpha
//! masks). The `lightgrid` command does it from the shell:
//! `lightgrid voxelize tree.glb --cell 0.25 -o tree.lgrid`.
//!
//! [`procedural`] makes deterministic trees (closed trunk and branches, alpha-masked leaf
//! cards), bushes and rocks, and writes them as `.glb`.
//!
//! At run time, [`compose::AreaComposer`] builds the material grid of any box from a
//! terrain heightmap and instances of model grids (it implements
//! `lightgrid_core::MaterialSource`).
//!
//! ## Map
//!
//! - [`model`]: triangles with UVs and materials, from glTF 2.0 ([`gltf_read`] checks
//!   every size, offset and reference first) or built in memory; `glb` writes them.
//! - [`voxelize`]: a model to a material grid by ray queries against an obvhs BVH.
//! - [`procedural`]: deterministic trees, bushes and rocks.
//! - [`compose`]: a light grid's box of material from terrain and placed instances.

pub mod compose;
mod glb;
pub mod gltf_read;
pub mod model;
pub mod procedural;
pub mod voxelize;
