//! Ray casts in the town's BVH (alone and with deposits) and toggling one light of 100.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use lightgrid_core::GridDesc;
use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_light_volumes::{
    CompressedVolume, Light, LightKind, LightSet, TraceParams, demo, trace_light,
};
use lightgrid_material_voxelizer::voxelize::RayScene;

fn bench(c: &mut Criterion) {
    let model = demo::town(&demo::assets_dir()).expect("shipped models");
    let scene = RayScene::new(&model, obvhs::BvhBuildParams::medium_build());
    let desc =
        GridDesc::new(Vec3::new(-24.0, -0.5, -24.0), 1.0, UVec3::new(49, 17, 49)).expect("valid");
    let mut g = c.benchmark_group("light-volumes");
    g.sample_size(10);
    let n = 20_000u64;
    g.throughput(Throughput::Elements(n));
    g.bench_function("closest_hit, 20k rays from a lamp", |b| {
        b.iter(|| {
            let mut hits = 0;
            for i in 0..n {
                let a = i as f32 * 2.399_963;
                let z = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
                let r = (1.0 - z * z).sqrt();
                let d = Vec3::new(r * a.cos(), z, r * a.sin());
                hits += scene
                    .closest_hit(Vec3::new(0.0, 3.0, 0.0), d, 100.0, 0.5)
                    .is_some() as u32;
            }
            hits
        })
    });
    let lamp = Light {
        kind: LightKind::Point {
            position: Vec3::new(0.0, 3.0, 0.0),
        },
        colour: Vec3::ONE,
        intensity: 1.0,
    };
    let p = TraceParams {
        rays: n,
        ..TraceParams::standard()
    };
    g.bench_function("trace_light with deposits, 20k rays", |b| {
        b.iter(|| trace_light(&scene, &desc, &lamp, &p, &|_, _| {}).expect("trace"))
    });
    g.throughput(Throughput::Elements(1));
    let mut set = LightSet::new(desc).expect("valid");
    let small = TraceParams {
        rays: 2_000,
        ..TraceParams::preview()
    };
    let ids: Vec<_> = (0..100)
        .map(|k| {
            let l = Light {
                kind: LightKind::Point {
                    position: Vec3::new(
                        -18.0 + 4.0 * (k % 10) as f32,
                        2.5,
                        -18.0 + 4.0 * (k / 10) as f32,
                    ),
                },
                colour: Vec3::ONE,
                intensity: 1.0,
            };
            let (v, _) = trace_light(&scene, &desc, &l, &small, &|_, _| {}).expect("trace");
            set.add(&CompressedVolume::compress(&v, 0), l.colour, 1.0)
                .expect("add")
        })
        .collect();
    let mut on = false;
    g.bench_function("toggle one of 100 lights", |b| {
        b.iter(|| {
            on = !on;
            set.set_on(ids[37], on).expect("toggle")
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
