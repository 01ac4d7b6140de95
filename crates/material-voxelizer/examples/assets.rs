//! Writes the procedural demo assets as glTF and their material grids.
//!
//! `cargo run --release -p lightgrid-material-voxelizer --example assets -- [out-dir]`

use lightgrid_material_voxelizer::procedural::{TreeParams, bush, rock, tree, write_glb};
use lightgrid_material_voxelizer::voxelize::{VoxelizeParams, voxelize};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::path::PathBuf::from(
        std::env::args()
            .nth(1)
            .unwrap_or_else(|| "out/assets".into()),
    );
    std::fs::create_dir_all(&out)?;
    let assets = [
        ("tree-broadleaf", tree(&TreeParams::broadleaf(1))?, 0.5),
        ("tree-young", tree(&TreeParams::young(2))?, 0.25),
        ("bush", bush(3, 0.8)?, 0.25),
        ("rock", rock(4, 1.2)?, 0.25),
    ];
    for (name, model, cell) in assets {
        let glb = out.join(format!("{name}.glb"));
        write_glb(&model, &glb)?;
        let (grid, stats) = voxelize(&model, &VoxelizeParams::standard(cell), &|_, _| {})?;
        lightgrid_core::GridFile::Material(grid).save(out.join(format!("{name}.lgrid")))?;
        println!(
            "{name}: {} triangles -> {} ({} cells of {cell} m, {} with material, {} rays in {:.0} ms)",
            model.triangles.len(),
            glb.display(),
            stats.cells,
            stats.cells_filled,
            stats.rays,
            stats.time.as_secs_f64() * 1e3
        );
    }
    Ok(())
}
