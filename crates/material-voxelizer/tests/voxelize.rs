//! The voxelizer against known answers and brute force.

use lightgrid_core::glam::{UVec3, Vec2, Vec3, Vec4};
use lightgrid_material_voxelizer::model::{AlphaMode, Model, SurfaceMaterial, Texture, Triangle};
use lightgrid_material_voxelizer::voxelize::{RayScene, VoxelizeParams, voxelize};
use obvhs::BvhBuildParams;
use proptest::prelude::*;

fn material(c: Vec3) -> SurfaceMaterial {
    SurfaceMaterial {
        base_colour: c.extend(1.0),
        ..Default::default()
    }
}

fn tri(p: [Vec3; 3], material: u32) -> Triangle {
    Triangle {
        positions: p,
        uvs: [Vec2::ZERO, Vec2::X, Vec2::Y],
        material,
        part: 0,
    }
}

/// A closed axis-aligned box (12 triangles).
fn cuboid(lo: Vec3, hi: Vec3, material: u32) -> Vec<Triangle> {
    let c = |i: u32| {
        Vec3::new(
            if i & 1 != 0 { hi.x } else { lo.x },
            if i & 2 != 0 { hi.y } else { lo.y },
            if i & 4 != 0 { hi.z } else { lo.z },
        )
    };
    let quads = [
        [0, 4, 6, 2],
        [1, 3, 7, 5],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 2, 3, 1],
        [4, 5, 7, 6],
    ];
    quads
        .iter()
        .flat_map(|q| {
            [
                tri([c(q[0]), c(q[1]), c(q[2])], material),
                tri([c(q[0]), c(q[2]), c(q[3])], material),
            ]
        })
        .collect()
}

fn params(cell: f32) -> VoxelizeParams {
    let mut p = VoxelizeParams::standard(cell);
    p.padding = 1;
    p
}

#[test]
fn closed_cube_is_solid_inside_clear_outside_and_graded_between() {
    let colour = Vec3::new(0.6, 0.3, 0.1);
    let model = Model {
        triangles: cuboid(Vec3::splat(-0.9), Vec3::splat(0.9), 0),
        materials: vec![material(colour)],
        textures: vec![],
    };
    let (g, stats) = voxelize(&model, &params(0.5), &|_, _| {}).unwrap();
    assert_eq!(stats.closed_triangles, 12);
    let d = *g.desc();
    let (mut inside, mut outside, mut border) = (0, 0, 0);
    for i in 0..d.point_count() {
        let p = d.position(d.coords(i).unwrap());
        let m = g.data()[i];
        let wholly_in = (p.abs() + Vec3::splat(0.25)).max_element() <= 0.9;
        let wholly_out = (p.abs() - Vec3::splat(0.25)).max_element() >= 0.9;
        if wholly_in {
            inside += 1;
            assert_eq!(m.pass, 0.0, "inside cell at {p}");
            assert!(
                (m.reflectance - colour).abs().max_element() < 1e-3,
                "{}",
                m.reflectance
            );
        } else if wholly_out {
            outside += 1;
            assert_eq!(m.pass, 1.0, "outside cell at {p}");
        } else {
            border += 1;
            assert!(
                m.pass > 0.0 && m.pass < 1.0,
                "border cell at {p}: {}",
                m.pass
            );
            assert!((m.reflectance - colour).abs().max_element() < 1e-3);
        }
    }
    assert!(
        inside > 0 && outside > 0 && border > 0,
        "{inside} {outside} {border}"
    );
    // More of a border cell covered, less light through it.
    let bigger = Model {
        triangles: cuboid(Vec3::splat(-0.95), Vec3::splat(0.95), 0),
        ..model.clone()
    };
    let (g2, _) = voxelize(&bigger, &params(0.5), &|_, _| {}).unwrap();
    let p = Vec3::splat(-0.75);
    let pick = |g: &lightgrid_core::MaterialGrid| {
        let c = g.desc().to_grid(p).round().as_uvec3();
        g.get(c).unwrap().pass
    };
    assert!(pick(&g2) < pick(&g), "{} vs {}", pick(&g2), pick(&g));
}

/// A seeded uniform `[0, 1)` stream (fastrand: statistics, not content).
fn uniform(seed: u64) -> impl FnMut() -> f32 {
    let mut r = fastrand::Rng::with_seed(seed);
    move || r.f32()
}

/// Brute force for a thin horizontal plane through a unit cell: the fraction of
/// μ-random chords (uniform directions, entry points uniform over the projected area)
/// that cross it, by plain random sampling (no BVH, no stratification).
fn crossing_fraction(height: f32) -> f32 {
    let mut rng = uniform(12345);
    let (mut crossed, n) = (0u32, 400_000u32);
    for _ in 0..n {
        let z = 1.0 - 2.0 * rng();
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = std::f32::consts::TAU * rng();
        let d = Vec3::new(r * phi.cos(), z, r * phi.sin());
        let w = d.abs();
        let pick = rng() * w.element_sum();
        let axis = if pick < w.x {
            0
        } else if pick < w.x + w.y {
            1
        } else {
            2
        };
        let mut p = Vec3::new(rng(), rng(), rng());
        p[axis] = if d[axis] > 0.0 { 0.0 } else { 1.0 };
        let mut len = f32::INFINITY;
        for ax in 0..3 {
            if d[ax] > 0.0 {
                len = len.min((1.0 - p[ax]) / d[ax]);
            } else if d[ax] < 0.0 {
                len = len.min(-p[ax] / d[ax]);
            }
        }
        let q = p + d * len;
        if (p.y - height) * (q.y - height) < 0.0 {
            crossed += 1;
        }
    }
    crossed as f32 / n as f32
}

#[test]
fn axis_aligned_plane_matches_brute_force_chords() {
    // A plane at y = 0.3 across 4 x 1 x 4 cells of 1 m spanning y in [0, 1].
    let y = 0.3;
    let c = [
        Vec3::new(0.0, y, 0.0),
        Vec3::new(4.0, y, 0.0),
        Vec3::new(4.0, y, 4.0),
        Vec3::new(0.0, y, 4.0),
    ];
    let mut triangles = vec![tri([c[0], c[1], c[2]], 0), tri([c[0], c[2], c[3]], 0)];
    // Two specks pin the bounds to y in [0, 1].
    triangles.push(tri(
        [
            Vec3::ZERO,
            Vec3::new(1e-3, 0.0, 0.0),
            Vec3::new(0.0, 0.0, 1e-3),
        ],
        0,
    ));
    triangles.push(tri(
        [
            Vec3::new(4.0, 1.0, 4.0),
            Vec3::new(4.0 - 1e-3, 1.0, 4.0),
            Vec3::new(4.0, 1.0, 4.0 - 1e-3),
        ],
        0,
    ));
    let model = Model {
        triangles,
        materials: vec![material(Vec3::splat(0.5))],
        textures: vec![],
    };
    let mut p = VoxelizeParams::fine(1.0);
    p.fill_closed = false;
    let (g, _) = voxelize(&model, &p, &|_, _| {}).unwrap();
    assert_eq!(g.desc().dims(), UVec3::new(4, 1, 4));
    let expect = (1.0 - crossing_fraction(y)).powf(1.5);
    let m = g.get(UVec3::new(1, 0, 2)).unwrap();
    assert!((m.pass - expect).abs() < 0.02, "{} vs {expect}", m.pass);
    assert!((m.reflectance - Vec3::splat(0.5)).abs().max_element() < 1e-5);
}

fn random_model(seed: u64, n: usize) -> Model {
    let mut rng = uniform(seed);
    let mut triangles = Vec::new();
    for i in 0..n {
        let c = Vec3::new(rng(), rng(), rng()) * 3.0;
        let e1 = Vec3::new(rng() - 0.5, rng() - 0.5, rng() - 0.5) * 0.6;
        let e2 = Vec3::new(rng() - 0.5, rng() - 0.5, rng() - 0.5) * 0.6;
        triangles.push(tri([c, c + e1, c + e2], (i % 3) as u32));
    }
    Model {
        triangles,
        materials: vec![material(Vec3::X), material(Vec3::Y), material(Vec3::Z)],
        textures: vec![],
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(16))]
    /// Thin random triangles: the BVH query and a brute-force loop agree on every ray.
    #[test]
    fn bvh_agrees_with_brute_force(seed in 1u64..1_000_000) {
        let model = random_model(seed, 60);
        let scene = RayScene::new(&model, BvhBuildParams::medium_build());
        let mut rng = uniform(seed ^ 0xabcdef);
        for _ in 0..300 {
            let o = Vec3::new(rng(), rng(), rng()) * 4.0 - Vec3::splat(0.5);
            let d = (Vec3::new(rng(), rng(), rng()) - Vec3::splat(0.5)).normalize_or(Vec3::Y);
            let len = rng() * 3.0;
            prop_assert_eq!(scene.first_block(o, d, len, 0.5), scene.first_block_brute(o, d, len, 0.5));
        }
    }
}

#[test]
fn every_obvhs_preset_gives_the_same_grid() {
    let mut model = random_model(7, 80);
    model
        .triangles
        .extend(cuboid(Vec3::splat(1.0), Vec3::splat(2.2), 1));
    let presets = [
        BvhBuildParams::fastest_build(),
        BvhBuildParams::very_fast_build(),
        BvhBuildParams::fast_build(),
        BvhBuildParams::medium_build(),
        BvhBuildParams::slow_build(),
        BvhBuildParams::very_slow_build(),
    ];
    let mut grids = Vec::new();
    for bvh in presets {
        let mut p = VoxelizeParams::preview(0.3);
        p.bvh = bvh;
        grids.push(voxelize(&model, &p, &|_, _| {}).unwrap().0);
    }
    for g in &grids[1..] {
        assert_eq!(g, &grids[0]);
    }
}

#[test]
fn alpha_mask_holes_let_light_through() {
    // A 2 x 2 checkerboard of alpha 1 and 0, repeated 8 times over the quad.
    let tex = Texture {
        width: 2,
        height: 2,
        texels: vec![
            Vec4::ONE,
            Vec4::new(1.0, 1.0, 1.0, 0.0),
            Vec4::new(1.0, 1.0, 1.0, 0.0),
            Vec4::ONE,
        ],
    };
    let c = [
        Vec3::new(0.0, 0.5, 0.0),
        Vec3::new(1.0, 0.5, 0.0),
        Vec3::new(1.0, 0.5, 1.0),
        Vec3::new(0.0, 0.5, 1.0),
    ];
    let uv = [
        Vec2::new(0.0, 0.0),
        Vec2::new(8.0, 0.0),
        Vec2::new(8.0, 8.0),
        Vec2::new(0.0, 8.0),
    ];
    let quad = vec![
        Triangle {
            positions: [c[0], c[1], c[2]],
            uvs: [uv[0], uv[1], uv[2]],
            material: 0,
            part: 0,
        },
        Triangle {
            positions: [c[0], c[2], c[3]],
            uvs: [uv[0], uv[2], uv[3]],
            material: 0,
            part: 0,
        },
    ];
    let run = |alpha| {
        let leaf = SurfaceMaterial {
            base_colour: Vec4::ONE,
            texture: Some(0),
            alpha,
            ..Default::default()
        };
        let model = Model {
            triangles: quad.clone(),
            materials: vec![leaf],
            textures: vec![tex.clone()],
        };
        let mut p = VoxelizeParams::standard(1.0);
        p.fill_closed = false;
        voxelize(&model, &p, &|_, _| {}).unwrap().0.data()[0].pass
    };
    let (opaque, masked) = (run(AlphaMode::Opaque), run(AlphaMode::Mask(0.5)));
    assert!(masked > opaque + 0.1, "masked {masked} opaque {opaque}");
}

#[test]
fn empty_space_is_not_traced() {
    let mut triangles = cuboid(Vec3::ZERO, Vec3::splat(0.2), 0);
    triangles.extend(cuboid(Vec3::splat(5.0), Vec3::splat(5.2), 0));
    let model = Model {
        triangles,
        materials: vec![material(Vec3::ONE)],
        textures: vec![],
    };
    let (_, stats) = voxelize(&model, &VoxelizeParams::preview(0.25), &|_, _| {}).unwrap();
    assert!(stats.cells > 8000);
    assert!(stats.cells_traced < 50, "{stats:?}");
}

#[test]
fn shipped_kenney_models_load_and_voxelize() {
    let dir =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/kenney-city-builder");
    assert!(dir.exists(), "test data missing at {}", dir.display());
    for name in [
        "grass-trees.glb",
        "building-small-a.glb",
        "road-straight-lightposts.glb",
    ] {
        let model = Model::load_gltf(dir.join(name)).unwrap();
        assert!(model.triangles.len() > 100, "{name}");
        assert!(
            !model.textures.is_empty(),
            "{name} uses the colormap texture"
        );
        let (g, stats) = voxelize(&model, &VoxelizeParams::preview(0.1), &|_, _| {}).unwrap();
        assert!(stats.cells_filled > 20, "{name}: {stats:?}");
        // Textured: the grid's colours vary.
        let filled: Vec<Vec3> = g
            .data()
            .iter()
            .filter(|m| !m.is_empty())
            .map(|m| m.reflectance)
            .collect();
        let spread = filled
            .iter()
            .fold(0.0f32, |s, c| s.max((*c - filled[0]).abs().max_element()));
        assert!(spread > 0.05, "{name}: {spread}");
    }
    let e = Model::load_gltf(dir.join("missing.glb"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("missing.glb"), "{e}");
}

#[test]
fn invalid_parameters_are_typed_errors() {
    let model = random_model(3, 5);
    let mut p = VoxelizeParams::preview(0.0);
    assert!(
        voxelize(&model, &p, &|_, _| {})
            .unwrap_err()
            .to_string()
            .contains("cell")
    );
    p.cell = 1e-4;
    assert!(
        voxelize(&model, &p, &|_, _| {})
            .unwrap_err()
            .to_string()
            .contains("max_cells")
    );
    let mut bad = model.clone();
    bad.triangles[2].positions[1].x = f32::NAN;
    let e = voxelize(&bad, &VoxelizeParams::preview(0.5), &|_, _| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("triangles[2]"), "{e}");
}
