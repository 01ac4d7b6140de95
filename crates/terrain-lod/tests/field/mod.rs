//! A material source from a function: each cell takes `f(its centre, its size)` (the
//! tests' made-up scenes), and the small hierarchy they are seen through.

use lightgrid_core::glam::Vec3;
use lightgrid_core::{GridDesc, GridError, Material, MaterialGrid, MaterialSource};
use lightgrid_terrain_lod::HierarchyParams;

/// A small hierarchy over a 64 m square: world grid 8 m, nodes of 8 points down to
/// 2 m, every node wanted (far level-of-detail and eviction distances), a budget of
/// `budget_points` a frame.
#[allow(dead_code)] // (the tests that include this module and build no hierarchy)
pub(crate) fn small_params(budget_points: u64) -> HierarchyParams {
    HierarchyParams {
        world_cell: 8.0,
        finest_cell: 2.0,
        node_points: 8,
        lod_factor: 100.0,
        evict_factor: 200.0,
        budget_points,
        ..Default::default()
    }
}

pub(crate) struct Field<F>(pub(crate) F);

impl<F: Fn(Vec3, f32) -> Material> MaterialSource for Field<F> {
    fn material(&self, desc: &GridDesc) -> Result<MaterialGrid, GridError> {
        let cells = (0..desc.point_count())
            .map(|i| (self.0)(desc.position(desc.coords(i).expect("in range")), desc.h()))
            .collect();
        MaterialGrid::new(*desc, cells)
    }
}
