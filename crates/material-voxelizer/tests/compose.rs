//! Area composition: resampling, rotation, cell-size consistency, ground, binning.

use lightgrid_core::glam::{Quat, UVec3, Vec2, Vec3};
use lightgrid_core::{GridDesc, Material, MaterialGrid, MaterialSource};
use lightgrid_material_voxelizer::compose::{
    AreaComposer, ComposeParams, GroundColour, Heightmap, Instance, Terrain,
};

fn random_model(seed: u64) -> MaterialGrid {
    let d = GridDesc::new(Vec3::new(-1.0, 0.25, -0.5), 0.5, UVec3::new(4, 3, 5)).unwrap();
    let mut s = seed;
    let mut rng = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 40) as f32 / (1u64 << 24) as f32
    };
    let cells = (0..d.point_count())
        .map(|_| Material {
            reflectance: Vec3::new(rng(), rng(), rng()),
            pass: if rng() < 0.3 { 1.0 } else { rng() },
        })
        .collect();
    MaterialGrid::new(d, cells).unwrap()
}

fn composer(model: MaterialGrid, instances: &[Instance], terrain: Option<Terrain>) -> AreaComposer {
    AreaComposer::new(vec![model], instances, terrain, ComposeParams::default()).unwrap()
}

fn same(a: &Material, b: &Material) -> bool {
    (a.pass - b.pass).abs() < 1e-5
        && (a.pass >= 1.0 || (a.reflectance - b.reflectance).abs().max_element() < 1e-5)
}

#[test]
fn one_instance_in_an_empty_area_is_the_model_grid_resampled() {
    let model = random_model(1);
    let pos = Vec3::new(10.0, 2.0, -3.0);
    let c = composer(
        model.clone(),
        &[Instance {
            model: 0,
            position: pos,
            rotation: Quat::IDENTITY,
            scale: 1.0,
        }],
        None,
    );
    let area = GridDesc::new(model.desc().origin() + pos, 0.5, model.desc().dims()).unwrap();
    let g = c.material(&area).unwrap();
    for (a, b) in g.data().iter().zip(model.data()) {
        assert!(same(a, b), "{a:?} vs {b:?}");
    }
}

#[test]
fn rotation_by_90_degrees_is_the_rotated_grid() {
    let model = random_model(2);
    let rot = Quat::from_rotation_y(std::f32::consts::FRAC_PI_2); // (x, y, z) -> (z, y, -x)
    let c = composer(
        model.clone(),
        &[Instance {
            model: 0,
            position: Vec3::ZERO,
            rotation: rot,
            scale: 1.0,
        }],
        None,
    );
    let md = *model.desc();
    let (lo, hi) = md.point_bounds();
    let corners = [rot * lo, rot * hi];
    let wlo = corners[0].min(corners[1]);
    let dims = UVec3::new(md.dims().z, md.dims().y, md.dims().x);
    let area = GridDesc::new(wlo, 0.5, dims).unwrap();
    let g = c.material(&area).unwrap();
    for i in 0..area.point_count() {
        let w = area.position(area.coords(i).unwrap());
        let m = md.to_grid(rot.inverse() * w).round().as_uvec3();
        assert!(same(&g.data()[i], model.get(m).unwrap()), "world {w}");
    }
}

#[test]
fn pass_through_scales_with_cell_size() {
    let fog = MaterialGrid::filled(
        GridDesc::new(Vec3::splat(-8.0), 0.25, UVec3::splat(65)).unwrap(),
        Material {
            reflectance: Vec3::splat(0.4),
            pass: 0.6,
        },
    )
    .unwrap();
    let c = composer(
        fog,
        &[Instance {
            model: 0,
            position: Vec3::ZERO,
            rotation: Quat::IDENTITY,
            scale: 1.0,
        }],
        None,
    );
    let small = c
        .material(&GridDesc::new(Vec3::splat(-2.0), 0.5, UVec3::splat(4)).unwrap())
        .unwrap();
    let big = c
        .material(&GridDesc::new(Vec3::splat(-2.0), 1.0, UVec3::splat(2)).unwrap())
        .unwrap();
    let p_small = small.data()[0].pass;
    assert!((p_small - 0.36).abs() < 1e-5, "{p_small}"); // two model cells: 0.6^2
    for m in big.data() {
        assert!(
            (m.pass - p_small * p_small).abs() < 1e-5,
            "{} vs {}",
            m.pass,
            p_small * p_small
        );
        assert!((m.reflectance - Vec3::splat(0.4)).abs().max_element() < 1e-5);
    }
    // A scaled instance has proportionally longer model cells.
    let fog = MaterialGrid::filled(
        GridDesc::new(Vec3::splat(-8.0), 0.25, UVec3::splat(65)).unwrap(),
        Material {
            reflectance: Vec3::ONE,
            pass: 0.6,
        },
    )
    .unwrap();
    let c2 = composer(
        fog,
        &[Instance {
            model: 0,
            position: Vec3::ZERO,
            rotation: Quat::IDENTITY,
            scale: 2.0,
        }],
        None,
    );
    let g2 = c2
        .material(&GridDesc::new(Vec3::splat(-2.0), 0.5, UVec3::splat(4)).unwrap())
        .unwrap();
    assert!((g2.data()[0].pass - 0.6).abs() < 1e-5);
}

#[test]
fn ground_is_dense_below_clear_above_with_a_biased_linear_band() {
    let hm = Heightmap::from_fn(Vec2::splat(-50.0), 1.0, 101, 101, |_, _| 10.0).unwrap();
    let colour = Vec3::new(0.3, 0.25, 0.2);
    let terrain = Terrain {
        heightmap: hm,
        colour: GroundColour::Uniform(colour),
    };
    let c = AreaComposer::new(vec![], &[], Some(terrain), ComposeParams::default()).unwrap();
    // Column of 1 m cells whose centres run from y = 5.75 to 14.75: the biased surface
    // (9.75) is a cell centre.
    let area = GridDesc::new(Vec3::new(0.0, 5.75, 0.0), 1.0, UVec3::new(1, 10, 1)).unwrap();
    let g = c.material(&area).unwrap();
    let passes: Vec<f32> = g.data().iter().map(|m| m.pass).collect();
    assert_eq!(passes[0], 0.0);
    assert!((g.data()[0].reflectance - colour).abs().max_element() < 1e-6);
    assert!((passes[4] - 0.5).abs() < 1e-6, "{passes:?}");
    assert_eq!(passes[9], 1.0);
    assert!(passes.windows(2).all(|w| w[0] <= w[1]), "{passes:?}");
}

/// A cell is composed from its own box alone: a grid's cells are, bit for bit, the
/// inner cells of a wider grid on the same lattice (a hierarchy composes a node with its
/// apron once and keeps the node's inner points), also where the wider grid alone holds
/// an instance of a smaller scale (0.4: 3 samples a side in its cells, against the
/// inner instances' 2: were the samples a side the area's, the inner cells would
/// differ).
#[test]
fn a_box_is_the_inner_cells_of_a_wider_box() {
    let hm = Heightmap::from_fn(Vec2::splat(-20.0), 1.0, 41, 41, |x, z| {
        1.0 + 0.3 * x + 0.2 * (0.7 * z).sin()
    })
    .unwrap();
    let terrain = Terrain {
        heightmap: hm,
        colour: GroundColour::Uniform(Vec3::new(0.3, 0.25, 0.2)),
    };
    let instances: Vec<Instance> = (0..12)
        .map(|i| Instance {
            model: 0,
            position: Vec3::new(-6.0 + i as f32 * 1.1, 1.5, -5.0 + (i * 7 % 11) as f32),
            rotation: Quat::from_rotation_y(0.4 * i as f32),
            scale: 0.8 + 0.1 * (i % 4) as f32,
        })
        .chain([Instance {
            model: 0,
            position: Vec3::new(2.4, 1.5, -2.0),
            rotation: Quat::IDENTITY,
            scale: 0.4,
        }])
        .collect();
    let c = composer(random_model(4), &instances, Some(terrain));
    let inner = GridDesc::new(Vec3::new(-4.25, -2.25, -3.75), 0.5, UVec3::new(12, 14, 10)).unwrap();
    let a = 3;
    let wide = GridDesc::new(
        inner.origin() - Vec3::new(a as f32, 0.0, a as f32) * 0.5,
        0.5,
        inner.dims() + UVec3::new(2 * a, 0, 2 * a),
    )
    .unwrap();
    let g = c.material(&inner).unwrap();
    let w = c.material(&wide).unwrap();
    assert!(g.data().iter().any(|m| m.pass > 0.0 && m.pass < 1.0));
    for i in 0..inner.point_count() {
        let q = inner.coords(i).unwrap();
        let m = w.data()[wide.index_unchecked(q + UVec3::new(a, 0, a))];
        assert_eq!(m, g.data()[i], "cell {q}");
    }
}

#[test]
fn far_instances_cost_nothing_and_change_nothing() {
    let model = random_model(3);
    let near = Instance {
        model: 0,
        position: Vec3::new(1.0, 0.0, 1.0),
        rotation: Quat::IDENTITY,
        scale: 1.0,
    };
    let far = |n: usize| -> Vec<Instance> {
        (0..n)
            .map(|i| Instance {
                model: 0,
                position: Vec3::new(
                    1000.0 + (i % 300) as f32 * 7.0,
                    0.0,
                    1000.0 + (i / 300) as f32 * 7.0,
                ),
                rotation: Quat::IDENTITY,
                scale: 1.0,
            })
            .collect()
    };
    let area = GridDesc::new(Vec3::new(-4.0, -1.0, -4.0), 0.5, UVec3::new(16, 8, 16)).unwrap();
    let mut few = far(100);
    few.push(near);
    let mut many = far(100_000);
    many.push(near);
    let (a, sa) = composer(model.clone(), &few, None).compose(&area).unwrap();
    let (b, sb) = composer(model, &many, None).compose(&area).unwrap();
    assert_eq!(a, b);
    assert_eq!((sa.candidates, sb.candidates), (1, 1));
}

#[test]
fn invalid_instances_name_the_field() {
    let e = AreaComposer::new(
        vec![random_model(4)],
        &[Instance {
            model: 0,
            position: Vec3::ZERO,
            rotation: Quat::IDENTITY,
            scale: 0.0,
        }],
        None,
        ComposeParams::default(),
    )
    .err()
    .unwrap()
    .to_string();
    assert!(e.contains("instances[0].scale"), "{e}");
    let e = AreaComposer::new(
        vec![],
        &[Instance {
            model: 3,
            position: Vec3::ZERO,
            rotation: Quat::IDENTITY,
            scale: 1.0,
        }],
        None,
        ComposeParams::default(),
    )
    .err()
    .unwrap()
    .to_string();
    assert!(e.contains("instances[0].model"), "{e}");
}

#[test]
fn shipped_dem_loads_as_a_heightmap() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../assets/dem-jacksboro/jacksboro_fault_dem_u16.png");
    let hm = lightgrid_material_voxelizer::compose::load_heightmap_png(
        &path,
        Vec2::ZERO,
        30.0,
        1.0,
        0.0,
    )
    .unwrap();
    assert_eq!((hm.width, hm.depth), (403, 344));
    let (lo, hi) = hm.range();
    assert_eq!((lo, hi), (236.0, 1076.0));
    assert!(
        lightgrid_material_voxelizer::compose::load_heightmap_png(
            "/nonexistent.png",
            Vec2::ZERO,
            1.0,
            1.0,
            0.0
        )
        .unwrap_err()
        .to_string()
        .contains("nonexistent.png")
    );
}

/// The shadow material (`MaterialSource::shadow_material`, what a march of the sun
/// crosses alone) takes a sample a side every two of the finest instance's cells, but
/// no fewer than two where the material takes two or more: for one instance of
/// 0.5 m cells at scales 0.5–2 over sloping ground, in areas of 0.5–4 m cells, it is
/// the material of a composer allowed that many samples a side, bit for bit; coarser
/// than the material where that is fewer (and the same where not).
#[test]
fn the_shadow_material_takes_half_the_samples_a_side_but_two() {
    let hm = Heightmap::from_fn(Vec2::new(-8.0, -8.0), 1.0, 17, 17, |x, z| {
        0.2 * x + 0.1 * z - 1.5
    })
    .unwrap();
    let terrain = Terrain {
        heightmap: hm,
        colour: GroundColour::Uniform(Vec3::new(0.3, 0.25, 0.2)),
    };
    let (mut coarser, mut same_k) = (0, 0);
    for scale in [0.5f32, 1.0, 2.0] {
        let inst = [Instance {
            model: 0,
            position: Vec3::new(0.3, -1.0, -0.2),
            rotation: Quat::from_rotation_y(0.7),
            scale,
        }];
        let with = |k: u32| {
            let params = ComposeParams {
                max_samples_per_axis: k,
                ..ComposeParams::default()
            };
            AreaComposer::new(vec![random_model(3)], &inst, Some(terrain.clone()), params).unwrap()
        };
        let c = with(ComposeParams::default().max_samples_per_axis);
        for h in [0.5f32, 1.0, 2.0, 4.0] {
            let n = (8.0 / h) as u32;
            let desc = GridDesc::new(Vec3::splat(-4.0 + 0.5 * h), h, UVec3::splat(n)).unwrap();
            let cell = 0.5 * scale;
            let k_material = ((h / cell).ceil() as u32).clamp(1, 4);
            let k_shadow = ((h / (2.0 * cell)).ceil() as u32)
                .clamp(1, 4)
                .max(k_material.min(2));
            let shadow = c.shadow_material(&desc).unwrap();
            assert!(
                shadow.data() == with(k_shadow).material(&desc).unwrap().data(),
                "scale {scale}, cells of {h} m: not the material of {k_shadow} a side"
            );
            let full = c.material(&desc).unwrap();
            if k_shadow < k_material {
                assert!(shadow.data() != full.data(), "scale {scale}, {h} m");
                coarser += 1;
            } else {
                assert!(shadow.data() == full.data(), "scale {scale}, {h} m");
                same_k += 1;
            }
        }
    }
    assert!(
        (coarser, same_k) == (3, 9),
        "{coarser} coarser, {same_k} the same"
    );
}
