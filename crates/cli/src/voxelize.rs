//! `lightgrid voxelize <model.glb|.gltf> --cell <metres> -o <file>`: a model's material
//! grid.

use std::path::PathBuf;

use anyhow::{Context, Result};
use lightgrid_core::GridFile;
use lightgrid_material_voxelizer::model::Model;
use lightgrid_material_voxelizer::voxelize::{VoxelizeParams, voxelize};

#[derive(clap::Args)]
pub(crate) struct Args {
    /// The model: .glb, or .gltf with embedded or external buffers.
    model: PathBuf,
    /// Cell size in metres.
    #[arg(long)]
    cell: f32,
    /// Output material grid file.
    #[arg(short, long)]
    output: PathBuf,
    /// Quality: preview (64 chords a cell), standard (256) or fine (1024).
    #[arg(long, default_value = "standard")]
    quality: String,
    /// Empty cells around the model on every side.
    #[arg(long, default_value_t = 0)]
    padding: u32,
    /// Leave closed meshes hollow.
    #[arg(long)]
    hollow: bool,
}

/// Runs `voxelize`.
pub(crate) fn run(cli: Args) -> Result<()> {
    crate::paths::check(&[&cli.model], &[&cli.output])?;
    let model =
        Model::load_gltf(&cli.model).with_context(|| format!("loading {}", cli.model.display()))?;
    let mut params = match cli.quality.as_str() {
        "preview" => VoxelizeParams::preview(cli.cell),
        "standard" => VoxelizeParams::standard(cli.cell),
        "fine" => VoxelizeParams::fine(cli.cell),
        q => anyhow::bail!("--quality must be preview, standard or fine, got `{q}`"),
    };
    params.padding = cli.padding;
    params.fill_closed = !cli.hollow;
    let bar = indicatif::ProgressBar::new(1);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{elapsed_precise} [{bar:40}] {pos}/{len} rows")
            .expect("valid template"),
    );
    let (grid, stats) = voxelize(&model, &params, &|done, total| {
        bar.set_length(total);
        bar.set_position(done);
    })
    .context("voxelizing")?;
    bar.finish_and_clear();
    let dims = grid.desc().dims();
    GridFile::Material(grid)
        .save(&cli.output)
        .with_context(|| format!("writing {}", cli.output.display()))?;
    println!(
        "{}: {} triangles ({} in closed meshes) -> {}x{}x{} cells of {} m; {} with material ({:.1} %), {} traced, {} rays in {:.2} s (BVH {:.1} ms, {:.2} M rays/s)",
        cli.model.display(),
        model.triangles.len(),
        stats.closed_triangles,
        dims.x,
        dims.y,
        dims.z,
        cli.cell,
        stats.cells_filled,
        100.0 * stats.cells_filled as f64 / stats.cells as f64,
        stats.cells_traced,
        stats.rays,
        stats.time.as_secs_f64(),
        stats.bvh_time.as_secs_f64() * 1e3,
        stats.rays as f64 / stats.time.as_secs_f64() / 1e6
    );
    println!("wrote {}", cli.output.display());
    Ok(())
}
