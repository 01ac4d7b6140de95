//! Scene values and files that used to crash or exhaust the machine: each is now a
//! clear error naming the field or file, given before the large allocation.

use std::path::{Path, PathBuf};

use lightgrid_viewer::{SceneFile, SweeperChoice, World};

/// `body` plus one view (every scene needs one).
fn scene(body: &str) -> SceneFile {
    let text = format!(
        "{body}\n[[views]]\nname = \"v\"\nposition = [0.0, 0.0]\nheight = 10.0\ntarget = [1.0, 1.0]\n"
    );
    SceneFile::parse(&text, "bad.toml", Path::new(".")).expect("parses")
}

/// The error parsing `body` plus one view gives.
fn parse_error(body: &str) -> String {
    let text = format!(
        "{body}\n[[views]]\nname = \"v\"\nposition = [0.0, 0.0]\nheight = 10.0\ntarget = [1.0, 1.0]\n"
    );
    format!(
        "{:#}",
        SceneFile::parse(&text, "bad.toml", Path::new(".")).unwrap_err()
    )
}

fn build_error(body: &str) -> String {
    match World::build(scene(body), SweeperChoice::Cpu) {
        Ok(_) => panic!("built a world from:\n{body}"),
        Err(e) => format!("{e:#}"),
    }
}

const TERRAIN_512: &str = r#"
[terrain]
procedural = { size = 512.0, relief = 20.0, feature_size = 100.0, seed = 1 }
spacing = 8.0
"#;

#[test]
fn a_world_grid_over_the_memory_limit_is_refused() {
    // world_cell = 0.25 over 512 m of terrain: about 2049² × 130 points × 640 bytes.
    let e = build_error(&format!(
        "{TERRAIN_512}\n[grid]\nworld_cell = 0.25\nfinest_cell = 0.25\n"
    ));
    assert!(e.contains("world grid") && e.contains("memory"), "{e}");
}

#[test]
fn a_terrain_spacing_that_needs_billions_of_samples_is_refused() {
    let e =
        build_error("[terrain]\nprocedural = { size = 512.0, relief = 20.0 }\nspacing = 0.001\n");
    assert!(e.contains("terrain.spacing"), "{e}");
}

#[test]
fn too_many_depths_are_refused() {
    // 2^40 between world and finest cells would overflow the depth shift.
    let e = build_error(&format!(
        "{TERRAIN_512}\n[grid]\nworld_cell = 16.0\nfinest_cell = 1.4551915228366852e-11\n"
    ));
    assert!(e.contains("finest_cell"), "{e}");
}

#[test]
fn scene_files_that_are_not_files_or_too_large_are_errors() {
    let dir = std::env::temp_dir().join(format!("viewer-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut bad: Vec<PathBuf> = vec![dir.clone()];
    if Path::new("/dev/zero").exists() {
        bad.push("/dev/zero".into());
    }
    let fifo = dir.join("scene.toml");
    if std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .is_ok_and(|s| s.success())
    {
        bad.push(fifo);
    }
    let big = dir.join("big.toml");
    std::fs::write(
        &big,
        vec![b'#'; (lightgrid_viewer::scene::MAX_SCENE_BYTES + 1) as usize],
    )
    .unwrap();
    bad.push(big);
    for p in bad {
        let e = format!("{:#}", SceneFile::load(&p).unwrap_err());
        assert!(e.contains(&p.display().to_string()), "{e}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn image_sizes_out_of_range_are_refused() {
    let opts = |w, h| lightgrid_viewer::Options {
        out: std::env::temp_dir().join("viewer-bad-size"),
        width: w,
        height: h,
        sweeper: SweeperChoice::Cpu,
        exr: false,
        bevy: false,
    };
    for (w, h) in [(0, 10), (10, 0), (100_000, 10)] {
        let e = lightgrid_viewer::run(SceneFile::demo().unwrap(), &opts(w, h))
            .map(|_| ())
            .unwrap_err();
        assert!(e.to_string().contains("must be in 1..="), "{e}");
    }
}

#[test]
fn non_finite_scene_values_name_their_field() {
    // TOML can spell nan and inf; every float that places something must be finite.
    let demo = lightgrid_viewer::scene::DEMO;
    for (from, to, field) in [
        ("target_height = ", "target_height = nan #", "target_height"),
        ("spacing = ", "spacing = inf #", "terrain.spacing"),
        ("time_of_day = ", "time_of_day = nan #", "sun.time_of_day"),
    ] {
        assert!(demo.contains(from), "the demo has no {from}");
        let text = demo.replacen(from, to, 1);
        let e = format!(
            "{:#}",
            SceneFile::parse(&text, "bad.toml", Path::new(".")).unwrap_err()
        );
        assert!(e.contains(field), "{field}: {e}");
    }
    let mut s = String::from(TERRAIN_512);
    s.push_str("[[models]]\nname = \"r\"\nprocedural = \"rock\"\n[[instances]]\nmodel = \"r\"\nposition = [1.0, 1.0]\nheight = inf\n");
    let e = parse_error(&s);
    assert!(e.contains("instances[0].height"), "{e}");
}

/// A probe spacing far too fine for the scene is refused by name, before any baking.
#[test]
fn a_probe_spacing_too_fine_is_refused_by_name() {
    let path = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/town.toml");
    let text = std::fs::read_to_string(&path)
        .unwrap()
        .replace("[probes]", "[probes]\nspacing = 0.01");
    let scene =
        lightgrid_viewer::SceneFile::parse(&text, "town.toml", path.parent().unwrap()).unwrap();
    let e = match lightgrid_viewer::World::build(scene, lightgrid_viewer::SweeperChoice::Cpu) {
        Ok(_) => panic!("a 0.01 m probe spacing over the town must be refused"),
        Err(e) => format!("{e:#}"),
    };
    assert!(e.contains("probes.spacing"), "{e}");
}

/// Values that are positive but make derived quantities overflow (the noise's
/// coordinates: position / feature size) and tables that would run for minutes are
/// refused by name when the scene is read.
#[test]
fn scene_values_out_of_range_and_huge_tables_are_refused() {
    for (terrain, field) in [
        (
            "size = 512.0, relief = 20.0, feature_size = 1e-30",
            "feature_size",
        ),
        (
            "size = 512.0, relief = 20.0, feature_size = 1e-17",
            "feature_size",
        ),
        ("size = 1e21, relief = 20.0", "terrain.procedural.size"),
    ] {
        let text = format!(
            "[terrain]\nprocedural = {{ {terrain} }}\nspacing = 8.0\n[[views]]\nname = \"v\"\nposition = [0.0, 0.0]\nheight = 10.0\ntarget = [1.0, 1.0]\n"
        );
        let e = format!(
            "{:#}",
            SceneFile::parse(&text, "bad.toml", Path::new(".")).unwrap_err()
        );
        assert!(e.contains(field), "{terrain}: {e}");
    }
    let mut text = String::from(TERRAIN_512);
    for i in 0..10_000 {
        text.push_str(&format!(
            "[[views]]\nname = \"v{i}\"\nposition = [0.0, 0.0]\nheight = 10.0\ntarget = [1.0, 1.0]\n"
        ));
    }
    let e = format!(
        "{:#}",
        SceneFile::parse(&text, "bad.toml", Path::new(".")).unwrap_err()
    );
    // Refused on reading, before any rendering.
    assert!(e.contains("views: 10000 entries, at most 64"), "{e}");
}

/// Names a scene chooses from (sky kind, procedural model, probe preset and sun) are
/// parsed once into typed values: an unknown one is refused at parse, with the line and
/// the names it could be.
#[test]
fn unknown_names_are_refused_when_the_scene_is_parsed() {
    let view =
        "[[views]]\nname = \"v\"\nposition = [0.0, 0.0]\nheight = 10.0\ntarget = [1.0, 1.0]\n";
    for (body, value, choices) in [
        (
            "[sky]\nkind = \"foggy\"\n",
            "foggy",
            "`clear`, `uniform`, `exr`, `daylight`",
        ),
        (
            "[[models]]\nname = \"m\"\nprocedural = \"oak\"\n",
            "oak",
            "`broadleaf`, `young`, `bush`, `rock`",
        ),
        (
            "[probes]\npreset = \"ultra\"\n",
            "ultra",
            "`preview`, `standard`, `fine`",
        ),
        ("[probes]\nsun = \"moon\"\n", "moon", "`rays` or `sweep`"),
    ] {
        let text = format!("{TERRAIN_512}\n{body}{view}");
        let e = match SceneFile::parse(&text, "bad.toml", Path::new(".")) {
            Ok(_) => panic!("parsed:\n{text}"),
            Err(e) => format!("{e:#}"),
        };
        assert!(
            e.contains(&format!("unknown variant `{value}`")) && e.contains(choices),
            "{e}"
        );
    }
}

/// A daylight sky's turbidity outside Preetham's fit is named with its field.
#[test]
fn daylight_turbidity_out_of_range_is_named() {
    let scene = "[terrain]\nprocedural = { size = 32.0, relief = 2.0, feature_size = 20.0, seed = 1 }\n\
                 [sky]\nkind = \"daylight\"\nturbidity = 40.0\n\
                 [[views]]\nname = \"v\"\nposition = [0.0, 0.0]\nheight = 10.0\ntarget = [1.0, 1.0]\n";
    let e =
        lightgrid_viewer::SceneFile::parse(scene, "t.toml", std::path::Path::new(".")).unwrap_err();
    let msg = format!("{e:#}");
    assert!(msg.contains("sky.turbidity = 40"), "{msg}");
}

/// The distance beyond which foliage is drawn as impostors must be finite and at least
/// 0 (0: none); the scene names it.
#[test]
fn a_bad_far_detail_is_named() {
    for v in ["-1.0", "inf", "nan"] {
        let e = parse_error(&format!("{TERRAIN_512}\n[render]\nfar_detail = {v}\n"));
        assert!(e.contains("render.far_detail"), "{v}: {e}");
    }
    let off = scene(&format!("{TERRAIN_512}\n[render]\nfar_detail = 0.0\n"));
    assert_eq!(off.render.impostors_beyond(), None);
    let default = scene(TERRAIN_512).render;
    assert_eq!(default.impostors_beyond(), Some(120.0), "the default");
}
