//! A flat ground with a block of dense medium on it, and a hierarchy over it whose
//! every node is built (the layout and volume tests share it).

use lightgrid_core::glam::{Vec2, Vec3};
use lightgrid_core::{BinLight, Heightmap, Material};
use lightgrid_sweep_cpu::CpuSweeper;
use lightgrid_terrain_lod::Hierarchy;

#[path = "../field/mod.rs"]
pub(crate) mod field;
use field::Field;

/// The top of the block of medium standing on the ground over `20..28` m in x and z.
pub(crate) const BLOCK_TOP: f32 = 6.0;

/// Opaque ground below height `ground` (a cell whose centre is below), the block of
/// dense medium above it, air elsewhere.
pub(crate) fn scene(ground: f32) -> Field<impl Fn(Vec3, f32) -> Material + Send + Sync> {
    Field(move |p: Vec3, _| {
        if p.y < ground {
            Material::opaque(Vec3::splat(0.3))
        } else if (20.0..28.0).contains(&p.x) && (20.0..28.0).contains(&p.z) && p.y < BLOCK_TOP {
            Material {
                reflectance: Vec3::splat(0.5),
                pass: 0.2,
            }
        } else {
            Material::EMPTY
        }
    })
}

/// The scene over a 64 m heightmap at `ground`: world grid 8 m, nodes of 8 points down
/// to 2 m, every node wanted and built in one frame.
#[allow(dead_code)] // (the tests that include this module and build their own)
pub(crate) fn hierarchy(ground: f32) -> Hierarchy {
    let hm = Heightmap::from_fn(Vec2::ZERO, 2.0, 33, 33, |_, _| ground).unwrap();
    let params = field::small_params(u64::MAX / 4);
    let sky = BinLight::uniform(Vec3::ONE).split_vertical().0;
    let mut h = Hierarchy::new(
        &hm,
        Box::new(scene(ground)),
        Box::new(CpuSweeper::new()),
        sky,
        params,
    )
    .unwrap();
    h.update(Vec3::new(32.0, 5.0, 32.0)).unwrap();
    h
}
