//! Image tests: small headless renders of `tests/data/tiny.toml` compared with the
//! references in `tests/reference/` (rendered on lavapipe). A render passes when its mean
//! absolute difference is at most 1.5 levels (of 255) per channel and at most 1 % of its
//! pixels differ by more than 24 levels in any channel: rasterisers may differ in edge
//! rules and float rounding, not in lighting. On failure the actual image and a diff
//! (differences × 8) are written to `target/image-tests/`. `LIGHTGRID_BLESS=1` rewrites
//! the references. Needs a GPU adapter (lavapipe in CI); fails without one unless
//! LIGHTGRID_ALLOW_NO_GPU=1.

use std::path::{Path, PathBuf};

use lightgrid_viewer::{Options, SceneFile, Summary, SweeperChoice};

fn manifest() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn load_rgba(path: &Path) -> (u32, u32, Vec<u8>) {
    let img = image::open(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .into_rgba8();
    let (w, h) = img.dimensions();
    (w, h, img.into_raw())
}

/// (mean absolute difference per channel, fraction of pixels off by more than 24).
fn compare(a: &[u8], b: &[u8]) -> (f64, f64) {
    let mut sum = 0u64;
    let mut bad = 0usize;
    for (pa, pb) in a.chunks(4).zip(b.chunks(4)) {
        let mut worst = 0;
        for c in 0..3 {
            let d = (pa[c] as i32 - pb[c] as i32).unsigned_abs();
            sum += d as u64;
            worst = worst.max(d);
        }
        bad += (worst > 24) as usize;
    }
    let pixels = a.len() / 4;
    (sum as f64 / (pixels * 3) as f64, bad as f64 / pixels as f64)
}

/// Renders `tests/data/tiny.toml` at 64 x 64 into `target/image-tests/<dir>`; `None`
/// when no adapter exists and LIGHTGRID_ALLOW_NO_GPU=1 opts out.
fn render_tiny(
    dir: &str,
    sweeper: SweeperChoice,
    extras: bool,
    split: bool,
) -> Option<(PathBuf, Summary)> {
    render_tiny_with(dir, sweeper, extras, split, 0)
}

/// Whether a GPU adapter exists, checked once a process with a device made and
/// dropped (each run makes its own). Fails loudly without one, as
/// `GpuContext::new_for_tests` does, unless LIGHTGRID_ALLOW_NO_GPU=1.
fn gpu_present() -> bool {
    static PRESENT: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *PRESENT.get_or_init(|| lightgrid_gpu::GpuContext::new_for_tests().is_some())
}

/// [`render_tiny`] with its nodes swept over an apron of `apron` cells (`grid.apron`).
fn render_tiny_with(
    dir: &str,
    sweeper: SweeperChoice,
    extras: bool,
    split: bool,
    apron: u32,
) -> Option<(PathBuf, Summary)> {
    if !gpu_present() {
        return None;
    }
    let out = manifest().join("../../target/image-tests").join(dir);
    std::fs::create_dir_all(&out).unwrap();
    let mut scene = SceneFile::load(&manifest().join("tests/data/tiny.toml")).unwrap();
    scene.sun.split = split;
    scene.grid.apron = apron;
    let summary = lightgrid_viewer::run(
        scene,
        &Options {
            out: out.clone(),
            width: 64,
            height: 64,
            sweeper,
            exr: extras,
            bevy: extras,
        },
    )
    .unwrap();
    Some((out, summary))
}

#[test]
fn tiny_scene_matches_the_reference_images() {
    let Some((out, summary)) = render_tiny("", SweeperChoice::Cpu, true, true) else {
        return;
    };
    assert!(summary.text().contains("view tiny"));
    // The sun kept apart (the default) and moved once after the view.
    assert!(summary.sun.starts_with("kept apart"), "{}", summary.sun);
    let moved = summary.sun_move.as_deref().expect("a sun move");
    // The CPU sweeper sweeps the sun's first collisions with the sky: a moved sun
    // sweeps every grid again.
    assert!(moved.contains("swept with the sky"), "{moved}");
    assert!(
        summary.sun.contains("swept with the sky"),
        "{}",
        summary.sun
    );
    assert!(out.join("tiny-sun-moved.png").is_file());
    // The sun's responses are counted beside the sky's grids: their transmittance, 4
    // bytes a point (the sky's bins hold the scattered sun); the sky's horizon halves
    // 96; the kept materials 16.
    for v in &summary.views {
        let points: u64 = v.points_per_depth.iter().sum();
        assert_eq!(v.sun_bytes, points * 4, "{}", v.name);
        assert_eq!(v.horizon_bytes, points * 96, "{}", v.name);
        assert_eq!(v.material_bytes, points * 16, "{}", v.name);
    }
    // --bevy: the world volume first, then one per quadtree depth, indirect light.
    let side: lightgrid_export::Sidecar =
        serde_json::from_str(&std::fs::read_to_string(out.join("bevy/tiny.json")).unwrap())
            .unwrap();
    assert!(
        (2..=8).contains(&side.volumes.len()),
        "{} volumes",
        side.volumes.len()
    );
    // The sun the indirect volumes leave out, towards the scene's sun (above the
    // horizon: it points up).
    let sun = side.sun.expect("the sidecar names the sun");
    assert!(
        sun.direction_to_sun[1] > 0.0 && sun.illuminance > 0.0,
        "{sun:?}"
    );
    for (i, v) in side.volumes.iter().enumerate() {
        assert_eq!(v.content, lightgrid_export::Content::Indirect);
        assert!(
            out.join("bevy").join(&v.dds).is_file() && out.join("bevy").join(&v.ktx2).is_file()
        );
        // Finer after coarser.
        if i > 0 {
            assert!(
                v.grid_spacing <= side.volumes[i - 1].grid_spacing,
                "volume {i}"
            );
        }
        assert!(v.intensity.is_finite() && v.intensity > 0.0);
    }
    // The EXR holds the same lit view in linear HDR: it reads back and is not black.
    let exr = exr::prelude::read_first_rgba_layer_from_file(
        out.join("tiny.exr"),
        |res, _| vec![0f32; res.width() * res.height()],
        |px: &mut Vec<f32>, p, (r, g, b, _a): (f32, f32, f32, f32)| {
            px[p.y() * 64 + p.x()] = r + g + b
        },
    )
    .unwrap();
    let hdr = &exr.layer_data.channel_data.pixels;
    assert!(hdr.iter().all(|v| v.is_finite()) && hdr.iter().sum::<f32>() > 1.0);

    let bless = std::env::var("LIGHTGRID_BLESS").as_deref() == Ok("1");
    let failures = compare_with_references(&out, &manifest().join("tests/reference"), bless);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    // The grids light the scene differently from the no-grid comparison (shadows and
    // bounce): the two images must not be the same.
    let (_, _, lit) = load_rgba(&out.join("tiny.png"));
    let (_, _, flat) = load_rgba(&out.join("tiny-no-grid.png"));
    assert!(compare(&lit, &flat).0 > 2.0, "grid light changes nothing?");
}

/// Compares the four images in `out` with those in `references` (or, with `bless`,
/// replaces them); returns the failures.
fn compare_with_references(out: &Path, references: &Path, bless: bool) -> Vec<String> {
    let mut failures = Vec::new();
    for name in ["tiny", "tiny-no-grid", "tiny-grid-points", "tiny-material"] {
        let actual = out.join(format!("{name}.png"));
        let reference = references.join(format!("{name}.png"));
        if bless {
            std::fs::copy(&actual, &reference).unwrap();
            continue;
        }
        let (w, h, a) = load_rgba(&actual);
        let (rw, rh, b) = load_rgba(&reference);
        assert_eq!((w, h), (rw, rh), "{name}: size");
        let (mean, off) = compare(&a, &b);
        eprintln!(
            "{name}: mean difference {mean:.3}, pixels off {:.2} %",
            off * 100.0
        );
        if mean > 1.5 || off > 0.01 {
            let diff: Vec<u8> = a
                .chunks(4)
                .zip(b.chunks(4))
                .flat_map(|(p, q)| {
                    let d =
                        |c: usize| ((p[c] as i32 - q[c] as i32).unsigned_abs() * 8).min(255) as u8;
                    [d(0), d(1), d(2), 255]
                })
                .collect();
            let diff_path = out.join(format!("{name}-diff.png"));
            image::save_buffer(&diff_path, &diff, w, h, image::ColorType::Rgba8).unwrap();
            failures.push(format!(
                "{name}: mean {mean:.3} (max 1.5), pixels off {:.2} % (max 1 %); actual {} diff {}",
                off * 100.0,
                actual.display(),
                diff_path.display()
            ));
        }
    }
    failures
}

/// The same scene swept on the GPU, with the grids left on the renderer's device and
/// sampled and drawn there (no grid through the CPU), equals the CPU sweep's images, with
/// the sun in the bins (`sun.split = false`).
#[test]
fn tiny_scene_swept_and_drawn_on_the_device_matches_the_cpu() {
    let Some((out, summary)) = render_tiny("gpu", SweeperChoice::Gpu, false, false) else {
        return;
    };
    assert!(summary.sweeper.starts_with("gpu"), "{}", summary.sweeper);
    assert!(summary.sun_move.is_none() && summary.sun.starts_with("in the sky's bins"));
    assert!(summary.views.iter().all(|v| v.sun_bytes == 0));
    sampled_on_device(&summary);
    let (cpu, _) = render_tiny("cpu-bins", SweeperChoice::Cpu, false, false).unwrap();
    let failures = compare_with_references(&out, &cpu, false);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// With the sun kept apart (the default) the device path samples the three responses in
/// place (sky bins scaled, scattered sun, transmittance uploaded) and matches the
/// references the CPU path rendered.
#[test]
fn tiny_scene_with_the_sun_apart_drawn_on_the_device_matches_the_references() {
    let Some((out, summary)) = render_tiny("gpu-split", SweeperChoice::Gpu, false, true) else {
        return;
    };
    assert!(summary.sun.starts_with("kept apart"), "{}", summary.sun);
    sampled_on_device(&summary);
    let failures = compare_with_references(&out, &manifest().join("tests/reference"), false);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Nodes swept over an apron (`grid.apron`, the library's default for its 32-point
/// nodes) keep their own points on the device too (`Sweeper::crop_resident`): the light
/// is sampled there and the images equal the CPU sweep's over the same apron.
#[test]
fn nodes_swept_over_an_apron_stay_on_the_device() {
    let Some((out, summary)) = render_tiny_with("gpu-apron", SweeperChoice::Gpu, false, true, 2)
    else {
        return;
    };
    sampled_on_device(&summary);
    let (cpu, _) = render_tiny_with("cpu-apron", SweeperChoice::Cpu, false, true, 2).unwrap();
    let failures = compare_with_references(&out, &cpu, false);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Every view's light was sampled on the device, from the grids the GPU sweeper left there.
fn sampled_on_device(summary: &Summary) {
    for v in &summary.views {
        assert!(
            v.sampled_on.starts_with("device"),
            "{}: {}",
            v.name,
            v.sampled_on
        );
    }
}

/// Foliage beyond `render.far_detail` is drawn as impostors (`lightgrid_render::impostor`)
/// that keep what the trees look like from afar: the tiny scene with every tree an
/// impostor (1 m) against every tree whole (0: none), at 128 × 128, differs (the
/// impostors are drawn), yet the pixels where foliage is (green over red and blue by
/// 10 levels) number the same within a fifth (a tree's cover differs with the side it
/// is seen from: 256 against 299 pixels here) and their mean colour is the same
/// within a tenth.
#[test]
fn impostors_keep_the_trees_cover_and_colour() {
    if !gpu_present() {
        return;
    }
    let render = |far: f32| {
        let dir = format!("impostors-{far}");
        let out = manifest().join("../../target/image-tests").join(dir);
        std::fs::create_dir_all(&out).unwrap();
        let mut scene = SceneFile::load(&manifest().join("tests/data/tiny.toml")).unwrap();
        scene.render.far_detail = far;
        let opts = Options {
            out: out.clone(),
            width: 128,
            height: 128,
            sweeper: SweeperChoice::Cpu,
            exr: false,
            bevy: false,
        };
        let summary = lightgrid_viewer::run(scene, &opts).unwrap();
        let (_, _, px) = load_rgba(&out.join("tiny.png"));
        (px, summary)
    };
    let (whole, s0) = render(0.0);
    let (far, s1) = render(1.0);
    assert!(s0.far_detail.is_none() && s1.far_detail == Some(1.0));
    assert!(whole != far, "the impostors are drawn");
    let foliage = |px: &[u8]| {
        let leaves: Vec<[f64; 3]> = px
            .chunks(4)
            .filter(|p| p[1] as i32 > p[0].max(p[2]) as i32 + 10)
            .map(|p| [p[0] as f64, p[1] as f64, p[2] as f64])
            .collect();
        let n = leaves.len().max(1) as f64;
        let mean = [0, 1, 2].map(|c| leaves.iter().map(|p| p[c]).sum::<f64>() / n);
        (leaves.len(), mean)
    };
    let ((n0, c0), (n1, c1)) = (foliage(&whole), foliage(&far));
    assert!(n0 > 100, "the scene shows foliage: {n0} pixels");
    assert!(
        (n1 as f64 / n0 as f64 - 1.0).abs() < 0.2,
        "foliage pixels: {n1} as impostors, {n0} whole"
    );
    for c in 0..3 {
        assert!(
            (c1[c] - c0[c]).abs() <= 0.1 * c0[c].max(25.0),
            "mean colour {c1:?} as impostors, {c0:?} whole"
        );
    }
}
