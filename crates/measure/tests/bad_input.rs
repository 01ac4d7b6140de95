//! Hand-made bad inputs for sweep-cpu: EXR skies with huge or broken headers, files that
//! are not files, light and option values that would overflow or never finish (the
//! command line's limits are in `crates/cli/tests/cli.rs`).

use std::path::{Path, PathBuf};
use std::process::Command;

use lightgrid_core::glam::Vec3;
use lightgrid_core::{BinLight, Boundary, SweepOptions};
use lightgrid_measure::reference::{ReferenceOptions, trace};
use lightgrid_measure::scenes::Scene;
use lightgrid_sky::EnvMap;

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("sweep-cpu-bad-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn exr_bytes() -> Vec<u8> {
    let dir = scratch("exr-seed");
    let p = dir.join("sky.exr");
    EnvMap::from_fn(8, 4, |d| Vec3::new(0.3, 0.5, 1.0) * (1.5 + d.y))
        .unwrap()
        .save_exr(&p)
        .unwrap();
    let b = std::fs::read(&p).unwrap();
    std::fs::remove_dir_all(&dir).ok();
    b
}

/// Overwrites the four i32 of the `box2i` attribute `name` in an EXR header.
fn set_box(b: &mut [u8], name: &str, v: [i32; 4]) {
    let key = format!("{name}\0box2i\0");
    let at = b
        .windows(key.len())
        .position(|w| w == key.as_bytes())
        .expect("attribute present")
        + key.len()
        + 4;
    for (k, x) in v.iter().enumerate() {
        b[at + 4 * k..at + 4 * k + 4].copy_from_slice(&x.to_le_bytes());
    }
}

#[test]
fn exr_headers_claiming_huge_images_are_refused_before_allocating() {
    let good = exr_bytes();
    assert_eq!(EnvMap::from_exr_bytes(&good).unwrap().width(), 8);
    for v in [
        [0, 0, i32::MAX - 1, i32::MAX - 1],
        [0, 0, 1 << 20, 1 << 20],
        [i32::MIN + 1, i32::MIN + 1, i32::MAX - 1, i32::MAX - 1],
        [0, 0, 16383, 16383 * 2],
    ] {
        let mut b = good.clone();
        set_box(&mut b, "dataWindow", v);
        set_box(&mut b, "displayWindow", v);
        assert!(EnvMap::from_exr_bytes(&b).is_err(), "{v:?} accepted");
    }
    // Truncated anywhere and bit-flipped anywhere in the header: errors, no panic.
    for cut in 0..good.len() {
        assert!(
            EnvMap::from_exr_bytes(&good[..cut]).is_err(),
            "cut at {cut} accepted"
        );
    }
    // Bit flips in the header: any result, but no panic, hang or huge allocation (a
    // panic fails this test; the hand-made huge headers above must be errors).
    for i in 0..good.len().min(400) {
        let mut b = good.clone();
        b[i] ^= 0x80;
        if let Ok(m) = EnvMap::from_exr_bytes(&b) {
            assert!(m.texels().iter().all(|t| t.is_finite()), "flip at {i}");
        }
    }
}

#[test]
fn texels_and_sizes_that_would_overflow_are_errors() {
    // Texel radiance near f32::MAX made the Monte Carlo reference write NaN.
    let e = EnvMap::new(2, 2, vec![Vec3::splat(3e38); 4])
        .unwrap_err()
        .to_string();
    assert!(e.contains("texels[0]") && e.contains("1e30"), "{e}");
    // width × height wrapping u32.
    assert!(EnvMap::new(u32::MAX, 2, vec![]).is_err());
    assert!(EnvMap::from_fn(1 << 16, 1 << 16, |_| Vec3::ONE).is_err());
    // The reference refuses boundary light over 1e30 as the sweep does, by name.
    let (m, _) = Scene::UniformFog.build(4);
    let b = Boundary::open_sky(BinLight::uniform(Vec3::splat(1e31)));
    let e = trace(&m, &b, &ReferenceOptions::default(), &|_, _| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("1e30"), "{e}");
    // Options that would run forever.
    let o = ReferenceOptions {
        paths: u64::MAX,
        ..Default::default()
    };
    let ok = Boundary::open_sky(BinLight::uniform(Vec3::ONE));
    assert!(
        trace(&m, &ok, &o, &|_, _| {})
            .unwrap_err()
            .to_string()
            .contains("paths")
    );
    let mut s = SweepOptions::multi_bounce();
    s.max_passes = u32::MAX;
    s.tolerance = 0.0;
    let e = lightgrid_sweep_cpu::run(&m, &ok, &s)
        .map(|_| ())
        .unwrap_err()
        .to_string();
    assert!(e.contains("max_passes"), "{e}");
}

#[test]
fn exr_readers_refuse_devices_fifos_and_folders() {
    let dir = scratch("special");
    let mut bad: Vec<PathBuf> = vec![dir.clone()];
    if Path::new("/dev/zero").exists() {
        bad.push("/dev/zero".into());
    }
    let fifo = dir.join("sky.exr");
    if Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .is_ok_and(|s| s.success())
    {
        bad.push(fifo);
    }
    for p in bad {
        let e = EnvMap::load_exr(&p).unwrap_err().to_string();
        assert!(e.contains("regular file"), "{}: {e}", p.display());
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// Inputs `cargo xtask fuzz` found slow or crashing, kept so they stay fixed: tiled EXRs
/// whose tile size (64 × 2^24 and more) made the reader allocate gigabytes.
#[test]
fn the_fuzz_corpus_is_rejected() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/corpus");
    let mut n = 0;
    for e in std::fs::read_dir(&dir).unwrap() {
        let p = e.unwrap().path();
        let b = std::fs::read(&p).unwrap();
        let e = EnvMap::from_exr_bytes(&b).unwrap_err().to_string();
        assert!(e.contains("tile size"), "{}: {e}", p.display());
        n += 1;
    }
    assert!(n >= 2, "corpus missing");
}
