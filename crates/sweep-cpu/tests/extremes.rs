//! The sweep's public entry points over extreme values (0, 1, `u32::MAX`, `f32::MAX`,
//! subnormals, NaN, infinities): a typed error or a finite result, never a panic or a
//! NaN (issue 47). The exact problems check their parameters before they allocate.

use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::{
    BinLight, Boundary, GridDesc, Material, MaterialGrid, SideBoundary, SweepOptions, Sweeper,
};
use lightgrid_sweep_cpu::sky::{ClearSky, Sun, uniform_sky};
use lightgrid_sweep_cpu::{CpuSweeper, exact};
use proptest::prelude::*;

/// The shared extreme values (`lightgrid_core::extremes`) and any `f32`.
fn f() -> BoxedStrategy<f32> {
    lightgrid_core::extremes::strategies::f32_with(&[])
}

fn v3() -> impl Strategy<Value = Vec3> {
    lightgrid_core::extremes::strategies::vec3_of(f())
}

fn count() -> impl Strategy<Value = u32> {
    prop_oneof![
        Just(0u32),
        Just(1),
        Just(2),
        Just(4096),
        Just(4097),
        Just(u32::MAX),
        0u32..8
    ]
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

    /// Suns and skies of any value: refused by name or light.
    #[test]
    fn suns_and_skies(elevation in f(), azimuth in f(), light in v3(), dir in v3()) {
        if let Ok(b) = Sun::at(elevation, azimuth, light).bins() {
            prop_assert!(b.is_valid());
        }
        if let Ok(s) = uniform_sky(light) {
            prop_assert!(s.top.is_valid());
        }
        if let Ok(s) = ClearSky::blue(dir).bins() {
            prop_assert!(s.top.is_valid());
        }
    }

    /// The exact problems: refused by name before they allocate, or a finite case.
    #[test]
    fn exact_problems(n in count(), w in f(), pass in f(), depth in f(), passes in count()) {
        lightgrid_core::limits::set_memory_limit(256 << 20);
        let small = |c: u32| c.min(6);
        if let Ok(m) = exact::furnace_material(n, 3) {
            prop_assert!(m.desc().dims().x == n);
        }
        prop_assert!(exact::furnace_material(u32::MAX, 3).is_err());
        if let Ok((e, _)) = exact::ground_fields(w, &uniform_sky(Vec3::ONE).unwrap().top) {
            prop_assert!(e.is_valid());
        }
        if let Ok(m) = exact::ground_material(n, w) {
            prop_assert!(m.data().iter().all(|c| c.pass.is_finite()));
        }
        // Sweeps only where they are short: a few passes over a thin slab.
        let thin = depth.is_finite() && depth.abs() < 8.0;
        if thin && let Ok(c) = exact::half_space(w, pass, depth, small(passes)) {
            prop_assert!(c.swept.is_finite() && c.exact.is_finite());
        }
        prop_assert!(exact::half_space(0.5, 1.0, 40.0, 4).is_err());
        prop_assert!(exact::half_space(0.5, 0.999_999, f32::MAX, 4).is_err());
        if let Ok(c) = exact::convergence(small(n), w, small(passes)) {
            prop_assert!(c.swept.is_finite());
        }
        prop_assert!(exact::convergence(u32::MAX, 0.5, 4).is_err());
        prop_assert!(exact::measure(0).is_err() && exact::measure(4097).is_err());
    }
}
