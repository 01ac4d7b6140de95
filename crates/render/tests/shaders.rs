//! Every render shader validates with naga (no GPU needed), and the structs shared with
//! Rust have the same layout on both sides.

use lightgrid_render::passes::dynamic::{DynLightGpu, DynParams};
use lightgrid_render::passes::mesh::{FrameUniforms, MeshUniforms};
use lightgrid_render::passes::sample::SampleParams;
use lightgrid_render::passes::scatter::ScatterParams;
use lightgrid_render::{passes, wgsl};

fn validate(name: &str, src: &str) -> naga::Module {
    lightgrid_gpu::check::validate(name, src).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn every_shader_validates() {
    let all = passes::shaders();
    assert_eq!(all.len(), 5);
    for (name, src) in all {
        validate(name, &src);
    }
}

fn check_layout(module: &naga::Module, name: &str, rust: Vec<(&str, usize)>, size: usize) {
    lightgrid_gpu::check::layout_in(module, name, &rust, size).unwrap();
}

#[test]
fn shared_structs_have_the_same_layout_in_rust_and_wgsl() {
    let mesh = validate("mesh", &passes::mesh::wgsl());
    check_layout(
        &mesh,
        "FrameUniforms",
        FrameUniforms::offsets(),
        size_of::<FrameUniforms>(),
    );
    check_layout(
        &mesh,
        "MeshUniforms",
        MeshUniforms::offsets(),
        size_of::<MeshUniforms>(),
    );
    let dynamic = validate("dynamic", &passes::dynamic::wgsl());
    check_layout(
        &dynamic,
        "DynLightGpu",
        DynLightGpu::offsets(),
        size_of::<DynLightGpu>(),
    );
    check_layout(
        &dynamic,
        "DynParams",
        DynParams::offsets(),
        size_of::<DynParams>(),
    );
    let sample = validate("sample", &passes::sample::wgsl());
    check_layout(
        &sample,
        "SampleParams",
        SampleParams::offsets(),
        size_of::<SampleParams>(),
    );
    let scatter = validate("scatter", &passes::scatter::wgsl());
    check_layout(
        &scatter,
        "ScatterParams",
        ScatterParams::offsets(),
        size_of::<ScatterParams>(),
    );
}

#[test]
fn generated_luminance_weights_are_grid_cores() {
    let p = wgsl::prelude();
    let line = p.lines().find(|l| l.starts_with("const LUMA")).unwrap();
    let inner = &line[line.find(">(").unwrap() + 2..line.rfind(')').unwrap()];
    let v: Vec<f32> = inner.split(", ").map(|x| x.parse().unwrap()).collect();
    assert_eq!(v, lightgrid_core::LUMA.to_vec());
}
