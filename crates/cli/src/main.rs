//! `lightgrid`: one command for the library's file-level work.
//!
//! ```text
//! lightgrid scene canopy --size 32 -o canopy.lgrid
//! lightgrid sweep canopy.lgrid -o light.lgrid --sky daylight --sun-from-sky --sun-elevation 40
//! lightgrid reference canopy.lgrid -o ref.lgrid --paths 2000000
//! lightgrid voxelize tree.glb --cell 0.05 -o tree.lgrid
//! lightgrid inspect light.lgrid
//! lightgrid bake canopy.lgrid -o bevy/ --sky daylight --sun-from-sky --sun-elevation 40
//! lightgrid export light.lgrid -o bevy/
//! lightgrid bake world.toml -o bevy/                      # a whole world, task by task
//! lightgrid bake world.toml -o bevy/ --plan plan.json     # its task graph, for a cluster
//! lightgrid bake world.toml -o bevy/ --task node-1-0-0    # one task of it
//! ```
//!
//! `bake` sweeps a material grid and writes a Bevy irradiance volume of the indirect
//! light (sky and scattered sun; Bevy's `DirectionalLight` adds the direct sun; faces
//! read across the horizon from the sweep's horizon halves), `export` writes one from a
//! light grid file as it is (with `--horizon`, the halves `sweep --horizon` wrote). Both write `<name>.dds`, `<name>.ktx2`
//! and `<name>.json` (see `lightgrid_export`).

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};

mod bake;
mod paths;
mod sweep;
mod voxelize;
mod world;

#[derive(Parser)]
#[command(
    name = "lightgrid",
    version,
    about = "Light grids: scenes, sweeps, the Monte Carlo reference, voxelizing, inspecting, baking for Bevy"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// Most memory one job may allocate (bytes, or with K/M/G/T); default: the
    /// LIGHTGRID_MEMORY_LIMIT environment variable, else half the machine's memory.
    #[arg(long, global = true, value_parser = lightgrid_core::limits::parse_size_arg)]
    memory_limit: Option<u64>,
}

#[derive(Subcommand)]
enum Command {
    #[command(flatten)]
    Sweep(sweep::Command),
    /// A glTF model's material grid (reflectance and pass-through per cell).
    Voxelize(voxelize::Args),
    /// Print the header of a grid file and a summary of its values.
    Inspect {
        /// The grid file.
        path: PathBuf,
    },
    /// Sweep a material grid and write a Bevy irradiance volume (DDS, KTX2, JSON).
    Bake(bake::BakeArgs),
    /// Write a light grid file as a Bevy irradiance volume (DDS, KTX2, JSON).
    Export(bake::ExportArgs),
}

fn main() -> Result<()> {
    let cli = Cli::parse();
    // The libraries' logs to stderr: RUST_LOG sets the levels (`debug`, or per crate as
    // `lightgrid_sweep_cpu=trace,info`), `info` without it.
    {
        use tracing_subscriber::{filter::Targets, layer::SubscriberExt, util::SubscriberInitExt};
        let level = Targets::new().with_default(tracing::Level::INFO);
        let env = std::env::var("RUST_LOG").ok().and_then(|s| s.parse().ok());
        let layer = tracing_subscriber::fmt::layer().with_writer(std::io::stderr);
        tracing_subscriber::registry()
            .with(layer)
            .with(env.unwrap_or(level))
            .init();
    }
    if let Some(limit) = cli.memory_limit {
        lightgrid_core::limits::set_memory_limit(limit);
    }
    match cli.command {
        Command::Sweep(c) => sweep::run(c),
        Command::Voxelize(a) => voxelize::run(a),
        Command::Inspect { path } => {
            let f = lightgrid_core::GridFile::load(&path)
                .with_context(|| format!("reading {}", path.display()))?;
            print!("{}", f.describe());
            Ok(())
        }
        Command::Bake(a) => bake::bake(a),
        Command::Export(a) => bake::export(a),
    }
}
