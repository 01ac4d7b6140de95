//! The WGSL prelude every render shader starts with: the direction tables from
//! `lightgrid-core` (through `lightgrid_gpu::wgsl::prelude`), π, the luminance weights
//! and the shading functions of `shaders/common.wgsl`. Each pass adds its own uniforms and
//! shader ([`crate::passes`]).

use std::fmt::Write;

/// Constants every render shader shares: π, luminance weights, direction tables, and
/// the common shading functions.
pub fn prelude() -> String {
    let mut s = lightgrid_gpu::wgsl::prelude();
    let _ = writeln!(s, "const PI: f32 = {:?};", std::f32::consts::PI);
    let _ = writeln!(
        s,
        "const FIRST_HORIZONTAL: u32 = {}u;\nconst HORIZONTAL_BINS: u32 = {}u;",
        lightgrid_core::dirs::FIRST_HORIZONTAL,
        lightgrid_core::dirs::HORIZONTAL_BINS
    );
    let l = lightgrid_core::LUMA;
    let _ = writeln!(
        s,
        "const LUMA: vec3<f32> = vec3<f32>({:?}, {:?}, {:?});",
        l[0], l[1], l[2]
    );
    s.push_str(include_str!("shaders/common.wgsl"));
    s
}
