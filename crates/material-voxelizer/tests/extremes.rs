//! Voxelization parameters over extreme values (issue 47): counts whose product leaves
//! `u32` (65536 directions × 65536 chords wrapped and ran on), cells of any size: a typed
//! error naming the field, or a grid of finite material.

use lightgrid_material_voxelizer::procedural::rock;
use lightgrid_material_voxelizer::voxelize::{MAX_CHORDS, VoxelizeParams, voxelize};
use proptest::prelude::*;

fn count() -> impl Strategy<Value = u32> {
    prop_oneof![
        Just(0u32),
        Just(1),
        Just(16),
        Just(512),
        Just(65536),
        Just(u32::MAX),
        1u32..8
    ]
}

fn cell() -> impl Strategy<Value = f32> {
    prop_oneof![
        Just(0.0f32),
        Just(-1.0),
        Just(1e-45),
        Just(f32::MAX),
        Just(f32::NAN),
        Just(f32::INFINITY),
        Just(0.5),
        Just(1e5),
        0.2f32..2.0,
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn parameters_are_refused_by_name_or_voxelize(directions in count(), chords in count(), cell in cell()) {
        let mut p = VoxelizeParams::preview(1.0);
        p.directions = directions;
        p.chords_per_direction = chords;
        p.cell = cell;
        match p.validate() {
            Ok(()) => {
                prop_assert!(directions as u64 * chords as u64 <= MAX_CHORDS);
                // Voxelize only what stays quick: a small rock, few chords.
                if directions as u64 * chords as u64 <= 4096 && cell >= 0.2 {
                    let model = rock(1, 1.0).unwrap();
                    let (g, _) = voxelize(&model, &p, &|_, _| {}).unwrap();
                    prop_assert!(g.data().iter().all(|c| c.pass.is_finite() && c.reflectance.is_finite()));
                }
            }
            Err(e) => {
                let e = e.to_string();
                prop_assert!(e.contains("cell") || e.contains("directions") || e.contains("chords"), "{}", e);
            }
        }
    }
}

#[test]
fn the_issues_product_is_refused() {
    let mut p = VoxelizeParams::preview(1.0);
    p.directions = 65536;
    p.chords_per_direction = 65536;
    let e = p.validate().unwrap_err().to_string();
    assert!(e.contains("chords_per_direction"), "{e}");
}
