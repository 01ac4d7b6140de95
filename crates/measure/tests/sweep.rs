//! Properties of the sweep: known answers, energy, linearity, symmetry, monotonicity.

use lightgrid_core::dirs::{self, NUM_DIRS, dir_index, dir_ivec};
use lightgrid_core::glam::{DVec3, IVec3, UVec3, Vec3};
use lightgrid_core::{
    BinLight, Boundary, GridDesc, HaloLayout, LightGrid, Material, MaterialGrid, MediumEmission,
    Outputs, SideBoundary, SweepOptions, TopBoundary,
};
use lightgrid_sweep_cpu::run;
use proptest::prelude::*;

fn desc(nx: u32, ny: u32, nz: u32) -> GridDesc {
    GridDesc::new(Vec3::ZERO, 1.0, UVec3::new(nx, ny, nz)).unwrap()
}

fn opts(passes: u32, smoothing: f32) -> SweepOptions {
    let mut o = SweepOptions::single_pass();
    o.max_passes = passes;
    o.smoothing = smoothing;
    o.tolerance = 0.0;
    o
}

/// A sky with a different value in every bin (full sphere).
fn lumpy_sky() -> BinLight {
    BinLight(std::array::from_fn(|d| {
        Vec3::new(1.0 + d as f32, 2.0 + (d % 5) as f32, 0.5 + (d % 3) as f32)
    }))
}

fn bins(out: &lightgrid_sweep_cpu::Sweep) -> &LightGrid {
    out.output.bins.as_ref().unwrap()
}

fn rel_close(a: Vec3, b: Vec3, rel: f32) -> bool {
    (a - b).abs().max_element() <= rel * a.abs().max(b.abs()).max_element().max(1e-20)
}

#[test]
fn empty_medium_every_point_gets_the_sky() {
    let sky = lumpy_sky();
    for sides in [SideBoundary::Open, SideBoundary::Periodic] {
        for smoothing in [0.0, 0.3] {
            let m = MaterialGrid::filled(desc(5, 7, 3), Material::EMPTY).unwrap();
            let mut b = Boundary::surrounding(&sky);
            b.sides = sides.clone();
            let out = run(&m, &b, &opts(2, smoothing)).unwrap();
            for (i, p) in bins(&out).data().iter().enumerate() {
                for d in 0..NUM_DIRS {
                    assert!(
                        rel_close(p.0[d], sky.0[d], 1e-6),
                        "{sides:?} point {i} bin {d}: {} vs {}",
                        p.0[d],
                        sky.0[d]
                    );
                }
            }
            // Levels above all material are copied, not computed, in the downward pass.
            assert_eq!(out.output.stats.levels_copied, 7);
        }
    }
}

#[test]
fn empty_medium_with_given_sides_and_per_point_top() {
    let sky = lumpy_sky();
    // Split across the horizon as the given sides split it: paths from above the top
    // take the top's light beyond the sides too.
    let (top, bottom) = sky.split_vertical_by_neighbours();
    let d = desc(3, 4, 2);
    let b = Boundary {
        top: TopBoundary::PerPoint(vec![top; d.level_len()]),
        bottom,
        sides: SideBoundary::Given(vec![sky; HaloLayout::new(d.dims()).len()]),
    };
    let m = MaterialGrid::filled(d, Material::EMPTY).unwrap();
    let out = run(&m, &b, &opts(2, 0.2)).unwrap();
    for p in bins(&out).data() {
        for k in 0..NUM_DIRS {
            assert!(rel_close(p.0[k], sky.0[k], 1e-6));
        }
    }
    assert_eq!(
        out.output.stats.levels_copied, 0,
        "a per-point top is not laterally uniform"
    );
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
        prop::collection::vec(cell, n)
            .prop_map(move |cells| MaterialGrid::new(desc(nx, ny, nz), cells).unwrap())
    })
}

fn sides_strategy() -> impl Strategy<Value = u8> {
    0u8..3
}

fn boundary_for(d: &GridDesc, kind: u8, sky: &BinLight) -> Boundary {
    let mut b = Boundary::surrounding(sky);
    b.sides = match kind {
        0 => SideBoundary::Open,
        1 => SideBoundary::Periodic,
        _ => SideBoundary::Given(vec![sky.scaled(0.7); HaloLayout::new(d.dims()).len()]),
    };
    b
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Input = absorbed + escaped + pending, to 1e-4, for any material, sides, smoothing
    /// and number of passes, whichever outputs are asked for, with media's sources flat
    /// or quadratic in height (`MediumEmission::Profile`).
    #[test]
    fn energy_is_accounted(m in material_strategy(9), sides in sides_strategy(), smoothing in 0f32..0.9, passes in 1u32..6, bins_out in any::<bool>(), profile in any::<bool>()) {
        let b = boundary_for(m.desc(), sides, &lumpy_sky());
        let mut o = opts(passes, smoothing);
        o.medium = if profile { lightgrid_core::MediumEmission::Profile } else { lightgrid_core::MediumEmission::Source };
        if !bins_out { o.outputs = Outputs::AVERAGE_DOMINANT; }
        let out = run(&m, &b, &o).unwrap();
        let bal = out.balance;
        prop_assert!(bal.relative_error() < 1e-4, "{bal:?} err {}", bal.relative_error());
        prop_assert!(bal.input().min_element() > 0.0);
    }

    /// The sweep is linear in the boundary light (media's sources flat or quadratic in
    /// height). A quadratic source may send light below 0 in places, which the sweep
    /// clamps at 0 in its output (`MediumEmission::Profile`): there, and only there, the
    /// output is not linear; so with it, values clamped to 0 in any of the three sweeps
    /// are left out (its light before the clamp is linear: the clamp is the last step).
    #[test]
    fn linear_in_the_sky(m in material_strategy(7), sides in 0u8..2, a in 0.1f32..3.0, c in 0.1f32..3.0, profile in any::<bool>()) {
        let s1 = lumpy_sky();
        let s2 = BinLight::uniform(Vec3::new(0.3, 1.0, 2.0));
        let mix = BinLight(std::array::from_fn(|d| s1.0[d] * a + s2.0[d] * c));
        let mut o = opts(3, 0.25);
        o.medium = if profile { lightgrid_core::MediumEmission::Profile } else { lightgrid_core::MediumEmission::Source };
        let r1 = run(&m, &boundary_for(m.desc(), sides, &s1), &o).unwrap();
        let r2 = run(&m, &boundary_for(m.desc(), sides, &s2), &o).unwrap();
        let rm = run(&m, &boundary_for(m.desc(), sides, &mix), &o).unwrap();
        for ((p1, p2), pm) in bins(&r1).data().iter().zip(bins(&r2).data()).zip(bins(&rm).data()) {
            for d in 0..NUM_DIRS {
                let expect = p1.0[d] * a + p2.0[d] * c;
                let scale = expect.max_element();
                for k in 0..3 {
                    let clamped = [p1.0[d][k], p2.0[d][k], pm.0[d][k]].contains(&0.0);
                    if profile && clamped {
                        continue;
                    }
                    prop_assert!(
                        (pm.0[d][k] - expect[k]).abs() <= 1e-4 * scale + 1e-6,
                        "bin {d} colour {k}: {} vs {}", pm.0[d][k], expect[k]
                    );
                }
            }
        }
    }
}

fn mirror_bin(d: usize, mx: bool, mz: bool) -> usize {
    let v = dir_ivec(d);
    dir_index(IVec3::new(
        if mx { -v.x } else { v.x },
        v.y,
        if mz { -v.z } else { v.z },
    ))
    .unwrap()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// Mirroring the material (and the sky) in x or z mirrors the light.
    #[test]
    fn mirror_symmetry(m in material_strategy(8), mx in any::<bool>(), periodic in any::<bool>()) {
        let mz = !mx;
        let d = *m.desc();
        let dims = d.dims();
        let flip = |p: UVec3| UVec3::new(if mx { dims.x - 1 - p.x } else { p.x }, p.y, if mz { dims.z - 1 - p.z } else { p.z });
        let cells: Vec<Material> = (0..d.point_count()).map(|i| *m.get(flip(d.coords(i).unwrap())).unwrap()).collect();
        let mm = MaterialGrid::new(d, cells).unwrap();
        let sky = lumpy_sky();
        let msky = BinLight(std::array::from_fn(|k| sky.0[mirror_bin(k, mx, mz)]));
        let sides = if periodic { 1 } else { 0 };
        let o = opts(3, 0.3);
        let a = run(&m, &boundary_for(&d, sides, &sky), &o).unwrap();
        let b = run(&mm, &boundary_for(&d, sides, &msky), &o).unwrap();
        for i in 0..d.point_count() {
            let p = d.coords(i).unwrap();
            let la = bins(&a).get(p).unwrap();
            let lb = bins(&b).get(flip(p)).unwrap();
            for k in 0..NUM_DIRS {
                let (x, y) = (la.0[k], lb.0[mirror_bin(k, mx, mz)]);
                prop_assert!((x - y).abs().max_element() <= 1e-4 * x.max(y).max_element() + 1e-6, "point {p} bin {k}: {x} vs {y}");
            }
        }
    }

    /// Darker cells never brighten anything; denser absorbing cells never brighten
    /// anything. Under the flat source every weight of the sweep is non-negative, so
    /// this holds value by value (to 1e-5 relative). The default quadratic source in
    /// height is not a positive scheme (as linear-discontinuous schemes in
    /// discrete-ordinates codes are not): its `P_1`, `P_2` terms move a cell's emission
    /// between its upper and lower segments, so less light colliding in one part of a
    /// cell can send a little more along another path. What holds there: the grid's
    /// total light falls (per colour, to `f32` rounding: 1e-6 relative; measured rises
    /// of 7e-10), and a value rises by at most 1e-3 of the largest fall the darker cell
    /// causes (the negative part of the scheme's response against the response). Measured: 2.2e-4 of it in both
    /// cases found (the regression seeds `991050c3…` and `4f15354f…`: an opaque cell
    /// darkened beside a medium of optical depth 3; rises of 6.3e-4 on 3.41 and 5.9e-3
    /// on 14.8, where the fall reached 2.8 and 27), at most 1e-4 over 300 random cases.
    /// (The bound this test held before, 1e-5 of the grid's brightest light, came from
    /// one measured case and failed on about one run in six (2 of 12 here): those two rose 2.4e-5
    /// and 1.6e-4 of it.)
    #[test]
    fn monotonic_in_reflectance_and_density(m in material_strategy(7), pick in any::<prop::sample::Index>(), factor in 0f32..1.0) {
        let d = *m.desc();
        let i = pick.index(d.point_count());
        let sky = lumpy_sky();
        for rule in [MediumEmission::Source, MediumEmission::Profile] {
            let mut o = opts(4, 0.25);
            o.medium = rule;
            let base = run(&m, &boundary_for(&d, 0, &sky), &o).unwrap();
            let mut darker = m.data().to_vec();
            darker[i].reflectance *= factor;
            let dk = run(&MaterialGrid::new(d, darker).unwrap(), &boundary_for(&d, 0, &sky), &o).unwrap();
            let pairs = || bins(&base).data().iter().zip(bins(&dk).data()).flat_map(|(a, b)| a.0.iter().zip(b.0.iter()));
            // Profile: the largest fall, and the totals.
            let fall = pairs().map(|(a, b)| (*a - *b).max_element()).fold(0f32, f32::max);
            if rule == MediumEmission::Profile {
                let total = |g: &LightGrid| g.data().iter().flat_map(|l| l.0.iter()).map(|v| v.as_dvec3()).sum::<DVec3>();
                let (ta, tb) = (total(bins(&base)), total(bins(&dk)));
                prop_assert!(tb.cmple(ta * (1.0 + 1e-6) + DVec3::splat(1e-6)).all(), "total light rose: {ta} to {tb}");
            }
            for (a, b) in pairs() {
                let allowed = if rule == MediumEmission::Source {
                    *a * (1.0 + 1e-5) + Vec3::splat(1e-6)
                } else {
                    *a * (1.0 + 1e-5) + Vec3::splat(1e-3 * fall + 1e-6)
                };
                prop_assert!(b.cmple(allowed).all(), "{rule:?}: {a} rose to {b} (largest fall {fall})");
            }
        }
        let o = opts(4, 0.25);
        let mut absorbing: Vec<Material> = m.data().iter().map(|c| Material { reflectance: Vec3::ZERO, pass: c.pass }).collect();
        let base = run(&MaterialGrid::new(d, absorbing.clone()).unwrap(), &boundary_for(&d, 0, &sky), &o).unwrap();
        absorbing[i].pass *= factor;
        let dense = run(&MaterialGrid::new(d, absorbing).unwrap(), &boundary_for(&d, 0, &sky), &o).unwrap();
        for (a, b) in bins(&base).data().iter().zip(bins(&dense).data()) {
            for k in 0..NUM_DIRS {
                prop_assert!(b.0[k].cmple(a.0[k] * (1.0 + 1e-5) + Vec3::splat(1e-6)).all());
            }
        }
    }
}

#[test]
fn one_cell_wall_blocks_near_horizontal_light() {
    let (nx, ny, nz) = (40u32, 8u32, 3u32);
    let wall = 14u32;
    let plus_x = dir_index(IVec3::X).unwrap();
    let sky = BinLight::single(plus_x, Vec3::ONE);
    let d = desc(nx, ny, nz);
    let mut cells = vec![Material::EMPTY; d.point_count()];
    for i in 0..d.point_count() {
        if d.coords(i).unwrap().x == wall {
            cells[i] = Material::opaque(Vec3::ZERO);
        }
    }
    let with_wall = run(
        &MaterialGrid::new(d, cells).unwrap(),
        &Boundary::open_sky(sky),
        &opts(1, 0.0),
    )
    .unwrap();
    let without = run(
        &MaterialGrid::filled(d, Material::EMPTY).unwrap(),
        &Boundary::open_sky(sky),
        &opts(1, 0.0),
    )
    .unwrap();
    let mut checked = 0;
    for i in 0..d.point_count() {
        let p = d.coords(i).unwrap();
        // Every chain of paths reaching this point started left of the wall.
        let start = p.x as i64 - 4 * (ny - p.y) as i64;
        if p.x > wall + 2 && start < wall as i64 - 2 {
            checked += 1;
            assert_eq!(
                bins(&with_wall).data()[i].0[plus_x],
                Vec3::ZERO,
                "point {p}"
            );
            assert_eq!(bins(&without).data()[i].0[plus_x], Vec3::ONE, "point {p}");
        }
    }
    assert!(checked > 100, "{checked}");
}

#[test]
fn single_pass_never_lights_upward_bins() {
    let d = desc(6, 6, 6);
    let m = MaterialGrid::filled(
        d,
        Material {
            reflectance: Vec3::ONE,
            pass: 0.5,
        },
    )
    .unwrap();
    let (top, _) = lumpy_sky().split_vertical();
    let out = run(&m, &Boundary::open_sky(top), &opts(1, 0.0)).unwrap();
    for p in bins(&out).data() {
        for k in 17..NUM_DIRS {
            assert_eq!(p.0[k], Vec3::ZERO);
        }
    }
    // With an upward pass, the bright fog lights them.
    let out = run(&m, &Boundary::open_sky(top), &opts(2, 0.0)).unwrap();
    assert!(bins(&out).data()[0].0[dirs::UP].x > 0.0);
}

#[test]
fn multi_bounce_converges_and_average_only_matches_bins() {
    let d = desc(8, 10, 8);
    let m = MaterialGrid::filled(
        d,
        Material {
            reflectance: Vec3::splat(0.9),
            pass: 0.7,
        },
    )
    .unwrap();
    let (top, _) = lumpy_sky().split_vertical();
    let mut o = SweepOptions::multi_bounce();
    o.tolerance = 1e-4;
    let full = run(&m, &Boundary::open_sky(top), &o).unwrap();
    assert!(
        full.output.stats.passes < o.max_passes,
        "{:?}",
        full.output.stats
    );
    assert!(full.balance.pending.max_element() <= 1e-4 * full.balance.input().max_element());
    o.outputs = Outputs::AVERAGE_DOMINANT;
    let lean = run(&m, &Boundary::open_sky(top), &o).unwrap();
    assert!(lean.output.bins.is_none());
    let (a, b) = (full.output.average.unwrap(), lean.output.average.unwrap());
    let (da, db) = (full.output.dominant.unwrap(), lean.output.dominant.unwrap());
    for i in 0..d.point_count() {
        assert!(rel_close(a.data()[i].0, b.data()[i].0, 1e-5));
        assert!((da.data()[i].0 - db.data()[i].0).length() < 1e-5);
    }
}

#[test]
fn invalid_input_is_a_typed_error() {
    let m = MaterialGrid::filled(desc(2, 2, 2), Material::EMPTY).unwrap();
    let mut sky = BinLight::ZERO;
    sky.0[3].y = f32::NAN;
    let e = run(&m, &Boundary::open_sky(sky), &SweepOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("top"), "{e}");
    let e = run(
        &m,
        &Boundary::open_sky(BinLight::single(4, Vec3::splat(1e35))),
        &SweepOptions::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("1e30"), "{e}");
    let mut o = SweepOptions::default();
    o.smoothing = f32::NAN;
    assert!(
        run(&m, &Boundary::open_sky(BinLight::ZERO), &o)
            .unwrap_err()
            .to_string()
            .contains("smoothing")
    );
}

#[test]
fn sun_and_sky_responses_combine_exactly() {
    use lightgrid_sky::{ClearSky, Sun};
    use lightgrid_sweep_cpu::sweep_responses;
    let (m, _) = lightgrid_measure::scenes::Scene::Canopy.build(8);
    let sun = Sun::at(0.6, 0.4, Vec3::ONE);
    let sky = ClearSky::blue(sun.direction).bins().unwrap();
    let sun_bins = sun.bins().unwrap();
    let o = opts(4, 0.2);
    let r = sweep_responses(&m, &sky, &sun_bins, SideBoundary::Periodic, &o).unwrap();
    let (cs, cu) = (Vec3::new(0.5, 0.7, 1.2), Vec3::new(3000.0, 2800.0, 2500.0));
    let combined = r.combine(cs, cu);
    let direct = run(
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
    .unwrap();
    for (a, b) in combined
        .bins
        .unwrap()
        .data()
        .iter()
        .zip(bins(&direct).data())
    {
        for d in 0..NUM_DIRS {
            assert!(rel_close(a.0[d], b.0[d], 1e-5), "{} vs {}", a.0[d], b.0[d]);
        }
    }
    for (a, b) in combined
        .average
        .unwrap()
        .data()
        .iter()
        .zip(direct.output.average.unwrap().data())
    {
        assert!(rel_close(a.0, b.0, 1e-5));
    }
}

/// `CpuSweeper::recycle`: a sweep into an earlier output's memory equals a fresh sweep
/// bit for bit, whatever that memory held (here NaN everywhere), for every output kind
/// and pass count; and memory of another size is not used.
#[test]
fn recycled_memory_is_fully_overwritten() {
    use lightgrid_core::{AverageLight, DominantDir, Grid, SweepOutput, Sweeper};
    let (m, b) = lightgrid_measure::scenes::Scene::Canopy.build(12);
    let d = *m.desc();
    let garbage = |d: GridDesc| SweepOutput {
        horizon: None,
        bins: Some(Grid::from_trusted(
            d,
            vec![BinLight([Vec3::NAN; NUM_DIRS]); d.point_count()],
        )),
        average: Some(Grid::from_trusted(
            d,
            vec![AverageLight(Vec3::NAN); d.point_count()],
        )),
        dominant: Some(Grid::from_trusted(
            d,
            vec![DominantDir(Vec3::NAN); d.point_count()],
        )),
        stats: Default::default(),
        resident: None,
    };
    for outputs in [Outputs::ALL, Outputs::AVERAGE_DOMINANT] {
        for passes in [1, 2, 5] {
            let mut o = SweepOptions::multi_bounce();
            o.outputs = outputs;
            o.max_passes = passes;
            let fresh = lightgrid_sweep_cpu::CpuSweeper::new()
                .sweep(&m, &b, &o)
                .unwrap();
            let mut sweeper = lightgrid_sweep_cpu::CpuSweeper::new();
            sweeper.recycle(garbage(d));
            let reused = sweeper.sweep(&m, &b, &o).unwrap();
            assert!(fresh.bins == reused.bins, "{outputs:?}, {passes} passes");
            assert!(fresh.average == reused.average);
            assert!(fresh.dominant == reused.dominant);
            assert!(fresh.average.is_some());
            // A second round through the same sweeper's own output.
            sweeper.recycle(reused);
            let again = sweeper.sweep(&m, &b, &o).unwrap();
            assert!(fresh.bins == again.bins && fresh.dominant == again.dominant);
        }
    }
    // One sweeper through scenes of one size but other material, sides and sources:
    // each equals a fresh sweep (no light, pending scatter or side ring of an earlier
    // sweep survives in the reused working buffers).
    let mut sweeper = lightgrid_sweep_cpu::CpuSweeper::new();
    let o = SweepOptions::multi_bounce();
    for (k, scene) in [
        lightgrid_measure::scenes::Scene::Canopy,
        lightgrid_measure::scenes::Scene::DenseBlock,
        lightgrid_measure::scenes::Scene::UniformFog,
        lightgrid_measure::scenes::Scene::Canopy,
    ]
    .into_iter()
    .enumerate()
    {
        let (m, mut b) = scene.build(12);
        if k % 2 == 1 {
            b.sides = SideBoundary::Open;
        }
        let fresh = lightgrid_sweep_cpu::CpuSweeper::new()
            .sweep(&m, &b, &o)
            .unwrap();
        let out = sweeper.sweep(&m, &b, &o).unwrap();
        assert!(out.bins == fresh.bins, "{scene:?} after other scenes");
        sweeper.recycle(out);
        // With a cell source (pending light in cells the next scene may leave empty).
        let removed = (0..d.point_count())
            .map(|i| Vec3::splat((i % 7) as f32 * 0.1))
            .collect();
        let src = lightgrid_core::CellSource::new(d, removed, Vec3::new(0.2, -0.9, 0.1)).unwrap();
        let fresh = lightgrid_sweep_cpu::CpuSweeper::new()
            .sweep_with_source(&m, &b, &src, &o)
            .unwrap();
        let out = sweeper.sweep_with_source(&m, &b, &src, &o).unwrap();
        assert!(out.bins == fresh.bins, "{scene:?} with a source");
        sweeper.recycle(out);
    }
    // Memory of another size is not used: a 12-level grid after an 8-level one.
    let mut sweeper = lightgrid_sweep_cpu::CpuSweeper::new();
    sweeper.recycle(garbage(desc(4, 8, 4)));
    let o = SweepOptions::multi_bounce();
    let out = sweeper.sweep(&m, &b, &o).unwrap();
    let fresh = lightgrid_sweep_cpu::CpuSweeper::new()
        .sweep(&m, &b, &o)
        .unwrap();
    assert!(out.bins == fresh.bins);
}

/// A point's light is the mean of its paths' light over its own cell: the segment mean
/// of the transmittance, `(1 − τ) / d` at optical depth `d`, has its known answers and
/// limits, also where `τ` underflows.
#[test]
fn segment_mean_known_answers() {
    use lightgrid_sweep_cpu::sweep::seg_mean;
    let m = |d: f32| seg_mean((-d).exp(), d);
    assert_eq!(m(0.0), 1.0);
    assert_eq!(seg_mean(0.0, f32::INFINITY), 0.0);
    assert_eq!(seg_mean(1.0, f32::NAN), 1.0);
    assert!((m(1.0) - (1.0 - (-1.0f32).exp())).abs() < 1e-6);
    // Continuous where the series takes over, monotonic, within [τ, 1].
    let mut last = 1.0;
    for i in 1..=4000 {
        let d = i as f32 * 0.01;
        let v = m(d);
        assert!(v >= (-d).exp() && v <= 1.0 && v <= last, "{d}: {v}");
        last = v;
    }
    let (a, b) = (m(0.02 * 0.999), m(0.02 * 1.001));
    assert!((a - b).abs() < 2e-5 && a >= b, "{a} {b}");
    // A thick cell lit from one face: the mean (0.317) above the centre's light (0.223);
    // past `f32`'s range of `τ` the mean is still `1 / d`.
    assert!((m(3.0) - (1.0 - (-3.0f32).exp()) / 3.0).abs() < 1e-6);
    assert!(m(3.0) > 1.4 * (-1.5f32).exp());
    assert!((seg_mean(0.0, 120.0) - 1.0 / 120.0).abs() < 1e-9);
}
