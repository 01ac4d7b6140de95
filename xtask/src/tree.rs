//! Walking the repository's files for the house tests (`xtask/tests/function_length.rs`,
//! `self_contained.rs`).

use std::path::{Path, PathBuf};

/// The workspace root (the folder above `xtask/`).
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map_or_else(|| PathBuf::from(".."), Path::to_path_buf)
}

/// Every file under `dir` that `keep(path, name)` takes, descending into the folders
/// whose name `enter` takes; unreadable folders are skipped.
pub fn files(
    dir: &Path,
    enter: &dyn Fn(&str) -> bool,
    keep: &dyn Fn(&Path, &str) -> bool,
) -> Vec<PathBuf> {
    let mut out = Vec::new();
    walk(dir, enter, keep, &mut out);
    out.sort();
    out
}

fn walk(
    dir: &Path,
    enter: &dyn Fn(&str) -> bool,
    keep: &dyn Fn(&Path, &str) -> bool,
    out: &mut Vec<PathBuf>,
) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        let name = e.file_name().to_string_lossy().into_owned();
        if p.is_dir() {
            if enter(&name) {
                walk(&p, enter, keep, out);
            }
        } else if keep(&p, &name) {
            out.push(p);
        }
    }
}
