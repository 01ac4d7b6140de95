//! The architecture invariants of `ARCHITECTURE.md`, checked against `cargo metadata`
//! (every dependency of every workspace crate, dev and build included) so they cannot
//! rot silently.

use std::collections::BTreeMap;
use std::path::Path;

/// One dependency of a workspace crate: its name and kind (`normal`, `dev`, `build`).
#[derive(Debug, Clone, PartialEq)]
struct Dep {
    name: String,
    kind: String,
    /// Built only when a feature asks for it.
    optional: bool,
}

/// Each workspace crate with all its dependencies (normal, dev and build), as
/// `cargo metadata` reports them: no hand parsing of manifests.
fn dependencies() -> BTreeMap<String, Vec<Dep>> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let out = std::process::Command::new(env!("CARGO"))
        .args(["metadata", "--format-version", "1", "--no-deps"])
        .current_dir(&root)
        .output()
        .expect("cargo metadata runs");
    assert!(
        out.status.success(),
        "cargo metadata: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let meta: serde_json::Value = serde_json::from_slice(&out.stdout).expect("metadata is JSON");
    let mut map = BTreeMap::new();
    for p in meta["packages"].as_array().expect("packages") {
        let deps = p["dependencies"]
            .as_array()
            .expect("dependencies")
            .iter()
            .map(|d| Dep {
                name: d["name"].as_str().expect("name").to_string(),
                kind: d["kind"].as_str().unwrap_or("normal").to_string(),
                optional: d["optional"].as_bool().unwrap_or(false),
            })
            .collect();
        map.insert(p["name"].as_str().expect("name").to_string(), deps);
    }
    map
}

/// The crates in layer order, each with the workspace crates it may depend on (any kind
/// of dependency); `None`: any crate below it (the applications at the top). A new crate
/// or a new edge is a decision: add it here, and to ARCHITECTURE.md.
const ALLOWED: [(&str, Option<&[&str]>); 15] = [
    ("lightgrid-core", Some(&[])),
    ("lightgrid-sky", Some(&["lightgrid-core"])),
    (
        "lightgrid-sweep-cpu",
        Some(&["lightgrid-core", "lightgrid-sky"]),
    ),
    (
        "lightgrid-measure",
        Some(&["lightgrid-core", "lightgrid-sky", "lightgrid-sweep-cpu"]),
    ),
    ("lightgrid-gpu", Some(&["lightgrid-core"])),
    (
        "lightgrid-sweep-gpu",
        Some(&["lightgrid-core", "lightgrid-sweep-cpu", "lightgrid-gpu"]),
    ),
    ("lightgrid-material-voxelizer", Some(&["lightgrid-core"])),
    (
        "lightgrid-light-volumes",
        Some(&["lightgrid-core", "lightgrid-material-voxelizer"]),
    ),
    (
        "lightgrid-light-probes",
        Some(&[
            "lightgrid-core",
            "lightgrid-gpu",
            "lightgrid-material-voxelizer",
        ]),
    ),
    ("lightgrid-terrain-lod", Some(&["lightgrid-core"])),
    (
        "lightgrid-render",
        Some(&[
            "lightgrid-core",
            "lightgrid-gpu",
            "lightgrid-material-voxelizer",
            "lightgrid-light-volumes",
        ]),
    ),
    (
        "lightgrid-export",
        Some(&["lightgrid-core", "lightgrid-sweep-cpu"]),
    ),
    // The viewer's scene files are the worlds `lightgrid bake` bakes.
    ("lightgrid-viewer", None),
    ("lightgrid", None),
    ("xtask", None),
];

/// Edges allowed only as dev-dependencies (tests, benches and examples), never in the
/// library: terrain-lod's demo forest is voxelized and swept by its tests only.
const DEV_ONLY: [(&str, &[&str]); 4] = [
    // The GPU sweep's tests and the export's tests measure against the canonical scenes
    // and the exact problems.
    (
        "lightgrid-sweep-gpu",
        &["lightgrid-measure", "lightgrid-sky"],
    ),
    ("lightgrid-export", &["lightgrid-measure", "lightgrid-sky"]),
    (
        "lightgrid-terrain-lod",
        &["lightgrid-material-voxelizer", "lightgrid-sweep-cpu"],
    ),
    // light-probes' town test and example load the Kenney town from light-volumes' demo.
    ("lightgrid-light-probes", &["lightgrid-light-volumes"]),
];

/// Whether `name` may depend on `dep` as a dev-dependency beyond its row.
fn allowed_dev(name: &str, dep: &str) -> bool {
    DEV_ONLY
        .iter()
        .any(|(c, deps)| *c == name && deps.contains(&dep))
}

/// Whether `name` may depend on `dep`: listed in its row, or (row `None`) below it.
fn allowed(name: &str, dep: &str) -> bool {
    let rank = |n: &str| ALLOWED.iter().position(|(c, _)| *c == n);
    match (
        ALLOWED.iter().find(|(c, _)| *c == name),
        rank(name),
        rank(dep),
    ) {
        (Some((_, Some(row))), _, _) => row.contains(&dep),
        (Some((_, None)), Some(me), Some(r)) => r < me,
        _ => false,
    }
}

#[test]
fn every_crate_exists() {
    let d = dependencies();
    for c in [
        "lightgrid-core",
        "lightgrid-material-voxelizer",
        "lightgrid-light-volumes",
        "lightgrid-sky",
        "lightgrid-sweep-cpu",
        "lightgrid-measure",
        "lightgrid-sweep-gpu",
        "lightgrid-terrain-lod",
        "lightgrid-render",
        "lightgrid-gpu",
        "lightgrid-export",
        "lightgrid",
        "lightgrid-viewer",
        "xtask",
    ] {
        assert!(d.contains_key(c), "crate {c} missing");
    }
}

#[test]
fn grid_core_has_no_gpu_or_io_heavy_dependency() {
    let d = dependencies();
    let allowed = ["glam", "bytemuck", "thiserror", "crc32fast", "tracing"];
    for dep in &d["lightgrid-core"] {
        let ok = match dep.kind.as_str() {
            "dev" => dep.name == "proptest",
            // The extreme values as strategies for the workspace's property tests
            // (`extremes::strategies`, feature `proptest`): never built by default.
            _ if dep.optional => dep.name == "proptest",
            _ => allowed.contains(&dep.name.as_str()),
        };
        assert!(ok, "lightgrid-core depends on {} ({})", dep.name, dep.kind);
    }
}

#[test]
fn only_gpu_crates_depend_on_wgpu() {
    for (name, deps) in dependencies() {
        if deps.iter().any(|d| d.name == "wgpu") {
            assert!(
                [
                    "lightgrid-gpu",
                    "lightgrid-sweep-gpu",
                    // Behind its optional `gpu` feature.
                    "lightgrid-light-probes",
                    "lightgrid-render",
                    "lightgrid-viewer",
                    "xtask"
                ]
                .contains(&name.as_str()),
                "{name} depends on wgpu"
            );
        }
    }
}

#[test]
fn every_edge_between_crates_is_allowed_and_points_down() {
    let rank = |n: &str| ALLOWED.iter().position(|(c, _)| *c == n);
    for (name, deps) in DEV_ONLY {
        for dep in deps {
            assert!(
                rank(dep) < rank(name),
                "{name} dev-allows {dep}, not below it"
            );
        }
    }
    // The table itself is layered: each crate may use only crates listed before it.
    for (i, (name, row)) in ALLOWED.iter().enumerate() {
        for dep in row.unwrap_or(&[]) {
            let r = rank(dep).unwrap_or_else(|| panic!("{name} allows unknown crate {dep}"));
            assert!(r < i, "{name} allows {dep}, which is not below it");
        }
    }
    let all = dependencies();
    for (name, deps) in &all {
        assert!(
            rank(name).is_some(),
            "crate {name} is not in the layer table"
        );
        for dep in deps.iter().filter(|d| all.contains_key(&d.name)) {
            // A dev-dependency on itself only turns the crate's own features on for its
            // tests and examples (light-probes' `gpu`).
            let itself = dep.kind == "dev" && dep.name == *name;
            assert!(
                itself
                    || allowed(name, &dep.name)
                    || (dep.kind == "dev" && allowed_dev(name, &dep.name)),
                "{name} depends on {} ({}), which its row does not allow",
                dep.name,
                dep.kind
            );
        }
    }
}
