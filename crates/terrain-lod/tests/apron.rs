//! A node's sky sweep widened by an apron (`HierarchyParams::apron`): the finest nodes
//! around a block of dense medium on a flat ground, against one sweep of the whole
//! scene at their cell, are nearer to it with an apron than without (the light entering
//! their sides has crossed the apron's fine material instead of coming from a coarser
//! grid's points), for the sky's light and for the sun's scattered light
//! (`HierarchyParams::sun_apron`); and the parameters are checked.

use lightgrid_core::glam::{UVec3, Vec2, Vec3};
use lightgrid_core::{
    BinLight, Boundary, GridDesc, Heightmap, LightField, MaterialSource, SunBoundary, Sweeper,
};
use lightgrid_sweep_cpu::CpuSweeper;
use lightgrid_terrain_lod::{Hierarchy, HierarchyParams, LodError, SunLight};

#[path = "block/mod.rs"]
mod block;
use block::field;

const GROUND: f32 = 1.0;

fn sky() -> BinLight {
    BinLight::uniform(Vec3::ONE).split_vertical().0
}

fn params(apron: u32) -> HierarchyParams {
    HierarchyParams {
        apron,
        sun_apron: apron,
        ..field::small_params(u64::MAX / 4)
    }
}

/// The sun of [`the_apron_brings_the_scattered_sun_nearer_too`]: 30° up, its light
/// crossing the block's side toward the finest nodes beyond it.
fn to_sun() -> Vec3 {
    let e = 30f32.to_radians();
    Vec3::new(-e.cos() * 0.8, e.sin(), -e.cos() * 0.6)
}

/// The hierarchy over the block scene lit by `sky` (and with `sun`, the sun kept
/// apart), every node built.
fn lit(apron: u32, sky: BinLight, sun: Option<SunLight>) -> Result<Hierarchy, LodError> {
    let hm = Heightmap::from_fn(Vec2::ZERO, 2.0, 33, 33, |_, _| GROUND).unwrap();
    let mut h = Hierarchy::new(
        &hm,
        Box::new(block::scene(GROUND)),
        Box::new(CpuSweeper::new()),
        sky,
        params(apron),
    )?;
    h.set_sun(sun)?;
    h.update(Vec3::new(32.0, 5.0, 32.0))?;
    Ok(h)
}

fn hierarchy(apron: u32) -> Result<Hierarchy, LodError> {
    lit(apron, sky(), None)
}

/// The points of the finest nodes within 12 m of the block's centre, a metre or more
/// above the ground.
fn finest_points(h: &Hierarchy) -> Vec<Vec3> {
    let mut out = Vec::new();
    for l in h.layers().iter().filter(|l| l.grid.desc().h() == 2.0) {
        let d = *l.grid.desc();
        for i in 0..d.point_count() {
            let p = d.position(d.coords(i).unwrap());
            if (p.x - 24.0).abs() <= 12.0 && (p.z - 24.0).abs() <= 12.0 && p.y >= GROUND + 1.0 {
                out.push(p);
            }
        }
    }
    out
}

/// Relative RMS difference of the irradiance on the six axes between the hierarchy and
/// `reference` at its [`finest_points`].
fn rms_against(h: &Hierarchy, reference: &impl LightField) -> f64 {
    let axes = lightgrid_core::light::AMBIENT_AXES;
    let (mut sum, mut n) = (0.0f64, 0usize);
    for p in finest_points(h) {
        for a in axes {
            let (got, want) = (
                h.irradiance(p, a).unwrap().x,
                reference.irradiance(p, a).unwrap().x,
            );
            sum += ((got - want) as f64 / want.max(1e-3) as f64).powi(2);
            n += 1;
        }
    }
    assert!(n > 1000, "{n} reads");
    (sum / n as f64).sqrt()
}

/// The largest difference of the sun's transmittance between the hierarchy and
/// `reference` at its [`finest_points`].
fn worst_transmittance(h: &Hierarchy, reference: &impl LightField) -> f32 {
    finest_points(h)
        .into_iter()
        .map(|p| {
            let got = h.sun_transmittance(p, None).unwrap();
            let want = reference.sun_transmittance(p, None).unwrap();
            (got - want).abs()
        })
        .fold(0.0, f32::max)
}

/// Measured: 8.8 % without an apron, 5.6 % with two cells and 4.4 % with four. (14.1 /
/// 8.3 / 5.5 % until 2026-12-07's hand-over rules: a ground's edge cells were surfaces
/// through a given side, sending the ground's light sideways out of a node, and the
/// top level's paths from beyond the sides started in the halo's top level
/// (`sweep_cpu::sweep::exposure`, `tests/handover.rs` there). An apron moved both away
/// from the finest points, so it has less left to mend: it took 41 % of the error
/// away with two cells, 37 % now; the error without one is held as well.)
#[test]
fn an_apron_brings_the_finest_nodes_nearer_to_one_sweep() {
    // One sweep of the scene at the finest cell, over the 64 m and 16 m beyond on every
    // side (its open sides far from the block), with the hierarchy's options.
    let desc = GridDesc::new(Vec3::new(-15.0, -5.0, -15.0), 2.0, UVec3::new(48, 12, 48)).unwrap();
    let m = block::scene(GROUND).material(&desc).unwrap();
    let mut o = params(0).sweep;
    o.outputs.bins = true;
    let out = CpuSweeper::new()
        .sweep(&m, &Boundary::open_sky(sky()), &o)
        .unwrap();
    let reference =
        lightgrid_core::SplitLightGrid::new(out.bins.unwrap(), out.horizon.unwrap()).unwrap();
    let errors: Vec<f64> = [0, 2, 4]
        .iter()
        .map(|&a| rms_against(&hierarchy(a).unwrap(), &reference))
        .collect();
    println!("relative RMS against one sweep, apron 0 / 2 / 4: {errors:?}");
    assert!(errors[0] < 0.1, "{errors:?}");
    assert!(errors[1] < 0.7 * errors[0], "{errors:?}");
    assert!(errors[2] < errors[1], "{errors:?}");
}

/// The sun's scattered light (the sky dark, the sun kept apart: what the bins hold is
/// the sun's light after a scattering) of the finest nodes around the block, against
/// one sun sweep of the whole scene at their cell: the light scattered by the block
/// enters their sides from the coarser grids without an apron, and has crossed the
/// apron's fine material with one.
///
/// Measured: 31 % without an apron, 24 % with two cells and 21 % with four (the
/// scattered sun is dim beside the block: relative errors are large; 38 / 30 / 24 %
/// before 2026-12-07's hand-over rules, and 52 / 20 / 15 % before that morning's
/// `HierarchyParams::halo_ground_lift`, which `git bisect` finds took the aprons' gain
/// from 62 to 22 %: measured, not mended). Its direct sun,
/// marched over the widened grid, stays the one sweep's.
#[test]
fn the_apron_brings_the_scattered_sun_nearer_too() {
    let desc = GridDesc::new(Vec3::new(-15.0, -5.0, -15.0), 2.0, UVec3::new(48, 12, 48)).unwrap();
    let m = block::scene(GROUND).material(&desc).unwrap();
    let o = params(0).sweep;
    let reference = CpuSweeper::new()
        .sweep_sun(
            &m,
            &SunBoundary {
                to_sun: to_sun(),
                scattered: Boundary::open_sky(BinLight::ZERO),
                outside: &|_| 1.0,
            },
            &o,
        )
        .unwrap();
    assert!(reference.horizon.is_some());
    let sun = Some(SunLight {
        to_sun: to_sun(),
        irradiance: Vec3::ONE,
    });
    let mut direct = Vec::new();
    let errors: Vec<f64> = [0, 2, 4]
        .iter()
        .map(|&a| {
            let h = lit(a, BinLight::ZERO, sun).unwrap();
            direct.push(worst_transmittance(&h, &reference));
            rms_against(&h, &reference)
        })
        .collect();
    println!("direct sun, largest difference in transmittance, apron 0 / 2 / 4: {direct:?}");
    println!("scattered sun, relative RMS against one sweep, apron 0 / 2 / 4: {errors:?}");
    // (Measured: 1.4e-5 with every apron: float rounding along different marches.)
    assert!(direct.iter().all(|&d| d < 1e-4), "{direct:?}");
    assert!(errors[1] < 0.8 * errors[0], "{errors:?}");
    assert!(errors[2] < errors[1], "{errors:?}");
}

/// An apron wider than a node is refused, naming the field; one that makes the largest
/// node sweep exceed the point budget too. A sun apron wider than the apron is taken as
/// the apron (the default's 3 cells with no apron: none).
#[test]
fn the_apron_is_checked() {
    let hm = Heightmap::from_fn(Vec2::ZERO, 2.0, 33, 33, |_, _| GROUND).unwrap();
    let build = |p: HierarchyParams| {
        Hierarchy::new(
            &hm,
            Box::new(block::scene(GROUND)),
            Box::new(CpuSweeper::new()),
            sky(),
            p,
        )
        .err()
        .map(|e| e.to_string())
    };
    let e = build(params(9)).expect("an apron of 9 cells around 8 points");
    assert!(e.contains("apron"), "{e}");
    let mut p = params(8);
    p.budget_points = 8 * 8 * p.max_levels as u64;
    let e = build(p).expect("a budget under the widened node");
    assert!(e.contains("budget_points"), "{e}");
    let mut p = params(2);
    p.sun_apron = 3;
    assert_eq!(p.sun_apron_cells(), 2);
    assert!(build(p).is_none(), "a sun apron wider than the apron");
    let p = HierarchyParams {
        apron: 0,
        sun_apron: HierarchyParams::default().sun_apron,
        ..params(2)
    };
    assert_eq!(p.sun_apron_cells(), 0);
    assert!(build(p).is_none(), "the default sun apron with no apron");
    assert!(build(params(8)).is_none());
}
