//! Numerical stress (DESIGN.md, "Numerical stability"): extreme ratios, sizes and values;
//! no NaN or infinity ever comes out, energy stays accounted.

use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::{BinLight, Boundary, GridDesc, Material, MaterialGrid, SweepOptions};
use lightgrid_sweep_cpu::run;

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

fn all_finite(s: &lightgrid_sweep_cpu::Sweep) -> bool {
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
    top.0[lightgrid_core::dirs::DOWN] +=
        Vec3::splat(1e6 * lightgrid_core::dirs::solid_angles()[lightgrid_core::dirs::DOWN]);
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
        assert!(lightgrid_sky::uniform_sky(Vec3::splat(bad)).is_err());
        if !bad.is_finite() {
            assert!(GridDesc::new(Vec3::splat(bad), 1.0, UVec3::ONE).is_err());
            assert!(lightgrid_sky::Sun::at(bad, 0.0, Vec3::ONE).bins().is_err());
        }
    }
}

/// Pass-through 0, 1 and 1 − 1e-7 (and 1e-30, optical depth 69 a cell) with albedo 0
/// and 1, under either medium rule (flat or quadratic source in height): finite, energy
/// accounted; fully clear cells (1) give exactly the empty sweep's light and 1 − 1e-7
/// within 1e-5 of it; black opaque cells (0, 0) absorb everything that enters the top.
#[test]
fn extreme_pass_through_and_albedo() {
    let (top, _) = BinLight::uniform(Vec3::new(1.0, 0.5, 0.25)).split_vertical();
    let b = Boundary::open_sky(top);
    let dims = UVec3::new(5, 6, 5);
    let empty = run(&fog(dims, 1.0, 0.0, 1.0), &b, &SweepOptions::multi_bounce()).unwrap();
    let empty_g = empty.output.bins.as_ref().unwrap();
    for (albedo, pass, rule) in [0.0, 1.0]
        .into_iter()
        .flat_map(|a| [0.0, 1.0, 1.0 - 1e-7, 1e-30].map(|p| (a, p)))
        .flat_map(|(a, p)| {
            [
                lightgrid_core::MediumEmission::Source,
                lightgrid_core::MediumEmission::Profile,
            ]
            .map(|r| (a, p, r))
        })
    {
        {
            let mut o = SweepOptions::multi_bounce();
            o.medium = rule;
            let s = run(&fog(dims, 1.0, albedo, pass), &b, &o).unwrap();
            assert!(all_finite(&s), "albedo {albedo} pass {pass} {rule:?}");
            assert!(
                s.balance.relative_error() < 1e-4,
                "albedo {albedo} pass {pass} {rule:?}: {}",
                s.balance.relative_error()
            );
            let g = s.output.bins.as_ref().unwrap();
            if pass == 1.0 {
                assert_eq!(g, empty_g, "clear cells must not touch the light");
            } else if pass > 0.999 {
                // Within 1e-5 of the grid's largest value (light scattered out of 1e-7 of
                // the beam shows up in bins the empty sweep leaves at zero).
                let tol = 1e-5 * empty_g.max_value();
                for (a, e) in g.data().iter().zip(empty_g.data()) {
                    for d in 0..26 {
                        assert!((a.0[d] - e.0[d]).abs().max_element() <= tol);
                    }
                }
            } else if albedo == 0.0 {
                // Black and opaque: what enters is absorbed, nothing comes back out.
                let bal = &s.balance;
                assert!(
                    bal.top_out.max_element() < 1e-6 * bal.top_in.max_element(),
                    "{bal:?}"
                );
                assert!(
                    (bal.absorbed - bal.top_in - bal.side_in)
                        .abs()
                        .max_element()
                        < 1e-4 * bal.top_in.max_element()
                );
            }
        }
    }
}

/// Light around and beyond R11G11B10's largest finite value (65024): a sweep whose bins
/// reach 6.5e4 to 5e6 stays finite and packs (with the per-grid exposure) within the format's
/// precision, instead of saturating to 65024 or overflowing.
#[test]
fn light_beyond_the_packed_format_range() {
    for scale in [1.45e5f32, 1e6, 1e7] {
        let (top, _) = BinLight::uniform(Vec3::splat(scale)).split_vertical();
        let s = run(
            &fog(UVec3::new(4, 5, 4), 1.0, 0.8, 0.6),
            &Boundary::open_sky(top),
            &SweepOptions::multi_bounce(),
        )
        .unwrap();
        assert!(all_finite(&s));
        let g = s.output.bins.unwrap();
        assert!(g.max_value() > 6.5e4, "{}", g.max_value());
        let back = g.pack().unpack();
        for (a, b) in g.data().iter().zip(back.data()) {
            for d in 0..26 {
                let tol = a.0[d].max_element() * 2f32.powi(-5) + g.max_value() * 1e-6;
                assert!(
                    (a.0[d] - b.0[d]).abs().max_element() <= tol,
                    "{} vs {}",
                    a.0[d],
                    b.0[d]
                );
            }
        }
    }
}

/// Ten million equal deposits into one Monte Carlo tally equal the f64 sum; a plain f32
/// running sum of the same deposits is off by more than 1 % (so the check has teeth).
#[test]
fn ten_million_equal_deposits_into_one_cell() {
    let n = 10_000_000u32;
    let v = Vec3::new(0.1, 0.3, 7.0);
    let mut t = lightgrid_measure::reference::Tally::new(2);
    let mut naive = 0f32;
    for _ in 0..n {
        t.add(1, v);
        naive += v.x;
    }
    let exact = v.as_dvec3() * n as f64;
    let got = t.get(1);
    assert!(
        ((got - exact) / exact).abs().max_element() < 1e-12,
        "{got} vs {exact}"
    );
    assert_eq!(t.get(0), lightgrid_core::glam::DVec3::ZERO);
    assert!(((naive as f64 - exact.x) / exact.x).abs() > 1e-2, "{naive}");
}
