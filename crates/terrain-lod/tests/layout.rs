//! A node's levels: from its depth's last lattice level below its lowest ground to two
//! empty levels above the ground and one above its highest object, whichever is higher
//! (`Hierarchy::node_desc` and `node_material`). The levels below lie inside the ground
//! and hold no light; the air above is served by the coarser grids.

use lightgrid_core::MaterialSource;

mod block;
use block::scene;

/// The ground's height (off the lattices' levels).
const GROUND: f32 = 0.3;

#[test]
fn a_nodes_levels_span_its_ground_and_objects_and_no_more() {
    let h = block::hierarchy(GROUND);
    let (mut with_block, mut bare) = (0, 0);
    for key in h.ready_nodes().into_iter().filter(|k| k.depth > 0) {
        let d = *h.node(key).unwrap().desc();
        let (cell, bottom) = (d.h(), d.origin().y);
        let ny = d.dims().y;
        // The bottom: the last level below the ground.
        assert!(
            bottom < GROUND && bottom >= GROUND - cell,
            "{key:?}: bottom {bottom}, cell {cell}"
        );
        // The highest level holding ground, and holding the block more than a cell
        // above the ground (an object), from the scene's own material.
        let m = scene(GROUND).material(&d).unwrap();
        let (mut top_ground, mut top_object) = (0, None);
        for (i, c) in m.data().iter().enumerate() {
            let q = d.coords(i).unwrap();
            let p = d.position(q);
            if c.is_empty() {
                continue;
            }
            if p.y - cell > GROUND {
                top_object = Some(q.y);
            } else {
                top_ground = top_ground.max(q.y);
            }
        }
        let want = match top_object {
            Some(t) => {
                with_block += 1;
                (top_ground + 2).max(t + 1)
            }
            None => {
                bare += 1;
                top_ground + 2
            }
        };
        assert_eq!(
            ny - 1,
            want,
            "{key:?}: top level (ground {top_ground}, object {top_object:?})"
        );
    }
    assert!(
        with_block > 0 && bare > 0,
        "{with_block} nodes with the block, {bare} bare"
    );
}

/// Objects taller than `margin` (12 m) above a node's highest ground are held whole: a
/// node over a 30 m tower of medium ends one level above the tower's top (before, its
/// column was cut 12 m above the ground and the tower's top was left to the world
/// grid's coarse cells, the sun's march through them included).
#[test]
fn a_tower_taller_than_the_margin_is_held_whole() {
    use lightgrid_core::glam::{UVec3, Vec2, Vec3};
    use lightgrid_core::{BinLight, GridDesc, Heightmap, Material};
    const TOWER_TOP: f32 = 30.0;
    let tower = || {
        block::field::Field(|p: Vec3, _| {
            if p.y < GROUND {
                Material::opaque(Vec3::splat(0.3))
            } else if (20.0..28.0).contains(&p.x) && (20.0..28.0).contains(&p.z) && p.y < TOWER_TOP
            {
                Material {
                    reflectance: Vec3::splat(0.5),
                    pass: 0.5,
                }
            } else {
                Material::EMPTY
            }
        })
    };
    let hm = Heightmap::from_fn(Vec2::ZERO, 2.0, 33, 33, |_, _| GROUND).unwrap();
    let params = block::field::small_params(u64::MAX / 4);
    assert!(params.margin < TOWER_TOP - GROUND);
    let sky = BinLight::uniform(Vec3::ONE).split_vertical().0;
    let mut h = lightgrid_terrain_lod::Hierarchy::new(
        &hm,
        Box::new(tower()),
        Box::new(lightgrid_sweep_cpu::CpuSweeper::new()),
        sky,
        params,
    )
    .unwrap();
    h.update(Vec3::new(32.0, 5.0, 32.0)).unwrap();
    let mut over_tower = 0;
    for key in h.ready_nodes() {
        let d = *h.node(key).unwrap().desc();
        let cell = d.h();
        // The scene's material over the node's columns up to 64 m.
        let levels = (64.0 / cell) as u32;
        let tall = GridDesc::new(d.origin(), cell, UVec3::new(d.dims().x, levels, d.dims().z));
        let m = tower().material(&tall.unwrap()).unwrap();
        let top_object = (m.data().iter().enumerate())
            .filter(|(_, c)| !c.is_empty())
            .map(|(i, _)| m.desc().coords(i).unwrap().y)
            .filter(|&y| m.desc().origin().y + y as f32 * cell - cell > GROUND)
            .max();
        let Some(top_object) = top_object else {
            continue;
        };
        over_tower += 1;
        assert!(
            d.dims().y > top_object + 1,
            "{key:?}: {} levels, the tower's top at level {top_object}",
            d.dims().y
        );
    }
    assert!(over_tower > 0, "nodes over the tower");
}
