//! The sweep against physics with exact answers that share none of its assumptions
//! (issue 13). Every case also holds the energy balance to 1e-5.
//!
//! **White furnace.** White media (albedo 1) inside uniform radiance 1: the light is 1
//! from every direction at every point, whatever the medium. Random blobs of pass-through
//! 0.02 to 1 and uniform media, any smoothing: to 1e-3, under the default rule (a
//! quadratic source in height, `lightgrid_sweep_cpu::profile`) and the flat one (the telescoping
//! emission along each path, `lightgrid_sweep_cpu::medium`).
//!
//! **Chandrasekhar's half-space albedo**, under a beam and under a uniform sky, at every
//! albedo and cell depth from 0.05 to 3 (the default rule; the flat rule's thick dark
//! cells are held where they are).
//!
//! **Infinite Lambertian ground.** Periodic sides make a grid an infinite slab; its
//! bottom levels are opaque ground of albedo `a`, the rest empty. Whatever the incident
//! light, exactly `a` of it must leave through the top and none through the bottom (the
//! ground is not a window), and the irradiance on a downward-facing normal anywhere
//! above it is `a` times the irradiance the ground receives. Issue 13 found one-level
//! ground reflecting `a/2` (its bottom face emitted into nothing).

use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::{Boundary, SideBoundary, SweepOptions};
use lightgrid_sky::{Sun, uniform_sky};

fn ground(levels: u32, albedo: f32) -> lightgrid_core::MaterialGrid {
    lightgrid_measure::exact::ground_material(levels, albedo).unwrap()
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
                let s = lightgrid_sweep_cpu::run(&m, &b, &converged()).unwrap();
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
fn light_above_lambertian_ground_is_the_exact_field() {
    // See `lightgrid_measure::exact::ground_fields`: the sweep must hold the rule's field to
    // 1e-4 at every point and level above the ground, and since the channels' cosines
    // are the bins' mean cosines (`sweep::channel_length`) the rule's field is the exact
    // continuous one (it was off by up to 2.1 % with the step vectors' cosines).
    for levels in [1, 2] {
        for albedo in [0.3f32, 0.9] {
            let m = ground(levels, albedo);
            let top = uniform_sky(Vec3::ONE).unwrap().top;
            let b = Boundary {
                sides: SideBoundary::Periodic,
                ..Boundary::open_sky(top)
            };
            let s = lightgrid_sweep_cpu::run(&m, &b, &converged()).unwrap();
            let g = s.output.bins.unwrap();
            let (exact, rule) = lightgrid_measure::exact::ground_fields(albedo, &top).unwrap();
            for bin in 0..lightgrid_core::NUM_DIRS {
                let (r, e) = (rule.0[bin].x, exact.0[bin].x);
                assert!(
                    (r - e).abs() <= 1e-5 * e.max(1e-3),
                    "bin {bin}: the rule's field {r}, exact {e}"
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

/// Empty space above an infinite Lambertian ground, handed the exact field through all
/// its faces as a hierarchy's node takes a coarser grid's light: the sky through the
/// top, the ground's light through the bottom and the full field through the sides
/// (`SideBoundary::Given`, full-sphere bins), holds the exact field at every point and
/// bin to 1e-4: the hand-over loses nothing. Each horizontal bin of the field is half sky
/// (radiance 1) and half ground (radiance `a`); the bottom takes the field's upward part
/// and the sides split it across the horizon by its neighbours
/// (`BinLight::split_vertical_by_neighbours`, `horizon_share`). An even split
/// (`split_vertical`) hands the downward pass `(1 + a) / 2` of the sky's half: 35 % off
/// at `a` = 0.3, half under a black ground.
#[test]
fn a_field_handed_over_through_the_faces_is_kept_exactly() {
    use lightgrid_core::{GridDesc, Material, MaterialGrid};
    let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(8, 6, 8)).unwrap();
    let m = MaterialGrid::filled(desc, Material::EMPTY).unwrap();
    for albedo in [0.0f32, 0.3, 0.9] {
        let sky = uniform_sky(Vec3::ONE).unwrap().top;
        let (exact, _) = lightgrid_measure::exact::ground_fields(albedo, &sky).unwrap();
        let (down, up) = exact.split_vertical_by_neighbours();
        for bin in 0..lightgrid_core::NUM_DIRS {
            assert!(
                (down.0[bin] - sky.0[bin]).abs().max_element() <= 1e-6,
                "bin {bin}"
            );
        }
        let halo = vec![exact; lightgrid_core::HaloLayout::new(desc.dims()).len()];
        let b = Boundary {
            top: lightgrid_core::TopBoundary::Uniform(Box::new(down)),
            bottom: up,
            sides: SideBoundary::Given(halo),
        };
        let g = lightgrid_sweep_cpu::run(&m, &b, &converged())
            .unwrap()
            .output
            .bins
            .unwrap();
        for (i, l) in g.data().iter().enumerate() {
            for bin in 0..lightgrid_core::NUM_DIRS {
                let (got, want) = (l.0[bin].x, exact.0[bin].x);
                assert!(
                    (got - want).abs() <= 1e-4 * want.max(1e-3),
                    "albedo {albedo}, point {i}, bin {bin}: {got} vs {want}"
                );
            }
        }
    }
}

/// A free-streaming field whose horizontal bins are not split across the horizon as
/// their neighbours say (a sky bright at the horizon over a dark ground: each horizontal
/// bin 80 % downward light, where the neighbours 45° above and below give another
/// share), handed over through all faces as a hierarchy's node takes a coarser grid's
/// light that kept its horizon halves: the top with the downward halves, the bottom with
/// the rest, the sides with the full bins and their downward halves
/// (`SideBoundary::GivenHalves`). Empty space keeps the field exactly, every point and
/// bin to 1e-4, and the downward halves the sweep writes are the given ones. The sides
/// without their halves (`SideBoundary::Given`, split by the neighbours) put the wrong
/// share into each pass: more than 10 % off near the sides.
#[test]
fn horizon_halves_handed_over_through_the_sides_are_kept_exactly() {
    use lightgrid_core::dirs::{FIRST_HORIZONTAL, HORIZONTAL_BINS, dir_unit};
    use lightgrid_core::{BinLight, GridDesc, HorizonLight, Material, MaterialGrid, NUM_DIRS};
    let desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(8, 6, 8)).unwrap();
    let m = MaterialGrid::filled(desc, Material::EMPTY).unwrap();
    // Radiance per bin, times its solid angle: a horizon band over a dim ground.
    let omega = lightgrid_core::dirs::solid_angles();
    let field = BinLight(std::array::from_fn(|b| {
        let dy = dir_unit(b).y;
        let radiance = if dy < 0.0 {
            1.0 + 0.2 * b as f32
        } else if dy > 0.0 {
            0.15
        } else {
            2.5
        };
        Vec3::new(1.0, 0.8, 0.6) * radiance * omega[b]
    }));
    let halves = HorizonLight(std::array::from_fn(|k| field.0[FIRST_HORIZONTAL + k] * 0.8));
    let (mut top, mut bottom) = (BinLight::ZERO, BinLight::ZERO);
    for b in 0..NUM_DIRS {
        let dy = dir_unit(b).y;
        if dy < 0.0 {
            top.0[b] = field.0[b];
        } else if dy > 0.0 {
            bottom.0[b] = field.0[b];
        }
    }
    for k in 0..HORIZONTAL_BINS {
        top.0[FIRST_HORIZONTAL + k] = halves.0[k];
        bottom.0[FIRST_HORIZONTAL + k] = field.0[FIRST_HORIZONTAL + k] - halves.0[k];
    }
    let n = lightgrid_core::HaloLayout::new(desc.dims()).len();
    let mut o = converged();
    o.outputs.horizon = true;
    let sweep = |sides: SideBoundary| {
        let b = Boundary {
            top: lightgrid_core::TopBoundary::Uniform(Box::new(top)),
            bottom,
            sides,
        };
        lightgrid_sweep_cpu::run(&m, &b, &o).unwrap().output
    };
    let given = sweep(SideBoundary::GivenHalves {
        light: vec![field; n],
        down: vec![halves; n],
        cells: None,
    });
    let (bins, down) = (given.bins.unwrap(), given.horizon.unwrap());
    for (i, (l, d)) in bins.data().iter().zip(down.data()).enumerate() {
        for bin in 0..NUM_DIRS {
            let (got, want) = (l.0[bin], field.0[bin]);
            assert!(
                (got - want).abs().max_element() <= 1e-4 * want.max_element(),
                "point {i}, bin {bin}: {got} vs {want}"
            );
        }
        for k in 0..HORIZONTAL_BINS {
            let (got, want) = (d.0[k], halves.0[k]);
            assert!(
                (got - want).abs().max_element() <= 1e-4 * want.max_element(),
                "point {i}, half {k}: {got} vs {want}"
            );
        }
    }
    // Split by the neighbours instead: the same field, read wrong near the sides.
    let split = sweep(SideBoundary::Given(vec![field; n])).horizon.unwrap();
    let worst = split
        .data()
        .iter()
        .flat_map(|d| (0..HORIZONTAL_BINS).map(move |k| (d.0[k].x / halves.0[k].x - 1.0).abs()))
        .fold(0.0f32, f32::max);
    assert!(worst > 0.1, "the neighbours' split, worst half {worst}");
}

/// Beam conservation with the sun in the bins (issue 44): over an infinite black ground
/// (periodic sides), what enters through the top per column and what the ground absorbs
/// are `E sin(elevation)` at every elevation from 2° to 90° and any azimuth, to 1e-4
/// (before: the bin's mean cosine instead of the beam's, +9 % at 25°).
#[test]
fn a_sun_in_the_bins_brings_the_beams_flux_at_any_elevation() {
    let m = ground(1, 0.0);
    let columns = m.desc().level_len() as f64;
    for elevation in [2.0f32, 7.0, 15.0, 25.0, 40.0, 55.0, 70.0, 90.0] {
        for azimuth in [0.0f32, 0.7, 2.2] {
            let top = Sun::at(elevation.to_radians(), azimuth, Vec3::ONE)
                .bins()
                .unwrap();
            let b = Boundary {
                sides: SideBoundary::Periodic,
                ..Boundary::open_sky(top)
            };
            let bal = lightgrid_sweep_cpu::run(&m, &b, &converged())
                .unwrap()
                .balance;
            let want = (elevation as f64).to_radians().sin();
            for (what, got) in [("entering", bal.top_in.x), ("absorbed", bal.absorbed.x)] {
                let got = got / columns;
                assert!(
                    (got / want - 1.0).abs() < 1e-4,
                    "{elevation}° {azimuth}: {what} {got} vs {want}"
                );
            }
        }
    }
}

#[test]
fn white_furnace_is_exact_in_random_media() {
    for seed in [7u64, 11, 23] {
        for smoothing in [0.0f32, 0.25, 0.6] {
            let (avg, irr) = lightgrid_measure::exact::furnace(10, seed, smoothing).unwrap();
            for c in [avg, irr] {
                assert!(c.balance < 1e-5, "{}: balance {}", c.name, c.balance);
                assert!(c.pending < 1e-5, "{}: not converged", c.name);
                assert!(
                    c.error.abs() < 1e-3,
                    "seed {seed}, {}: {:+.2e}",
                    c.name,
                    c.error
                );
            }
        }
    }
    for pass in [0.95f32, 0.5, 0.1, 0.02] {
        let c = lightgrid_measure::exact::uniform_furnace(pass).unwrap();
        assert!(c.pending < 1e-5, "{}: not converged", c.name);
        assert!(
            c.balance < 1e-5 && c.error.abs() < 1e-3,
            "{}: {:+.2e}",
            c.name,
            c.error
        );
    }
}

/// The escape rule (`MediumEmission::Escape`) fails the furnace: kept as an option (it
/// is closer on thick dark cells), it must still show it (this suite tells the rules
/// apart).
#[test]
fn the_escape_rule_fails_the_furnace() {
    use lightgrid_core::MediumEmission;
    let m = lightgrid_measure::exact::furnace_material(8, 7).unwrap();
    let b = Boundary {
        sides: SideBoundary::Periodic,
        ..Boundary::surrounding(&lightgrid_core::BinLight::uniform(Vec3::ONE))
    };
    let mut o = converged();
    o.medium = MediumEmission::Escape;
    o.max_passes = 200;
    o.tolerance = 1e-6;
    let s = lightgrid_sweep_cpu::run(&m, &b, &o).unwrap();
    let worst = s
        .output
        .bins
        .unwrap()
        .data()
        .iter()
        .map(|l| (l.average().x - 1.0).abs())
        .fold(0f32, f32::max);
    assert!(worst > 0.05, "worst deviation {worst}");
}

/// The flat source (`MediumEmission::Source`, the option) against Chandrasekhar's
/// half-space albedo: within 2 % for `w` in {0.1, 0.5, 0.9, 0.99} at cells of optical
/// depth 0.05 and 0.69 (measured +1.6 / +1.1 / +0.2 / −0.1 % and −1.4 / −0.4 / +0.3 /
/// +0.1 %), and at depth 3 for `w` ≥ 0.9 (+0.4 %, +2.5 % allowed 3 %). At depth 3 it
/// reflects too little for `w` 0.1 and 0.5 (measured −23 % and −15 %: a flat source
/// within a cell, shared up and down by a beam's profile, `lightgrid_sweep_cpu::medium`), which
/// is why the default is the quadratic source in height; the bound below holds them
/// there so that a change that makes them worse fails.
#[test]
fn flat_rule_half_space_albedo() {
    let mut o = converged();
    o.medium = lightgrid_core::MediumEmission::Source;
    o.tolerance = 1e-5;
    o.max_passes = 400;
    let check = |w: f32, pass: f32, tol: f64| {
        let c = lightgrid_measure::exact::half_space_with(w, pass, 40.0, &o).unwrap();
        assert!(c.balance < 1e-5, "{}: balance {}", c.name, c.balance);
        assert!(
            c.error.abs() < tol,
            "{}: {:+.4} (allowed {tol})",
            c.name,
            c.error
        );
    };
    for w in [0.1f32, 0.5, 0.9, 0.99] {
        check(w, 0.95, 0.02);
        check(w, 0.5, 0.02);
    }
    check(0.9, 0.05, 0.02);
    check(0.99, 0.05, 0.03);
    // Dark, thick cells (see above).
    check(0.1, 0.05, 0.25);
    check(0.5, 0.05, 0.17);
}

/// The escape rule, kept for thick dark cells: there it is closer than the source rule
/// (measured −3.3 % and −4.2 % at cell optical depth 3, `w` 0.1 and 0.5).
#[test]
fn the_escape_rule_is_closer_on_thick_dark_cells() {
    use lightgrid_core::MediumEmission;
    let mut o = converged();
    o.tolerance = 1e-5;
    o.max_passes = 200;
    for w in [0.1f32, 0.5] {
        o.medium = MediumEmission::Escape;
        let escape = lightgrid_measure::exact::half_space_with(w, 0.05, 40.0, &o).unwrap();
        o.medium = MediumEmission::Source;
        let source = lightgrid_measure::exact::half_space_with(w, 0.05, 40.0, &o).unwrap();
        assert!(
            escape.error.abs() < 0.05 && escape.error.abs() < source.error.abs(),
            "{}: escape {:+.3}, source {:+.3}",
            escape.name,
            escape.error,
            source.error
        );
    }
}

/// The medium emission weights' known answers: a slab of pass-through 0.5 lets
/// `τ p / (1 − p) = ln 2` of a beam's scattered light out straight on and `(1 + p)/2 =
/// 0.75` straight back; clear cells emit isotropically, opaque-like ones a quarter each
/// way; finite everywhere.
#[test]
fn medium_emission_weights_known_answers() {
    use lightgrid_sweep_cpu::sweep::medium_emission;
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

/// The flat source (`MediumEmission::Source`, the option) keeps the white furnace exact
/// too: random blobs of pass-through 0.02 to 1, any smoothing, to 1e-3.
#[test]
fn white_furnace_is_exact_with_the_flat_rule() {
    let mut o = SweepOptions::multi_bounce();
    o.medium = lightgrid_core::MediumEmission::Source;
    o.max_passes = 400;
    o.tolerance = 1e-6;
    for seed in [7u64, 23] {
        for smoothing in [0.0f32, 0.25] {
            o.smoothing = smoothing;
            let (avg, irr) = lightgrid_measure::exact::furnace_with(10, seed, &o).unwrap();
            for c in [avg, irr] {
                assert!(c.balance < 1e-5, "{}: balance {}", c.name, c.balance);
                assert!(
                    c.error.abs() < 1e-3,
                    "seed {seed}, {}: {:+.2e}",
                    c.name,
                    c.error
                );
            }
        }
    }
}

/// **Chandrasekhar's half-space albedo** (a thick slab of isotropic scatterers under a
/// zenith beam reflects `1 − H(1) √(1 − w)`) with the default rule, a quadratic source
/// in height (`MediumEmission::Profile`): within 2 % for `w` in {0.1, 0.5, 0.9} at
/// cells of optical depth 0.05 to 3, the whole range (measured +1.66 / +1.07 /
/// +0.20 % at depth 0.05, +0.75 / +1.14 / +0.46 % at depth 3: the channels' own angular
/// error, `examples/do1d.rs`), where the flat source is 23 % low at depth 3, `w` 0.1.
#[test]
fn half_space_albedo_within_two_percent() {
    let mut o = converged();
    assert_eq!(
        o.medium,
        lightgrid_core::MediumEmission::Profile,
        "the default"
    );
    o.tolerance = 1e-5;
    o.max_passes = 400;
    for w in [0.1f32, 0.5, 0.9] {
        for pass in [0.95f32, 0.5, 0.2, 0.05] {
            let c = lightgrid_measure::exact::half_space_with(w, pass, 40.0, &o).unwrap();
            assert!(c.balance < 1e-5, "{}: balance {}", c.name, c.balance);
            assert!(c.error.abs() < 0.02, "{}: {:+.4}", c.name, c.error);
        }
    }
}

/// The same at `w` 0.99 (measured −0.06 % at depth 0.05, −0.02 % at depth 3; the flat
/// source is +2.5 % at depth 3). Plain passes (hundreds): the rule itself, not the
/// acceleration (`tests/accel.rs` runs that).
#[test]
fn bright_half_space_within_two_percent() {
    let mut o = converged();
    o.tolerance = 1e-5;
    o.max_passes = 1000;
    for pass in [0.95f32, 0.5, 0.05] {
        let c = lightgrid_measure::exact::half_space_with(0.99, pass, 40.0, &o).unwrap();
        assert!(c.balance < 1e-5, "{}: balance {}", c.name, c.balance);
        assert!(c.error.abs() < 0.02, "{}: {:+.4}", c.name, c.error);
    }
}

/// **Half-space albedo under a uniform sky** (Chandrasekhar's diffuse albedo; the light
/// enters through the top boundary's bins, not as a cell source). With the default
/// profile rule within 5 % at cells of optical depth 0.05 to 3 (measured: +4.5 / +3.5 / +1.7 % at
/// depth 0.05 for `w` 0.1 / 0.5 / 0.9, the channels' angular error under diffuse light,
/// and −0.1 / +1.4 / +1.6 % at depth 3); the flat source is −47 / −39 / −18 % at depth
/// 3 (`examples/hs_diffuse.rs`), which this test also shows.
#[test]
fn sky_lit_half_space() {
    use lightgrid_core::glam::UVec3 as U;
    use lightgrid_core::{BinLight, GridDesc, Material, MaterialGrid, MediumEmission};
    let (sky, _) = BinLight::uniform(Vec3::ONE).split_vertical();
    let albedo = |w: f32, tau: f32, rule: MediumEmission| {
        let levels = ((40.0 / tau).ceil() as u32).max(2);
        let d = GridDesc::new(Vec3::ZERO, 1.0, U::new(4, levels, 4)).unwrap();
        let cell = Material {
            reflectance: Vec3::splat(w),
            pass: (-tau).exp(),
        };
        let m = MaterialGrid::filled(d, cell).unwrap();
        let b = Boundary {
            sides: SideBoundary::Periodic,
            ..Boundary::open_sky(sky)
        };
        let mut o = converged();
        o.medium = rule;
        o.tolerance = 1e-6;
        o.max_passes = 400;
        let s = lightgrid_sweep_cpu::run(&m, &b, &o).unwrap();
        assert!(s.balance.relative_error() < 1e-5, "{:?}", s.balance);
        let exact = lightgrid_measure::exact::half_space_albedo_diffuse(w as f64);
        s.balance.top_out.x / s.balance.top_in.x / exact - 1.0
    };
    for w in [0.1f32, 0.5, 0.9] {
        for tau in [0.05f32, 0.69, 3.0] {
            let e = albedo(w, tau, MediumEmission::Profile);
            assert!(e.abs() < 0.05, "w {w}, depth {tau}: {:+.4}", e);
        }
        let flat = albedo(w, 3.0, MediumEmission::Source);
        assert!(flat < -0.15, "w {w}: the flat rule at depth 3 {flat:+.4}");
    }
}

/// The horizon (issue 44): above an infinite Lambertian ground under a uniform sky a
/// surface facing up receives `pi`, one facing down `a pi` and one facing sideways
/// `(1 + a) pi / 2`, exactly. Each horizontal bin holds sky above the horizon and ground
/// below it; read as even across the horizon (`BinLight::irradiance`) facing down is
/// `(1 + a) / 2`'s share too much (+13 % at `a` = 0.3) and facing up too little. With the
/// sweep's downward halves (`Outputs::horizon`, `BinLight::irradiance_split`) all three
/// hold to 1e-3 at every level above one, two and three ground levels.
#[test]
fn surfaces_facing_up_and_down_over_a_lambertian_ground_read_exactly_with_the_halves() {
    let pi = std::f32::consts::PI;
    let top = uniform_sky(Vec3::ONE).unwrap().top;
    let b = Boundary {
        sides: SideBoundary::Periodic,
        ..Boundary::open_sky(top)
    };
    let mut o = converged();
    o.outputs = o.outputs.with_horizon();
    for levels in [1, 2, 3] {
        for albedo in [0.0f32, 0.3, 0.8] {
            let m = ground(levels, albedo);
            let out = lightgrid_sweep_cpu::run(&m, &b, &o).unwrap().output;
            let (g, h) = (out.bins.unwrap(), out.horizon.unwrap());
            for j in levels..g.desc().levels() {
                let p = UVec3::new(2, j, 6);
                let (l, down) = (g.get(p).unwrap(), h.get(p).unwrap());
                for (n, want) in [
                    (Vec3::Y, pi),
                    (Vec3::NEG_Y, albedo * pi),
                    (Vec3::Z, (1.0 + albedo) * pi / 2.0),
                ] {
                    let got = l.irradiance_split(n, down).x;
                    assert!(
                        (got - want).abs() <= 1e-3 * pi,
                        "{levels} levels, albedo {albedo}, level {j}, facing {n}: {got}, exact {want}"
                    );
                }
                if albedo == 0.3 {
                    let even = l.irradiance(Vec3::NEG_Y).x / (albedo * pi);
                    assert!(even > 1.1, "the even reading facing down: {even}");
                }
            }
        }
    }
}

/// A 10° sun's first scatterings gathered by rays (`Gather::LOW_SUN`) over one and
/// three levels of Lambertian ground: a surface facing down just above the ground
/// receives the ground's exitance `a sin 10°` within 1 % (the rays' quadrature; the
/// case `cargo xtask exact` lists).
#[test]
fn a_gathered_low_sun_over_lambertian_ground_is_exact() {
    for levels in [1, 3] {
        let c = lightgrid_measure::exact::gathered_ground(levels, 0.3, 10.0).unwrap();
        eprintln!("{c:?}");
        assert!(c.error.abs() < 0.01, "{c:?}");
    }
}
