//! The sweep against physics with exact answers that share none of its assumptions.
//!
//! **Infinite Lambertian ground.** Periodic sides make a grid an infinite slab; its
//! bottom levels are opaque ground of albedo `a`, the rest empty. Whatever the incident
//! light, exactly `a` of it must leave through the top and none through the bottom (the
//! ground is not a window), and the irradiance on a downward-facing normal anywhere
//! above it is `a` times the irradiance the ground receives. Issue 13 found one-level
//! ground reflecting `a/2` (its bottom face emitted into nothing).

use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::{Boundary, SideBoundary, SweepOptions};
use sweep_cpu::sky::{Sun, uniform_sky};

fn ground(levels: u32, albedo: f32) -> lightgrid_core::MaterialGrid {
    sweep_cpu::exact::ground_material(levels, albedo)
}

fn converged() -> SweepOptions {
    let mut o = SweepOptions::multi_bounce();
    o.max_passes = 64;
    o.tolerance = 1e-7;
    o
}

/// (name, top boundary light) for a zenith sun, a low sun between bins and a uniform sky.
fn lights() -> Vec<(&'static str, lightgrid_core::BinLight)> {
    vec![
        (
            "zenith sun",
            Sun::at(90f32.to_radians(), 0.0, Vec3::ONE).bins().unwrap(),
        ),
        (
            "sun at 37 deg, azimuth 20 deg",
            Sun::at(37f32.to_radians(), 20f32.to_radians(), Vec3::ONE)
                .bins()
                .unwrap(),
        ),
        ("uniform sky", uniform_sky(Vec3::ONE).unwrap().top),
    ]
}

#[test]
fn infinite_lambertian_ground_reflects_exactly_its_albedo() {
    for levels in [1, 2, 3] {
        for albedo in [0.0, 0.3, 0.8, 1.0] {
            for (name, top) in lights() {
                let m = ground(levels, albedo);
                let b = Boundary {
                    sides: SideBoundary::Periodic,
                    ..Boundary::open_sky(top)
                };
                let s = sweep_cpu::run(&m, &b, &converged()).unwrap();
                let bal = s.balance;
                let input = bal.input().x;
                let case = format!("{levels} ground levels, albedo {albedo}, {name}");
                assert!(bal.relative_error() < 1e-5, "{case}: balance {bal:?}");
                assert!(bal.pending.x < 1e-6 * input, "{case}: not converged");
                assert!(
                    bal.bottom_out.x.abs() < 1e-6 * input,
                    "{case}: {} of the input left through the ground",
                    bal.bottom_out.x / input
                );
                let reflected = bal.top_out.x / input;
                assert!(
                    (reflected - albedo as f64).abs() < 1e-3,
                    "{case}: reflected {reflected}, exact {albedo}"
                );
            }
        }
    }
}

#[test]
fn light_above_lambertian_ground_is_the_exact_field_up_to_the_channel_cosines() {
    // See `sweep_cpu::exact::ground_fields`: the sweep must hold the rule's field to
    // 1e-4 at every point and level above the ground, and the rule's field differs from
    // the continuous one by the channel cosines alone (printed; within 2.1 % on the axes
    // for albedo <= 0.9). Making `mu_c` the bins' mean cosines is the rest of issue 13.
    for levels in [1, 2] {
        for albedo in [0.3f32, 0.9] {
            let m = ground(levels, albedo);
            let top = uniform_sky(Vec3::ONE).unwrap().top;
            let b = Boundary {
                sides: SideBoundary::Periodic,
                ..Boundary::open_sky(top)
            };
            let s = sweep_cpu::run(&m, &b, &converged()).unwrap();
            let g = s.output.bins.unwrap();
            let (exact, rule) = sweep_cpu::exact::ground_fields(albedo, &top);
            for n in [-Vec3::Y, Vec3::X, Vec3::Y] {
                let (p, e) = (rule.irradiance(n).x, exact.irradiance(n).x);
                println!(
                    "{levels} levels, albedo {albedo}, normal {n}: the rule's field differs from the exact one by {:+.2} %",
                    100.0 * (p / e - 1.0)
                );
                assert!(
                    (p / e - 1.0).abs() < 0.021,
                    "channel cosines off by more than measured"
                );
            }
            let d = *g.desc();
            for j in levels..d.levels() {
                for p in [UVec3::new(0, j, 0), UVec3::new(5, j, 3)] {
                    let l = g.get(p).unwrap();
                    for bin in 0..lightgrid_core::NUM_DIRS {
                        let (got, want) = (l.0[bin].x, rule.0[bin].x);
                        assert!(
                            (got - want).abs() <= 1e-4 * want.max(1e-3),
                            "{levels} levels, albedo {albedo}, point {p}, bin {bin}: {got} vs {want}"
                        );
                    }
                }
            }
        }
    }
}

/// **Chandrasekhar's half-space albedo** (a thick slab of isotropic scatterers under a
/// zenith beam reflects `1 − H(1) √(1 − w)`): with the medium emission rule of a slab's
/// escape (the default) the sweep is within 10 % at cells of optical depth 0.69 and 3
/// (measured +8.7 % / −4.0 % for `w = 0.5`, +5.1 % / −1.5 % for `w = 0.9`); the seed's rule
/// reflects far too much from thick cells (+58 % and +29 % at depth 3).
#[test]
fn half_space_albedo_within_ten_percent_at_any_cell_depth() {
    use lightgrid_core::MediumEmission;
    let mut o = converged();
    o.tolerance = 1e-5;
    o.max_passes = 200;
    for w in [0.5f32, 0.9] {
        for pass in [0.5f32, 0.05] {
            let c = sweep_cpu::exact::half_space_with(w, pass, 40.0, &o);
            assert!(c.error.abs() < 0.10, "{}: {:+.3}", c.name, c.error);
        }
        let mut seed = o;
        seed.medium = MediumEmission::Seed;
        let c = sweep_cpu::exact::half_space_with(w, 0.05, 40.0, &seed);
        assert!(
            c.error > 0.25,
            "the seed's rule, {}: {:+.3}",
            c.name,
            c.error
        );
    }
}

/// The medium emission weights' known answers: a slab of pass-through 0.5 lets
/// `τ p / (1 − p) = ln 2` of a beam's scattered light out straight on and `(1 + p)/2 =
/// 0.75` straight back; clear cells emit isotropically, opaque-like ones a quarter each
/// way; finite everywhere.
#[test]
fn medium_emission_weights_known_answers() {
    use sweep_cpu::sweep::medium_emission;
    let (a, b) = medium_emission(0.5);
    assert!((a - b - std::f32::consts::LN_2).abs() < 1e-6, "{a} {b}");
    assert!((a + b - 0.75).abs() < 1e-6);
    let (a, b) = medium_emission(1.0 - 1e-7);
    assert!((a - 1.0).abs() < 1e-6 && b.abs() < 1e-6, "{a} {b}");
    let (a, b) = medium_emission(1e-30);
    assert!(
        (a - 0.25).abs() < 1e-6 && (b - 0.25).abs() < 1e-6,
        "{a} {b}"
    );
    for i in 1..1000 {
        let (a, b) = medium_emission(i as f32 / 1000.0);
        assert!(a.is_finite() && b.is_finite() && a >= b && b >= 0.0 && a <= 1.0);
    }
}
