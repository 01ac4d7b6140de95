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
