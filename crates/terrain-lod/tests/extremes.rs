//! The hierarchy's parameters, camera and reads over extreme values (issue 47): a typed
//! error naming the field, or frames within the budget and finite light.

use lightgrid_core::glam::{Vec2, Vec3};
use lightgrid_core::{BinLight, Heightmap, LightField, Material};
use lightgrid_sweep_cpu::CpuSweeper;
use lightgrid_terrain_lod::{Hierarchy, HierarchyParams};
use proptest::prelude::*;

mod field;

/// Opaque ground below y = 0, empty above.
fn ground() -> field::Field<impl Fn(Vec3, f32) -> Material + Send + Sync> {
    field::Field(|p: Vec3, _| {
        if p.y < 0.0 {
            Material::opaque(Vec3::splat(0.3))
        } else {
            Material::EMPTY
        }
    })
}

/// Mostly `valid`, else an extreme value.
fn or_f(valid: f32) -> impl Strategy<Value = f32> {
    prop_oneof![4 => Just(valid), 1 => f()]
}

fn or_count(valid: u32) -> impl Strategy<Value = u32> {
    prop_oneof![4 => Just(valid), 1 => count()]
}

/// The shared extreme values (`lightgrid_core::extremes`), this crate's own edges, any `f32`.
fn f() -> impl Strategy<Value = f32> {
    prop_oneof![
        proptest::sample::select(&lightgrid_core::extremes::F32[..]),
        Just(1e-3),
        4.0f32..64.0,
        any::<f32>(),
    ]
}

fn count() -> impl Strategy<Value = u32> {
    prop_oneof![Just(0u32), Just(1), Just(u32::MAX), Just(1 << 20), 2u32..16]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn any_parameters_are_refused_by_name_or_run(
        world_cell in or_f(16.0), finest_cell in or_f(4.0), node_points in or_count(8),
        margin in or_f(8.0), lod in or_f(1.0),
        budget in prop_oneof![Just(0u64), Just(u64::MAX), 1000u64..100_000],
        max_levels in or_count(16), camera in (or_f(30.0), f(), or_f(30.0)),
    ) {
        lightgrid_core::limits::set_memory_limit(512 << 20);
        let hm = Heightmap::from_fn(Vec2::ZERO, 8.0, 9, 9, |_, _| 0.0).unwrap();
        let mut p = HierarchyParams {
            world_cell,
            finest_cell,
            node_points,
            margin,
            lod_factor: lod,
            budget_points: budget,
            max_levels,
            ..Default::default()
        };
        p.sweep.max_passes = 2;
        let (sky, _) = BinLight::uniform(Vec3::ONE).split_vertical();
        let Ok(mut h) = Hierarchy::new(&hm, Box::new(ground()), Box::new(CpuSweeper::new()), sky, p)
        else {
            return Ok(());
        };
        let cam = Vec3::new(camera.0, camera.1, camera.2);
        if let Ok(s) = h.update(cam) {
            prop_assert!(s.points_swept <= p.budget_points);
        }
        for q in [cam, Vec3::new(30.0, 2.0, 30.0)] {
            if let Ok(e) = h.irradiance(q, Vec3::Y) {
                prop_assert!(e.is_finite() && e.cmpge(Vec3::ZERO).all());
            }
        }
    }
}

/// The valid values the property's parameters mostly take build a hierarchy (so the
/// property reaches frames and reads, not only refusals: about a third of its cases).
#[test]
fn the_properties_base_parameters_build_a_hierarchy() {
    let hm = Heightmap::from_fn(Vec2::ZERO, 8.0, 9, 9, |_, _| 0.0).unwrap();
    let p = HierarchyParams {
        world_cell: 16.0,
        finest_cell: 4.0,
        node_points: 8,
        margin: 8.0,
        max_levels: 16,
        ..Default::default()
    };
    let (sky, _) = BinLight::uniform(Vec3::ONE).split_vertical();
    assert!(Hierarchy::new(&hm, Box::new(ground()), Box::new(CpuSweeper::new()), sky, p).is_ok());
}
