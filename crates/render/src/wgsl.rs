//! WGSL sources. Every struct and constant the shaders share with Rust is generated here
//! from one Rust declaration (`lightgrid_gpu::gpu_struct!` writes the Rust struct
//! and its WGSL text together; a naga test compares the two layouts); the direction
//! tables come from `lightgrid-core` through `lightgrid_gpu::wgsl::prelude`.

use std::fmt::Write;

use crate::dynamic::{DynLightGpu, DynParams};
use crate::gpu::{SampleParams, ScatterParams};
use crate::raster::{FrameUniforms, MeshUniforms};

/// Constants every render shader shares: π, luminance weights, direction tables.
pub fn prelude() -> String {
    let mut s = lightgrid_gpu::wgsl::prelude();
    let _ = writeln!(s, "const PI: f32 = {:?};", std::f32::consts::PI);
    let l = lightgrid_core::LUMA;
    let _ = writeln!(
        s,
        "const LUMA: vec3<f32> = vec3<f32>({:?}, {:?}, {:?});",
        l[0], l[1], l[2]
    );
    let _ = writeln!(
        s,
        "const LIGHTING_VERTEX: u32 = {}u;\nconst LIGHTING_SURFACE: u32 = {}u;\nconst LIGHTING_FOLIAGE: u32 = {}u;\nconst LIGHTING_EMISSIVE: u32 = {}u;\nconst LIGHTING_FLAT: u32 = {}u;",
        crate::Lighting::Vertex as u32,
        crate::Lighting::Surface as u32,
        crate::Lighting::Foliage as u32,
        crate::Lighting::Emissive as u32,
        crate::Lighting::Flat as u32,
    );
    let _ = writeln!(
        s,
        "const MODE_GRID: u32 = {}u;\nconst MODE_NO_GRID: u32 = {}u;",
        crate::LightingMode::Grid as u32,
        crate::LightingMode::NoGrid as u32
    );
    s.push_str(include_str!("shaders/common.wgsl"));
    s
}

/// The light sampling compute kernel.
pub fn sample_kernel() -> String {
    format!(
        "{}\n{}\n{}",
        prelude(),
        SampleParams::wgsl(),
        include_str!("shaders/sample.wgsl")
    )
}

/// The dynamic-light structs and shading functions.
fn dynamic_common() -> String {
    format!(
        "{}\nconst DYN_FALLOFF_EPSILON: f32 = {:?};\n{}",
        DynLightGpu::wgsl(),
        crate::dynamic::FALLOFF_EPSILON,
        include_str!("shaders/dynamic.wgsl")
    )
}

/// The mesh shader (terrain, instanced meshes, debug views).
pub fn mesh_shader() -> String {
    format!(
        "{}\n{}\n{}\n{}\n{}",
        prelude(),
        FrameUniforms::wgsl(),
        MeshUniforms::wgsl(),
        dynamic_common(),
        include_str!("shaders/mesh.wgsl")
    )
}

/// The kernel that writes sampled light into vertices or the ground light.
pub fn scatter_kernel() -> String {
    format!(
        "{}\n{}",
        ScatterParams::wgsl(),
        include_str!("shaders/scatter.wgsl")
    )
}

/// The dynamic-light compute kernel (a batch of points).
pub fn dynamic_kernel() -> String {
    format!(
        "{}\n{}\n{}\n{}",
        prelude(),
        DynParams::wgsl(),
        dynamic_common(),
        include_str!("shaders/dynamic_kernel.wgsl")
    )
}

/// The tone-mapping pass (HDR to sRGB).
pub fn tonemap_shader() -> String {
    format!("{}\n{}", prelude(), include_str!("shaders/tonemap.wgsl"))
}

/// Every complete shader, by name (for validation).
pub fn all() -> Vec<(&'static str, String)> {
    vec![
        ("sample_kernel", sample_kernel()),
        ("mesh_shader", mesh_shader()),
        ("tonemap_shader", tonemap_shader()),
        ("dynamic_kernel", dynamic_kernel()),
        ("scatter_kernel", scatter_kernel()),
    ]
}
