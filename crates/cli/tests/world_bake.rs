//! `lightgrid bake world.toml`: the whole world in one process against the same tasks
//! run one process each (`--plan`, `--task`), a task killed half way, re-bakes that
//! reuse the store, and bad requests.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_lightgrid"));
    c.env("LIGHTGRID_QUIET", "1")
        .env_remove("LIGHTGRID_BAKE_FAULT");
    c
}

fn world() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/world.toml")
}

/// `lightgrid bake world.toml -o out`, more arguments to add.
fn bake(out: &Path) -> Command {
    let mut c = bin();
    c.arg("bake").arg(world()).arg("-o").arg(out);
    c
}

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("lightgrid-world-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn run(c: &mut Command) -> String {
    let out = c.output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).to_string()
}

/// Every file of a folder (the store left out), name -> bytes.
fn files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(dir)
        .unwrap()
        .flatten()
        .filter(|e| e.file_type().unwrap().is_file())
        .map(|e| {
            (
                e.file_name().to_string_lossy().to_string(),
                std::fs::read(e.path()).unwrap(),
            )
        })
        .collect()
}

fn plan(dir: &Path, out: &Path, store: &Path, extra: &[&str]) -> serde_json::Value {
    let p = dir.join("plan.json");
    run(bake(out)
        .arg("--store")
        .arg(store)
        .arg("--plan")
        .arg(&p)
        .args(extra));
    serde_json::from_slice(&std::fs::read(&p).unwrap()).unwrap()
}

#[test]
fn one_process_equals_one_process_per_task() {
    let dir = scratch("tasks");
    let (single, per_task) = (dir.join("single"), dir.join("per-task"));
    let s = run(bake(&single).arg("--store").arg(dir.join("store-a")));
    assert!(s.contains("28 ran, 0 found"), "{s}");
    let p = plan(&dir, &per_task, &dir.join("store-b"), &[]);
    let tasks = p["tasks"].as_array().unwrap();
    assert_eq!(tasks.len(), 28);
    // The plan's order runs every task after those it depends on.
    let ids: Vec<&str> = tasks.iter().map(|t| t["id"].as_str().unwrap()).collect();
    for (i, t) in tasks.iter().enumerate() {
        for d in t["deps"].as_array().unwrap() {
            let d = ids.iter().position(|x| *x == d.as_str().unwrap()).unwrap();
            assert!(d < i, "{} before its input {}", ids[i], ids[d]);
        }
        assert!(t["memory_bytes"].as_u64().unwrap() > 0);
    }
    for t in tasks {
        let argv: Vec<&str> = t["argv"]
            .as_array()
            .unwrap()
            .iter()
            .map(|a| a.as_str().unwrap())
            .collect();
        let o: serde_json::Value = serde_json::from_str(run(bin().args(&argv)).trim()).unwrap();
        assert_eq!(o["task"], t["id"]);
        assert_eq!(o["hash"], t["hash"]);
        assert_eq!(o["ran"], true);
    }
    let (a, b) = (files(&single), files(&per_task));
    assert_eq!(a.len(), 13 * 3 + 1, "{:?}", a.keys());
    assert_eq!(a, b, "the two bakes differ");
    let manifest: serde_json::Value = serde_json::from_slice(&a["volume.manifest.json"]).unwrap();
    assert_eq!(manifest["volumes"].as_array().unwrap().len(), 13);
    // Run again: every task's output is found in the store.
    let s = run(bake(&single).arg("--store").arg(dir.join("store-a")));
    assert!(s.contains("1 ran, 27 found"), "{s}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_task_killed_half_way_leaves_nothing_and_its_rerun_completes() {
    let dir = scratch("fault");
    let (out, store) = (dir.join("out"), dir.join("store"));
    let p = plan(&dir, &out, &store, &[]);
    let marker = dir.join("marker");
    for t in p["tasks"].as_array().unwrap() {
        let argv: Vec<&str> = t["argv"]
            .as_array()
            .unwrap()
            .iter()
            .map(|a| a.as_str().unwrap())
            .collect();
        if t["id"] == "node-2-1-1" {
            let r = bin()
                .args(&argv)
                .env(
                    "LIGHTGRID_BAKE_FAULT",
                    format!("node-2-1-1@{}", marker.display()),
                )
                .output()
                .unwrap();
            assert!(!r.status.success(), "the fault hook did not kill the task");
            assert!(marker.exists());
            let objects = store.join("objects");
            let names: Vec<String> = std::fs::read_dir(&objects)
                .unwrap()
                .flatten()
                .map(|e| e.file_name().to_string_lossy().to_string())
                .collect();
            let hash = t["hash"].as_str().unwrap();
            assert!(
                !names.iter().any(|n| n == hash),
                "a killed task's output in place"
            );
            assert!(names.iter().any(|n| n.starts_with(".tmp-")), "{names:?}");
        }
        run(bin().args(&argv));
    }
    let names: Vec<String> = std::fs::read_dir(store.join("objects"))
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().to_string())
        .collect();
    assert!(!names.iter().any(|n| n.starts_with(".tmp")), "{names:?}");
    assert_eq!(names.len(), 27);
    assert_eq!(files(&out).len(), 13 * 3 + 1);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn export_settings_change_only_the_exports_and_depths_add_tasks() {
    let dir = scratch("settings");
    let (out, store) = (dir.join("out"), dir.join("store"));
    let a = plan(&dir, &out, &store, &[]);
    let b = plan(&dir, &out, &store, &["--unit-scale", "2"]);
    let hashes = |p: &serde_json::Value| -> BTreeMap<String, String> {
        p["tasks"]
            .as_array()
            .unwrap()
            .iter()
            .map(|t| {
                (
                    t["id"].as_str().unwrap().to_string(),
                    t["hash"].as_str().unwrap().to_string(),
                )
            })
            .collect()
    };
    let (a, b) = (hashes(&a), hashes(&b));
    for (id, h) in &a {
        let changed = b[id] != *h;
        assert_eq!(
            changed,
            id.starts_with("export-") || id == "manifest",
            "{id}"
        );
    }
    // A shallower bake is the deeper one's coarse part: the same tasks, the same hashes.
    let shallow = hashes(&plan(&dir, &out, &store, &["--depths", "1"]));
    assert_eq!(shallow.len(), 1 + 4 + 4 + 1);
    for (id, h) in &shallow {
        assert_eq!(id == "manifest", a[id] != *h, "{id}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// `[grid] gather` in the world file reaches the bake's sweeps: the world and node
/// tasks hash anew and their light changes (a cheap gather, one scattering by 64 rays
/// a cell).
#[test]
fn a_gather_in_the_world_file_reaches_the_bake() {
    let dir = scratch("gather");
    let text = std::fs::read_to_string(world()).unwrap();
    let gathered = dir.join("gathered.toml");
    let with = text.replacen(
        "passes = 2",
        "passes = 2\ngather = { orders = 1, rays = 64 }",
        1,
    );
    assert_ne!(with, text);
    std::fs::write(&gathered, with).unwrap();
    let (a, b) = (dir.join("a"), dir.join("b"));
    run(bake(&a)
        .args(["--depths", "1"])
        .arg("--store")
        .arg(dir.join("store")));
    run(bin()
        .arg("bake")
        .arg(&gathered)
        .arg("-o")
        .arg(&b)
        .args(["--depths", "1", "--store"])
        .arg(dir.join("store")));
    let (a, b) = (files(&a), files(&b));
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
    let changed: Vec<&String> = a.keys().filter(|k| a[*k] != b[*k]).collect();
    assert!(
        changed
            .iter()
            .any(|k| k.ends_with(".dds") || k.ends_with(".ktx2")),
        "no volume changed: {changed:?} of {:?}",
        a.keys().collect::<Vec<_>>()
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_world_requests_are_refused_with_a_message() {
    let dir = scratch("bad");
    let fail = |c: &mut Command| {
        let out = c.output().unwrap();
        assert!(!out.status.success());
        String::from_utf8_lossy(&out.stderr).to_string()
    };
    let e = fail(bake(&dir.join("o")).args(["--task", "node-9-9-9"]));
    assert!(e.contains("node-9-9-9"), "{e}");
    let e = fail(
        bake(&dir.join("o"))
            .args(["--task", "node-2-0-0", "--store"])
            .arg(dir.join("empty")),
    );
    assert!(e.contains("run it first"), "{e}");
    let e = fail(bake(&dir.join("o")).args(["--depths", "0"]));
    assert!(e.contains("--depths"), "{e}");
    let grid = dir.join("m.lgrid");
    run(bin()
        .args(["scene", "canopy", "--size", "8", "-o"])
        .arg(&grid));
    let e = fail(
        bin()
            .arg("bake")
            .arg(&grid)
            .arg("-o")
            .arg(dir.join("o"))
            .args(["--task", "world"]),
    );
    assert!(e.contains("world"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}
