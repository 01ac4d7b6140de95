//! Light volumes: known answers for tracing, linearity in albedo, determinism, the
//! compressed cache (error bound, corruption, staleness) and the light set's toggles.

use lightgrid_core::glam::{UVec3, Vec2, Vec3, Vec4};
use lightgrid_core::{GridDesc, LightField, LightGrid, NUM_DIRS, SumField, dirs};
use lightgrid_light_volumes::{
    CacheOutcome, CompressedVolume, Light, LightKind, LightSet, TraceParams, load_or_make,
    trace_light,
};
use lightgrid_material_voxelizer::model::{Model, SurfaceMaterial, Triangle};
use lightgrid_material_voxelizer::voxelize::RayScene;
use obvhs::BvhBuildParams;

fn quad(y: f32, half: f32, albedo: f32) -> Model {
    let p = |x: f32, z: f32| Vec3::new(x, y, z);
    let tri = |a, b, c| Triangle {
        positions: [a, b, c],
        uvs: [Vec2::ZERO; 3],
        material: 0,
        part: 0,
    };
    Model {
        triangles: vec![
            tri(p(-half, -half), p(half, -half), p(half, half)),
            tri(p(-half, -half), p(half, half), p(-half, half)),
        ],
        materials: vec![SurfaceMaterial {
            base_colour: Vec4::new(albedo, albedo, albedo, 1.0),
            ..Default::default()
        }],
        textures: Vec::new(),
    }
}

fn point(p: Vec3) -> Light {
    Light {
        kind: LightKind::Point { position: p },
        colour: Vec3::ONE,
        intensity: 1.0,
    }
}

fn params(rays: u64) -> TraceParams {
    TraceParams {
        rays,
        ..TraceParams::preview()
    }
}

#[test]
fn point_light_in_empty_space_follows_the_inverse_square_law() {
    // A floor far below the grid: nothing in the grid is hit.
    let model = quad(-100.0, 1.0, 0.5);
    let scene = RayScene::new(&model, BvhBuildParams::fast_build());
    let desc = GridDesc::new(Vec3::splat(-5.0), 0.5, UVec3::splat(21)).unwrap();
    let (g, stats) = trace_light(
        &scene,
        &desc,
        &point(Vec3::ZERO),
        &params(400_000),
        &|_, _| {},
    )
    .unwrap();
    assert_eq!(stats.hits, 0);
    // Fluence of a unit-power isotropic source: 1 / (4π r²); the mean over a shell of
    // cells 2.5–4.5 m away, times 4π r², is 1.
    let (mut sum, mut n) = (0.0, 0);
    for (i, b) in g.data().iter().enumerate() {
        let p = desc.position(desc.coords(i).unwrap());
        let r = p.length();
        if (2.5..4.5).contains(&r) {
            sum += b.total().x as f64 * 4.0 * std::f64::consts::PI * (r * r) as f64;
            n += 1;
            // All of it travels away from the light: in bins within 45° of the direction
            // from the light to the cell (the cell spans ±6°; a bin up to 35°).
            let u = p.normalize();
            let near: f32 = (0..NUM_DIRS)
                .filter(|&d| dirs::dir_unit(d).dot(u) >= std::f32::consts::FRAC_1_SQRT_2)
                .map(|d| b.0[d].x)
                .sum();
            assert!(near >= 0.999 * b.total().x, "cell {p}");
        }
    }
    let mean = sum / n as f64;
    assert!((mean - 1.0).abs() < 0.02, "{mean} over {n} cells");
}

#[test]
fn reflected_light_is_linear_in_albedo_and_deterministic_on_any_thread_count() {
    let desc = GridDesc::new(Vec3::new(-2.0, -0.25, -2.0), 0.25, UVec3::new(17, 12, 17)).unwrap();
    let light = point(Vec3::new(0.0, 2.0, 0.0));
    let run = |albedo: f32, threads: usize| -> LightGrid {
        let model = quad(0.0, 3.0, albedo);
        let scene = RayScene::new(&model, BvhBuildParams::fast_build());
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| trace_light(&scene, &desc, &light, &params(60_000), &|_, _| {}))
            .unwrap()
            .0
    };
    let a = run(0.4, 2);
    let b = run(0.8, 2);
    assert_eq!(a, run(0.4, 1), "the same volume on one thread");
    assert_eq!(a, run(0.4, 3), "the same volume on three threads");
    // Below the light, upward-travelling light exists only by reflection off the floor
    // (one bounce): twice the albedo, twice the light, ray for ray.
    let up = |g: &LightGrid| -> f64 {
        g.data()
            .iter()
            .enumerate()
            .filter(|(i, _)| desc.position(desc.coords(*i).unwrap()).y < 1.5)
            .map(|(_, x)| {
                (0..NUM_DIRS)
                    .filter(|&d| dirs::dir_ivec(d).y > 0)
                    .map(|d| x.0[d].x as f64)
                    .sum::<f64>()
            })
            .sum()
    };
    let (ua, ub) = (up(&a), up(&b));
    assert!(ua > 0.0);
    assert!((ub / ua - 2.0).abs() < 1e-4, "{ub} / {ua}");
    // Downward light (straight from the source) does not depend on the floor.
    let down = |g: &LightGrid| -> f64 { g.data().iter().map(|x| x.0[dirs::DOWN].x as f64).sum() };
    assert!((down(&a) - down(&b)).abs() <= 1e-9 * down(&a));
}

#[test]
fn compression_bounds_the_error_and_the_cache_rejects_corrupt_and_stale_files() {
    let model = quad(0.0, 3.0, 0.6);
    let scene = RayScene::new(&model, BvhBuildParams::fast_build());
    let desc = GridDesc::new(Vec3::new(-4.0, -0.25, -4.0), 0.25, UVec3::new(33, 20, 33)).unwrap();
    let light = Light {
        kind: LightKind::Spot {
            position: Vec3::new(0.0, 1.5, 0.0),
            direction: Vec3::NEG_Y,
            inner: 0.3,
            outer: 0.6,
        },
        colour: Vec3::ONE,
        intensity: 1.0,
    };
    let p = params(50_000);
    let (g, _) = trace_light(&scene, &desc, &light, &p, &|_, _| {}).unwrap();
    let key = lightgrid_light_volumes::volume_key(&light, &model, &desc, &p);
    let c = CompressedVolume::compress(&g, key);
    let cd = c.desc.unwrap();
    assert!(
        cd.point_count() < desc.point_count(),
        "the spot's box is smaller than the grid"
    );
    let full_bytes = desc.point_count() * NUM_DIRS * 12;
    assert!(
        c.file_bytes() * 4 < full_bytes,
        "{} vs {full_bytes}",
        c.file_bytes()
    );
    // Inside the box: within half a code of the square-root curve; outside: below the
    // threshold.
    let back = c.decode().unwrap();
    let max = g.max_value();
    for (i, b) in g.data().iter().enumerate() {
        let pt = desc.coords(i).unwrap();
        let pos = desc.position(pt);
        let inside = cd.contains(pos);
        for d in 0..NUM_DIRS {
            let v = b.0[d].max_element();
            if inside {
                let q = back.sample(pos).unwrap().0[d];
                for c in 0..3 {
                    let v = b.0[d][c];
                    let s = (v / max).sqrt();
                    let bound = max * (s / 255.0 + (0.5f32 / 255.0).powi(2)) + 1e-6 * max;
                    assert!((q[c] - v).abs() <= bound, "{} vs {v}", q[c]);
                }
            } else {
                assert!(
                    v <= max * lightgrid_light_volumes::THRESHOLD,
                    "{v} outside the box"
                );
            }
        }
    }
    // The cache: written when missing, read when valid, replaced when corrupt or stale.
    let dir = std::env::temp_dir().join(format!("light-volumes-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("spot.lgvol");
    let make = || Ok(CompressedVolume::compress(&g, key));
    let (v1, o1) = load_or_make(&path, key, make).unwrap();
    assert_eq!(o1, CacheOutcome::Missing);
    let (v2, o2) = load_or_make(&path, key, make).unwrap();
    assert_eq!((o2, &v2), (CacheOutcome::Hit, &v1));
    let mut bytes = std::fs::read(&path).unwrap();
    let mid = bytes.len() / 2;
    bytes[mid] ^= 0x40;
    std::fs::write(&path, &bytes).unwrap();
    let err = CompressedVolume::load(&path, key).unwrap_err();
    assert!(err.to_string().contains("checksum"), "{err}");
    let (_, o3) = load_or_make(&path, key, make).unwrap();
    assert_eq!(o3, CacheOutcome::Replaced);
    let err = CompressedVolume::load(&path, key ^ 1).unwrap_err();
    assert!(err.to_string().contains("stale"), "{err}");
    // A moved light is another key.
    let mut moved = light;
    moved.kind = LightKind::Point {
        position: Vec3::ONE,
    };
    assert_ne!(
        key,
        lightgrid_light_volumes::volume_key(&moved, &model, &desc, &p)
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn light_set_toggles_touch_only_the_light_box_and_restore_the_grid() {
    let model = quad(0.0, 4.0, 0.7);
    let scene = RayScene::new(&model, BvhBuildParams::fast_build());
    let desc = GridDesc::new(Vec3::new(-4.0, -0.25, -4.0), 0.25, UVec3::new(33, 16, 33)).unwrap();
    let p = params(20_000);
    let lights: Vec<Light> = [
        Vec3::new(-2.5, 1.0, -2.5),
        Vec3::new(2.5, 1.0, 2.5),
        Vec3::new(0.0, 2.0, 0.0),
    ]
    .iter()
    .map(|&pos| Light {
        kind: LightKind::Spot {
            position: pos,
            direction: Vec3::NEG_Y,
            inner: 0.2,
            outer: 0.4,
        },
        colour: Vec3::ONE,
        intensity: 1.0,
    })
    .collect();
    let volumes: Vec<CompressedVolume> = lights
        .iter()
        .map(|l| {
            let (g, _) = trace_light(&scene, &desc, l, &p, &|_, _| {}).unwrap();
            CompressedVolume::compress(&g, 0)
        })
        .collect();
    let mut set = LightSet::new(desc).unwrap();
    let ids: Vec<_> = volumes
        .iter()
        .enumerate()
        .map(|(i, v)| {
            set.add(v, Vec3::new(1.0, 0.5 + 0.2 * i as f32, 0.3), 2.0)
                .unwrap()
        })
        .collect();
    let all_on = set.grid().clone();
    set.take_dirty();
    // Toggling one light changes only its box, and marks exactly that box dirty.
    set.set_on(ids[0], false).unwrap();
    let r = set.take_dirty().unwrap();
    let b0 = volumes[0].desc.unwrap();
    assert_eq!(r.point_count(), b0.point_count());
    for (i, (x, y)) in set.grid().data().iter().zip(all_on.data()).enumerate() {
        let pos = desc.position(desc.coords(i).unwrap());
        if !b0.contains(pos) {
            assert_eq!(x, y, "outside the box nothing changes");
        }
    }
    // Many changes, then back: the grid is restored within float tolerance.
    for k in 0..50 {
        let id = ids[k % 3];
        set.set_on(id, k % 2 == 0).unwrap();
        set.set_colour(id, Vec3::new(0.1 * k as f32, 1.0, 2.0), 0.5 + k as f32)
            .unwrap();
    }
    for (i, id) in ids.iter().enumerate() {
        set.set_colour(*id, Vec3::new(1.0, 0.5 + 0.2 * i as f32, 0.3), 2.0)
            .unwrap();
        set.set_on(*id, true).unwrap();
    }
    let max = all_on.max_value();
    for (x, y) in set.grid().data().iter().zip(all_on.data()) {
        for d in 0..NUM_DIRS {
            assert!((x.0[d] - y.0[d]).abs().max_element() <= 1e-4 * max);
        }
    }
    // All off: zero everywhere (negative rounding is clamped away).
    for id in &ids {
        set.set_on(*id, false).unwrap();
    }
    assert!(
        set.grid()
            .data()
            .iter()
            .all(|b| b.0.iter().all(|v| v.max_element() <= 1e-4 * max))
    );
    // The local lights add to another field.
    set.set_on(ids[2], true).unwrap();
    let sky =
        LightGrid::filled(desc, lightgrid_core::BinLight::uniform(Vec3::splat(0.25))).unwrap();
    let q = Vec3::new(0.0, 1.0, 0.0);
    let sum = SumField(&set, &sky).average(q).unwrap();
    let parts = set.average(q).unwrap() + sky.average(q).unwrap();
    assert!((sum - parts).abs().max_element() < 1e-6);
    // Bad input is a typed error.
    assert!(
        set.set_colour(ids[0], Vec3::NAN, 1.0)
            .unwrap_err()
            .to_string()
            .contains("colour")
    );
}
