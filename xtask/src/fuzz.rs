//! `cargo xtask fuzz`: every reader of user files, fed millions of generated inputs.
//!
//! Each [`Target`] is one reader (grid files, scene TOML, light-volume cache files, glTF
//! and GLB models, EXR skies, PNG heightmaps), the export and bake paths, or the library's
//! entry points called with values from the input (`export`, `bake`, `api`:
//! [`crate::fuzz_api`]),
//! with a few valid **seed** inputs. Inputs are
//! seeds mutated by a deterministic generator (bit flips, interesting integers such as
//! `u32::MAX` written over header fields, truncation, insertion, deletion, duplication,
//! splicing two seeds); half of them are **fixed up** afterwards (checksums and length
//! fields recomputed) so that they get past the first checks and reach the deeper ones.
//!
//! Every input runs under `catch_unwind`. Per target the report gives: inputs tried,
//! accepted, rejected with an error, **panics that escaped the reader** (must be 0),
//! panics of third-party parsers that the reader caught and turned into errors (counted
//! by a panic hook), **slow inputs** (over [`SLOW`], counted as timeouts; must be 0), the
//! slowest input, and the peak memory (`VmHWM`, reset between targets through
//! `/proc/self/clear_refs`). An input whose panic escaped is written to
//! `target/fuzz/crash-<target>-<n>.bin` (a slow one to `slow-...`) to reproduce it.
//!
//! The memory limit ([`lightgrid_core::limits`]) is set to 2 GiB while fuzzing, so an input
//! that asks for more is refused, and the peak shows that no input got round it.
//!
//! `xtask/tests/fuzz.rs` runs every target over a few thousand inputs in CI; the command
//! runs a million per target:
//!
//! ```text
//! cargo xtask fuzz                      # 1 000 000 inputs per target
//! cargo xtask fuzz --inputs 20000 --target gltf
//! ```

use std::io::Write as _;
use std::path::Path;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use lightgrid_core::glam::{UVec3, Vec3, Vec4};
use lightgrid_core::{BinLight, GridDesc, GridFile, Material};
use rayon::prelude::*;

/// An input slower than this counts as a timeout.
pub const SLOW: Duration = Duration::from_secs(2);

/// Memory limit in force while fuzzing.
pub const FUZZ_MEMORY_LIMIT: u64 = 2 << 30;

/// One reader under test.
pub struct Target {
    /// Short name (`grid`, `scene`, ...).
    pub name: &'static str,
    /// Valid inputs the mutations start from.
    pub seeds: Vec<Vec<u8>>,
    /// Recomputes checksums and length fields after a mutation.
    pub fixup: fn(&mut [u8]),
    /// Runs the reader: `Ok(true)` accepted, `Ok(false)` rejected with an error.
    pub run: fn(&[u8]) -> bool,
}

/// What one target's run found.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct Report {
    /// The target.
    pub target: String,
    /// Inputs tried.
    pub inputs: u64,
    /// Inputs the reader accepted.
    pub accepted: u64,
    /// Inputs rejected with an error.
    pub rejected: u64,
    /// Panics that escaped the reader (a defect).
    pub escaped_panics: u64,
    /// Panics inside third-party parsers that the reader caught and reported as errors.
    pub caught_panics: u64,
    /// Inputs slower than [`SLOW`] (counted as timeouts).
    pub slow: u64,
    /// The slowest input, milliseconds.
    pub slowest_ms: f64,
    /// Wall time of the target, seconds.
    pub seconds: f64,
    /// Peak resident memory of the process during the target, bytes (0 where unknown).
    pub peak_rss: u64,
}

impl Report {
    /// No escaped panic and no slow input.
    pub fn clean(&self) -> bool {
        self.escaped_panics == 0 && self.slow == 0
    }
    /// One line of the table.
    pub fn line(&self) -> String {
        format!(
            "{:<8} {:>9} {:>9} {:>9} {:>8} {:>7} {:>5} {:>9.1} {:>8.1} {:>9.0}",
            self.target,
            self.inputs,
            self.accepted,
            self.rejected,
            self.escaped_panics,
            self.caught_panics,
            self.slow,
            self.slowest_ms,
            self.seconds,
            self.peak_rss as f64 / (1 << 20) as f64
        )
    }
    /// The table header.
    pub fn header() -> &'static str {
        "target      inputs  accepted  rejected  panics  caught  slow  max (ms)  time (s)  peak (MB)"
    }
}

static HOOK_PANICS: AtomicU64 = AtomicU64::new(0);
static HOOK: std::sync::Once = std::sync::Once::new();

thread_local! {
    /// True while this thread runs a fuzz input: its panics are counted, not printed.
    static IN_INPUT: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Installs (once per process) a panic hook that counts the panics of fuzz inputs
/// quietly and leaves every other panic to the previous hook.
fn install_hook() {
    HOOK.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if IN_INPUT.with(|f| f.get()) {
                HOOK_PANICS.fetch_add(1, Ordering::Relaxed);
            } else {
                previous(info);
            }
        }));
    });
}

fn peak_rss() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1)?.parse::<u64>().ok())
        })
        .map_or(0, |kib| kib * 1024)
}

fn reset_peak_rss() {
    // Linux: writing 5 resets the peak resident set size.
    if let Ok(mut f) = std::fs::OpenOptions::new()
        .write(true)
        .open("/proc/self/clear_refs")
    {
        let _ = f.write_all(b"5");
    }
}

const INTERESTING: [u32; 12] = [
    0,
    1,
    2,
    3,
    4,
    0x7f,
    0xff,
    0xffff,
    0x7fff_ffff,
    0x8000_0000,
    0xffff_fffe,
    0xffff_ffff,
];

/// The `i`-th input of a target: a seed, mutated 1 to 4 times, fixed up half the time.
pub fn generate(t: &Target, seed: u64, i: u64) -> Vec<u8> {
    let mut rng = fastrand::Rng::with_seed(seed ^ i.wrapping_mul(0x9E37_79B9_7F4A_7C15));
    let mut b = t.seeds[rng.usize(..t.seeds.len())].clone();
    for _ in 0..rng.usize(1..=4) {
        let len = b.len();
        match rng.u8(..9) {
            0 if len > 0 => {
                let p = rng.usize(..len);
                b[p] ^= 1 << rng.u8(..8);
            }
            1 if len > 0 => {
                let p = rng.usize(..len);
                b[p] = rng.u8(..);
            }
            2 if len >= 4 => {
                // An interesting integer over a (likely) header field.
                let span = if rng.bool() { 96 } else { len - 3 };
                let p = rng.usize(..(len - 3).min(span));
                let v = INTERESTING[rng.usize(..INTERESTING.len())];
                b[p..p + 4].copy_from_slice(&v.to_le_bytes());
            }
            3 if len > 0 => b.truncate(rng.usize(..len)),
            4 => {
                let p = rng.usize(..=len);
                let n = rng.usize(1..=16);
                let bytes: Vec<u8> = (0..n).map(|_| rng.u8(..)).collect();
                b.splice(p..p, bytes);
            }
            5 if len > 1 => {
                let p = rng.usize(..len);
                let n = rng.usize(1..=(len - p).min(64));
                b.drain(p..p + n);
            }
            6 if len > 1 => {
                let p = rng.usize(..len);
                let n = rng.usize(1..=(len - p).min(64));
                let chunk = b[p..p + n].to_vec();
                let q = rng.usize(..=len);
                b.splice(q..q, chunk);
            }
            7 => {
                let other = &t.seeds[rng.usize(..t.seeds.len())];
                let cut = rng.usize(..=b.len());
                let from = rng.usize(..=other.len());
                b.truncate(cut);
                b.extend_from_slice(&other[from..]);
            }
            _ if len > 0 => {
                // A text-level mutation: a digit run replaced by a large or odd number.
                let p = rng.usize(..len);
                let n = [
                    "0",
                    "-1",
                    "1e39",
                    "nan",
                    "4294967296",
                    "1e-45",
                    "65536",
                    "\"",
                    "]",
                ][rng.usize(..9)];
                b.splice(p..p, n.bytes());
            }
            _ => {}
        }
    }
    if rng.bool() {
        (t.fixup)(&mut b);
    }
    b
}

/// Runs `inputs` generated inputs through target `t` (in parallel) and reports.
pub fn run_target(t: &Target, inputs: u64, seed: u64, crash_dir: Option<&Path>) -> Report {
    install_hook();
    lightgrid_core::limits::set_memory_limit(FUZZ_MEMORY_LIMIT);
    reset_peak_rss();
    let hook_before = HOOK_PANICS.load(Ordering::Relaxed);
    let accepted = AtomicU64::new(0);
    let rejected = AtomicU64::new(0);
    let escaped = AtomicU64::new(0);
    let slow = AtomicU64::new(0);
    let slowest = Mutex::new(0f64);
    let start = Instant::now();
    (0..inputs).into_par_iter().for_each(|i| {
        let input = generate(t, seed, i);
        let t0 = Instant::now();
        IN_INPUT.with(|f| f.set(true));
        let r = std::panic::catch_unwind(|| (t.run)(&input));
        IN_INPUT.with(|f| f.set(false));
        let dt = t0.elapsed();
        match r {
            Ok(true) => accepted.fetch_add(1, Ordering::Relaxed),
            Ok(false) => rejected.fetch_add(1, Ordering::Relaxed),
            Err(_) => {
                let n = escaped.fetch_add(1, Ordering::Relaxed);
                if let Some(d) = crash_dir
                    && n < 20
                {
                    let _ = std::fs::create_dir_all(d);
                    let _ = std::fs::write(d.join(format!("crash-{}-{i}.bin", t.name)), &input);
                }
                0
            }
        };
        if dt > SLOW {
            let n = slow.fetch_add(1, Ordering::Relaxed);
            if let Some(d) = crash_dir
                && n < 20
            {
                let _ = std::fs::create_dir_all(d);
                let _ = std::fs::write(d.join(format!("slow-{}-{i}.bin", t.name)), &input);
            }
        }
        let ms = dt.as_secs_f64() * 1e3;
        let mut s = slowest.lock().expect("not poisoned");
        if ms > *s {
            *s = ms;
        }
    });
    let escaped = escaped.load(Ordering::Relaxed);
    let hook = HOOK_PANICS.load(Ordering::Relaxed) - hook_before;
    lightgrid_core::limits::set_memory_limit(0);
    Report {
        target: t.name.to_string(),
        inputs,
        accepted: accepted.load(Ordering::Relaxed),
        rejected: rejected.load(Ordering::Relaxed),
        escaped_panics: escaped,
        caught_panics: hook.saturating_sub(escaped),
        slow: slow.load(Ordering::Relaxed),
        slowest_ms: *slowest.lock().expect("not poisoned"),
        seconds: start.elapsed().as_secs_f64(),
        peak_rss: peak_rss(),
    }
}

// ---------------------------------------------------------------- fix-ups

/// Recomputes a trailing CRC-32 over everything before it (grid and volume files).
fn fix_trailing_crc(b: &mut [u8]) {
    if b.len() >= 8 {
        let n = b.len() - 4;
        let crc = crc32fast::hash(&b[..n]);
        b[n..].copy_from_slice(&crc.to_le_bytes());
    }
}

/// Grid files: the payload length field follows the bytes present, then the CRC.
fn fix_grid(b: &mut [u8]) {
    if b.len() >= 68 {
        let payload = (b.len() - 68) as u64;
        b[56..64].copy_from_slice(&payload.to_le_bytes());
    }
    fix_trailing_crc(b);
}

/// GLB: the total length field follows the bytes present; the JSON chunk length too
/// when there is no BIN chunk after it.
fn fix_glb(b: &mut [u8]) {
    if b.len() >= 12 && b.starts_with(b"glTF") {
        let n = b.len() as u32;
        b[8..12].copy_from_slice(&n.to_le_bytes());
    }
}

fn no_fixup(_: &mut [u8]) {}

// ---------------------------------------------------------------- seeds and readers

const VOLUME_KEY: u64 = 0x1234_5678_9abc_def0;

fn grid_seeds() -> Vec<Vec<u8>> {
    let d = GridDesc::new(Vec3::new(-1.0, 0.0, 2.0), 0.5, UVec3::new(3, 2, 2)).expect("valid");
    let m = lightgrid_core::MaterialGrid::filled(
        d,
        Material {
            reflectance: Vec3::splat(0.4),
            pass: 0.7,
        },
    )
    .expect("valid");
    let l = lightgrid_core::LightGrid::filled(d, BinLight::uniform(Vec3::new(1.0, 2.0, 3.0)))
        .expect("valid");
    vec![
        GridFile::Material(m).to_bytes(),
        GridFile::PackedLight(l.pack()).to_bytes(),
        GridFile::Average(l.average_grid()).to_bytes(),
        GridFile::Light(l).to_bytes(),
    ]
}

fn run_grid(b: &[u8]) -> bool {
    match GridFile::from_bytes(b) {
        Ok(GridFile::PackedLight(p)) => {
            // Unpacking must not make NaN or infinity either.
            assert!(p.unpack().data().iter().all(|x| x.is_valid()));
            true
        }
        Ok(_) => true,
        Err(_) => false,
    }
}

fn scene_seeds() -> Vec<Vec<u8>> {
    let tiny = include_str!("../../crates/viewer/tests/data/tiny.toml");
    vec![
        lightgrid_viewer::scene::DEMO.as_bytes().to_vec(),
        tiny.as_bytes().to_vec(),
    ]
}

fn run_scene(b: &[u8]) -> bool {
    let text = String::from_utf8_lossy(b);
    lightgrid_viewer::SceneFile::parse(&text, "fuzz.toml", Path::new("/nonexistent")).is_ok()
}

fn volume_seeds() -> Vec<Vec<u8>> {
    let d = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(3, 3, 2)).expect("valid");
    let mut data = vec![BinLight::ZERO; d.point_count()];
    for (i, b) in data.iter_mut().enumerate() {
        b.0[i % 26] = Vec3::new(1.0 + i as f32, 0.5, 0.25);
    }
    let g = lightgrid_core::LightGrid::new(d, data).expect("valid");
    let empty = lightgrid_core::LightGrid::filled(d, BinLight::ZERO).expect("valid");
    vec![
        lightgrid_light_volumes::CompressedVolume::compress(&g, VOLUME_KEY).to_bytes(),
        lightgrid_light_volumes::CompressedVolume::compress(&empty, VOLUME_KEY).to_bytes(),
    ]
}

fn run_volume(b: &[u8]) -> bool {
    lightgrid_light_volumes::CompressedVolume::from_bytes(b, VOLUME_KEY).is_ok()
}

/// A one-triangle glTF with an embedded buffer and a 1 × 1 PNG texture.
fn triangle_gltf() -> Vec<u8> {
    let mut bin = Vec::new();
    for v in [0f32, 0., 0., 1., 0., 0., 0., 1., 0., 0., 0., 1., 0., 0., 1.] {
        bin.extend_from_slice(&v.to_le_bytes());
    }
    // 36 bytes of positions, then 24 bytes of UVs (the last 24 of 60).
    let mut png = Vec::new();
    image::RgbaImage::from_pixel(1, 1, image::Rgba([200, 100, 50, 255]))
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .expect("encodes");
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],
"nodes":[{{"mesh":0,"translation":[1,2,3]}}],
"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"TEXCOORD_0":1}},"material":0}}]}}],
"materials":[{{"pbrMetallicRoughness":{{"baseColorTexture":{{"index":0}}}},"alphaMode":"MASK"}}],
"textures":[{{"source":0}}],"images":[{{"uri":"data:image/png;base64,{}"}}],
"buffers":[{{"byteLength":60,"uri":"data:application/octet-stream;base64,{}"}}],
"bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":36}},{{"buffer":0,"byteOffset":36,"byteLength":24}}],
"accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}},
{{"bufferView":1,"componentType":5126,"count":3,"type":"VEC2"}}]}}"#,
        base64::encode(&png),
        base64::encode(&bin[..60])
    )
    .into_bytes()
}

/// A fresh folder for writing a seed through a library writer (unique per call).
fn scratch_dir(what: &str) -> std::path::PathBuf {
    static N: AtomicU64 = AtomicU64::new(0);
    std::env::temp_dir().join(format!(
        "xtask-fuzz-{what}-{}-{}",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    ))
}

fn gltf_seeds() -> Vec<Vec<u8>> {
    let dir = scratch_dir("gltf");
    let _ = std::fs::create_dir_all(&dir);
    let path = dir.join("rock.glb");
    let mut seeds = vec![triangle_gltf()];
    // A procedural rock with a texture, written by the library's own GLB writer.
    let mut rock = lightgrid_material_voxelizer::procedural::rock(3, 1.0).expect("valid rock");
    rock.textures
        .push(lightgrid_material_voxelizer::model::Texture {
            width: 2,
            height: 2,
            texels: vec![Vec4::new(0.5, 0.4, 0.3, 1.0); 4],
        });
    rock.materials[0].texture = Some(0);
    if lightgrid_material_voxelizer::procedural::write_glb(&rock, &path).is_ok()
        && let Ok(b) = std::fs::read(&path)
    {
        seeds.push(b);
    }
    let _ = std::fs::remove_dir_all(&dir);
    seeds
}

fn run_gltf(b: &[u8]) -> bool {
    lightgrid_material_voxelizer::model::Model::from_gltf_slice(b, "fuzz.glb").is_ok()
}

fn exr_seeds() -> Vec<Vec<u8>> {
    let dir = scratch_dir("exr");
    let _ = std::fs::create_dir_all(&dir);
    let path = dir.join("sky.exr");
    let map = lightgrid_sky::EnvMap::from_fn(8, 4, |d| Vec3::new(0.2, 0.4, 1.0) * (1.0 + d.y))
        .expect("valid sky");
    map.save_exr(&path).expect("writes");
    let b = std::fs::read(&path).expect("reads");
    let _ = std::fs::remove_dir_all(&dir);
    vec![b]
}

fn run_exr(b: &[u8]) -> bool {
    lightgrid_sky::EnvMap::from_exr_bytes(b).is_ok()
}

fn png_seeds() -> Vec<Vec<u8>> {
    let img = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(5, 4, |x, y| {
        image::Luma([(x * 1000 + y * 300) as u16])
    });
    let mut png = Vec::new();
    image::DynamicImage::ImageLuma16(img)
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .expect("encodes");
    let mut rgba = Vec::new();
    image::RgbaImage::from_pixel(3, 2, image::Rgba([10, 20, 30, 40]))
        .write_to(
            &mut std::io::Cursor::new(&mut rgba),
            image::ImageFormat::Png,
        )
        .expect("encodes");
    vec![png, rgba]
}

fn run_png(b: &[u8]) -> bool {
    lightgrid_material_voxelizer::compose::decode_limited(b, 1 << 16, 8).is_ok()
}

/// Every target.
pub fn targets() -> Vec<Target> {
    vec![
        Target {
            name: "grid",
            seeds: grid_seeds(),
            fixup: fix_grid,
            run: run_grid,
        },
        Target {
            name: "scene",
            seeds: scene_seeds(),
            fixup: no_fixup,
            run: run_scene,
        },
        Target {
            name: "volume",
            seeds: volume_seeds(),
            fixup: fix_trailing_crc,
            run: run_volume,
        },
        Target {
            name: "gltf",
            seeds: gltf_seeds(),
            fixup: fix_glb,
            run: run_gltf,
        },
        Target {
            name: "exr",
            seeds: exr_seeds(),
            fixup: no_fixup,
            run: run_exr,
        },
        Target {
            name: "png",
            seeds: png_seeds(),
            fixup: no_fixup,
            run: run_png,
        },
        Target {
            name: "export",
            seeds: crate::fuzz_api::export_seeds(),
            fixup: fix_grid,
            run: crate::fuzz_api::run_export,
        },
        Target {
            name: "bake",
            seeds: crate::fuzz_api::bake_seeds(),
            fixup: fix_grid,
            run: crate::fuzz_api::run_bake,
        },
        Target {
            name: "api",
            seeds: crate::fuzz_api::api_seeds(),
            fixup: no_fixup,
            run: crate::fuzz_api::run_api,
        },
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_seed_is_accepted() {
        for t in targets() {
            assert!(!t.seeds.is_empty(), "{}", t.name);
            for (i, s) in t.seeds.iter().enumerate() {
                assert!((t.run)(s), "{} seed {i} rejected", t.name);
            }
        }
    }

    #[test]
    fn generation_is_deterministic_and_mutates() {
        let t = &targets()[0];
        let a: Vec<Vec<u8>> = (0..50).map(|i| generate(t, 7, i)).collect();
        let b: Vec<Vec<u8>> = (0..50).map(|i| generate(t, 7, i)).collect();
        assert_eq!(a, b);
        assert!(a.iter().filter(|x| !t.seeds.contains(x)).count() > 40);
    }
}
