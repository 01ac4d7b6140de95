//! The `lightgrid-sweep` command line, end to end.

use std::process::Command;

use grid_core::GridFile;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_lightgrid-sweep"))
}

#[test]
fn scene_sweep_reference_round_trip() {
    let dir = std::env::temp_dir().join(format!("lightgrid-sweep-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mat = dir.join("m.lgrid");
    let light = dir.join("l.lgrid");
    let refp = dir.join("r.lgrid");
    let ok = |c: &mut Command| {
        let out = c.output().unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).to_string()
    };
    ok(bin()
        .args(["scene", "canopy", "--size", "8", "-o"])
        .arg(&mat));
    let s = ok(bin()
        .arg("sweep")
        .arg(&mat)
        .arg("-o")
        .arg(&light)
        .args(["--sun", "500", "--packed"]));
    assert!(s.contains("swept 512 points"), "{s}");
    let packed = GridFile::load(&light).unwrap().into_packed_light().unwrap();
    assert_eq!(packed.grid.desc().point_count(), 512);
    let s = ok(bin()
        .arg("reference")
        .arg(&mat)
        .arg("-o")
        .arg(&refp)
        .args(["--paths", "20000", "--sky", "uniform"]));
    assert!(s.contains("traced 20000 paths"), "{s}");
    assert!(GridFile::load(&refp).unwrap().into_light().is_ok());

    // Bad input: a clear message naming the file or the value, and a failure status.
    let out = bin()
        .arg("sweep")
        .arg(dir.join("missing.lgrid"))
        .arg("-o")
        .arg(&light)
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("missing.lgrid"));
    let out = bin()
        .arg("sweep")
        .arg(&light)
        .arg("-o")
        .arg(dir.join("x"))
        .output()
        .unwrap();
    assert!(String::from_utf8_lossy(&out.stderr).contains("expected a material grid"));
    let out = bin()
        .arg("sweep")
        .arg(&mat)
        .arg("-o")
        .arg(&light)
        .args(["--sun", "1,2"])
        .output()
        .unwrap();
    assert!(String::from_utf8_lossy(&out.stderr).contains("R,G,B"));
    std::fs::remove_dir_all(&dir).unwrap();
}
