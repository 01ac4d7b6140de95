//! The exact problems over extreme values (0, 1, `u32::MAX`, `f32::MAX`, subnormals,
//! NaN, infinities): each checks its parameters before it allocates, and a case it
//! runs is finite (issue 47).

use lightgrid_core::glam::Vec3;
use lightgrid_measure::exact;
use lightgrid_sky::uniform_sky;
use proptest::prelude::*;

/// The shared extreme values (`lightgrid_core::extremes`) and any `f32`.
fn f() -> BoxedStrategy<f32> {
    lightgrid_core::extremes::strategies::f32_with(&[])
}

/// Counts: 0, 1, 2, around the 4096 limit, the largest, and small ones.
fn count() -> BoxedStrategy<u32> {
    lightgrid_core::extremes::strategies::u32_of(&[0, 1, 2, 4096, 4097, u32::MAX], 0..8)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

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
