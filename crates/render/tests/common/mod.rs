//! Helpers the GPU test binaries share (`gpu.rs`, `gpu_sampling.rs`): the adapter, a
//! renderer compiled once a binary, and the quads and views the known answers draw.

#![allow(dead_code)] // each binary uses its own share of them

use std::sync::{Arc, Mutex, OnceLock};

use lightgrid_core::glam::{Mat4, UVec3, Vec3, Vec4};
use lightgrid_core::{BinLight, Grid, GridDesc, LightGrid};
use lightgrid_gpu::GpuContext;
use lightgrid_render::{
    Camera, Lighting, LightingMode, MeshInstance, MeshMaterial, Renderer, Vertex, View,
};

pub(crate) fn context() -> Option<Arc<GpuContext>> {
    GpuContext::shared_for_tests()
}

/// A grid whose bins vary with position and direction (every value distinct, > 0).
pub(crate) fn test_grid() -> LightGrid {
    let desc = GridDesc::new(Vec3::new(-1.0, 0.5, 2.0), 0.75, UVec3::new(5, 4, 3)).unwrap();
    let data = (0..desc.point_count())
        .map(|i| {
            BinLight(std::array::from_fn(|d| {
                let x = (i * 31 + d * 17) % 23;
                Vec3::new(0.1 + x as f32, 0.5 + (d % 5) as f32, 0.2 + (i % 7) as f32) * 0.1
            }))
        })
        .collect();
    Grid::from_trusted(desc, data)
}

pub(crate) const SIZE: u32 = 32;

/// One renderer for the binary (pipelines compile once), behind a lock.
pub(crate) fn renderer() -> Option<&'static Mutex<Renderer>> {
    static R: OnceLock<Option<Mutex<Renderer>>> = OnceLock::new();
    R.get_or_init(|| context().map(|c| Mutex::new(Renderer::new(c, SIZE, SIZE).unwrap())))
        .as_ref()
}

/// A horizontal square at height `y`, 20 m wide, normal up, every vertex lit by `light`.
pub(crate) fn quad(y: f32, light: Vec3) -> (Vec<Vertex>, Vec<u32>) {
    let v = |x: f32, z: f32, u: f32, w: f32| Vertex {
        position: [x, y, z],
        normal: [0.0, 1.0, 0.0],
        uv: [u, w],
        light: light.extend(1.0).to_array(),
    };
    (
        vec![
            v(-10.0, -10.0, 0.0, 0.0),
            v(10.0, -10.0, 1.0, 0.0),
            v(10.0, 10.0, 1.0, 1.0),
            v(-10.0, 10.0, 0.0, 1.0),
        ],
        // Counter-clockwise seen from above.
        vec![0, 2, 1, 0, 3, 2],
    )
}

pub(crate) fn view(mode: LightingMode, meshes: Vec<lightgrid_render::MeshId>) -> View {
    View {
        camera: Camera::look_at(Vec3::new(0.0, 5.0, 0.0), Vec3::ZERO),
        mode,
        sun_direction: Vec3::NEG_Y,
        sun_colour: Vec3::new(2.0, 1.5, 1.0),
        sky_ambient: Vec3::new(0.1, 0.2, 0.3),
        direct_sun: Vec3::ZERO,
        exposure: 0.7,
        water: None,
        ground_blend: 0.0,
        background: Vec3::new(9.0, 9.0, 9.0),
        meshes,
    }
}

pub(crate) fn add_quad(
    r: &mut Renderer,
    y: f32,
    light: Vec3,
    material: MeshMaterial,
) -> lightgrid_render::MeshId {
    let (v, i) = quad(y, light);
    let id = r.add_mesh(&v, &i, &material).unwrap();
    r.set_instances(id, &[MeshInstance::new(Mat4::IDENTITY, Vec4::ONE)])
        .unwrap();
    id
}

/// A white quad at height `y` lit per pixel by `lighting` (no vertex light).
pub(crate) fn lit_quad(r: &mut Renderer, y: f32, lighting: Lighting) -> lightgrid_render::MeshId {
    add_quad(
        r,
        y,
        Vec3::ZERO,
        MeshMaterial {
            lighting,
            ..Default::default()
        },
    )
}
