//! Compression and light sets over extreme values (issue 47): any light a grid can hold
//! (through `data_mut`: infinity, NaN, negatives, subnormals, `f32::MAX`) compresses to a
//! finite volume; a light set refuses volumes off its grid (however far) and colours
//! that are not light, and its combined grid stays light.

use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::{BinLight, GridDesc, LightGrid};
use lightgrid_light_volumes::{CompressedVolume, LightSet};
use proptest::prelude::*;

/// The shared extreme values (`lightgrid_core::extremes`), this crate's own edges, any `f32`.
fn f() -> BoxedStrategy<f32> {
    lightgrid_core::extremes::strategies::f32_with(&[9e8, 1e-4])
}

fn v3() -> impl Strategy<Value = Vec3> {
    lightgrid_core::extremes::strategies::vec3_of(f())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn any_light_compresses_to_a_finite_volume(values in proptest::collection::vec(v3(), 4)) {
        let d = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(2, 2, 2)).unwrap();
        let mut g = LightGrid::filled(d, BinLight::ZERO).unwrap();
        for (i, v) in values.iter().enumerate() {
            g.data_mut()[i * 2].0[i * 5] = *v;
        }
        let c = CompressedVolume::compress(&g, 1);
        prop_assert!(c.scale.is_finite() && c.scale >= 0.0);
        if let Some(back) = c.decode() {
            prop_assert!(back.data().iter().all(|b| b.is_valid()));
        }
    }

    #[test]
    fn light_sets_refuse_what_is_off_their_grid(origin in v3(), h in f(), colour in v3(), intensity in f()) {
        let d = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(6, 4, 6)).unwrap();
        let mut set = LightSet::new(d).unwrap();
        let Ok(vd) = GridDesc::new(origin, h, UVec3::new(2, 2, 2)) else {
            return Ok(());
        };
        let g = LightGrid::filled(vd, BinLight::uniform(Vec3::ONE)).unwrap();
        let c = CompressedVolume::compress(&g, 2);
        match set.add(&c, colour, intensity) {
            Ok(_) => {
                // Only a volume on the set's points (to the documented snap), inside it,
                // with a colour of light.
                let lo_f = (vd.origin() - d.origin()) / d.h();
                let lo = lo_f.round();
                prop_assert!((lo_f - lo).abs().max_element() <= lightgrid_light_volumes::SNAP);
                prop_assert!(lo.cmpge(Vec3::ZERO).all() && (lo + 2.0).cmple(d.dims().as_vec3()).all());
                prop_assert!(set.grid().data().iter().all(|b| b.is_valid()));
            }
            Err(e) => prop_assert!(!e.to_string().is_empty()),
        }
    }
}

/// The case: a volume at 9e8 m on 1e-4 m points was accepted and applied nothing.
#[test]
fn a_far_volume_is_refused() {
    let d = GridDesc::new(Vec3::ZERO, 1e-4, UVec3::new(6, 4, 6)).unwrap();
    let mut set = LightSet::new(d).unwrap();
    let vd = GridDesc::new(Vec3::splat(9e8), 1e-4, UVec3::new(2, 2, 2)).unwrap();
    let g = LightGrid::filled(vd, BinLight::uniform(Vec3::ONE)).unwrap();
    let e = set
        .add(&CompressedVolume::compress(&g, 3), Vec3::ONE, 1.0)
        .unwrap_err()
        .to_string();
    assert!(e.contains("volume.desc"), "{e}");
}

/// A grid holding infinity (the issue: compress panicked) compresses as the largest
/// light.
#[test]
fn infinity_compresses_as_the_largest_light() {
    let d = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(2, 1, 1)).unwrap();
    let mut g = LightGrid::filled(d, BinLight::ZERO).unwrap();
    g.data_mut()[1].0[0] = Vec3::new(f32::INFINITY, 1.0, f32::NAN);
    let c = CompressedVolume::compress(&g, 4);
    assert_eq!(c.scale, f32::MAX);
    let back = c.decode().unwrap();
    assert!(back.data().iter().all(|b| b.is_valid()));
    assert_eq!(back.data().last().unwrap().0[0].x, f32::MAX);
}

/// CI's case: an origin a subnormal below the set's point is snapped onto it (within
/// [`lightgrid_light_volumes::SNAP`]) and accepted, not refused as outside.
#[test]
fn an_origin_a_hair_off_a_point_is_snapped() {
    let d = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(6, 4, 6)).unwrap();
    let mut set = LightSet::new(d).unwrap();
    let vd = GridDesc::new(
        Vec3::new(1e-4, -8.245247e-39, 1e-4),
        1.0,
        UVec3::new(2, 2, 2),
    )
    .unwrap();
    let g = LightGrid::filled(vd, BinLight::uniform(Vec3::ONE)).unwrap();
    set.add(&CompressedVolume::compress(&g, 2), Vec3::ONE, 1.0)
        .unwrap();
    assert!(set.grid().get(UVec3::ZERO).unwrap().total().max_element() > 0.0);
}
