//! The sweep's public entry points over extreme values (0, 1, `u32::MAX`, `f32::MAX`,
//! subnormals, NaN, infinities): a typed error or a finite result, never a panic or a
//! NaN (issue 47). The exact problems are checked in `lightgrid-measure`.

use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::{
    BinLight, Boundary, GridDesc, Material, MaterialGrid, SideBoundary, SweepOptions, Sweeper,
};
use lightgrid_sweep_cpu::CpuSweeper;
use proptest::prelude::*;

/// The shared extreme values (`lightgrid_core::extremes`) and any `f32`.
fn f() -> BoxedStrategy<f32> {
    lightgrid_core::extremes::strategies::f32_with(&[])
}

fn v3() -> impl Strategy<Value = Vec3> {
    lightgrid_core::extremes::strategies::vec3_of(f())
}

/// Counts: 0, 1, 2, around the 4096 limit, the largest, and small ones.
fn count() -> BoxedStrategy<u32> {
    lightgrid_core::extremes::strategies::u32_of(&[0, 1, 2, 4096, 4097, u32::MAX], 0..8)
}

/// Every output of a sweep is light (finite, not negative).
fn all_light(out: &lightgrid_core::SweepOutput) -> bool {
    out.bins
        .as_ref()
        .is_none_or(|g| g.data().iter().all(|b| b.is_valid()))
        && out
            .average
            .as_ref()
            .is_none_or(|g| g.data().iter().all(|a| a.0.is_finite()))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    /// Any options, material and sky on a small grid: refused by name or light.
    #[test]
    fn sweeps_of_extreme_inputs(
        smoothing in f(), tolerance in f(), passes in count(),
        pass in f(), reflectance in v3(), sky in v3(), periodic in any::<bool>(),
    ) {
        lightgrid_core::limits::set_memory_limit(256 << 20);
        let d = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(4, 3, 4)).unwrap();
        let Ok(m) = MaterialGrid::filled(d, Material { reflectance, pass }) else {
            return Ok(());
        };
        let mut o = SweepOptions::multi_bounce();
        o.smoothing = smoothing;
        o.tolerance = tolerance;
        // Past 4096 refused; valid counts kept short.
        o.max_passes = if (65..=4096).contains(&passes) { 64 } else { passes };
        let top = BinLight::uniform(sky).split_vertical().0;
        let b = Boundary {
            sides: if periodic { SideBoundary::Periodic } else { SideBoundary::Open },
            ..Boundary::open_sky(top)
        };
        if let Ok(out) = CpuSweeper::new().sweep(&m, &b, &o) {
            prop_assert!(all_light(&out));
        }
    }
}
