//! Test support shared by the crate's unit tests: a small hierarchy over a layer of
//! medium whose density varies across it, or over columns of many heights.

use lightgrid_core::glam::{Vec2, Vec3};
use lightgrid_core::{
    BinLight, GridDesc, GridError, Heightmap, Material, MaterialGrid, MaterialSource,
};

use crate::{Hierarchy, HierarchyParams, SunLight};

/// A flat ground under a layer of medium whose density changes across x and z.
pub(crate) struct Layer;

impl MaterialSource for Layer {
    fn material(&self, desc: &GridDesc) -> Result<MaterialGrid, GridError> {
        over_flat_ground(desc, |p| {
            (2.0..8.0).contains(&p.y).then(|| Material {
                reflectance: Vec3::new(0.2, 0.5, 0.3),
                pass: 0.5 + 0.45 * (0.37 * p.x).sin() * (0.23 * p.z + 0.5).cos(),
            })
        })
    }
}

/// The material of `desc`: opaque ground below 0, above it `medium` where it gives
/// one, else air.
fn over_flat_ground(
    desc: &GridDesc,
    medium: impl Fn(Vec3) -> Option<Material>,
) -> Result<MaterialGrid, GridError> {
    let cells = (0..desc.point_count())
        .map(|i| {
            let p = desc.position(desc.coords(i).expect("in range"));
            if p.y < 0.0 {
                Material::opaque(Vec3::splat(0.3))
            } else {
                medium(p).unwrap_or(Material::EMPTY)
            }
        })
        .collect();
    MaterialGrid::new(*desc, cells)
}

/// A hierarchy over a flat 64 m square of [`Layer`], every node wanted and built
/// (8-point nodes down to 2 m cells), a sun apart; with `apron` and `neighbour_halo`.
pub(crate) fn layer_hierarchy(apron: u32, neighbour_halo: bool) -> Hierarchy {
    built_over(Box::new(Layer), apron, neighbour_halo)
}

/// Columns of medium 3 m square on a third of a 3 m lattice, each of its own height
/// (up to 12 m), over a flat ground: material whose top varies across a node.
pub(crate) struct Columns;

impl Columns {
    /// The top of the column at `(x, z)` (0: none).
    pub(crate) fn top(x: f32, z: f32) -> f32 {
        let (i, k) = ((x / 3.0).floor() as i64, (z / 3.0).floor() as i64);
        let h = (i.wrapping_mul(73_856_093) ^ k.wrapping_mul(19_349_663)).rem_euclid(97);
        if h < 33 { 1.0 + (h % 12) as f32 } else { 0.0 }
    }
}

impl MaterialSource for Columns {
    fn material(&self, desc: &GridDesc) -> Result<MaterialGrid, GridError> {
        over_flat_ground(desc, |p| {
            (p.y < Self::top(p.x, p.z)).then_some(Material {
                reflectance: Vec3::splat(0.5),
                pass: 0.4,
            })
        })
    }
}

/// A hierarchy over a flat 128 m square of [`Layer`] under a budget of a node or two a
/// frame (8-point nodes with an apron of 2 cells, down to 1 m; depth 1 wanted within
/// 32 m of the camera, the finest within 8 m), no sun: nodes near the camera are swept
/// before coarser nodes their boundaries read (`order.rs`).
pub(crate) fn budgeted_layer_hierarchy() -> Hierarchy {
    let params = HierarchyParams {
        finest_cell: 1.0,
        lod_factor: 1.0,
        max_levels: 16,
        apron: 2,
        budget_points: (8 + 4) * (8 + 4) * 16,
        ..layer_params()
    };
    flat(128.0, Box::new(Layer), params)
}

/// 8-point nodes under an 8 m world grid.
fn layer_params() -> HierarchyParams {
    HierarchyParams {
        world_cell: 8.0,
        node_points: 8,
        ..Default::default()
    }
}

/// A hierarchy of `params` over `source` on flat ground `size` metres square, under a
/// uniform sky.
fn flat(
    size: f32,
    source: Box<dyn MaterialSource + Send + Sync>,
    params: HierarchyParams,
) -> Hierarchy {
    let n = (size / 2.0) as u32 + 1;
    let ground = Heightmap::from_fn(Vec2::ZERO, 2.0, n, n, |_, _| 0.0).unwrap();
    let sky = BinLight::uniform(Vec3::ONE).split_vertical().0;
    let sweeper = Box::new(lightgrid_sweep_cpu::CpuSweeper::new());
    Hierarchy::new(&ground, source, sweeper, sky, params).unwrap()
}

/// [`layer_hierarchy`] over `source`.
pub(crate) fn built_over(
    source: Box<dyn MaterialSource + Send + Sync>,
    apron: u32,
    neighbour_halo: bool,
) -> Hierarchy {
    let params = HierarchyParams {
        finest_cell: 2.0,
        lod_factor: 100.0,
        evict_factor: 200.0,
        budget_points: u64::MAX / 4,
        apron,
        // The sun's responses over the node's own grid: the tests' invariants of the
        // march beyond a node (its ring, `shadow`'s early end) are stated for it.
        sun_apron: 0,
        neighbour_halo,
        ..layer_params()
    };
    let mut h = flat(64.0, source, params);
    h.set_sun(Some(SunLight {
        to_sun: Vec3::new(0.6, 0.5, 0.3),
        irradiance: Vec3::splat(3.0),
    }))
    .unwrap();
    h.update(Vec3::new(32.0, 5.0, 32.0)).unwrap();
    h
}
