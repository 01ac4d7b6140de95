//! A material source from a function: each cell takes `f(its centre, its size)` (the
//! tests' made-up scenes), and the small hierarchy they are seen through.

use lightgrid_core::glam::{Vec2, Vec3};
use lightgrid_core::{
    BinLight, GridDesc, GridError, Heightmap, Material, MaterialGrid, MaterialSource, Sweeper,
};
use lightgrid_terrain_lod::{Hierarchy, HierarchyParams, SunLight};

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
        // (No apron: budgets of a node or two, and 8-point nodes it would triple.)
        apron: 0,
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

/// The flat ground of [`small_params`]' 64 m square (height 0, samples 2 m apart).
#[allow(dead_code)] // (the tests that include this module and build no hierarchy)
pub(crate) fn flat_ground() -> Heightmap {
    Heightmap::from_fn(Vec2::ZERO, 2.0, 33, 33, |_, _| 0.0).expect("a valid heightmap")
}

/// A flat ground (albedo 0.3) below 0 under a layer of medium of reflectance
/// `reflectance` 2 to 8 m up whose density changes across x and z (so that every node
/// has objects and finer children, and the light changes from node to node).
#[allow(dead_code)] // (the tests that include this module and build no hierarchy)
pub(crate) fn varying_layer(
    reflectance: Vec3,
) -> Field<impl Fn(Vec3, f32) -> Material + Send + Sync> {
    Field(move |p: Vec3, _| {
        if p.y < 0.0 {
            Material::opaque(Vec3::splat(0.3))
        } else if (2.0..8.0).contains(&p.y) {
            Material {
                reflectance,
                pass: 0.5 + 0.45 * (0.37 * p.x).sin() * (0.23 * p.z + 0.5).cos(),
            }
        } else {
            Material::EMPTY
        }
    })
}

/// A hierarchy over [`flat_ground`] and [`varying_layer`] of `reflectance`, under a
/// uniform sky and the sun toward `(0.6, 0.5, 0.3)` (irradiance 3), before its first
/// frame.
#[allow(dead_code)] // (the tests that include this module and build no hierarchy)
pub(crate) fn over_varying_layer(
    reflectance: Vec3,
    sweeper: Box<dyn Sweeper + Send + Sync>,
    params: HierarchyParams,
) -> Hierarchy {
    let sky = BinLight::uniform(Vec3::ONE).split_vertical().0;
    let scene = Box::new(varying_layer(reflectance));
    let mut h = Hierarchy::new(&flat_ground(), scene, sweeper, sky, params).expect("valid");
    h.set_sun(Some(SunLight {
        to_sun: Vec3::new(0.6, 0.5, 0.3),
        irradiance: Vec3::splat(3.0),
    }))
    .expect("a valid sun");
    h
}
