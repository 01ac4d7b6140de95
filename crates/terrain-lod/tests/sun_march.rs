//! A moved sun under a time budget: `set_sun` re-marches the direct sun of the grids
//! nearest the last frame's camera (those over the camera whatever the time) for about
//! a frame's budget and leaves the others to the frames after, which march them alone
//! while their scattered sun is still current; once settled, every grid's sun is what
//! the same move without a budget gives.

use lightgrid_core::LightField;
use lightgrid_core::glam::Vec3;
use lightgrid_sweep_cpu::CpuSweeper;
use lightgrid_terrain_lod::{Hierarchy, SunLight};

#[path = "field/mod.rs"]
mod field;

const CAMERA: Vec3 = Vec3::new(20.0, 5.0, 20.0);

fn sun(to_sun: Vec3) -> Option<SunLight> {
    Some(SunLight {
        to_sun,
        irradiance: Vec3::splat(3.0),
    })
}

/// A flat ground under a layer of medium whose density changes across x and z, every
/// node of a 64 m square wanted (world grid 8 m, nodes of 8 points down to 2 m), built
/// until nothing is left under a sun; `budget_ms` the frames' time budget.
fn settled(budget_ms: Option<f32>) -> Hierarchy {
    let mut params = field::small_params(u64::MAX / 4);
    params.budget_ms = budget_ms;
    let mut h = field::over_varying_layer(Vec3::splat(0.5), Box::new(CpuSweeper::new()), params);
    settle(&mut h);
    h
}

fn settle(h: &mut Hierarchy) {
    for _ in 0..100_000 {
        let s = h.update(CAMERA).unwrap();
        if s.pending == 0 && !h.sun_moving() {
            return;
        }
    }
    panic!("not settled");
}

#[test]
fn a_moved_sun_relights_the_grids_over_the_camera_first_and_the_rest_after() {
    let moved = Vec3::new(-0.2, 0.8, 0.5);
    // A budget of a microsecond: set_sun marches the world grid and the nodes over
    // the camera alone.
    let mut budgeted = settled(Some(1e-3));
    budgeted.set_sun(sun(moved)).unwrap();
    let layers = budgeted.layers();
    let nodes = layers.iter().filter(|l| l.owner.is_some()).count();
    let shown: Vec<_> = layers
        .iter()
        .filter(|l| l.owner.is_some() && l.sun.is_some())
        .collect();
    let depths = budgeted.params().depths() as usize;
    assert_eq!(
        shown.len(),
        depths,
        "the nodes over the camera, one a depth"
    );
    for l in &shown {
        let o = l.owner.unwrap();
        assert!(o.owns(l.grid.desc(), Vec3::new(CAMERA.x, 3.0, CAMERA.z)));
    }
    assert!(nodes > 2 * depths, "{nodes} nodes");
    // The light over the camera already has the new direct sun: that of the same
    // move without a budget.
    let mut unbudgeted = settled(None);
    unbudgeted.set_sun(sun(moved)).unwrap();
    let p = Vec3::new(CAMERA.x, 3.0, CAMERA.z);
    assert_eq!(
        budgeted.sun_transmittance(p, None).unwrap(),
        unbudgeted.sun_transmittance(p, None).unwrap()
    );
    drop(layers);
    // Settled, every node's sun responses are those of the move without a budget.
    settle(&mut budgeted);
    settle(&mut unbudgeted);
    let (a, b) = (budgeted.layers(), unbudgeted.layers());
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(x.grid.desc(), y.grid.desc());
        let (sx, sy) = (x.sun.unwrap(), y.sun.unwrap());
        assert_eq!(sx.transmittance.data(), sy.transmittance.data());
        assert_eq!(sx.scattered.unwrap().data(), sy.scattered.unwrap().data());
    }
}
