//! A clone of the repository is all the project needs: no source, scene, script or doc
//! names a path that climbs out of the repository (the test data lives in `assets/`),
//! and the crates' READMEs, shown on a registry's page, link nothing relative.

use std::path::{Path, PathBuf};

use xtask::tree::root;

/// Every text file of the project, `target/`, `.git/` and `out/` left out.
fn text_files(dir: &Path) -> Vec<PathBuf> {
    let enter = |name: &str| {
        !(name.starts_with('.') && name != ".ci" && name != ".cargo")
            && name != "target"
            && name != "out"
            && !name.starts_with("target-")
    };
    let keep = |p: &Path, name: &str| {
        [".rs", ".toml", ".md", ".wgsl", ".sh"]
            .iter()
            .any(|s| name.ends_with(s))
            || p.parent()
                .and_then(|d| d.file_name())
                .is_some_and(|n| n == ".ci")
    };
    xtask::tree::files(dir, &enter, &keep)
}

/// How deep `dir` lies below the repository's root (0 for the root itself).
fn depth(dir: &Path, root: &Path) -> usize {
    dir.strip_prefix(root).map_or(0, |r| r.components().count())
}

/// The folder of the nearest `Cargo.toml` at or above `file` (paths in Rust code are
/// joined to `CARGO_MANIFEST_DIR`).
fn crate_dir(file: &Path, root: &Path) -> PathBuf {
    let mut d = file.parent().expect("a file has a folder");
    while d != root {
        if d.join("Cargo.toml").exists() {
            return d.to_path_buf();
        }
        d = d.parent().expect("below the root");
    }
    root.to_path_buf()
}

/// The length of every run of `../` in `line`.
fn climbs(line: &str) -> Vec<usize> {
    let b = line.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i + 3 <= b.len() {
        if &b[i..i + 3] == b"../" && (i == 0 || !b[i - 1].is_ascii_alphanumeric()) {
            let mut n = 0;
            while i + 3 <= b.len() && &b[i..i + 3] == b"../" {
                n += 1;
                i += 3;
            }
            out.push(n);
        } else {
            i += 1;
        }
    }
    out
}

/// Where paths in `file` start from: its crate's folder for Rust code (joined to
/// `CARGO_MANIFEST_DIR`), except `include_*!` lines (the file's folder); the file's own
/// folder for scenes and docs.
fn allowed_climb(file: &Path, line: &str, root: &Path) -> usize {
    let rust = file.extension().is_some_and(|e| e == "rs");
    if rust && !line.contains("include_") {
        depth(&crate_dir(file, root), root)
    } else {
        depth(file.parent().expect("a folder"), root)
    }
}

#[test]
fn no_path_climbs_out_of_the_repository() {
    let root = root();
    let files = text_files(&root);
    assert!(files.len() > 100, "found only {} files", files.len());
    let mut bad = Vec::new();
    for f in &files {
        let Ok(text) = std::fs::read_to_string(f) else {
            continue;
        };
        // This file names the forbidden paths as examples.
        if f.ends_with("xtask/tests/self_contained.rs") {
            continue;
        }
        for (k, line) in text.lines().enumerate() {
            let limit = allowed_climb(f, line, &root);
            let worst = climbs(line).into_iter().max().unwrap_or(0);
            if worst > limit || line.contains(concat!("shared", "/testdata")) {
                bad.push(format!(
                    "{}:{}: climbs {worst} folders (at most {limit}): {}",
                    f.strip_prefix(&root).unwrap_or(f).display(),
                    k + 1,
                    line.trim()
                ));
            }
        }
    }
    assert!(
        bad.is_empty(),
        "paths outside the repository:\n{}",
        bad.join("\n")
    );
}

#[test]
fn the_climb_rule_catches_the_old_test_data_path() {
    let root = root();
    let test = root.join("crates/viewer/tests/scene_files.rs");
    // The old path, built so that this file does not name it.
    let old = format!("{}shared/x", "../".repeat(3));
    let line = format!(r#"    let d = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("{old}");"#);
    assert_eq!(climbs(&line), vec![3]);
    assert!(climbs(&line)[0] > allowed_climb(&test, &line, &root));
    let ok = r#"    let d = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../assets");"#;
    assert!(climbs(ok)[0] <= allowed_climb(&test, ok, &root));
    let scene = root.join("crates/viewer/scenes/town.toml");
    assert_eq!(allowed_climb(&scene, "", &root), 3);
}

#[test]
fn the_assets_are_in_the_repository() {
    let a = root().join("assets");
    for f in [
        "LICENSES.md",
        "kenney-city-builder/LICENSE-CC0.txt",
        "kenney-city-builder/grass-trees.glb",
        "kenney-city-builder/Textures/colormap.png",
        "dem-jacksboro/LICENSE-matplotlib.txt",
        "dem-jacksboro/jacksboro_fault_dem_u16.png",
    ] {
        assert!(a.join(f).is_file(), "assets/{f} missing");
    }
}

#[test]
fn crate_readmes_link_nothing_relative() {
    let root = root();
    for e in std::fs::read_dir(root.join("crates")).expect("crates/") {
        let readme = e.expect("entry").path().join("README.md");
        let Ok(text) = std::fs::read_to_string(&readme) else {
            continue;
        };
        for (k, line) in text.lines().enumerate() {
            assert!(
                !line.contains("](../") && !line.contains("](./"),
                "{}:{}: a relative link breaks on a registry's page: {line}",
                readme.display(),
                k + 1
            );
        }
    }
}
