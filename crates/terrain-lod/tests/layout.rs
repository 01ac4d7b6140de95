//! A node's levels: from its depth's last lattice level below its lowest ground to two
//! empty levels above the ground and one above its highest object, whichever is higher
//! (`Hierarchy::node_desc` and `node_material`). The levels below lie inside the ground
//! and hold no light; the air above is served by the coarser grids.

use lightgrid_core::glam::{Vec2, Vec3};
use lightgrid_core::{
    BinLight, GridDesc, GridError, Heightmap, Material, MaterialGrid, MaterialSource,
};
use lightgrid_sweep_cpu::CpuSweeper;
use lightgrid_terrain_lod::{Hierarchy, HierarchyParams};

/// The ground's height (off the lattices' levels).
const GROUND: f32 = 0.3;
/// The top of a block of medium standing on the ground over `20..28` m in x and z.
const BLOCK_TOP: f32 = 6.0;

/// Opaque ground below [`GROUND`] (a cell whose centre is below), the block of dense
/// medium above it, air elsewhere.
struct Scene;

fn in_block(p: Vec3) -> bool {
    (20.0..28.0).contains(&p.x) && (20.0..28.0).contains(&p.z) && p.y < BLOCK_TOP
}

impl MaterialSource for Scene {
    fn material(&self, desc: &GridDesc) -> Result<MaterialGrid, GridError> {
        let cells = (0..desc.point_count())
            .map(|i| {
                let p = desc.position(desc.coords(i).expect("in range"));
                if p.y < GROUND {
                    Material::opaque(Vec3::splat(0.3))
                } else if in_block(p) {
                    Material {
                        reflectance: Vec3::splat(0.5),
                        pass: 0.2,
                    }
                } else {
                    Material::EMPTY
                }
            })
            .collect();
        MaterialGrid::new(*desc, cells)
    }
}

#[test]
fn a_nodes_levels_span_its_ground_and_objects_and_no_more() {
    let hm = Heightmap::from_fn(Vec2::ZERO, 2.0, 33, 33, |_, _| GROUND).unwrap();
    let params = HierarchyParams {
        world_cell: 8.0,
        finest_cell: 2.0,
        node_points: 8,
        lod_factor: 100.0,
        evict_factor: 200.0,
        budget_points: u64::MAX / 4,
        ..Default::default()
    };
    let sky = BinLight::uniform(Vec3::ONE).split_vertical().0;
    let mut h = Hierarchy::new(
        &hm,
        Box::new(Scene),
        Box::new(CpuSweeper::new()),
        sky,
        params,
    )
    .unwrap();
    h.update(Vec3::new(32.0, 5.0, 32.0)).unwrap();
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
        let m = Scene.material(&d).unwrap();
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
