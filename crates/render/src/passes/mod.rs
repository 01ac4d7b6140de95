//! The GPU passes, one a module, each owning its uniforms (declared once with
//! `lightgrid_gpu::gpu_struct!`, which writes the Rust struct and its WGSL), its shader
//! and its bind group layouts; bind groups are made with `lightgrid_gpu::bind::group`.
//! The CPU specifications they implement are `crate::sampling`, `crate::shading` and
//! `crate::dynamic`.
//!
//! - [`sample`]: light at a batch of points from a grid or a hierarchy's layers.
//! - [`scatter`]: sampled light into vertex and ground-light buffers on the device.
//! - [`dynamic`]: many small point, spot and line lights (mesh shader and a kernel).
//! - [`mesh`]: terrain and instanced meshes into the linear HDR target.
//! - [`tonemap`]: the HDR target into an sRGB image or a window's surface.

pub mod dynamic;
pub mod mesh;
pub mod sample;
pub mod scatter;
pub mod tonemap;

/// Every complete shader, by name (for validation with naga).
pub fn shaders() -> Vec<(&'static str, String)> {
    vec![
        ("sample", sample::wgsl()),
        ("mesh", mesh::wgsl()),
        ("tonemap", tonemap::wgsl()),
        ("dynamic", dynamic::wgsl()),
        ("scatter", scatter::wgsl()),
    ]
}
