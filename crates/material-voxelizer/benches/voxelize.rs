//! Voxelization of the shipped models, and area composition with a forest of instances.

use std::path::Path;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use lightgrid_core::GridDesc;
use lightgrid_core::glam::{Quat, UVec3, Vec2, Vec3};
use lightgrid_material_voxelizer::compose::{
    AreaComposer, ComposeParams, GroundColour, Heightmap, Instance, Terrain,
};
use lightgrid_material_voxelizer::model::Model;
use lightgrid_material_voxelizer::voxelize::{VoxelizeParams, voxelize};

fn models() -> Vec<(String, Model)> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/kenney-city-builder");
    [
        "grass-trees.glb",
        "grass-trees-tall.glb",
        "building-small-c.glb",
    ]
    .iter()
    .map(|n| {
        (
            n.to_string(),
            Model::load_gltf(dir.join(n)).expect("shipped model"),
        )
    })
    .collect()
}

fn bench_voxelize(c: &mut Criterion) {
    let mut g = c.benchmark_group("voxelize");
    g.sample_size(10);
    for (name, model) in models() {
        // The Kenney tiles are 1 m wide: 0.25 m cells give 4 cells across, as a 4 m tree
        // at 1 m cells. Throughput counts chords (rays) cast.
        for cell in [0.25f32, 0.05] {
            let p = VoxelizeParams::standard(cell);
            let (_, stats) = voxelize(&model, &p, &|_, _| {}).expect("voxelize");
            g.throughput(Throughput::Elements(stats.rays));
            g.bench_function(format!("{name} {cell} m ({} cells)", stats.cells), |b| {
                b.iter(|| voxelize(&model, &p, &|_, _| {}).expect("voxelize"))
            });
        }
    }
    g.finish();
}

fn forest(n: usize, spread: f32, offset: Vec3) -> Vec<Instance> {
    let mut r = lightgrid_core::SeededRng::new(0x2545_f491_4f6c_dd1d);
    let mut rng = move || r.f32();
    (0..n)
        .map(|_| Instance {
            model: 0,
            position: offset + Vec3::new(rng() * spread, 0.0, rng() * spread),
            rotation: Quat::from_rotation_y(rng() * std::f32::consts::TAU),
            scale: 4.0 + rng() * 2.0,
        })
        .collect()
}

fn bench_compose(c: &mut Criterion) {
    let (_, trees) = models().remove(0);
    let (tree_grid, _) =
        voxelize(&trees, &VoxelizeParams::standard(0.05), &|_, _| {}).expect("voxelize");
    let terrain = Terrain {
        heightmap: Heightmap::from_fn(Vec2::splat(-64.0), 1.0, 256, 256, |x, z| {
            2.0 * (x * 0.05).sin() + 1.5 * (z * 0.07).cos()
        })
        .expect("heightmap"),
        colour: GroundColour::Uniform(Vec3::new(0.3, 0.25, 0.2)),
    };
    let area = GridDesc::new(Vec3::new(0.0, -4.0, 0.0), 1.0, UVec3::new(32, 64, 32)).expect("area");
    let mut g = c.benchmark_group("compose 32x32x64 at 1 m");
    g.sample_size(10);
    g.throughput(Throughput::Elements(area.point_count() as u64));
    let near = forest(60, 32.0, Vec3::ZERO);
    for far_count in [100usize, 100_000] {
        let mut inst = near.clone();
        inst.extend(forest(far_count, 2000.0, Vec3::splat(500.0)));
        let comp = AreaComposer::new(
            vec![tree_grid.clone()],
            &inst,
            Some(terrain.clone()),
            ComposeParams::default(),
        )
        .expect("composer");
        g.bench_function(format!("forest of 60 + {far_count} far instances"), |b| {
            b.iter(|| comp.compose(&area).expect("compose"))
        });
    }
    g.finish();
}

criterion_group!(benches, bench_voxelize, bench_compose);
criterion_main!(benches);
