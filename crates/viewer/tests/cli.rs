//! The viewer binary: a bad scene file is an error naming the file, the line and the
//! field, and nothing is rendered. (The rendering itself is covered by `images.rs`.)

use std::process::Command;

#[test]
fn bad_scene_file_names_file_line_and_field() {
    let dir = std::env::temp_dir().join(format!("viewer-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let scene = dir.join("broken.toml");
    let text = lightgrid_viewer::scene::DEMO
        .replacen("elevation_deg", "x", 0)
        .replacen(
            "illuminance = [8.0, 7.5, 6.5]",
            "illuminance = \"bright\"",
            1,
        );
    std::fs::write(&scene, text).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_lightgrid-viewer"))
        .args(["--scene", scene.to_str().unwrap(), "--out"])
        .arg(dir.join("out"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("broken.toml"), "{err}");
    assert!(err.contains("line"), "{err}");
    assert!(err.contains("illuminance"), "{err}");
    assert!(
        !dir.join("out").exists(),
        "nothing may be written for a bad scene"
    );
    // A missing file is named too.
    let out = Command::new(env!("CARGO_BIN_EXE_lightgrid-viewer"))
        .args(["--scene", "no/such/scene.toml"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("no/such/scene.toml"));
    std::fs::remove_dir_all(&dir).unwrap();
}
