//! Every WGSL source parses and validates with naga (no GPU needed), and the generated
//! constants carry grid-core's values exactly.

use lightgrid_core::dirs;
use sweep_gpu::wgsl;

fn validate(name: &str, src: &str) -> naga::Module {
    let module = naga::front::wgsl::parse_str(src)
        .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(src)));
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::all(),
    )
    .validate(&module)
    .unwrap_or_else(|e| panic!("{name}: {e:?}"));
    module
}

#[test]
fn every_shader_validates() {
    let all = wgsl::all();
    assert!(!all.is_empty());
    for (name, src) in all {
        validate(name, &src);
    }
}

#[test]
fn generated_constants_are_grid_cores() {
    // Parse the prelude's float literals back and compare bit for bit.
    let p = wgsl::prelude();
    let line = p
        .lines()
        .find(|l| l.starts_with("const SOLID_ANGLE"))
        .unwrap();
    let inner = &line[line.find(">(").unwrap() + 2..line.rfind(')').unwrap()];
    let values: Vec<f32> = inner.split(", ").map(|v| v.parse().unwrap()).collect();
    assert_eq!(values.len(), dirs::NUM_DIRS);
    for (d, v) in values.iter().enumerate() {
        assert_eq!(v.to_bits(), dirs::solid_angles()[d].to_bits(), "bin {d}");
    }
    let line = p.lines().find(|l| l.starts_with("const DIR_UNIT")).unwrap();
    let parsed: Vec<f32> = line
        .split("vec3<f32>(")
        .skip(1)
        .flat_map(|c| {
            c.split(')')
                .next()
                .unwrap()
                .split(", ")
                .map(|v| v.parse::<f32>().unwrap())
                .collect::<Vec<_>>()
        })
        .collect();
    for d in 0..dirs::NUM_DIRS {
        assert_eq!(parsed[3 * d], dirs::units()[d].x);
        assert_eq!(parsed[3 * d + 1], dirs::units()[d].y);
        assert_eq!(parsed[3 * d + 2], dirs::units()[d].z);
    }
    assert!(p.contains(&format!(
        "const HALO_WIDTH: i32 = {};",
        lightgrid_core::HALO_WIDTH
    )));
    validate("prelude", &p);
}
