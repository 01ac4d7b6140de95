//! # light-volumes
//!
//! Indirect light of local lights, the 3DWorld way (seeds 001 and 003): each light's
//! rays are traced through the mesh scene (obvhs BVH via `material-voxelizer`), bounce
//! diffusely off surfaces, and deposit every segment into the 26 bins of every grid cell
//! they cross; the volume is stored per light as white light, cropped and compressed to
//! 8 bits, cached on disk under a hash of the light and the scene; a [`LightSet`] merges
//! volumes and updates the combined grid by adding or subtracting only the changed
//! light's box. The combined grid is a `lightgrid_core::LightField`; add it to the sky and sun
//! hierarchy with `lightgrid_core::SumField`.
//!
//! ```
//! use lightgrid_core::glam::{UVec3, Vec3};
//! use lightgrid_core::{GridDesc, LightField};
//! use lightgrid_light_volumes::{CompressedVolume, Light, LightKind, LightSet, TraceParams, trace_light};
//! use lightgrid_material_voxelizer::model::Model;
//! use lightgrid_material_voxelizer::procedural::rock;
//! use lightgrid_material_voxelizer::voxelize::RayScene;
//!
//! // A rock lit by a point light above it.
//! let model: Model = rock(1, 1.0)?;
//! let scene = RayScene::new(&model, obvhs::BvhBuildParams::fast_build());
//! let desc = GridDesc::new(Vec3::splat(-2.0), 0.25, UVec3::splat(17))?;
//! let light = Light {
//!     kind: LightKind::Point { position: Vec3::new(0.0, 1.8, 0.0) },
//!     colour: Vec3::new(1.0, 0.8, 0.6),
//!     intensity: 10.0,
//! };
//! let params = TraceParams { rays: 20_000, ..TraceParams::preview() };
//! let (volume, stats) = trace_light(&scene, &desc, &light, &params, &|_, _| {})?;
//! assert!(stats.hits > 0);
//! let key = lightgrid_light_volumes::volume_key(&light, &model, &desc, &params);
//! let packed = CompressedVolume::compress(&volume, key);
//! let mut set = LightSet::new(desc)?;
//! let id = set.add(&packed, light.colour, light.intensity)?;
//! assert!(set.average(Vec3::new(0.0, 1.5, 0.0))?.x > 0.0);
//! set.set_on(id, false)?;
//! assert_eq!(set.average(Vec3::new(0.0, 1.5, 0.0))?, Vec3::ZERO);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! ## Map
//!
//! - [`light`]: local light sources and how they emit rays.
//! - [`trace`]: one light's light traced into a volume, 3DWorld's way.
//! - [`volume`]: one light's volume, cropped and compressed as 3DWorld caches it.
//! - [`set`]: the lights of one grid, toggled and recoloured by adding or subtracting
//!   only their boxes.
//! - [`demo`]: the Kenney town for the examples, benchmark and tests.

pub mod demo;
pub mod light;
pub mod set;
pub mod trace;
pub mod volume;

pub use light::{Light, LightKind};
pub use set::{LightId, LightSet, Region, SNAP};
pub use trace::{TraceParams, TraceStats, trace_light};
pub use volume::{CacheOutcome, CompressedVolume, THRESHOLD, load_or_make};

use lightgrid_core::GridDesc;
use lightgrid_material_voxelizer::model::Model;

/// The cache key of a light's volume: its shape (not colour or intensity: volumes are
/// white), the scene's triangles, materials and textures, the grid and the trace
/// parameters, through [`lightgrid_core::hash::ContentHash`]. Any change gives another key,
/// so a stale cache file is never used.
pub fn volume_key(light: &Light, model: &Model, desc: &GridDesc, params: &TraceParams) -> u64 {
    let mut h = lightgrid_core::hash::ContentHash::new(b"lightgrid-light-volume-v2");
    light.hash_shape(&mut h);
    h.desc(desc)
        .u64(params.rays)
        .u32(params.max_bounces)
        .u32(params.bounce_limit)
        .u64(params.seed);
    for t in &model.triangles {
        for p in t.positions {
            h.vec3(p);
        }
        for uv in t.uvs {
            h.f32s(&uv.to_array());
        }
        h.u32(t.material);
    }
    for m in &model.materials {
        h.f32s(&m.base_colour.to_array())
            .u64(m.texture.map_or(u64::MAX, |t| t as u64))
            .f32s(&m.uv_transform.offset.to_array())
            .f32s(&[m.uv_transform.rotation])
            .f32s(&m.uv_transform.scale.to_array());
        match m.alpha {
            lightgrid_material_voxelizer::model::AlphaMode::Opaque => h.u32(0),
            lightgrid_material_voxelizer::model::AlphaMode::Mask(c) => h.u32(1).f32s(&[c]),
            lightgrid_material_voxelizer::model::AlphaMode::Blend => h.u32(2),
        };
    }
    for tex in &model.textures {
        h.u32(tex.width).u32(tex.height);
        for c in &tex.texels {
            h.f32s(&c.to_array());
        }
    }
    h.finish()
}
