//! The sampling entry points over extreme values (issue 47): any normal, any light, any
//! table size, any point: a typed error or a finite result, never a panic or a NaN.

use lightgrid_core::glam::{UVec3, Vec2, Vec3};
use lightgrid_core::{BinLight, GridDesc, LightGrid, NUM_DIRS};
use lightgrid_render::sampling::{octahedral_decode, octahedral_encode};
use lightgrid_render::{IrradianceTable, SamplePoints, sample_points};
use proptest::prelude::*;

/// The shared extreme values (`lightgrid_core::extremes`) and any `f32`.
fn f() -> BoxedStrategy<f32> {
    lightgrid_core::extremes::strategies::f32_with(&[])
}

fn v3() -> impl Strategy<Value = Vec3> {
    lightgrid_core::extremes::strategies::vec3_of(f())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn encodings_and_table_reads_are_finite(n in v3(), uv in (f(), f()), light in proptest::collection::vec(v3(), NUM_DIRS)) {
        let e = octahedral_encode(n);
        prop_assert!(e.is_finite() && e.cmpge(Vec2::ZERO).all() && e.cmple(Vec2::ONE).all());
        let d = octahedral_decode(Vec2::new(uv.0, uv.1));
        prop_assert!(d.is_finite() && (d.length() - 1.0).abs() < 1e-3);
        let bins = BinLight(std::array::from_fn(|k| light[k]));
        prop_assert!(IrradianceTable::get().irradiance(&bins, n).is_finite());
    }

    #[test]
    fn sampled_points_are_refused_or_finite(p in v3(), n in v3(), value in v3()) {
        let d = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(3, 3, 3)).unwrap();
        let mut g = LightGrid::filled(d, BinLight::uniform(Vec3::ONE)).unwrap();
        g.data_mut()[13].0[3] = value;
        let normals = [n];
        let positions = [p];
        let points = SamplePoints { positions: &positions, normals: Some(&normals) };
        if let Ok(s) = sample_points(&g, points) {
            prop_assert!(s.iter().all(|s| s.light.is_finite() && s.sun.is_finite() && s.dominant.is_finite()));
        }
    }
}

#[test]
fn table_sizes_are_clamped() {
    for size in [0, 1, 2] {
        assert_eq!(IrradianceTable::build(size).size, 2);
    }
    assert_eq!(
        IrradianceTable::build(u32::MAX).size,
        IrradianceTable::MAX_SIZE
    );
}
