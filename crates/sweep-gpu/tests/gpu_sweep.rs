//! The GPU sweep equals sweep-cpu's (the specification) within the stated tolerance.
//! Runs on any adapter (lavapipe in CI); fails without one unless LIGHTGRID_ALLOW_NO_GPU=1.

use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::{
    BinLight, Boundary, GridDesc, HaloLayout, Material, MaterialGrid, SideBoundary, SweepOptions,
    TopBoundary,
};
use lightgrid_sweep_gpu::{GpuContext, GpuSweeper};
use proptest::prelude::*;

/// One sweeper for all tests of this binary: pipelines compile once.
fn sweeper() -> Option<&'static GpuSweeper> {
    static S: std::sync::OnceLock<Option<GpuSweeper>> = std::sync::OnceLock::new();
    S.get_or_init(|| GpuContext::new_for_tests().map(GpuSweeper::with_context))
        .as_ref()
}

/// Relative 1e-4 of the larger value plus 1e-5 of the grid's largest value (f32
/// rounding in a different order, and exp/log of another library).
fn assert_close(
    cpu: &lightgrid_core::LightGrid,
    gpu: &lightgrid_core::LightGrid,
) -> Result<(), String> {
    let scale = cpu.max_value().max(1e-20);
    for (i, (a, b)) in cpu.data().iter().zip(gpu.data()).enumerate() {
        for d in 0..26 {
            let (x, y) = (a.0[d], b.0[d]);
            let tol = 1e-4 * x.abs().max(y.abs()).max_element() + 1e-5 * scale;
            if (x - y).abs().max_element() > tol {
                return Err(format!("point {i} bin {d}: cpu {x} gpu {y}"));
            }
        }
    }
    Ok(())
}

/// [`assert_close`]'s tolerance for the horizon halves (scaled by the bins' largest
/// value).
fn assert_halves_close(
    cpu: &lightgrid_core::HorizonGrid,
    gpu: &lightgrid_core::HorizonGrid,
    scale: f32,
) -> Result<(), String> {
    for (i, (a, b)) in cpu.data().iter().zip(gpu.data()).enumerate() {
        for k in 0..a.0.len() {
            let (x, y) = (a.0[k], b.0[k]);
            let tol = 1e-4 * x.abs().max(y.abs()).max_element() + 1e-5 * scale.max(1e-20);
            if (x - y).abs().max_element() > tol {
                return Err(format!("point {i} half {k}: cpu {x} gpu {y}"));
            }
        }
    }
    Ok(())
}

fn lumpy_sky() -> BinLight {
    BinLight(std::array::from_fn(|d| {
        Vec3::new(1.0 + d as f32, 2.0 + (d % 5) as f32, 0.5 + (d % 3) as f32)
    }))
}

#[test]
fn canonical_scenes_match_the_cpu() {
    let Some(gpu) = sweeper() else { return };
    for scene in lightgrid_measure::scenes::Scene::ALL {
        let (m, b) = scene.build(10);
        let mut o = SweepOptions::multi_bounce();
        o.tolerance = 0.0;
        o.max_passes = 5;
        // Every medium emission rule (the source rules have their own third phase).
        for medium in [
            lightgrid_core::MediumEmission::Source,
            lightgrid_core::MediumEmission::Profile,
            lightgrid_core::MediumEmission::Escape,
        ] {
            o.medium = medium;
            let cpu = lightgrid_sweep_cpu::run(&m, &b, &o)
                .unwrap()
                .output
                .bins
                .unwrap();
            let g = gpu.run(&m, &b, &o).unwrap().bins.unwrap();
            assert_close(&cpu, &g).unwrap_or_else(|e| panic!("{} ({medium:?}): {e}", scene.name()));
        }
    }
}

fn material_strategy(max: u32) -> impl Strategy<Value = MaterialGrid> {
    (1..=max, 1..=max, 1..=max).prop_flat_map(|(nx, ny, nz)| {
        let n = (nx * ny * nz) as usize;
        let cell = (
            prop_oneof![Just(0.0f32), Just(1.0), 0.0f32..1.0],
            prop_oneof![Just(0.0f32), Just(1.0), Just(1.0 - 1e-7), 0.0f32..1.0],
        )
            .prop_map(|(a, p)| Material {
                reflectance: Vec3::new(a, a * 0.5, 1.0 - a),
                pass: p,
            });
        prop::collection::vec(cell, n).prop_map(move |cells| {
            MaterialGrid::new(
                GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(nx, ny, nz)).unwrap(),
                cells,
            )
            .unwrap()
        })
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    /// Random grids (each side 1 to 40 points; pass-through and reflectance including exact
    /// 0 and 1), every side mode (given halos with and without their downward halves,
    /// and with their cells) and a per-point top, random sky and sun, smoothing and
    /// pass count.
    #[test]
    fn random_grids_match_the_cpu(m in material_strategy(40), sides in 0u8..5, smoothing in 0f32..0.9, passes in 1u32..5, sun in 0f32..100.0, sun_bin in 0usize..17, profile in any::<bool>(), horizon in any::<bool>()) {
        let Some(gpu) = sweeper() else { return Ok(()) };
        let d = *m.desc();
        let mut sky = lumpy_sky();
        sky.0[sun_bin] += Vec3::splat(sun);
        let (top, bottom) = sky.split_vertical();
        let b = Boundary {
            top: if sides == 3 { TopBoundary::PerPoint((0..d.level_len()).map(|i| top.scaled(1.0 + i as f32 * 0.01)).collect()) } else { TopBoundary::Uniform(Box::new(top)) },
            bottom,
            sides: match sides {
                0 | 3 => SideBoundary::Open,
                1 => SideBoundary::Periodic,
                2 => SideBoundary::Given((0..HaloLayout::new(d.dims()).len()).map(|i| sky.scaled(0.5 + (i % 7) as f32 * 0.1)).collect()),
                // Given halves: each horizontal bin's downward half its own fraction.
                _ => {
                    let light: Vec<BinLight> = (0..HaloLayout::new(d.dims()).len()).map(|i| sky.scaled(0.5 + (i % 7) as f32 * 0.1)).collect();
                    let down = light.iter().enumerate().map(|(i, l)| lightgrid_core::HorizonLight(std::array::from_fn(|k| l.0[lightgrid_core::dirs::FIRST_HORIZONTAL + k] * (0.1 + ((i + k) % 9) as f32 * 0.1)))).collect();
                    // The halo's cells given for half the cases (media, opaque and
                    // empty cells): both sweepers carry the halo's light through them.
                    let cells = (sun_bin % 2 == 0).then(|| (0..HaloLayout::new(d.dims()).len()).map(|i| match i % 5 {
                        0 => lightgrid_core::Material::EMPTY,
                        1 => lightgrid_core::Material::opaque(Vec3::splat(0.4)),
                        k => lightgrid_core::Material { reflectance: Vec3::new(0.3, 0.5, 0.7), pass: 0.15 * k as f32 },
                    }).collect());
                    SideBoundary::GivenHalves { light, down, cells }
                }
            },
        };
        let mut o = SweepOptions::multi_bounce();
        o.smoothing = smoothing;
        o.max_passes = passes;
        o.tolerance = 0.0;
        o.medium = if profile { lightgrid_core::MediumEmission::Profile } else { lightgrid_core::MediumEmission::Source };
        if horizon {
            o.outputs = o.outputs.with_horizon();
        }
        let cpu = lightgrid_sweep_cpu::run(&m, &b, &o).unwrap().output;
        let g = gpu.run(&m, &b, &o).unwrap();
        let (cb, gb) = (cpu.bins.unwrap(), g.bins.unwrap());
        if let Err(e) = assert_close(&cb, &gb) {
            prop_assert!(false, "{e}");
        }
        prop_assert_eq!(cpu.horizon.is_some(), horizon);
        prop_assert_eq!(g.horizon.is_some(), horizon);
        if let (Some(ch), Some(gh)) = (cpu.horizon, g.horizon)
            && let Err(e) = assert_halves_close(&ch, &gh, cb.max_value())
        {
            prop_assert!(false, "{e}");
        }
    }
}

/// Known answer: in an empty medium every point holds the sky exactly, so a point the
/// kernels never wrote (left at 0) fails.
#[test]
fn empty_medium_known_answer() {
    let Some(gpu) = sweeper() else { return };
    let sky = lumpy_sky();
    for sides in [SideBoundary::Open, SideBoundary::Periodic] {
        let m = MaterialGrid::filled(
            GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(7, 5, 9)).unwrap(),
            Material::EMPTY,
        )
        .unwrap();
        let mut b = Boundary::surrounding(&sky);
        b.sides = sides;
        let mut o = SweepOptions::single_pass();
        o.max_passes = 2;
        let g = gpu.run(&m, &b, &o).unwrap().bins.unwrap();
        for p in g.data() {
            for d in 0..26 {
                assert!(
                    (p.0[d] - sky.0[d]).abs().max_element() <= 1e-5 * sky.0[d].max_element(),
                    "bin {d}: {} vs {}",
                    p.0[d],
                    sky.0[d]
                );
            }
        }
    }
}

#[test]
fn invalid_input_is_the_same_typed_error() {
    let Some(gpu) = sweeper() else { return };
    let m = MaterialGrid::filled(
        GridDesc::new(Vec3::ZERO, 1.0, UVec3::splat(2)).unwrap(),
        Material::EMPTY,
    )
    .unwrap();
    let mut sky = BinLight::ZERO;
    sky.0[2].x = f32::NAN;
    let e = gpu
        .run(&m, &Boundary::open_sky(sky), &SweepOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("top"), "{e}");
}

/// The GPU sweeper does not trace the halo's paths (`SweepOptions::halo_paths`): asked
/// to with given sides, it says so, and its `carries_halo_paths` says no.
#[test]
fn halo_paths_are_refused_by_name() {
    use lightgrid_core::Sweeper;
    let Some(gpu) = sweeper() else { return };
    assert!(!gpu.carries_halo_paths());
    let d = GridDesc::new(Vec3::ZERO, 1.0, UVec3::splat(2)).unwrap();
    let m = MaterialGrid::filled(d, Material::EMPTY).unwrap();
    let b = Boundary {
        sides: SideBoundary::Given(vec![BinLight::ZERO; HaloLayout::new(d.dims()).len()]),
        ..Boundary::open_sky(BinLight::ZERO)
    };
    let mut o = SweepOptions::default();
    o.halo_paths = true;
    let e = gpu.run(&m, &b, &o).unwrap_err().to_string();
    assert!(e.contains("halo_paths"), "{e}");
    o.halo_paths = false;
    assert!(gpu.run(&m, &b, &o).is_ok());
}

/// The final grid packed on the GPU equals sweep-cpu's grid packed by grid-core within
/// one code per channel, with the same exposure.
#[test]
fn packed_on_the_gpu_within_one_code() {
    let Some(gpu) = sweeper() else { return };
    for scene in lightgrid_measure::scenes::Scene::ALL {
        let (m, b) = scene.build(9);
        let mut o = SweepOptions::multi_bounce();
        o.tolerance = 0.0;
        o.max_passes = 3;
        let cpu = lightgrid_sweep_cpu::run(&m, &b, &o)
            .unwrap()
            .output
            .bins
            .unwrap()
            .pack();
        let g = gpu.run_packed(&m, &b, &o).unwrap();
        assert_eq!(g.exposure, cpu.exposure, "{}", scene.name());
        for (a, c) in g.grid.data().iter().zip(cpu.grid.data()) {
            for (wa, wc) in a.0.iter().zip(&c.0) {
                for (shift, mask) in [(0, 0x7ff), (11, 0x7ff), (22, 0x3ff)] {
                    let (x, y) = ((wa >> shift) & mask, (wc >> shift) & mask);
                    assert!(
                        x.abs_diff(y) <= 1,
                        "{}: word {wa:#x} vs {wc:#x}",
                        scene.name()
                    );
                }
            }
        }
    }
}

/// Sun and sky as separate responses on the GPU combine to the CPU's direct sweep.
#[test]
fn sun_and_sky_responses_on_the_gpu() {
    let Some(gpu) = sweeper() else { return };
    use lightgrid_sky::{ClearSky, Sun};
    use lightgrid_sweep_cpu::{combine_outputs, responses_with};
    let (m, _) = lightgrid_measure::scenes::Scene::Canopy.build(8);
    let sun = Sun::at(0.6, 0.4, Vec3::ONE);
    let sky = ClearSky::blue(sun.direction).bins().unwrap();
    let sun_bins = sun.bins().unwrap();
    let mut o = SweepOptions::multi_bounce();
    o.tolerance = 0.0;
    o.max_passes = 4;
    let mut shared = gpu;
    let (a, b) =
        responses_with(&mut shared, &m, &sky, &sun_bins, SideBoundary::Periodic, &o).unwrap();
    let (cs, cu) = (Vec3::new(0.5, 0.7, 1.2), Vec3::new(3000.0, 2800.0, 2500.0));
    let combined = combine_outputs(&a, &b, cs, cu).bins.unwrap();
    let direct = lightgrid_sweep_cpu::run(
        &m,
        &Boundary {
            top: TopBoundary::Uniform(Box::new(BinLight(std::array::from_fn(|d| {
                sky.top.0[d] * cs + sun_bins.0[d] * cu
            })))),
            bottom: BinLight(sky.bottom.0.map(|v| v * cs)),
            sides: SideBoundary::Periodic,
        },
        &o,
    )
    .unwrap()
    .output
    .bins
    .unwrap();
    assert_close(&direct, &combined).unwrap();
}

/// The exact-answer case of `measure/tests/exact.rs` on the GPU: above an infinite
/// Lambertian ground (one and two levels, albedo 0.3 and 0.9) under a uniform sky, every
/// bin at every point holds the rules' field (`lightgrid_measure::exact::ground_fields`).
#[test]
fn lambertian_ground_holds_the_exact_rule_field_on_the_gpu() {
    let Some(gpu) = sweeper() else { return };
    let top = lightgrid_sky::uniform_sky(Vec3::ONE).unwrap().top;
    let b = Boundary {
        sides: SideBoundary::Periodic,
        ..Boundary::open_sky(top)
    };
    let mut o = SweepOptions::multi_bounce();
    o.max_passes = 8;
    o.tolerance = 0.0;
    o.outputs = o.outputs.with_horizon();
    let pi = std::f32::consts::PI;
    for levels in [1, 2] {
        for albedo in [0.3f32, 0.9] {
            let m = lightgrid_measure::exact::ground_material(levels, albedo).unwrap();
            let out = gpu.run(&m, &b, &o).unwrap();
            let (g, h) = (out.bins.unwrap(), out.horizon.unwrap());
            let (_, rule) = lightgrid_measure::exact::ground_fields(albedo, &top).unwrap();
            for j in levels..g.desc().levels() {
                let l = g.get(UVec3::new(3, j, 5)).unwrap();
                // The horizon halves: facing up the sky's pi, facing down the ground's
                // a pi (`measure/tests/exact.rs`, to 1e-3 as there).
                let down = h.get(UVec3::new(3, j, 5)).unwrap();
                for (n, want) in [(Vec3::Y, pi), (Vec3::NEG_Y, albedo * pi)] {
                    let got = l.irradiance_split(n, down).x;
                    assert!(
                        (got - want).abs() <= 1e-3 * pi,
                        "{levels} levels, albedo {albedo}, level {j}, facing {n}: gpu {got}, exact {want}"
                    );
                }
                for bin in 0..26 {
                    let (got, want) = (l.0[bin].x, rule.0[bin].x);
                    // The stated CPU == GPU tolerance (see `assert_close`).
                    let tol = 1e-4 * got.max(want) + 1e-5 * g.max_value();
                    assert!(
                        (got - want).abs() <= tol,
                        "{levels} levels, albedo {albedo}, level {j}, bin {bin}: gpu {got}, rule {want}"
                    );
                }
            }
        }
    }
}

/// The white furnace on the GPU (issue 13's exact answers run on both sweepers): white
/// blobs of pass-through 0.02 to 1 inside uniform radiance 1 keep radiance 1 at every
/// point, to 1e-3, as on the CPU.
#[test]
fn white_furnace_is_exact_on_the_gpu() {
    let Some(gpu) = sweeper() else { return };
    let m = lightgrid_measure::exact::furnace_material(8, 11).unwrap();
    let b = Boundary {
        sides: SideBoundary::Periodic,
        ..Boundary::surrounding(&BinLight::uniform(Vec3::ONE))
    };
    let mut o = SweepOptions::multi_bounce();
    o.max_passes = 400;
    o.tolerance = 1e-6;
    o.smoothing = 0.25;
    // Both source rules: flat, and quadratic in height (`MediumEmission::Profile`).
    for medium in [
        lightgrid_core::MediumEmission::Source,
        lightgrid_core::MediumEmission::Profile,
    ] {
        o.medium = medium;
        let g = gpu.run(&m, &b, &o).unwrap().bins.unwrap();
        let omega = lightgrid_core::dirs::solid_angles();
        for (i, l) in g.data().iter().enumerate() {
            for bin in 0..26 {
                let v = l.0[bin].x / omega[bin];
                assert!(
                    (v - 1.0).abs() < 1e-3,
                    "{medium:?}: point {i}, bin {bin}: radiance {v}"
                );
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    /// A cell source (the sun's first collisions, issue 14) sweeps on the GPU as on the
    /// CPU: random media, sides, suns, passes.
    #[test]
    fn cell_sources_match_the_cpu(
        m in material_strategy(24),
        periodic in any::<bool>(),
        sun in (-1.0f32..1.0, 0.05f32..1.0, -1.0f32..1.0),
        passes in 1u32..5,
        profile in any::<bool>(),
    ) {
        let Some(gpu) = sweeper() else { return Ok(()) };
        let to_sun = Vec3::new(sun.0, sun.1, sun.2);
        let open = |_: Vec3| 1.0;
        let src = lightgrid_sweep_cpu::sun::first_collision(&m, to_sun, Vec3::new(3.0, 2.0, 1.0), periodic, &open).unwrap();
        let b = Boundary {
            sides: if periodic { SideBoundary::Periodic } else { SideBoundary::Open },
            ..Boundary::open_sky(lumpy_sky().scaled(0.1))
        };
        let mut o = SweepOptions::multi_bounce();
        o.max_passes = passes;
        o.tolerance = 0.0;
        o.medium = if profile { lightgrid_core::MediumEmission::Profile } else { lightgrid_core::MediumEmission::Source };
        let cpu = lightgrid_sweep_cpu::run_with_source(&m, &b, Some(&src), &o).unwrap().output.bins.unwrap();
        let g = gpu.run_with_source(&m, &b, Some(&src), &o).unwrap().bins.unwrap();
        if let Err(e) = assert_close(&cpu, &g) {
            prop_assert!(false, "{e}");
        }
    }
}

/// The sun split's responses (issue 14) computed with the GPU sweeper equal the CPU's.
#[test]
fn sun_split_on_the_gpu() {
    let Some(gpu) = sweeper() else { return };
    let (m, b) = lightgrid_measure::scenes::Scene::DenseBlock.build(10);
    let mut o = SweepOptions::multi_bounce();
    o.tolerance = 0.0;
    o.max_passes = 4;
    let to_sun = Vec3::new(0.5, 0.6, -0.3);
    let cpu = lightgrid_sweep_cpu::sun::SunSplit::compute(
        &mut lightgrid_sweep_cpu::CpuSweeper::new(),
        &m,
        &b,
        to_sun,
        &o,
    )
    .unwrap();
    let mut g = gpu;
    let on_gpu = lightgrid_sweep_cpu::sun::SunSplit::compute(&mut g, &m, &b, to_sun, &o).unwrap();
    assert_close(&cpu.sky, &on_gpu.sky).unwrap();
    assert_close(&cpu.sun_scattered, &on_gpu.sun_scattered).unwrap();
    assert!(cpu.sun_scattered.max_value() > 0.0);
}

/// A hierarchy node's kind of sweep for the sun's tests: a 10³ canopy, four passes
/// with no early stop.
fn canopy_node() -> (MaterialGrid, SweepOptions) {
    let (m, _) = lightgrid_measure::scenes::Scene::Canopy.build(10);
    let mut o = SweepOptions::multi_bounce();
    o.tolerance = 0.0;
    o.max_passes = 4;
    (m, o)
}

/// Faint light of five levels, as a coarser grid hands a node over (`k`: the point).
fn glow(k: usize) -> BinLight {
    BinLight::uniform(Vec3::new(0.02, 0.03, 0.01) * (1 + k % 5) as f32)
}

/// A transmittance outside the box that varies across x.
fn varying_outside(p: Vec3) -> f32 {
    0.4 + 0.5 * (0.3 * p.x).sin().abs()
}

/// `Sweeper::sweep_sun` on the GPU sweeper (the first collisions swept on the device)
/// equals the CPU's, with a hierarchy's kind of sun boundary: scattered light coming in
/// through the top and a given halo, and a transmittance outside that varies.
#[test]
fn sweep_sun_on_the_gpu_equals_the_cpu() {
    use lightgrid_core::{HaloLayout, SideBoundary, SunBoundary, Sweeper, TopBoundary};
    let Some(mut gpu) = sweeper() else { return };
    let (m, o) = canopy_node();
    let d = *m.desc();
    let top: Vec<BinLight> = (0..d.level_len())
        .map(|k| glow(k).split_vertical().0)
        .collect();
    let halo: Vec<BinLight> = (0..HaloLayout::new(d.dims()).len()).map(glow).collect();
    let sun = SunBoundary {
        to_sun: Vec3::new(0.5, 0.6, -0.3),
        scattered: lightgrid_core::Boundary {
            top: TopBoundary::PerPoint(top),
            bottom: BinLight::ZERO,
            sides: SideBoundary::Given(halo),
        },
        outside: &varying_outside,
    };
    let cpu = lightgrid_sweep_cpu::CpuSweeper::new()
        .sweep_sun(&m, &sun, &o)
        .unwrap();
    let on_gpu = gpu.sweep_sun(&m, &sun, &o).unwrap();
    assert_close(&cpu.scattered, &on_gpu.scattered).unwrap();
    assert!(cpu.scattered.max_value() > 0.0);
    assert_eq!(cpu.transmittance, on_gpu.transmittance);
    let t = cpu.transmittance.data();
    assert!(t.iter().any(|&t| t > 0.3) && t.iter().all(|t| (0.0..=1.0).contains(t)));
}

/// `Sweeper::sweep_with_sun` (a grid's light and the sun's first collisions in one
/// sweep, `HierarchyParams::sun_with_sky`) on the GPU sweeper equals the CPU's, with a
/// node's kind of boundary (a sky top, a given halo) and an outside transmittance that
/// varies; the beam adds light the boundary's sweep alone lacks.
#[test]
fn sweep_with_sun_on_the_gpu_equals_the_cpu() {
    use lightgrid_core::{HaloLayout, SideBoundary, SunBeam, Sweeper};
    let Some(mut gpu) = sweeper() else { return };
    let (m, o) = canopy_node();
    let d = *m.desc();
    let b = Boundary {
        sides: SideBoundary::Given((0..HaloLayout::new(d.dims()).len()).map(glow).collect()),
        ..Boundary::open_sky(lumpy_sky().scaled(0.01).split_vertical().0)
    };
    let beam = SunBeam {
        to_sun: Vec3::new(0.5, 0.6, -0.3),
        irradiance: Vec3::new(2.0, 3.0, 1.5),
        outside: &varying_outside,
    };
    let mut cpu = lightgrid_sweep_cpu::CpuSweeper::new();
    let both = cpu.sweep_with_sun(&m, &b, &beam, &o).unwrap().bins.unwrap();
    let on_gpu = gpu.sweep_with_sun(&m, &b, &beam, &o).unwrap().bins.unwrap();
    assert_close(&both, &on_gpu).unwrap();
    let alone = cpu.sweep(&m, &b, &o).unwrap().bins.unwrap();
    assert!(
        assert_close(&alone, &on_gpu).is_err(),
        "the beam adds nothing"
    );
}

/// At the presets' default (`SweepOptions::multi_bounce`, `Gather::AUTO`) a 10° sun over
/// the patchy canopy (issue 44's scene, which `measure/tests/beam.rs` holds within 5 %
/// of Monte Carlo in every quiet cell on the CPU) is gathered on the GPU sweeper as on
/// the CPU's: the same light as `Gather::LOW_SUN` asked for, not the swept light; a 45°
/// sun is swept alike on both.
#[test]
fn the_default_gathers_a_low_sun_on_the_gpu_as_on_the_cpu() {
    use lightgrid_core::{Gather, SideBoundary, SunBoundary, Sweeper};
    let Some(mut gpu) = sweeper() else { return };
    let m = lightgrid_measure::sun_measure::patchy_canopy(16, 3);
    let mut o = SweepOptions::multi_bounce();
    o.outputs.horizon = true;
    let dark = Boundary {
        sides: SideBoundary::Periodic,
        ..Boundary::open_sky(BinLight::ZERO)
    };
    let at = |deg: f32| {
        let (e, a) = (deg.to_radians(), 20f32.to_radians());
        Vec3::new(e.cos() * a.cos(), e.sin(), e.cos() * a.sin())
    };
    let run = |s: &mut dyn Sweeper, deg: f32, gather: Gather| {
        let mut o = o;
        o.gather = gather;
        let sun = SunBoundary {
            to_sun: at(deg),
            scattered: dark.clone(),
            outside: &|_| 1.0,
        };
        s.sweep_sun(&m, &sun, &o).unwrap().scattered
    };
    let mut cpu = lightgrid_sweep_cpu::CpuSweeper::new();
    let default = run(&mut cpu, 10.0, o.gather);
    assert_eq!(o.gather, Gather::AUTO);
    assert_close(&default, &run(&mut gpu, 10.0, o.gather)).unwrap();
    assert_eq!(default.data(), run(&mut cpu, 10.0, Gather::LOW_SUN).data());
    assert!(assert_close(&default, &run(&mut cpu, 10.0, Gather::OFF)).is_err());
    let high = run(&mut cpu, 45.0, o.gather);
    assert_eq!(high.data(), run(&mut cpu, 45.0, Gather::OFF).data());
    assert_close(&high, &run(&mut gpu, 45.0, o.gather)).unwrap();
}

/// With the first scatterings gathered (`SweepOptions::gather`: on the CPU for both
/// sweepers, the rest swept on each) the GPU sweeper's `sweep_sun` equals the CPU's,
/// with a node's kind of boundary; the gathered light differs from the swept, and the
/// response keeps no device copy (the gathered light is added on the CPU).
#[test]
fn gathered_first_scatterings_on_the_gpu_equal_the_cpu() {
    use lightgrid_core::{Gather, SunBoundary, Sweeper};
    let Some(mut gpu) = sweeper() else { return };
    let (m, mut o) = canopy_node();
    let d = *m.desc();
    let sun = SunBoundary {
        to_sun: Vec3::new(0.5, 0.2, -0.3),
        scattered: Boundary {
            top: TopBoundary::Uniform(Box::new(BinLight::ZERO)),
            bottom: BinLight::ZERO,
            sides: SideBoundary::Given((0..HaloLayout::new(d.dims()).len()).map(glow).collect()),
        },
        outside: &varying_outside,
    };
    o.gather = Gather::OFF;
    let swept = lightgrid_sweep_cpu::CpuSweeper::new()
        .sweep_sun(&m, &sun, &o)
        .unwrap();
    o.gather = Gather {
        orders: 2,
        rays: 256,
        max_elevation_deg: 90,
    };
    let cpu = lightgrid_sweep_cpu::CpuSweeper::new()
        .sweep_sun(&m, &sun, &o)
        .unwrap();
    let on_gpu = gpu.sweep_sun(&m, &sun, &o).unwrap();
    assert_close(&cpu.scattered, &on_gpu.scattered).unwrap();
    assert!(on_gpu.resident.is_none());
    assert!(
        assert_close(&swept.scattered, &cpu.scattered).is_err(),
        "nothing gathered"
    );
}
