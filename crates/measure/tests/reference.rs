//! The Monte Carlo reference against analytic answers, its convergence, its accounting,
//! its determinism; then the sweep against it on the canonical scenes.

use lightgrid_core::dirs::{DOWN, NUM_DIRS, nearest_dir};
use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::{
    BinLight, Boundary, GridDesc, LightGrid, Material, MaterialGrid, SideBoundary, SweepOptions,
};
use lightgrid_measure::reference::{Reference, ReferenceOptions, trace};
use lightgrid_measure::scenes::{Scene, compare};

fn fog(dims: UVec3, albedo: f32, pass: f32) -> MaterialGrid {
    let d = GridDesc::new(Vec3::ZERO, 1.0, dims).unwrap();
    MaterialGrid::filled(
        d,
        Material {
            reflectance: Vec3::splat(albedo),
            pass,
        },
    )
    .unwrap()
}

fn down_only_periodic() -> Boundary {
    let mut b = Boundary::open_sky(BinLight::single(DOWN, Vec3::ONE));
    b.sides = SideBoundary::Periodic;
    b
}

fn mc(m: &MaterialGrid, b: &Boundary, paths: u64, seed: u64) -> Reference {
    trace(
        m,
        b,
        &ReferenceOptions {
            paths,
            seed,
            ..Default::default()
        },
        &|_, _| {},
    )
    .unwrap()
}

/// Down-bin light averaged over each level's cells, top level first.
fn level_means(g: &LightGrid, bin: usize) -> Vec<f64> {
    let d = g.desc();
    (0..d.levels())
        .rev()
        .map(|j| {
            let r = d.level_range(j);
            g.data()[r.clone()]
                .iter()
                .map(|p| p.0[bin].x as f64)
                .sum::<f64>()
                / r.len() as f64
        })
        .collect()
}

/// Exact cell averages for a purely absorbing slab lit by constant radiance within the
/// down bin: `∫_bin L0 (μ/σ)(e^{-σ D/μ} - e^{-σ (D+1)/μ}) dω` by a 2M-point lattice.
fn absorbing_slab_answer(levels: u32, pass: f32) -> Vec<f64> {
    let sigma = -(pass as f64).ln();
    let n = 2_000_000usize;
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let omega = lightgrid_core::dirs::bins().omega[DOWN];
    let w = 4.0 * std::f64::consts::PI / n as f64;
    let l0 = 1.0 / omega;
    let mut out = vec![0.0; levels as usize];
    for i in 0..n {
        let y = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
        let r = (1.0 - y * y).sqrt();
        let phi = golden * i as f64;
        let t = Vec3::new((r * phi.cos()) as f32, y as f32, (r * phi.sin()) as f32);
        if nearest_dir(t) != DOWN {
            continue;
        }
        let mu = -y;
        for (k, o) in out.iter_mut().enumerate() {
            let d0 = k as f64;
            *o +=
                w * l0 * mu / sigma * ((-sigma * d0 / mu).exp() - (-sigma * (d0 + 1.0) / mu).exp());
        }
    }
    out
}

#[test]
fn purely_absorbing_slab_matches_the_analytic_answer() {
    let m = fog(UVec3::new(4, 8, 4), 0.0, 0.7);
    let r = mc(&m, &down_only_periodic(), 400_000, 7);
    let got = level_means(&r.light, DOWN);
    let want = absorbing_slab_answer(8, 0.7);
    for (k, (g, w)) in got.iter().zip(&want).enumerate() {
        assert!(
            (g - w).abs() / w < 0.01,
            "level {k} from the top: {g} vs {w}"
        );
    }
    // No scattering: every other bin stays exactly dark.
    for p in r.light.data() {
        for d in 0..NUM_DIRS {
            if d != DOWN {
                assert_eq!(p.0[d], Vec3::ZERO);
            }
        }
    }
}

#[test]
fn error_falls_like_one_over_sqrt_paths_in_a_fog_slab() {
    let m = fog(UVec3::new(4, 6, 4), 0.5, 0.7);
    let b = down_only_periodic();
    let truth = mc(&m, &b, 512_000, 99);
    let rms = |r: &Reference| {
        let mut s = 0.0;
        for (a, t) in r.light.data().iter().zip(truth.light.data()) {
            s += ((a.average().x - t.average().x) as f64).powi(2);
        }
        (s / r.light.data().len() as f64).sqrt()
    };
    let e1 = rms(&mc(&m, &b, 2_000, 1));
    let e16 = rms(&mc(&m, &b, 32_000, 2));
    let ratio = e1 / e16;
    // Expected 4 (sqrt of 16); the reference's own noise is 1/16 of e1's.
    assert!(
        (2.8..5.5).contains(&ratio),
        "error ratio {ratio} ({e1} vs {e16})"
    );
}

#[test]
fn energy_is_accounted_per_path() {
    for (albedo, pass) in [(0.0, 0.5), (0.9, 0.6), (1.0, 0.0), (0.5, 1.0 - 1e-7)] {
        let m = fog(UVec3::new(5, 4, 3), albedo, pass);
        for sides in [SideBoundary::Open, SideBoundary::Periodic] {
            let mut b = Boundary::surrounding(&BinLight::uniform(Vec3::new(1.0, 0.5, 2.0)));
            b.sides = sides;
            let r = mc(&m, &b, 20_000, 3);
            let bal = r.balance;
            assert!(
                bal.relative_error() < 1e-5,
                "albedo {albedo} pass {pass}: {bal:?}"
            );
            assert!(bal.input().min_element() > 0.0);
        }
    }
}

#[test]
fn deterministic_for_a_seed_on_any_thread_count() {
    let m = fog(UVec3::new(4, 4, 4), 0.8, 0.5);
    let b = down_only_periodic();
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| mc(&m, &b, 40_000, 11))
    };
    let (a, c) = (run(1), run(2));
    assert_eq!(a.light, c.light);
    assert_eq!(a.balance, c.balance);
    let other_seed = mc(&m, &b, 40_000, 12);
    assert_ne!(a.light, other_seed.light);
}

#[test]
fn empty_medium_sees_the_sky() {
    let sky = BinLight::uniform(Vec3::new(1.0, 2.0, 3.0));
    let m = fog(UVec3::new(3, 3, 3), 0.0, 1.0);
    let r = mc(&m, &Boundary::surrounding(&sky), 400_000, 5);
    for p in r.light.data() {
        let a = p.average();
        assert!(
            (a - Vec3::new(1.0, 2.0, 3.0)).abs().max_element() < 0.03 * 3.0,
            "{a}"
        );
    }
    assert!(r.relative_std_error(0.0) < 0.02);
}

#[test]
fn unsupported_boundaries_are_typed_errors() {
    let m = fog(UVec3::new(2, 2, 2), 0.0, 1.0);
    let mut b = Boundary::open_sky(BinLight::ZERO);
    b.sides = SideBoundary::Given(vec![
        BinLight::ZERO;
        lightgrid_core::HaloLayout::new(UVec3::splat(2)).len()
    ]);
    let e = trace(&m, &b, &ReferenceOptions::default(), &|_, _| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("sides"), "{e}");
    let e = trace(
        &m,
        &down_only_periodic(),
        &ReferenceOptions {
            paths: 0,
            ..Default::default()
        },
        &|_, _| {},
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("paths"), "{e}");
}

/// The sweep (multi-bounce defaults) against the reference on the five canonical scenes,
/// 12³ cells, 600k paths, seed 1: relative RMSE of the average light and of irradiance
/// on the six axis normals. A measured error `e` is the sweep's own error `b` and the
/// reference's noise `n` together, `e² ≈ b² + n²`; the guard holds the sweep's own part,
/// `b = √(e² − n²)`, to fixed targets tied to what each scene asks of the sweep, not to
/// its last figures. The noise is measured with the same measure: a second reference
/// (seed 2) against the first differs by `√2 n`.
///
/// - **0.5 %** where the sweep is exact (the empty scene: the error is the noise alone);
/// - **1.5 %** in smooth media (the fog, both canopies: the channels' angular error, which
///   the exact half-space problems measure at 0.2–1.7 % for cells this thin);
/// - **4 %** for the dense block (cells of optical depth 3, the sweep's known weak case;
///   issue 44's target for irradiance on the six axes).
///
/// The noise must itself be small for the test to mean anything: `n < 2 %`. (Measured,
/// average / irradiance: the empty scene's error is its noise, 0.0114 / 0.0126 against
/// 0.0115 / 0.0127; the sweep's own error 1.3 / 1.3 % in the fog, 0.0 / 0.5 % in the
/// canopies, 2.9 / 3.5 % in the dense block.)
#[test]
fn sweep_against_reference_on_canonical_scenes() {
    let targets = [
        (Scene::Empty, 0.005),
        (Scene::UniformFog, 0.015),
        (Scene::DenseBlock, 0.04),
        (Scene::Canopy, 0.015),
        (Scene::CanopyOneLevelGround, 0.015),
    ];
    let own = |e: f64, n: f64| (e * e - n * n).max(0.0).sqrt();
    let mut report = String::new();
    for (scene, target) in targets {
        let (m, b) = scene.build(12);
        let mut o = SweepOptions::multi_bounce();
        o.tolerance = 1e-4;
        let s = lightgrid_sweep_cpu::run(&m, &b, &o).unwrap();
        let r = mc(&m, &b, 600_000, 1);
        let e = compare(s.output.bins.as_ref().unwrap(), &r.light, &m);
        let twin = compare(&mc(&m, &b, 600_000, 2).light, &r.light, &m);
        let (na, ni) = (
            twin.average / std::f64::consts::SQRT_2,
            twin.irradiance / std::f64::consts::SQRT_2,
        );
        let (ba, bi) = (own(e.average, na), own(e.irradiance, ni));
        report += &format!(
            "{}: average {:.4} (noise {na:.4}, own {ba:.4}), irradiance {:.4} (noise {ni:.4}, own {bi:.4}), target {target}\n",
            scene.name(),
            e.average,
            e.irradiance,
        );
        assert!(e.points > 100);
        assert!(na < 0.02 && ni < 0.02, "{report}");
        assert!(ba <= target && bi <= target, "{report}");
    }
    println!("{report}");
}

/// The reference's irradiance tally (`Reference::irradiance`, from the paths' exact
/// directions, no bins) over an infinite Lambertian ground of albedo `a` under a
/// uniform sky of radiance 1: at every point above the ground, `π` on a surface facing
/// up, `a π` facing down and `(1 + a) π / 2` facing sideways (the sky over the upper
/// half of its hemisphere, the ground's radiance `a` over the lower), within the
/// reference's noise; nothing at all travels upward over a black ground.
#[test]
fn irradiance_tally_over_a_lambertian_ground_is_exact() {
    use lightgrid_core::light::AMBIENT_AXES;
    for albedo in [0.0f32, 0.3] {
        let m = lightgrid_measure::exact::ground_material(1, albedo).unwrap();
        let b = Boundary {
            sides: SideBoundary::Periodic,
            ..Boundary::open_sky(lightgrid_sky::uniform_sky(Vec3::ONE).unwrap().top)
        };
        // Grazing paths travel far before they reach the ground: a long track limit
        // keeps all but those within 0.2° of the horizon.
        let r = trace(
            &m,
            &b,
            &ReferenceOptions {
                paths: 400_000,
                seed: 5,
                max_track: 200.0,
                ..Default::default()
            },
            &|_, _| {},
        )
        .unwrap();
        let d = *m.desc();
        let pi = std::f64::consts::PI;
        let a = albedo as f64;
        for (k, n) in AMBIENT_AXES.iter().enumerate() {
            let want = match n.y as i32 {
                1 => pi,
                -1 => a * pi,
                _ => (1.0 + a) * pi / 2.0,
            };
            // Mean over the levels above the ground (noise about 0.3 % a level mean).
            let (mut sum, mut count) = (0.0f64, 0usize);
            for i in d.level_len()..d.point_count() {
                sum += r.irradiance[i][k].x as f64;
                count += 1;
            }
            let got = sum / count as f64;
            if want == 0.0 {
                assert_eq!(got, 0.0, "albedo {albedo}, axis {n}");
            } else {
                assert!(
                    (got / want - 1.0).abs() < 0.01,
                    "albedo {albedo}, axis {n}: {got} vs exact {want}"
                );
            }
        }
    }
}
