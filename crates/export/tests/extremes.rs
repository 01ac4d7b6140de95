//! The export's entry points over extreme values (issue 47): light of any magnitude a
//! grid can hold (through `data_mut`: infinity and NaN too), any unit scale, any sun:
//! a typed error naming the field, or volumes, files and sidecars of finite positive
//! numbers.

use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::{BinLight, GridDesc, LightGrid};
use lightgrid_export::{BevyVolume, Content, SidecarSun, TexelFormat};
use proptest::prelude::*;

/// The shared extreme values (`lightgrid_core::extremes`), this crate's own edges, any `f32`.
fn f() -> BoxedStrategy<f32> {
    lightgrid_core::extremes::strategies::f32_with(&[1e20, 1e-38])
}

fn v3() -> impl Strategy<Value = Vec3> {
    lightgrid_core::extremes::strategies::vec3_of(f())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn volumes_of_any_light(values in proptest::collection::vec(v3(), 3), scale in f(), rg11 in any::<bool>()) {
        let d = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(2, 2, 1)).unwrap();
        let mut g = LightGrid::filled(d, BinLight::uniform(Vec3::splat(0.5))).unwrap();
        for (i, v) in values.iter().enumerate() {
            g.data_mut()[i].0[i * 7] = *v;
        }
        let format = if rg11 { TexelFormat::Rg11b10 } else { TexelFormat::Rgb9e5 };
        let Ok(v) = BevyVolume::from_field(&g, &d, format) else {
            return Ok(());
        };
        prop_assert!(v.intensity().is_finite() && v.intensity() > 0.0);
        for p in 0..4u32 {
            for face in 0..6 {
                let t = v.texel(UVec3::new(p % 2, p / 2, 0), face);
                prop_assert!(t.is_finite() && t.cmpge(Vec3::ZERO).all());
            }
        }
        prop_assert!(v.to_dds().is_ok() && !v.to_ktx2().is_empty());
        if let Ok(info) = v.sidecar("x", Content::Indirect, scale) {
            prop_assert!(info.intensity.is_finite() && info.intensity > 0.0);
            prop_assert!(scale.is_finite() && scale > 0.0);
        }
    }

    #[test]
    fn suns_of_any_value(to_sun in v3(), irradiance in v3(), scale in f()) {
        if let Ok(Some(s)) = SidecarSun::new(to_sun, irradiance, scale) {
            prop_assert!(s.illuminance.is_finite() && s.illuminance > 0.0);
            prop_assert!(s.direction_to_sun.iter().all(|c| c.is_finite()));
            prop_assert!(s.color.iter().all(|c| c.is_finite() && *c >= 0.0));
        }
    }
}
