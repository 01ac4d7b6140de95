//! Numerical stress (DESIGN.md, "Numerical stability"): extreme ratios, sizes and values;
//! no NaN or infinity ever comes out, energy stays accounted.

use grid_core::glam::{UVec3, Vec3};
use grid_core::{BinLight, Boundary, GridDesc, Material, MaterialGrid, SweepOptions};
use sweep_cpu::run;

fn fog(dims: UVec3, h: f32, albedo: f32, pass: f32) -> MaterialGrid {
    MaterialGrid::filled(
        GridDesc::new(Vec3::ZERO, h, dims).unwrap(),
        Material {
            reflectance: Vec3::splat(albedo),
            pass,
        },
    )
    .unwrap()
}

fn all_finite(s: &sweep_cpu::Sweep) -> bool {
    s.output
        .bins
        .as_ref()
        .is_none_or(|g| g.data().iter().all(|b| b.is_valid()))
        && s.output
            .average
            .as_ref()
            .is_none_or(|g| g.data().iter().all(|a| a.0.is_finite()))
        && s.output.dominant.as_ref().is_none_or(|g| {
            g.data()
                .iter()
                .all(|d| d.0.is_finite() && d.0.length() <= 1.0 + 1e-5)
        })
}

#[test]
fn sun_to_sky_ratio_of_a_million() {
    let (mut top, _) = BinLight::uniform(Vec3::ONE).split_vertical();
    top.0[grid_core::dirs::DOWN] +=
        Vec3::splat(1e6 * grid_core::dirs::solid_angles()[grid_core::dirs::DOWN]);
    for (albedo, pass) in [(0.0, 0.5), (1.0, 0.5), (0.9, 0.0), (0.5, 1.0 - 1e-7)] {
        let s = run(
            &fog(UVec3::new(6, 8, 6), 1.0, albedo, pass),
            &Boundary::open_sky(top),
            &SweepOptions::multi_bounce(),
        )
        .unwrap();
        assert!(all_finite(&s));
        assert!(
            s.balance.relative_error() < 1e-4,
            "albedo {albedo} pass {pass}: {}",
            s.balance.relative_error()
        );
        // Packing keeps the dim sky light: the exposure scales the sun into range.
        let g = s.output.bins.unwrap();
        let p = g.pack().unpack();
        let dim = g.data()[0].0[20];
        if dim.x > 1e-3 {
            assert!(
                (p.data()[0].0[20] - dim).abs().max_element() <= dim.max_element() * 2f32.powi(-6)
            );
        }
    }
}

#[test]
fn one_point_wide_and_1024_levels_tall() {
    let (top, _) = BinLight::uniform(Vec3::ONE).split_vertical();
    for pass in [0.999, 0.9, 0.0] {
        let s = run(
            &fog(UVec3::new(1, 1024, 1), 1.0, 0.8, pass),
            &Boundary::open_sky(top),
            &SweepOptions::multi_bounce(),
        )
        .unwrap();
        assert!(all_finite(&s));
        assert!(
            s.balance.relative_error() < 1e-4,
            "pass {pass}: {:?}",
            s.balance
        );
        // Monotone darkening with depth in an absorbing column.
        let g = s.output.average.unwrap();
        assert!(g.data()[0].0.x <= g.data()[1023].0.x + 1e-6);
    }
}

#[test]
fn cell_size_does_not_change_the_light() {
    // Pass-through is per cell, so the same cells at 1 cm and at 1 km give the same light.
    let (top, _) = BinLight::uniform(Vec3::ONE).split_vertical();
    let a = run(
        &fog(UVec3::new(4, 5, 3), 0.01, 0.6, 0.7),
        &Boundary::open_sky(top),
        &SweepOptions::multi_bounce(),
    )
    .unwrap();
    let b = run(
        &fog(UVec3::new(4, 5, 3), 1000.0, 0.6, 0.7),
        &Boundary::open_sky(top),
        &SweepOptions::multi_bounce(),
    )
    .unwrap();
    assert_eq!(a.output.bins.unwrap().data(), b.output.bins.unwrap().data());
}

#[test]
fn denormal_and_huge_boundary_light() {
    for scale in [1e-40f32, 1e-30, 65024.0, 1e20, 1e30] {
        let (top, _) = BinLight::uniform(Vec3::splat(scale)).split_vertical();
        let s = run(
            &fog(UVec3::new(3, 4, 3), 1.0, 1.0, 0.5),
            &Boundary::open_sky(top),
            &SweepOptions::multi_bounce(),
        )
        .unwrap();
        assert!(all_finite(&s), "scale {scale}");
        let g = s.output.bins.unwrap();
        let packed = g.pack();
        assert!(packed.exposure.is_finite() && packed.exposure > 0.0);
        assert!(packed.unpack().data().iter().all(|b| b.is_valid()));
    }
}

#[test]
fn nan_and_infinity_in_every_input_are_typed_errors() {
    let m = fog(UVec3::splat(2), 1.0, 0.5, 0.5);
    for bad in [f32::NAN, f32::INFINITY, -1.0] {
        let mut sky = BinLight::ZERO;
        sky.0[3].y = bad;
        assert!(
            run(&m, &Boundary::open_sky(sky), &SweepOptions::default()).is_err(),
            "top {bad}"
        );
        let mut b = Boundary::open_sky(BinLight::ZERO);
        b.bottom.0[20].z = bad;
        assert!(
            run(&m, &b, &SweepOptions::default())
                .unwrap_err()
                .to_string()
                .contains("bottom")
        );
        let mut o = SweepOptions::default();
        o.tolerance = bad;
        assert!(
            run(&m, &Boundary::open_sky(BinLight::ZERO), &o)
                .unwrap_err()
                .to_string()
                .contains("tolerance")
        );
        let cells = vec![
            Material {
                reflectance: Vec3::new(bad, 0.0, 0.0),
                pass: 0.5
            };
            8
        ];
        assert!(
            MaterialGrid::new(*m.desc(), cells)
                .unwrap_err()
                .to_string()
                .contains("reflectance.x")
        );
        assert!(GridDesc::new(Vec3::ZERO, bad, UVec3::ONE).is_err());
        assert!(sweep_cpu::sky::uniform_sky(Vec3::splat(bad)).is_err());
        if !bad.is_finite() {
            assert!(GridDesc::new(Vec3::splat(bad), 1.0, UVec3::ONE).is_err());
            assert!(sweep_cpu::Sun::at(bad, 0.0, Vec3::ONE).bins().is_err());
        }
    }
}
