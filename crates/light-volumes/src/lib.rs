//! # light-volumes
//!
//! Indirect light of local lights, the 3DWorld way (seeds 001 and 003): each light's
//! rays are traced through the mesh scene (obvhs BVH via `material-voxelizer`), bounce
//! diffusely off surfaces, and deposit every segment into the 26 bins of every grid cell
//! they cross; the volume is stored per light as white light, cropped and compressed to
//! 8 bits, cached on disk under a hash of the light and the scene; a [`LightSet`] merges
//! volumes and updates the combined grid by adding or subtracting only the changed
//! light's box. The combined grid is a `grid_core::LightField`; add it to the sky and sun
//! hierarchy with `grid_core::SumField`.
//!
//! ```
//! use grid_core::glam::{UVec3, Vec3};
//! use grid_core::{GridDesc, LightField};
//! use light_volumes::{CompressedVolume, Light, LightKind, LightSet, TraceParams, trace_light};
//! use material_voxelizer::model::Model;
//! use material_voxelizer::procedural::rock;
//! use material_voxelizer::voxelize::Scene;
//!
//! // A rock lit by a point light above it.
//! let model: Model = rock(1, 1.0)?;
//! let scene = Scene::new(&model, obvhs::BvhBuildParams::fast_build());
//! let desc = GridDesc::new(Vec3::splat(-2.0), 0.25, UVec3::splat(17))?;
//! let light = Light {
//!     kind: LightKind::Point { position: Vec3::new(0.0, 1.8, 0.0) },
//!     colour: Vec3::new(1.0, 0.8, 0.6),
//!     intensity: 10.0,
//! };
//! let params = TraceParams { rays: 20_000, ..TraceParams::preview() };
//! let (volume, stats) = trace_light(&scene, &desc, &light, &params, &|_, _| {})?;
//! assert!(stats.hits > 0);
//! let key = light_volumes::volume_key(&light, &model, &desc, &params);
//! let packed = CompressedVolume::compress(&volume, key);
//! let mut set = LightSet::new(desc)?;
//! let id = set.add(&packed, light.colour, light.intensity)?;
//! assert!(set.average(Vec3::new(0.0, 1.5, 0.0))?.x > 0.0);
//! set.set_on(id, false)?;
//! assert_eq!(set.average(Vec3::new(0.0, 1.5, 0.0))?, Vec3::ZERO);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod demo;
pub mod light;
pub mod set;
pub mod trace;
pub mod volume;

pub use light::{Light, LightKind};
pub use set::{LightId, LightSet, Region};
pub use trace::{TraceParams, TraceStats, trace_light};
pub use volume::{CacheOutcome, CompressedVolume, THRESHOLD, load_or_make};

use grid_core::GridDesc;
use material_voxelizer::model::Model;

/// FNV-1a, stable across runs and Rust versions (cache keys).
fn fnv(bytes: impl IntoIterator<Item = u8>, mut h: u64) -> u64 {
    for b in bytes {
        h ^= b as u64;
        h = h.wrapping_mul(0x100_0000_01b3);
    }
    h
}

/// The cache key of a light's volume: its shape (not colour or intensity: volumes are
/// white), the scene's triangles, materials and textures, the grid and the trace
/// parameters. Any change gives another key, so a stale cache file is never used.
pub fn volume_key(light: &Light, model: &Model, desc: &GridDesc, params: &TraceParams) -> u64 {
    let mut h = fnv(
        b"lightgrid-light-volume-v1".iter().copied(),
        0xcbf2_9ce4_8422_2325,
    );
    h = fnv(light.shape_key().into_bytes(), h);
    h = fnv(format!("{desc:?}{params:?}").into_bytes(), h);
    for t in &model.triangles {
        for p in t.positions {
            h = fnv(p.to_array().iter().flat_map(|v| v.to_le_bytes()), h);
        }
        for uv in t.uvs {
            h = fnv(uv.to_array().iter().flat_map(|v| v.to_le_bytes()), h);
        }
        h = fnv(t.material.to_le_bytes(), h);
    }
    h = fnv(format!("{:?}", model.materials).into_bytes(), h);
    for tex in &model.textures {
        for c in &tex.texels {
            h = fnv(c.to_array().iter().flat_map(|v| v.to_le_bytes()), h);
        }
    }
    h
}
