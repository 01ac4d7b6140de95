//! `viewer`: renders the lightgrid demo scene (or `--scene file.toml`) headless into
//! `out/`, or opens an interactive window with `--window`. See the crate docs.

use std::path::PathBuf;

use anyhow::Result;
use clap::Parser;
use lightgrid_viewer::{Options, SceneFile, SweeperChoice};

/// Render a scene lit by lightgrid's volumetric light grids.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Args {
    /// Scene file (TOML); the embedded demo scene when omitted (see scenes/demo.toml).
    #[arg(long)]
    scene: Option<PathBuf>,
    /// Output folder for images and the summary.
    #[arg(long, default_value = "out")]
    out: PathBuf,
    /// Which sweeper computes the grids.
    #[arg(long, value_enum, default_value_t = SweeperChoice::Auto)]
    sweeper: SweeperChoice,
    /// Image width in pixels.
    #[arg(long, default_value_t = 960)]
    width: u32,
    /// Render only this view of the scene file (repeatable).
    #[arg(long = "view")]
    views: Vec<String>,
    /// Image height in pixels.
    #[arg(long, default_value_t = 540)]
    height: u32,
    /// Also write each view's indirect light as Bevy irradiance volumes (DDS, KTX2 and a
    /// JSON sidecar) into `<out>/bevy/`.
    #[arg(long)]
    bevy: bool,
    /// Open an interactive window instead of writing images.
    #[arg(long)]
    window: bool,
    /// With --window: fly forward on autopilot and quit after this many frames.
    #[arg(long, requires = "window")]
    frames: Option<u32>,
    /// Most memory one job may allocate (bytes, or with K/M/G/T); default: the
    /// LIGHTGRID_MEMORY_LIMIT environment variable, else half the machine's memory.
    #[arg(long, value_parser = lightgrid_core::limits::parse_size_arg)]
    memory_limit: Option<u64>,
}

/// glibc's malloc hands large freed blocks back to the kernel (unmapped, or trimmed
/// off the heap's top), and the next view's buffers of the same sizes (readback copies,
/// the 51 MB light volume, node grids) are then faulted in and zeroed again. The viewer
/// keeps them: blocks up to 32 MB come from the heap, which is not trimmed. The demo
/// 4.13 → 3.95 s, its kernel time 1.0 → 0.66 s (medians of three interleaved runs,
/// 2026-12-03; the mmap threshold alone, which stops glibc raising its trim threshold,
/// made it 4.6 s). Elsewhere, and with other allocators, nothing changes.
fn keep_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    #[allow(unsafe_code)]
    // SAFETY: `mallopt` only sets the allocator's parameters; it is called first in
    // `main`, before any other thread exists.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 32 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, libc::c_int::MAX);
        libc::mallopt(libc::M_TOP_PAD, 64 << 20);
    }
}

fn main() -> Result<()> {
    keep_freed_memory();
    let args = Args::parse();
    lightgrid_viewer::init_logs();
    if let Some(limit) = args.memory_limit {
        lightgrid_core::limits::set_memory_limit(limit);
    }
    for (name, v) in [("--width", args.width), ("--height", args.height)] {
        if !(1..=lightgrid_viewer::MAX_IMAGE_SIDE).contains(&v) {
            anyhow::bail!(
                "{name} {v}: must be in 1..={}",
                lightgrid_viewer::MAX_IMAGE_SIDE
            );
        }
    }
    let mut scene = match &args.scene {
        Some(p) => SceneFile::load(p)?,
        None => SceneFile::demo()?,
    };
    if !args.views.is_empty() {
        if let Some(bad) = args
            .views
            .iter()
            .find(|v| !scene.views.iter().any(|s| &s.name == *v))
        {
            let names: Vec<&str> = scene.views.iter().map(|v| v.name.as_str()).collect();
            anyhow::bail!("--view {bad}: the scene has no such view (it has {names:?})");
        }
        scene.views.retain(|v| args.views.contains(&v.name));
    }
    if args.window {
        let summary = lightgrid_viewer::window::run(
            scene,
            args.sweeper,
            args.width,
            args.height,
            args.frames,
        )?;
        println!("{summary}");
        return Ok(());
    }
    let summary = lightgrid_viewer::run(
        scene,
        &Options {
            out: args.out.clone(),
            width: args.width,
            height: args.height,
            sweeper: args.sweeper,
            exr: true,
            bevy: args.bevy,
        },
    )?;
    print!("{}", summary.text());
    Ok(())
}
