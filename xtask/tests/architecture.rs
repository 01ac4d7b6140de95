//! The architecture invariants of `ARCHITECTURE.md`, checked against every crate's
//! `Cargo.toml` so they cannot rot silently.

use std::collections::BTreeMap;
use std::path::Path;

/// Each workspace crate with the names in its `[dependencies]` table.
fn dependencies() -> BTreeMap<String, Vec<String>> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut manifests = vec![root.join("xtask/Cargo.toml")];
    for e in std::fs::read_dir(root.join("crates")).unwrap() {
        manifests.push(e.unwrap().path().join("Cargo.toml"));
    }
    let mut out = BTreeMap::new();
    for m in manifests {
        let text = std::fs::read_to_string(&m).unwrap();
        let mut name = String::new();
        let mut deps = Vec::new();
        let mut section = String::new();
        for line in text.lines().map(str::trim) {
            if line.starts_with('[') {
                section = line.to_string();
            } else if let Some((key, value)) = line.split_once('=') {
                let key = key.trim().split('.').next().unwrap().to_string();
                if section == "[package]" && key == "name" {
                    name = value.trim().trim_matches('"').to_string();
                } else if section == "[dependencies]" && !key.is_empty() {
                    deps.push(key);
                }
            }
        }
        assert!(!name.is_empty(), "{} has no package name", m.display());
        out.insert(name, deps);
    }
    out
}

#[test]
fn all_nine_crates_exist() {
    let d = dependencies();
    for c in [
        "grid-core",
        "material-voxelizer",
        "light-volumes",
        "sweep-cpu",
        "sweep-gpu",
        "terrain-lod",
        "render",
        "viewer",
        "xtask",
    ] {
        assert!(d.contains_key(c), "crate {c} missing");
    }
}

#[test]
fn grid_core_has_no_gpu_or_io_heavy_dependency() {
    let d = dependencies();
    let allowed = ["glam", "bytemuck", "thiserror", "crc32fast"];
    for dep in &d["grid-core"] {
        assert!(
            allowed.contains(&dep.as_str()),
            "grid-core depends on {dep}"
        );
    }
}

#[test]
fn only_gpu_crates_depend_on_wgpu() {
    for (name, deps) in dependencies() {
        if deps.iter().any(|d| d == "wgpu") {
            assert!(
                ["sweep-gpu", "render", "viewer", "xtask"].contains(&name.as_str()),
                "{name} depends on wgpu"
            );
        }
    }
}

#[test]
fn layers_point_downwards() {
    // A crate may depend only on crates below it (grid-core at the bottom).
    let order = [
        "grid-core",
        "sweep-cpu",
        "sweep-gpu",
        "material-voxelizer",
        "light-volumes",
        "terrain-lod",
        "render",
        "viewer",
        "xtask",
    ];
    let rank = |n: &str| order.iter().position(|o| *o == n);
    for (name, deps) in dependencies() {
        // Every workspace crate has a place in the order (a new crate must be added).
        let me = rank(&name).unwrap_or_else(|| panic!("crate {name} is not in the layer order"));
        for dep in deps {
            if let Some(r) = rank(&dep) {
                assert!(r < me, "{name} depends on {dep}, which is not below it");
            }
        }
    }
}
