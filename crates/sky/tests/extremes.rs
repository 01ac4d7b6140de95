//! Suns and skies of extreme values (0, 1, `f32::MAX`, subnormals, NaN, infinities):
//! refused by name or light, never a panic or a NaN (issue 47).

use lightgrid_core::glam::Vec3;
use lightgrid_sky::{ClearSky, Sun, uniform_sky};
use proptest::prelude::*;

/// The shared extreme values (`lightgrid_core::extremes`) and any `f32`.
fn f() -> BoxedStrategy<f32> {
    lightgrid_core::extremes::strategies::f32_with(&[])
}

fn v3() -> impl Strategy<Value = Vec3> {
    lightgrid_core::extremes::strategies::vec3_of(f())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

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
}
