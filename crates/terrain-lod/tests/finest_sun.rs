//! `LodSkips::finest_scattered_sun`: the finest depth sweeps no scattered sun of its
//! own; its nodes' scattered sun (bins and horizon halves) is what the coarser grids
//! give at their points, their direct sun their own march, through a sun move. Off,
//! the finest depth's sun is swept as every other depth's.

use std::sync::{Arc, Mutex};

use lightgrid_core::glam::Vec3;
use lightgrid_core::{
    BinLight, Boundary, CellSource, Grid, LightField, MaterialGrid, SunBoundary, SunResponse,
    SweepError, SweepOptions, SweepOutput, Sweeper,
};
use lightgrid_sweep_cpu::CpuSweeper;
use lightgrid_terrain_lod::{Hierarchy, Layer, SunLight};

#[path = "field/mod.rs"]
mod field;

const CAMERA: Vec3 = Vec3::new(32.0, 5.0, 32.0);

/// The CPU sweeper, noting the cell size of every grid whose sun it sweeps (its
/// forks into the same list).
struct Counting {
    inner: CpuSweeper,
    sun_swept: Arc<Mutex<Vec<f32>>>,
}

impl Sweeper for Counting {
    fn name(&self) -> &'static str {
        "cpu, counting sun sweeps"
    }
    fn fork(&self) -> Option<Box<dyn Sweeper + Send + Sync>> {
        Some(Box::new(Counting {
            inner: CpuSweeper::new(),
            sun_swept: self.sun_swept.clone(),
        }))
    }
    fn sweep(
        &mut self,
        m: &MaterialGrid,
        b: &Boundary,
        o: &SweepOptions,
    ) -> Result<SweepOutput, SweepError> {
        self.inner.sweep(m, b, o)
    }
    fn sweep_with_source(
        &mut self,
        m: &MaterialGrid,
        b: &Boundary,
        s: &CellSource,
        o: &SweepOptions,
    ) -> Result<SweepOutput, SweepError> {
        self.inner.sweep_with_source(m, b, s, o)
    }
    fn sweep_sun(
        &mut self,
        m: &MaterialGrid,
        sun: &SunBoundary<'_>,
        o: &SweepOptions,
    ) -> Result<SunResponse, SweepError> {
        self.sun_swept.lock().unwrap().push(m.desc().h());
        self.inner.sweep_sun(m, sun, o)
    }
    fn sun_transmittance(
        &mut self,
        m: &MaterialGrid,
        sun: &SunBoundary<'_>,
    ) -> Result<Grid<f32>, SweepError> {
        self.inner.sun_transmittance(m, sun)
    }
}

fn sun(to_sun: Vec3) -> Option<SunLight> {
    Some(SunLight {
        to_sun,
        irradiance: Vec3::splat(3.0),
    })
}

/// A flat ground under a layer of medium 2 to 8 m up whose density changes across x
/// and z, every node of a 64 m square wanted (world grid 8 m, nodes of 8 points down
/// to 2 m), a sun kept apart; built until nothing is left, with the finest depth's
/// scattered sun read from the coarser grids (`skip`) or swept. Returns the hierarchy
/// and the cell sizes of the grids whose sun was swept.
fn settled(skip: bool) -> (Hierarchy, Arc<Mutex<Vec<f32>>>) {
    let mut params = field::small_params(u64::MAX / 4);
    params.skip.finest_scattered_sun = skip;
    let sun_swept = Arc::new(Mutex::new(Vec::new()));
    let sweeper = Counting {
        inner: CpuSweeper::new(),
        sun_swept: sun_swept.clone(),
    };
    let mut h = field::over_varying_layer(Vec3::new(0.5, 0.6, 0.4), Box::new(sweeper), params);
    settle(&mut h);
    (h, sun_swept)
}

fn settle(h: &mut Hierarchy) {
    for _ in 0..50 {
        if h.update(CAMERA).unwrap().pending == 0 {
            return;
        }
    }
    panic!("not settled in 50 frames");
}

/// The finest depth's layers.
fn finest<'a>(h: &'a Hierarchy, layers: &'a [Layer<'a>]) -> Vec<&'a Layer<'a>> {
    let cell = h.params().finest_cell;
    let found: Vec<_> = layers
        .iter()
        .filter(|l| l.owner.is_some() && l.grid.desc().h() == cell)
        .collect();
    assert!(found.len() >= 4, "{} finest nodes", found.len());
    found
}

/// Every finest node's scattered sun is, point for point, what the coarser grid that
/// serves the point gives there (bins and horizon halves), and its sun is current.
fn assert_read_from_coarser_grids(h: &Hierarchy) {
    let layers = h.layers();
    let cell = h.params().finest_cell;
    for l in finest(h, &layers) {
        let s = l.sun.expect("the finest node's sun, current once settled");
        let halves = s
            .horizon
            .expect("halves kept, as the coarser grids keep them");
        let d = *l.grid.desc();
        for i in 0..d.point_count() {
            let p = d.position(d.coords(i).unwrap());
            // The finest coarser layer owning the point (the world grid at worst).
            let coarse = layers
                .iter()
                .rev()
                .filter(|c| c.grid.desc().h() > cell)
                .find(|c| c.owner.is_none_or(|o| o.owns(c.grid.desc(), p)))
                .and_then(|c| c.sun)
                .unwrap();
            assert_eq!(
                s.scattered.unwrap().data()[i],
                coarse.scattered.unwrap().light(p, None).unwrap(),
                "scattered sun at {p}"
            );
            let want = coarse.horizon.unwrap().sample(p).unwrap();
            assert_eq!(halves.data()[i], want, "horizon halves at {p}");
        }
    }
}

/// The finest nodes' direct sun in `a` and `b` (the same nodes) bit for bit.
fn assert_same_direct_sun(a: &Hierarchy, b: &Hierarchy) {
    let (la, lb) = (a.layers(), b.layers());
    let (fa, fb) = (finest(a, &la), finest(b, &lb));
    assert_eq!(fa.len(), fb.len());
    for (x, y) in fa.iter().zip(&fb) {
        assert_eq!(x.grid.desc(), y.grid.desc());
        assert_eq!(
            x.sun.unwrap().transmittance.data(),
            y.sun.unwrap().transmittance.data()
        );
    }
}

#[test]
fn the_finest_depth_reads_its_scattered_sun_from_the_coarser_grids() {
    let (read, read_swept) = settled(true);
    let (swept, swept_swept) = settled(false);
    let cell = read.params().finest_cell;
    // No finest grid's sun swept with the skip; every finest grid's without it.
    let count = |v: &Arc<Mutex<Vec<f32>>>| {
        let v = v.lock().unwrap();
        (v.iter().filter(|&&h| h == cell).count(), v.len())
    };
    let (finest_read, all_read) = count(&read_swept);
    let (finest_swept, _) = count(&swept_swept);
    assert_eq!(finest_read, 0);
    assert!(all_read > 0, "the coarser depths' sun is swept");
    assert_eq!(finest_swept, finest(&swept, &swept.layers()).len());
    assert_read_from_coarser_grids(&read);
    assert_same_direct_sun(&read, &swept);
    // The two differ only in the finest nodes' scattered sun: a point's sun light is
    // within a few percent of the swept one's, not the same.
    let p = Vec3::new(29.0, 3.0, 35.0);
    let (a, b) = (read.light(p, None).unwrap(), swept.light(p, None).unwrap());
    let (ta, tb) = (a.total().element_sum(), b.total().element_sum());
    assert!(ta != tb && (ta / tb - 1.0).abs() < 0.1, "{ta} against {tb}");
}

#[test]
fn a_moved_sun_reaches_the_finest_depth_through_the_coarser_grids() {
    let (mut read, _) = settled(true);
    let (mut swept, _) = settled(false);
    let before: Vec<BinLight> = {
        let layers = read.layers();
        finest(&read, &layers)[0]
            .sun
            .unwrap()
            .scattered
            .unwrap()
            .data()
            .to_vec()
    };
    for h in [&mut read, &mut swept] {
        h.set_sun(sun(Vec3::new(-0.2, 0.8, 0.5))).unwrap();
        settle(h);
    }
    assert_read_from_coarser_grids(&read);
    assert_same_direct_sun(&read, &swept);
    let layers = read.layers();
    assert_ne!(
        finest(&read, &layers)[0]
            .sun
            .unwrap()
            .scattered
            .unwrap()
            .data(),
        before
    );
}

/// A moved sun re-lit by a round of `refresh` frames takes `update`'s path: the
/// finest depth's scattered sun is read from the coarser grids, never swept (a refresh
/// used to sweep every stale sun whole), and the finest nodes end as `update` leaves
/// them.
#[test]
fn a_refresh_round_reads_the_finest_depth_sun_too() {
    let (mut refreshed, swept) = settled(true);
    let (mut updated, _) = settled(true);
    let to = sun(Vec3::new(-0.2, 0.8, 0.5));
    refreshed.set_sun(to).unwrap();
    updated.set_sun(to).unwrap();
    swept.lock().unwrap().clear();
    let round = (0..50).any(|_| refreshed.refresh(CAMERA).unwrap().pending == 0);
    assert!(round, "the round ended");
    settle(&mut updated);
    let cell = refreshed.params().finest_cell;
    let swept = swept.lock().unwrap().clone();
    assert!(
        swept.iter().all(|&h| h != cell),
        "cells of the suns swept: {swept:?}"
    );
    assert!(!swept.is_empty(), "the coarser depths' sun is swept");
    assert_read_from_coarser_grids(&refreshed);
    assert_same_direct_sun(&refreshed, &updated);
}
