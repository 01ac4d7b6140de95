//! `HierarchyParams::sun_with_sky`: every grid sweeps the sun's first collisions with
//! its sky in one sweep. The light read is the split's (the sweep is linear: the same
//! passes over the sum of the two sources), the direct sun the same march bit for bit,
//! and a new sun (direction or irradiance) sweeps every grid again.

use lightgrid_core::LightField;
use lightgrid_core::glam::Vec3;
use lightgrid_sweep_cpu::CpuSweeper;
use lightgrid_terrain_lod::{Hierarchy, SunLight};

#[path = "field/mod.rs"]
mod field;

const CAMERA: Vec3 = Vec3::new(32.0, 5.0, 32.0);

/// [`field::over_varying_layer`] settled under `sun`, with `budget_ms` the frames'
/// time budget and the sun swept with the sky or apart; four passes always (no early
/// stop: the two then run the same passes).
fn settled_within(with_sky: bool, sun: SunLight, budget_ms: Option<f32>) -> Hierarchy {
    let mut params = field::small_params(u64::MAX / 4);
    params.sun_with_sky = with_sky;
    params.sweep.max_passes = 4;
    params.sweep.tolerance = 0.0;
    params.budget_ms = budget_ms;
    let mut h = field::over_varying_layer(
        Vec3::new(0.5, 0.6, 0.4),
        Box::new(CpuSweeper::new()),
        params,
    );
    h.set_sun(Some(sun)).unwrap();
    settle(&mut h);
    h
}

/// [`settled_within`] with no time budget.
fn settled(with_sky: bool, sun: SunLight) -> Hierarchy {
    settled_within(with_sky, sun, None)
}

fn settle(h: &mut Hierarchy) {
    for _ in 0..50 {
        if h.update(CAMERA).unwrap().pending == 0 {
            return;
        }
    }
    panic!("not settled in 50 frames");
}

const SUN: SunLight = SunLight {
    to_sun: Vec3::new(0.6, 0.5, 0.3),
    irradiance: Vec3::splat(3.0),
};

/// Points over the whole square, in the air, in the medium and near the ground.
fn probes() -> Vec<Vec3> {
    let mut v = Vec::new();
    for x in 0..9 {
        for z in 0..9 {
            for y in [0.6, 2.5, 4.9, 7.3, 10.2] {
                v.push(Vec3::new(3.3 + 7.1 * x as f32, y, 2.9 + 7.2 * z as f32));
            }
        }
    }
    v
}

/// The largest difference of `a`'s and `b`'s bins (sky and scattered sun, all 26)
/// relative to the brightest bin there, and whether their direct sun is the same bit
/// for bit, over [`probes`].
fn compare(a: &Hierarchy, b: &Hierarchy) -> (f32, bool) {
    let mut worst = 0.0f32;
    let mut same_sun = true;
    for p in probes() {
        let (la, lb) = (a.light(p, None).unwrap(), b.light(p, None).unwrap());
        let top = la.0.iter().map(|c| c.max_element()).fold(1e-6, f32::max);
        for (x, y) in la.0.iter().zip(&lb.0) {
            worst = worst.max((*x - *y).abs().max_element() / top);
        }
        same_sun &= a.sun_transmittance(p, None).unwrap().to_bits()
            == b.sun_transmittance(p, None).unwrap().to_bits();
    }
    (worst, same_sun)
}

#[test]
fn the_sun_swept_with_the_sky_reads_as_the_split_does() {
    let split = settled(false, SUN);
    let with_sky = settled(true, SUN);
    // The same grids.
    let (ls, lw) = (split.layers(), with_sky.layers());
    assert_eq!(ls.len(), lw.len());
    assert!(ls.len() > 10, "{} grids", ls.len());
    for (s, w) in ls.iter().zip(&lw) {
        assert_eq!(s.grid.desc(), w.grid.desc());
        // Its scattered sun is in the bins: the response holds none of its own.
        let sun = w.sun.expect("every grid's sun current once settled");
        assert!(sun.scattered.is_none() && sun.horizon.is_none());
        assert!(s.sun.expect("swept apart").scattered.is_some());
    }
    let (worst, same_sun) = compare(&split, &with_sky);
    assert!(same_sun, "the direct sun is the same march");
    // Rounding of two sums in another order, not a physical difference.
    assert!(
        worst < 1e-4,
        "largest bin difference {worst} of the brightest bin"
    );
    // And the sun is in there: the sky alone differs by far.
    let mut sky_only = settled(false, SUN);
    sky_only
        .set_sun(Some(SunLight {
            irradiance: Vec3::ZERO,
            ..SUN
        }))
        .unwrap();
    let (apart, _) = compare(&sky_only, &with_sky);
    assert!(
        apart > 0.01,
        "the scattered sun is {apart} of the brightest bin"
    );
}

#[test]
fn a_new_sun_sweeps_every_grid_again() {
    let moved = SunLight {
        to_sun: Vec3::new(-0.2, 0.8, 0.5),
        irradiance: Vec3::new(2.0, 2.5, 3.0),
    };
    let brighter = SunLight {
        irradiance: SUN.irradiance * 2.0,
        ..SUN
    };
    for new in [moved, brighter] {
        let mut h = settled(true, SUN);
        h.set_sun(Some(new)).unwrap();
        settle(&mut h);
        let fresh = settled(true, new);
        let (worst, same_sun) = compare(&h, &fresh);
        assert!(same_sun, "the direct sun marched for {new:?}");
        assert!(
            worst < 1e-5,
            "{worst} of the brightest bin off a fresh build, {new:?}"
        );
    }
}

#[test]
fn a_sky_scale_other_than_one_is_refused() {
    let mut h = settled(true, SUN);
    let e = h.set_sky_scale(Vec3::splat(2.0)).unwrap_err().to_string();
    assert!(e.contains("sky_scale"), "{e}");
    h.set_sky_scale(Vec3::ONE).unwrap();
}

/// Under a time budget a moved sun's world grid is swept again on a thread:
/// `set_sun` returns with the sun moving, the grids' light as it was and the direct sun
/// moved; frames then install the world grid's new light and sweep the nodes again, and
/// once settled the hierarchy is a fresh build's, as without a budget.
#[test]
fn under_a_time_budget_the_world_grid_is_swept_on_a_thread() {
    let moved = SunLight {
        to_sun: Vec3::new(-0.2, 0.8, 0.5),
        irradiance: Vec3::new(2.0, 2.5, 3.0),
    };
    // Time enough for every node of a frame (the budget only decides where the world
    // grid's sweep runs here).
    let mut h = settled_within(true, SUN, Some(1e6));
    let before: Vec<_> = probes()
        .iter()
        .map(|&p| h.light(p, None).unwrap())
        .collect();
    h.set_sun(Some(moved)).unwrap();
    assert!(h.sun_moving(), "the world grid is swept on a thread");
    let during: Vec<_> = probes()
        .iter()
        .map(|&p| h.light(p, None).unwrap())
        .collect();
    assert!(
        before == during,
        "the light shown stays until the new one is installed"
    );
    let fresh = settled(true, moved);
    let direct_moved = probes().iter().all(|&p| {
        h.sun_transmittance(p, None).unwrap().to_bits()
            == fresh.sun_transmittance(p, None).unwrap().to_bits()
    });
    assert!(direct_moved, "the direct sun moves in set_sun");
    let mut installed = false;
    for _ in 0..50 {
        let s = h.update(CAMERA).unwrap();
        installed |= s.sun_moved;
        if !h.sun_moving() && s.pending == 0 {
            break;
        }
    }
    assert!(installed, "a frame installed the new world grid");
    settle(&mut h);
    let (worst, same_sun) = compare(&h, &fresh);
    assert!(same_sun);
    assert!(
        worst < 1e-5,
        "{worst} of the brightest bin off a fresh build"
    );
    // A brighter sun the same way, and back: nothing left moving.
    h.set_sun(Some(SunLight {
        irradiance: moved.irradiance * 2.0,
        ..moved
    }))
    .unwrap();
    assert!(h.sun_moving());
    h.set_sun(Some(moved)).unwrap();
    settle(&mut h);
    assert!(!h.sun_moving());
    let (worst, _) = compare(&h, &fresh);
    assert!(worst < 1e-5, "{worst} after a move undone");
}

/// Removing the sun sweeps the world grid's sky alone again, and a round of `refresh`
/// the nodes': then the light is the sky's alone, as the split's sky response is.
#[test]
fn removing_the_sun_leaves_the_sky_alone_after_a_refresh() {
    let mut h = settled(true, SUN);
    h.set_sun(None).unwrap();
    for _ in 0..50 {
        if h.refresh(CAMERA).unwrap().pending == 0 {
            break;
        }
    }
    let mut split = settled(false, SUN);
    split.set_sun(None).unwrap();
    let (worst, _) = compare(&h, &split);
    assert!(
        worst < 1e-5,
        "{worst} of the brightest bin off the sky alone"
    );
    // Without the refresh the nodes still hold the sun's scattered light.
    let mut stale = settled(true, SUN);
    stale.set_sun(None).unwrap();
    let (apart, _) = compare(&stale, &split);
    assert!(apart > 0.01, "{apart}");
}
