//! The point reference (`lightgrid_measure::points`) against exact answers that share
//! none of its code (an infinite Lambertian ground under a uniform sky and under a sun,
//! at one and three ground levels, facing up, down and sideways) and against the
//! forward reference's six-axis irradiance, cell by cell, on a patchy canopy with open
//! sides under the sky and a low sun.

use std::f32::consts::PI;

use lightgrid_core::glam::Vec3;
use lightgrid_core::light::{AMBIENT_AXES, luminance};
use lightgrid_core::{BinLight, Boundary, GridError, MaterialGrid, SideBoundary, SweepError};
use lightgrid_measure::exact::ground_material;
use lightgrid_measure::points::{PointIrradiance, PointOptions, PointProbe, trace_points};
use lightgrid_measure::reference::{CollimatedSun, ReferenceOptions, trace_with_sun};

fn uniform_sky() -> BinLight {
    BinLight::uniform(Vec3::ONE).split_vertical().0
}

fn periodic(top: BinLight) -> Boundary {
    Boundary {
        sides: SideBoundary::Periodic,
        ..Boundary::open_sky(top)
    }
}

fn one(
    m: &MaterialGrid,
    b: &Boundary,
    sun: Option<&CollimatedSun>,
    p: Vec3,
    n: Vec3,
    paths: u32,
) -> PointIrradiance {
    let o = PointOptions {
        paths,
        ..Default::default()
    };
    trace_points(
        m,
        b,
        sun,
        &[PointProbe {
            position: p,
            normal: n,
        }],
        &o,
    )
    .unwrap()[0]
        .expect("a point in the air")
}

fn sun_at(elevation_deg: f32, azimuth_deg: f32) -> CollimatedSun {
    let (e, a) = (elevation_deg.to_radians(), azimuth_deg.to_radians());
    CollimatedSun {
        to_sun: Vec3::new(e.cos() * a.cos(), e.sin(), e.cos() * a.sin()),
        irradiance: Vec3::new(2.0, 1.5, 1.0),
    }
}

/// Over an infinite Lambertian ground of albedo `a` under a uniform sky of radiance 1:
/// facing up `π` (sky alone), facing down `a π` (the ground, lit by `π`), facing
/// sideways `π (1 + a) / 2`. Every path of the first two gives the answer exactly.
#[test]
fn a_lambertian_ground_under_a_uniform_sky_is_exact() {
    for levels in [1, 3] {
        for a in [0.3f32, 0.8] {
            let m = ground_material(levels, a).unwrap();
            let b = periodic(uniform_sky());
            let p = Vec3::new(3.3, levels as f32 + 1.2, 4.6);
            for (n, exact, tol) in [
                (Vec3::Y, PI, 1e-4f32),
                (Vec3::NEG_Y, a * PI, 1e-4),
                (Vec3::X, PI * (1.0 + a) / 2.0, 0.01),
                (Vec3::new(0.3, -1.0, 0.2), f32::NAN, 0.0),
            ] {
                let e = one(&m, &b, None, p, n, 4000);
                assert_eq!(e.sun_scattered, Vec3::ZERO);
                assert_eq!(e.sun_direct, Vec3::ZERO);
                if exact.is_nan() {
                    assert!(
                        e.sky.x > a * PI && e.sky.x < PI,
                        "{levels} levels, albedo {a}"
                    );
                    continue;
                }
                let rel = (e.sky.x / exact - 1.0).abs();
                assert!(
                    rel < tol.max(4.0 * e.sky_se / exact),
                    "{levels} levels, albedo {a}, facing {n}: {} against {exact}",
                    e.sky.x
                );
                assert!(rel < 0.02, "facing {n}: {}", e.sky.x);
            }
        }
    }
}

/// The same ground under a sun of irradiance `E` at elevation `θ` (between bins): the
/// ground receives `E sin θ` and reflects `a E sin θ / π` radiance; facing down the
/// scattered sun is `a E sin θ` exactly, facing up it is 0 and the direct sun `E sin θ`,
/// facing sideways half the ground's, `a E sin θ / 2`.
#[test]
fn a_lambertian_ground_under_a_sun_is_exact() {
    for (elevation, azimuth) in [(10.0f32, 20.0f32), (35.0, 77.0), (80.0, -130.0)] {
        let sun = sun_at(elevation, azimuth);
        let s = sun.to_sun.normalize();
        let e_ground = sun.irradiance * s.y;
        for levels in [1, 3] {
            let a = 0.4f32;
            let m = ground_material(levels, a).unwrap();
            let b = periodic(BinLight::ZERO);
            let p = Vec3::new(2.1, levels as f32 + 0.7, 5.9);
            let down = one(&m, &b, Some(&sun), p, Vec3::NEG_Y, 500);
            assert!((down.sun_scattered - a * e_ground).abs().max_element() < 1e-4);
            assert_eq!(down.sun_direct, Vec3::ZERO);
            assert_eq!(down.transmittance, 1.0);
            let up = one(&m, &b, Some(&sun), p, Vec3::Y, 500);
            assert_eq!(up.sun_scattered, Vec3::ZERO);
            assert!((up.sun_direct - e_ground).abs().max_element() < 1e-5);
            let side = one(&m, &b, Some(&sun), p, Vec3::Z, 8000);
            let want = a * e_ground / 2.0;
            let rel = luminance(side.sun_scattered) / luminance(want) - 1.0;
            assert!(
                rel.abs() < (4.0 * side.sun_se / luminance(want)).max(1e-3),
                "sun {elevation}°: sideways {} against {want}",
                side.sun_scattered
            );
            assert!(
                (side.sun_direct - sun.irradiance * s.z.max(0.0))
                    .abs()
                    .max_element()
                    < 1e-5
            );
        }
    }
}

/// Probes outside the grid or inside an opaque cell have no answer; bad probes and
/// options are typed errors naming the field.
#[test]
fn points_outside_or_in_walls_and_bad_input() {
    let m = ground_material(2, 0.5).unwrap();
    let b = periodic(uniform_sky());
    let o = PointOptions::default();
    let probes = [
        PointProbe {
            position: Vec3::new(3.0, 0.4, 3.0), // ground
            normal: Vec3::Y,
        },
        PointProbe {
            position: Vec3::new(3.0, 40.0, 3.0), // above the grid
            normal: Vec3::Y,
        },
        PointProbe {
            position: Vec3::new(3.0, 5.0, 3.0),
            normal: Vec3::Y,
        },
    ];
    let r = trace_points(&m, &b, None, &probes, &PointOptions { paths: 16, ..o }).unwrap();
    assert!(r[0].is_none() && r[1].is_none() && r[2].is_some());
    let field = |e: SweepError| match e {
        SweepError::Invalid(GridError::InvalidField { field, .. }) => field,
        e => panic!("{e}"),
    };
    let bad = [PointProbe {
        position: Vec3::new(f32::NAN, 1.0, 1.0),
        normal: Vec3::Y,
    }];
    assert_eq!(
        field(trace_points(&m, &b, None, &bad, &o).unwrap_err()),
        "probes[0].position"
    );
    let bad = [PointProbe {
        position: Vec3::ONE,
        normal: Vec3::ZERO,
    }];
    assert_eq!(
        field(trace_points(&m, &b, None, &bad, &o).unwrap_err()),
        "probes[0].normal"
    );
    let o1 = PointOptions { paths: 1, ..o };
    assert_eq!(
        field(trace_points(&m, &b, None, &probes, &o1).unwrap_err()),
        "paths"
    );
}

/// Cell by cell against the forward reference (`Reference::irradiance`, tallied from
/// its paths' exact directions) on a patchy canopy with open sides, under the sky and a
/// 20° sun apart: the points are drawn uniformly in each cell, so their mean is the
/// cell's mean the forward reference tallies. Per axis, summed over the cells, the two
/// agree within four of their combined standard errors (about 0.5 % each).
#[test]
fn agrees_with_the_forward_reference_cell_by_cell() {
    let m = lightgrid_measure::sun_measure::patchy_canopy(10, 3);
    let desc = *m.desc();
    let sky = lightgrid_sky::ClearSky::blue(Vec3::new(0.5, 0.4, 0.3))
        .bins()
        .unwrap()
        .top;
    let sun = sun_at(20.0, 30.0);
    for (name, top, sun) in [("sky", sky, None), ("sun", BinLight::ZERO, Some(&sun))] {
        let b = Boundary::open_sky(top);
        let fwd = trace_with_sun(
            &m,
            &b,
            sun,
            &ReferenceOptions {
                paths: 3_000_000,
                ..Default::default()
            },
            &|_, _| {},
        )
        .unwrap();
        // Every fourth cell that is not opaque, 8 points in it, on the six axes.
        let mut rng = fastrand::Rng::with_seed(5);
        let cells: Vec<usize> = (0..desc.point_count())
            .filter(|&i| m.data()[i].pass > 0.0)
            .step_by(4)
            .collect();
        let per_cell = 8;
        let mut probes = Vec::new();
        for &i in &cells {
            let c = desc.coords(i).unwrap().as_vec3();
            for _ in 0..per_cell {
                let p = c + Vec3::new(rng.f32(), rng.f32(), rng.f32()) - 0.5;
                for n in AMBIENT_AXES {
                    probes.push(PointProbe {
                        position: desc.to_world(p),
                        normal: n,
                    });
                }
            }
        }
        let back = trace_points(
            &m,
            &b,
            sun,
            &probes,
            &PointOptions {
                paths: 64,
                ..Default::default()
            },
        )
        .unwrap();
        for axis in 0..6 {
            let (mut f_sum, mut b_sum, mut var) = (0.0f64, 0.0f64, 0.0f64);
            for (k, &i) in cells.iter().enumerate() {
                let f = luminance(fwd.irradiance[i][axis]) as f64;
                // The forward reference's noise: its cell's average light's, relative.
                let avg = luminance(fwd.light.data()[i].average()) as f64;
                let f_rel = if avg > 0.0 {
                    luminance(fwd.std_error[i]) as f64 / avg
                } else {
                    0.0
                };
                let mut bm = 0.0f64;
                for j in 0..per_cell {
                    let e = back[(k * per_cell + j) * 6 + axis].unwrap();
                    let (v, se) = match sun {
                        None => (luminance(e.sky), e.sky_se),
                        Some(_) => (luminance(e.sun_scattered), e.sun_se),
                    };
                    bm += v as f64 / per_cell as f64;
                    var += (se as f64 / per_cell as f64).powi(2);
                }
                var += (f * f_rel).powi(2);
                f_sum += f;
                b_sum += bm;
            }
            let rel = b_sum / f_sum - 1.0;
            let se = var.sqrt() / f_sum;
            println!("{name} axis {axis}: backward / forward - 1 = {rel:+.4} (se {se:.4})");
            assert!(
                rel.abs() < 4.0 * se,
                "{name}, axis {axis}: {rel:+.4} (standard error {se:.4})"
            );
        }
    }
}
