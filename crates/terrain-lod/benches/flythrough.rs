//! Time of a short fly-through (8 frames from a cold hierarchy) over the shipped DEM with
//! a procedural forest, for node grids of 16 and 32 points.

use criterion::{Criterion, criterion_group, criterion_main};
use lightgrid_core::BinLight;
use lightgrid_core::glam::{Vec2, Vec3};
use lightgrid_material_voxelizer::compose::{AreaComposer, ComposeParams, GroundColour, Terrain};
use lightgrid_material_voxelizer::procedural::{TreeParams, tree};
use lightgrid_material_voxelizer::voxelize::{VoxelizeParams, voxelize};
use lightgrid_sweep_cpu::CpuSweeper;
use lightgrid_terrain_lod::{Hierarchy, HierarchyParams};

#[path = "../tests/demo/mod.rs"]
mod demo;

fn bench(c: &mut Criterion) {
    let hm = demo::jacksboro(&demo::assets_dir()).expect("dem");
    let (tree_grid, _) = voxelize(
        &tree(&TreeParams::young(3)).expect("tree"),
        &VoxelizeParams::preview(0.5),
        &|_, _| {},
    )
    .expect("voxelize");
    let instances = demo::scatter_forest(&hm, 2000, Vec2::splat(450.0), 400.0, (2.0, 2.0), 7);
    let terrain = Terrain {
        heightmap: hm.clone(),
        colour: GroundColour::Uniform(Vec3::splat(0.25)),
    };
    let (sky, _) = BinLight::uniform(Vec3::ONE).split_vertical();
    let mut g = c.benchmark_group("flythrough 8 frames");
    g.sample_size(10);
    for node_points in [16u32, 32] {
        g.bench_function(format!("{node_points} points a node"), |b| {
            b.iter(|| {
                let composer = AreaComposer::new(
                    vec![tree_grid.clone()],
                    &instances,
                    Some(terrain.clone()),
                    ComposeParams::default(),
                )
                .expect("composer");
                let params = HierarchyParams {
                    node_points,
                    finest_cell: 2.0,
                    budget_points: node_points as u64 * node_points as u64 * 48 * 2,
                    // As the flythrough example: no apron.
                    apron: 0,
                    ..Default::default()
                };
                let mut h = Hierarchy::new(
                    &hm,
                    Box::new(composer),
                    Box::new(CpuSweeper::new()),
                    sky,
                    params,
                )
                .expect("hierarchy");
                for f in 0..8 {
                    let (x, z) = (500.0 + 10.0 * f as f32, 520.0 + 8.0 * f as f32);
                    h.update(Vec3::new(x, hm.height_at(x, z) + 20.0, z))
                        .expect("frame");
                }
            })
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
