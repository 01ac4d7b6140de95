//! The sun split (issue 14): the beam attenuated along its exact direction
//! (`SunTransmittance`), its first collisions scattered into the sweep as a cell source
//! (`first_collision`, `run_with_source`), against answers that need no sweep.
//!
//! **Infinite Lambertian ground under a sun between the bins.** The ground receives
//! exactly `E cos θ` (direct irradiance on its face: the transmittance is 1 above it),
//! reflects exactly its albedo of that through the top, and nothing leaves through it.
//! With the sun in the bins instead, its light moves along the nearest bin and lands on
//! the ground with the bin's mean cosine.

use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::{
    BinLight, Boundary, GridDesc, Material, MaterialGrid, SideBoundary, SweepOptions,
};
use lightgrid_sweep_cpu::run_with_source;
use lightgrid_sweep_cpu::sun::first_collision;

fn converged() -> SweepOptions {
    let mut o = SweepOptions::multi_bounce();
    o.max_passes = 64;
    o.tolerance = 1e-7;
    o
}

fn dark_periodic() -> Boundary {
    Boundary {
        sides: SideBoundary::Periodic,
        ..Boundary::open_sky(BinLight::ZERO)
    }
}

fn sun(elevation_deg: f32, azimuth_deg: f32) -> Vec3 {
    let (e, a) = (elevation_deg.to_radians(), azimuth_deg.to_radians());
    Vec3::new(e.cos() * a.cos(), e.sin(), e.cos() * a.sin())
}

#[test]
fn ground_receives_e_cos_theta_and_reflects_exactly_its_albedo() {
    let e = Vec3::new(1.0, 0.8, 0.5);
    for levels in [1, 2] {
        for albedo in [0.3f32, 0.8] {
            for (elev, azim) in [(90.0, 0.0), (37.0, 20.0), (12.0, 63.0)] {
                let m = lightgrid_measure::exact::ground_material(levels, albedo).unwrap();
                let to_sun = sun(elev, azim);
                let open = |_: Vec3| 1.0;
                let src = first_collision(&m, to_sun, e, true, &open).unwrap();
                let case = format!("{levels} levels, albedo {albedo}, sun {elev}/{azim}");
                // Every top ground cell takes exactly E cos(theta); nothing else does.
                let d = *m.desc();
                for (i, r) in src.removed().iter().enumerate() {
                    let top_ground = d.coords(i).unwrap().y == levels - 1;
                    let want = if top_ground { e * to_sun.y } else { Vec3::ZERO };
                    assert!(
                        (*r - want).abs().max_element() < 1e-6,
                        "{case}: cell {i} {r}"
                    );
                }
                let s = run_with_source(&m, &dark_periodic(), Some(&src), &converged()).unwrap();
                let b = s.balance;
                assert!(b.relative_error() < 1e-5, "{case}: {b:?}");
                let input = b.source_in;
                assert!((input.x - (e.x * to_sun.y) as f64 * 64.0).abs() < 1e-4);
                let reflected = b.top_out / input;
                assert!(
                    (reflected - Vec3::splat(albedo).as_dvec3())
                        .abs()
                        .max_element()
                        < 1e-3,
                    "{case}: reflected {reflected}"
                );
                assert!(b.bottom_out.max_element() < 1e-6 * input.x, "{case}");
                // Above the ground: the field the sweep's rules give for a Lambertian
                // ground lit with E cos(theta) (`exact::ground_fields` with that flux
                // arriving straight down), at every level: since the channels' cosines
                // are the bins' mean cosines, the exact continuous field.
                // (`ground_fields` is grey: run it for red and scale the colour.)
                let mut straight = BinLight::ZERO;
                let mu = lightgrid_sweep_cpu::sweep::channels(false)[lightgrid_core::dirs::DOWN].mu;
                straight.0[lightgrid_core::dirs::DOWN] = Vec3::splat(to_sun.y / mu);
                let (_, rule) = lightgrid_measure::exact::ground_fields(albedo, &straight).unwrap();
                let g = s.output.bins.unwrap();
                for j in levels..d.levels() {
                    let l = g.get(UVec3::new(3, j, 5)).unwrap();
                    for bin in 0..lightgrid_core::NUM_DIRS {
                        if lightgrid_core::dirs::dir_unit(bin).y < 0.0 {
                            assert_eq!(l.0[bin], Vec3::ZERO, "{case}: level {j} bin {bin}");
                            continue;
                        }
                        let (got, want) = (l.0[bin], rule.0[bin].x * e);
                        assert!(
                            (got - want).abs().max_element() <= 1e-4 * want.max_element().max(1e-3),
                            "{case}: level {j} bin {bin}: {got} vs {want}"
                        );
                    }
                }
            }
        }
    }
}

/// A uniform half-space under an oblique sun: the cells' deposits add up to the beam's
/// loss, `E cos θ (1 - T(bottom face))`; and the sweep conserves it all.
#[test]
fn deposits_telescope_to_the_beams_loss_and_energy_balances() {
    for (pass, w) in [(0.9f32, 0.5f32), (0.5, 0.9), (0.05, 0.99)] {
        let levels = 12u32;
        let d = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(4, levels, 4)).unwrap();
        let m = MaterialGrid::filled(
            d,
            Material {
                reflectance: Vec3::splat(w),
                pass,
            },
        )
        .unwrap();
        let to_sun = sun(41.0, 17.0);
        // Beyond the sides the medium goes on: the exact transmittance of the layers
        // above the exit point.
        let top = levels as f32 - 0.5;
        let outside = move |wp: Vec3| pass.powf((top - wp.y) / to_sun.normalize().y);
        let s_y = to_sun.normalize().y;
        let src = first_collision(&m, to_sun, Vec3::ONE, true, &outside).unwrap();
        let total: f32 = src.removed().iter().map(|r| r.x).sum();
        let want = 16.0 * s_y * (1.0 - pass.powf(levels as f32 / s_y));
        assert!(
            (total - want).abs() < 1e-4 * want,
            "pass {pass}: deposited {total}, the beam lost {want}"
        );
        let r = run_with_source(&m, &dark_periodic(), Some(&src), &converged()).unwrap();
        assert!(r.balance.relative_error() < 1e-5, "{:?}", r.balance);
    }
}

#[test]
fn bad_sources_are_refused_by_name() {
    let m = lightgrid_measure::exact::ground_material(1, 0.5).unwrap();
    let open = |_: Vec3| 1.0;
    let e = first_collision(&m, Vec3::Y, Vec3::ONE, true, &open);
    assert!(e.is_ok());
    let e = first_collision(&m, Vec3::ZERO, Vec3::ONE, true, &open).unwrap_err();
    assert!(e.to_string().contains("to_sun"), "{e}");
    let e = first_collision(&m, Vec3::Y, Vec3::new(f32::NAN, 1.0, 1.0), true, &open).unwrap_err();
    assert!(e.to_string().contains("irradiance"), "{e}");
    let e = lightgrid_sweep_cpu::CellSource::new(*m.desc(), vec![Vec3::NEG_ONE; 512], Vec3::Y)
        .unwrap_err();
    assert!(e.to_string().contains("removed[0]"), "{e}");
}

/// The reference's collimated sun: in an empty grid every cell's uncollided light is
/// the sun's irradiance (the track length of parallel rays per unit volume), nothing is
/// scattered; over a Lambertian ground the reflected fraction is the albedo.
#[test]
fn reference_collimated_sun_known_answers() {
    use lightgrid_measure::reference::{CollimatedSun, ReferenceOptions, trace_with_sun};
    // 1 M paths: with open sides a cell is crossed by about 30 000 of them, a relative
    // standard error near 0.7 %; the bound below is about 5 of those.
    let opts = ReferenceOptions {
        paths: 1_000_000,
        time_budget: None,
        seed: 3,
        max_events: 64,
        max_track: 8.0,
    };
    let e = Vec3::new(2.0, 1.0, 0.5);
    let sun = CollimatedSun {
        to_sun: sun(37.0, 20.0),
        irradiance: e,
    };
    let empty = MaterialGrid::filled(
        GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(6, 5, 6)).unwrap(),
        Material::EMPTY,
    )
    .unwrap();
    for sides in [SideBoundary::Periodic, SideBoundary::Open] {
        let b = Boundary {
            sides: sides.clone(),
            ..Boundary::open_sky(BinLight::ZERO)
        };
        let r = trace_with_sun(&empty, &b, Some(&sun), &opts, &|_, _| {}).unwrap();
        for (i, d) in r.direct.iter().enumerate() {
            assert!(
                ((*d - e) / e).abs().max_element() < 0.03,
                "{sides:?} cell {i}: {d}"
            );
        }
        assert!(r.light.data().iter().all(|b| *b == BinLight::ZERO));
    }
    let ground = lightgrid_measure::exact::ground_material(1, 0.4).unwrap();
    let r = trace_with_sun(&ground, &dark_periodic(), Some(&sun), &opts, &|_, _| {}).unwrap();
    let reflected = r.balance.top_out.x / r.balance.input().x;
    assert!((reflected - 0.4).abs() < 0.005, "reflected {reflected}");
}

/// The three responses: colours combine linearly, the direct sun is exact on the
/// ground, moving the sun recomputes the sun's responses and keeps the sky's.
#[test]
fn sun_split_responses() {
    use lightgrid_sweep_cpu::sun::SunSplit;
    let m = lightgrid_measure::exact::ground_material(1, 0.3).unwrap();
    let sky = Boundary {
        sides: SideBoundary::Periodic,
        ..Boundary::open_sky(lightgrid_sky::uniform_sky(Vec3::ONE).unwrap().top)
    };
    let mut cpu = lightgrid_sweep_cpu::CpuSweeper::new();
    let s1 = sun(37.0, 20.0);
    let mut split = SunSplit::compute(&mut cpu, &m, &sky, s1, &converged()).unwrap();
    let p = Vec3::new(3.0, 1.0, 4.0);
    let (c_sky, c_sun) = (Vec3::new(0.2, 0.3, 0.5), Vec3::new(3.0, 2.5, 2.0));
    let both = split.irradiance(p, Vec3::Y, c_sky, c_sun).unwrap();
    let sky_only = split.irradiance(p, Vec3::Y, c_sky, Vec3::ZERO).unwrap();
    let sun_only = split.irradiance(p, Vec3::Y, Vec3::ZERO, c_sun).unwrap();
    assert!((both - sky_only - sun_only).abs().max_element() < 1e-5 * both.max_element());
    // Above the ground the sun is unshadowed: direct E cos(theta) exactly.
    let d = split.direct(p, Vec3::Y, c_sun).unwrap();
    assert!(
        (d - c_sun * s1.normalize().y).abs().max_element() < 1e-6,
        "{d}"
    );
    // Facing away from the sun: no direct light.
    assert_eq!(split.direct(p, -s1, c_sun).unwrap(), Vec3::ZERO);
    // A new sun: the sky's response is kept bit for bit, the sun's equal a fresh split.
    let sky_before = split.sky.clone();
    let s2 = sun(60.0, 110.0);
    split
        .resun(&mut cpu, &m, &sky.sides, s2, &converged())
        .unwrap();
    assert_eq!(split.sky, sky_before);
    let fresh = SunSplit::compute(&mut cpu, &m, &sky, s2, &converged()).unwrap();
    assert_eq!(split.sun_scattered, fresh.sun_scattered);
    assert_eq!(split.transmittance, fresh.transmittance);
}

/// A sweeper that implements only `sweep` (no cell sources, no sun).
struct Plain;

impl lightgrid_core::Sweeper for Plain {
    fn name(&self) -> &'static str {
        "plain"
    }
    fn sweep(
        &mut self,
        m: &MaterialGrid,
        b: &Boundary,
        o: &SweepOptions,
    ) -> Result<lightgrid_core::SweepOutput, lightgrid_core::SweepError> {
        Ok(lightgrid_sweep_cpu::run(m, b, o)?.output)
    }
}

/// A sweeper without cell sources says so by name instead of ignoring the source.
#[test]
fn sweepers_without_sources_refuse_them() {
    let m = lightgrid_measure::exact::ground_material(1, 0.3).unwrap();
    let src = lightgrid_sweep_cpu::CellSource::new(*m.desc(), vec![Vec3::ZERO; 512], Vec3::NEG_Y)
        .unwrap();
    let e = lightgrid_core::Sweeper::sweep_with_source(
        &mut Plain,
        &m,
        &dark_periodic(),
        &src,
        &SweepOptions::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("plain") && e.contains("source"), "{e}");
}

/// `Sweeper::sweep_sun`: refused by name where a sweeper cannot keep the sun apart; a
/// sun below the horizon has no beam (transmittance 0) and its bins hold only the
/// scattered light of the boundary.
#[test]
fn sweep_sun_refusal_and_a_sun_below_the_horizon() {
    use lightgrid_core::{SunBoundary, Sweeper};
    let m = lightgrid_measure::exact::ground_material(1, 0.3).unwrap();
    let sb = SunBoundary {
        to_sun: sun(40.0, 20.0),
        scattered: dark_periodic(),
        outside: &|_| 1.0,
    };
    let e = Plain
        .sweep_sun(&m, &sb, &SweepOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("plain") && e.contains("sun"), "{e}");
    // Below the horizon, with some scattered light coming in from above.
    let lit = Boundary {
        sides: SideBoundary::Periodic,
        ..Boundary::open_sky(lightgrid_sky::uniform_sky(Vec3::ONE).unwrap().top)
    };
    let below = SunBoundary {
        to_sun: Vec3::new(1.0, -0.2, 0.0),
        scattered: lit.clone(),
        outside: &|_| 1.0,
    };
    let mut cpu = lightgrid_sweep_cpu::CpuSweeper::new();
    let r = cpu.sweep_sun(&m, &below, &converged()).unwrap();
    assert!(r.transmittance.data().iter().all(|&t| t == 0.0));
    let plain = cpu.sweep(&m, &lit, &converged()).unwrap().bins.unwrap();
    assert_eq!(r.scattered, plain);
}

/// The nesting a hierarchy relies on: a grid's lower levels swept on their own, with
/// the sun boundary taken from the whole grid's response (the top from its downward
/// light one level above, the transmittance outside from its transmittance where the
/// ray leaves), give the whole grid's response there. A canopy fills the lower levels;
/// the cut lies in the air above it, where nothing scatters back down. The cut lies
/// above the canopy, so the transmittance handed over is 1: its nesting through a
/// canopy is the march's `outside` rule, tested in `sun.rs`.
#[test]
fn sun_responses_nest_like_a_hierarchy() {
    use lightgrid_core::{SunBoundary, Sweeper, TopBoundary};
    let dims = UVec3::new(12, 14, 12);
    let desc = GridDesc::new(Vec3::ZERO, 1.0, dims).unwrap();
    let mut rng = fastrand::Rng::with_seed(5);
    let cells: Vec<Material> = (0..desc.point_count())
        .map(|i| {
            let y = desc.coords(i).unwrap().y;
            let pass = match y {
                0 => 0.0,
                1..=6 if rng.f32() < 0.5 => 0.3 + 0.6 * rng.f32(),
                _ => 1.0,
            };
            Material {
                reflectance: Vec3::new(0.3, 0.5, 0.2),
                pass,
            }
        })
        .collect();
    let full_m = MaterialGrid::new(desc, cells.clone()).unwrap();
    let s = sun(33.0, 25.0);
    let mut cpu = lightgrid_sweep_cpu::CpuSweeper::new();
    let full = cpu
        .sweep_sun(
            &full_m,
            &SunBoundary {
                to_sun: s,
                scattered: dark_periodic(),
                outside: &|_| 1.0,
            },
            &converged(),
        )
        .unwrap();
    // The lower 10 levels on their own.
    let ny = 10;
    let sub_desc = GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(12, ny, 12)).unwrap();
    let sub_m = MaterialGrid::new(sub_desc, cells[..sub_desc.point_count()].to_vec()).unwrap();
    let top: Vec<BinLight> = full
        .scattered
        .level(ny)
        .iter()
        .map(|b| {
            // The strictly downward bins: the horizontal bins of a light grid hold both
            // the light going slightly down and slightly up (the 4:1 channels), and
            // above a sunlit canopy only the upward half is lit (no light goes down in
            // the air here). Handing over half of each horizontal bin, as
            // `split_vertical` does and terrain-lod's node tops do, adds 11 % of the
            // largest value at the cut (13 % for the sky): a known defect of the
            // top hand-over (ARCHITECTURE, known defects).
            let mut d = b.split_vertical().0;
            for k in 0..lightgrid_core::NUM_DIRS {
                if lightgrid_core::dirs::dir_ivec(k).y == 0 {
                    d.0[k] = Vec3::ZERO;
                }
            }
            d
        })
        .collect();
    let t_full = &full.transmittance;
    let sub = cpu
        .sweep_sun(
            &sub_m,
            &SunBoundary {
                to_sun: s,
                scattered: Boundary {
                    top: TopBoundary::PerPoint(top),
                    ..dark_periodic()
                },
                outside: &|p| t_full.sample(p).unwrap(),
            },
            &converged(),
        )
        .unwrap();
    let scale = full
        .scattered
        .data()
        .iter()
        .map(|b| b.total().max_element())
        .fold(0.0, f32::max);
    let worst = sub
        .scattered
        .data()
        .iter()
        .zip(full.scattered.data())
        .map(|(a, b)| (a.total() - b.total()).abs().max_element())
        .fold(0.0, f32::max);
    assert!(worst < 1e-4 * scale, "nesting error {}", worst / scale);
    for (i, (a, b)) in sub
        .transmittance
        .data()
        .iter()
        .zip(t_full.data())
        .enumerate()
    {
        assert!((a - b).abs() < 1e-5, "point {i}: T {a} vs {b}");
    }
}
