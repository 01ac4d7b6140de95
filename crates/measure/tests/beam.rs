//! The sun's first collisions by beam tracing (`lightgrid_sweep_cpu::beam`, issue 44),
//! against answers that share none of its assumptions: the flux entering the box
//! (geometry alone), the beam leaving it (an independent march from random points of
//! the exit faces), the Monte Carlo reference's uncollided tally cell by cell, and the
//! reference's light in the media of a patchy canopy under a 10° sun.

use lightgrid_core::glam::{IVec3, UVec3, Vec3};
use lightgrid_core::{GridDesc, Material, MaterialGrid, SweepOptions};
use lightgrid_measure::sun_measure::{medium_errors, patchy_canopy};
use lightgrid_sweep_cpu::sun::{BeamOptions, first_collisions};
use proptest::prelude::*;

fn sun(elevation_deg: f32, azimuth_deg: f32) -> Vec3 {
    let (e, a) = (elevation_deg.to_radians(), azimuth_deg.to_radians());
    Vec3::new(e.cos() * a.cos(), e.sin(), e.cos() * a.sin())
}

/// The flux entering the box through the faces facing the sun, for unit irradiance.
fn entering(dims: UVec3, s: Vec3, periodic: bool) -> f64 {
    let (d, s) = (dims.as_dvec3(), s.normalize().as_dvec3());
    let top = s.y * d.x * d.z;
    if periodic {
        top
    } else {
        top + s.x.abs() * d.y * d.z + s.z.abs() * d.x * d.y
    }
}

fn random_grid() -> impl Strategy<Value = MaterialGrid> {
    (2u32..9, 2u32..9, 2u32..9, any::<u64>()).prop_map(|(nx, ny, nz, seed)| {
        let desc =
            GridDesc::new(Vec3::new(-3.0, 5.0, 11.0), 0.7, UVec3::new(nx, ny, nz)).expect("valid");
        let mut rng = fastrand::Rng::with_seed(seed);
        let cells = (0..desc.point_count())
            .map(|_| {
                let pass = match rng.u8(0..6) {
                    0 => 0.0,
                    1 | 2 => 1.0,
                    3 => 0.999 + 0.001 * rng.f32(),
                    _ => rng.f32().max(1e-6),
                };
                Material {
                    reflectance: Vec3::splat(0.5),
                    pass,
                }
            })
            .collect();
        MaterialGrid::new(desc, cells).expect("valid")
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    /// First collisions plus the beam leaving through the bottom and open sides equal
    /// the beam entering, to 1e-4, at any elevation from 2 to 90 degrees and any
    /// azimuth, over random media and opaque cells; what enters is the geometry's exact
    /// flux; the cells' deposits add up to the budget's collisions.
    #[test]
    fn the_beam_is_conserved(
        m in random_grid(),
        elevation in 2.0f32..=90.0,
        azimuth in 0.0f32..360.0,
        periodic in any::<bool>(),
    ) {
        let s = sun(elevation, azimuth);
        let f = first_collisions(&m, s, Vec3::ONE, periodic, &|_| 1.0, &BeamOptions::DEFAULT)
            .unwrap();
        let b = f.budget;
        prop_assert!(b.relative_error() < 1e-4, "{b:?}");
        prop_assert!(b.stopped == 0.0, "{b:?}");
        let want = entering(m.desc().dims(), s, periodic);
        prop_assert!((b.entered - want).abs() < 1e-4 * want, "entered {} want {want}", b.entered);
        let deposited: f64 = f.source.removed().iter().map(|r| r.x as f64).sum();
        prop_assert!((deposited - b.collided).abs() < 1e-4 * want, "{deposited} vs {b:?}");
        if periodic {
            prop_assert!(b.left_sides == 0.0);
        }
        // Where every column has an opaque cell, nothing leaves through the bottom.
        if m.data().iter().all(|c| c.pass <= 0.0) {
            prop_assert!(b.left_bottom == 0.0 && b.left_sides == 0.0);
        }
    }

    /// The transmittance already lost outside scales what enters and every deposit.
    #[test]
    fn outside_scales_the_beam(m in random_grid(), elevation in 5.0f32..=90.0, o in 0.0f32..=1.0) {
        let s = sun(elevation, 33.0);
        let one = first_collisions(&m, s, Vec3::ONE, false, &|_| 1.0, &BeamOptions::DEFAULT).unwrap();
        let part = first_collisions(&m, s, Vec3::ONE, false, &|_| o, &BeamOptions::DEFAULT).unwrap();
        prop_assert!((part.budget.entered - o as f64 * one.budget.entered).abs() < 1e-5 * one.budget.entered);
        for (a, b) in part.source.removed().iter().zip(one.source.removed()) {
            prop_assert!((a.x - o * b.x).abs() <= 1e-5 * (1.0 + b.x));
        }
    }
}

/// Exact march toward the sun from a point (grid units) to the box; open sides.
fn march(m: &MaterialGrid, from: Vec3, s: Vec3) -> f64 {
    let dims = m.desc().dims().as_ivec3();
    let far = from + s * (4.0 * dims.element_sum() as f32);
    let mut log_t = 0.0f64;
    lightgrid_core::dda::walk_segment(from, far, dims, |c: IVec3, len| {
        let p = m.data()[m.desc().index_unchecked(c.as_uvec3())].pass as f64;
        log_t += if p <= 0.0 {
            f64::NEG_INFINITY
        } else {
            len as f64 * p.ln()
        };
    });
    log_t.exp()
}

/// The beam leaving through the bottom and the open sides, against a Monte Carlo
/// integral of `|n·s| T` over the exit faces with `T` marched from random points: the
/// rays put the beam where an independent walk finds it.
#[test]
fn the_beam_leaves_where_a_march_finds_it() {
    let m = patchy_canopy(16, 3);
    let dims = m.desc().dims();
    let d = dims.as_vec3();
    for elevation in [10.0f32, 40.0, 75.0] {
        let s = sun(elevation, 20.0);
        let left = |rays: u32| {
            let f = first_collisions(
                &m,
                s,
                Vec3::ONE,
                false,
                &|_| 1.0,
                &BeamOptions::DEFAULT.with_rays(rays),
            )
            .unwrap();
            f.budget.left_bottom + f.budget.left_sides
        };
        let mut rng = fastrand::Rng::with_seed(9);
        let samples = 40_000;
        let mut est = 0.0f64;
        // Exit faces: the bottom, and the x and z faces facing away from the sun.
        let faces = [
            (1usize, -0.5f32, s.y, d.x * d.z),
            (
                0,
                if s.x > 0.0 { -0.5 } else { d.x - 0.5 },
                s.x.abs(),
                d.y * d.z,
            ),
            (
                2,
                if s.z > 0.0 { -0.5 } else { d.z - 0.5 },
                s.z.abs(),
                d.x * d.y,
            ),
        ];
        for (axis, at, cos, area) in faces {
            let mut sum = 0.0f64;
            for _ in 0..samples {
                let mut p = Vec3::new(
                    rng.f32() * d.x - 0.5,
                    rng.f32() * d.y - 0.5,
                    rng.f32() * d.z - 0.5,
                );
                p[axis] = at;
                // Just inside the box, so the walk starts in the face's cell.
                p += s * 1e-4;
                sum += march(&m, p, s);
            }
            est += cos as f64 * area as f64 * sum / samples as f64;
        }
        // The default's lattice of at least 16 rays a cell counts the beam within
        // 2 %; with more rays it converges to the march's answer (whose own noise at
        // 40 000 points a face is about 0.3 %).
        for (rays, tol) in [
            (lightgrid_sweep_cpu::beam::RAYS_PER_CELL, 0.02),
            (256, 0.005),
        ] {
            let got = left(rays);
            let rel = (got - est).abs() / est;
            eprintln!("sun {elevation}°, {rays} rays: leaving {got:.4}, march {est:.4} ({rel:.4})");
            assert!(
                rel < tol,
                "sun {elevation}°, {rays} rays: the rays' beam leaving {got:.3}, a march finds {est:.3}"
            );
        }
    }
}

/// Each cell's mean transmittance (the rays' track lengths) against the Monte Carlo
/// reference's uncollided tally, cell by cell, on the patchy canopy with a 10° sun.
#[test]
fn cell_mean_transmittance_matches_the_reference() {
    let m = patchy_canopy(12, 4);
    for periodic in [true, false] {
        let s = sun(10.0, 20.0);
        let f = first_collisions(
            &m,
            s,
            Vec3::ONE,
            periodic,
            &|_| 1.0,
            &BeamOptions::DEFAULT.with_mean_transmittance(),
        )
        .unwrap();
        let t = f.mean_transmittance.unwrap();
        let sides = if periodic {
            lightgrid_core::SideBoundary::Periodic
        } else {
            lightgrid_core::SideBoundary::Open
        };
        let b = lightgrid_core::Boundary {
            sides,
            ..lightgrid_core::Boundary::open_sky(lightgrid_core::BinLight::ZERO)
        };
        let r = lightgrid_measure::sun_measure::sun_reference(&m, &b, s, 400_000, 3).unwrap();
        let (mut se, mut sw) = (0.0f64, 0.0f64);
        for (i, c) in m.data().iter().enumerate() {
            if c.pass <= 0.0 {
                continue;
            }
            let want = r.direct[i].x as f64;
            se += (t[i] as f64 - want).powi(2);
            sw += want * want;
        }
        let rms = (se / sw).sqrt();
        eprintln!("periodic {periodic}: mean transmittance relative RMS {rms:.4}");
        // The reference's own noise is about 1 % a cell at 400 000 paths.
        assert!(rms < 0.03, "periodic {periodic}: relative RMS {rms:.4}");
    }
}

/// The light the sweep computes in a patchy canopy's media under a 10° sun (the first
/// collisions swept, plus the beam) against the Monte Carlo reference: bias within 2 %,
/// relative RMS within 5 % (the reference's noise about 1 %). Before beam tracing a
/// fifth of a 10° beam never reached the cells.
#[test]
fn a_low_sun_lights_a_patchy_canopy_as_the_reference() {
    let m = patchy_canopy(16, 3);
    let mut o = SweepOptions::multi_bounce();
    o.tolerance = 1e-6;
    o.max_passes = 64;
    let e = medium_errors(
        &m,
        true,
        10f32.to_radians(),
        20f32.to_radians(),
        1_000_000,
        &o,
    )
    .unwrap();
    eprintln!("{e:?}");
    assert!((e.collided - 1.0).abs() < 1e-6, "{e:?}");
    assert!(e.bias.abs() < 0.02, "{e:?}");
    assert!(e.rms < 0.05, "{e:?}");
    assert!(e.direct_rms < 0.03, "{e:?}");
}

/// The same canopy and sun at the presets' default (`SweepOptions::multi_bounce`, whose
/// `Gather::AUTO` gathers the first two scatterings of a sun at or below 30° by rays,
/// as `Gather::LOW_SUN`): every cell whose reference noise is under 1 % within 5 % of
/// the reference (issue 44's target; the sweep alone leaves 87 of 407 cells over 5 %,
/// the worst 16 % off: the 26 directions' ray effects between the patches), the media
/// within 1 % in all (measured: the worst 3.5 %, none of 407 cells over 5 %, RMS
/// 0.7 %; the media +0.0 %). 8 M reference paths: the cells' noise 0.3–0.6 %
/// (`lightgrid_measure::exact::patchy_low_sun_errors`, which `cargo xtask exact`
/// reports).
#[test]
fn a_low_sun_lights_every_patchy_cell_within_five_percent_by_default() {
    let e = lightgrid_measure::exact::patchy_low_sun_errors(true).unwrap();
    eprintln!("{e:?}");
    assert!(e.max < 0.05, "{e:?}");
    assert!(e.bias.abs() < 0.01, "{e:?}");
    assert!(e.scattered_bias.abs() < 0.01, "{e:?}");
}

/// One thread or two, the same bits (deposits are summed in ray order).
#[test]
fn the_deposits_do_not_depend_on_the_threads() {
    let m = patchy_canopy(16, 5);
    let s = sun(23.0, 71.0);
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                first_collisions(&m, s, Vec3::ONE, false, &|_| 1.0, &BeamOptions::DEFAULT).unwrap()
            })
    };
    let (a, b) = (run(1), run(2));
    assert_eq!(a.source, b.source);
    assert_eq!(a.budget, b.budget);
}

#[test]
fn bad_options_are_refused_by_name() {
    let m = patchy_canopy(8, 1);
    for rays in [0u32, 4097] {
        let e = first_collisions(
            &m,
            Vec3::Y,
            Vec3::ONE,
            true,
            &|_| 1.0,
            &BeamOptions::DEFAULT.with_rays(rays),
        )
        .unwrap_err();
        assert!(e.to_string().contains("rays_per_cell"), "{e}");
    }
    let below = first_collisions(
        &m,
        Vec3::new(1.0, -0.1, 0.0),
        Vec3::ONE,
        true,
        &|_| 1.0,
        &BeamOptions::DEFAULT,
    )
    .unwrap();
    assert_eq!(below.budget, Default::default());
    assert!(below.source.removed().iter().all(|r| *r == Vec3::ZERO));
}
