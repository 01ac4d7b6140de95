//! The demo scene shared by the fly-through test, example and benchmark (each includes
//! this file with `#[path]`; it is not part of the library, so the library needs no
//! voxelizer): the shipped DEM and a deterministic forest of procedural trees.

use std::path::Path;

use lightgrid_core::GridError;
use lightgrid_core::glam::{Quat, Vec2, Vec3};
use lightgrid_material_voxelizer::compose::{
    AreaComposer, ComposeParams, GroundColour, Heightmap, Instance, Terrain, load_heightmap_png,
};
use lightgrid_material_voxelizer::procedural::{TreeParams, tree};
use lightgrid_material_voxelizer::voxelize::{VoxelizeParams, voxelize};

/// Where a demo forest stands: `count` trees of `tree` voxelized by `voxel`, scattered
/// over the square `lo .. lo + size` ([`scatter_forest`], scaled in `scale`, from
/// `seed`), on the ground coloured `ground`. (The benchmark builds its composer inside
/// the timed loop from a tree voxelized once, so it does not use this.)
#[allow(dead_code)]
pub(crate) struct Forest {
    pub tree: TreeParams,
    pub voxel: VoxelizeParams,
    pub count: usize,
    pub lo: Vec2,
    pub size: f32,
    pub scale: (f32, f32),
    pub seed: u64,
    pub ground: Vec3,
}

#[allow(dead_code)]
impl Forest {
    /// The fly-through's forest (`examples/flythrough.rs`, `examples/scene_edit.rs`):
    /// 4000 broadleaf trees over 500 m × 500 m from (400, 400).
    pub(crate) fn flythrough() -> Self {
        Self {
            tree: TreeParams::broadleaf(3),
            voxel: VoxelizeParams::standard(0.5),
            count: 4000,
            lo: Vec2::splat(400.0),
            size: 500.0,
            scale: (0.8, 1.3),
            seed: 99,
            ground: Vec3::new(0.25, 0.22, 0.18),
        }
    }

    /// The forest on `hm` as a composer of its material.
    pub(crate) fn composer(
        &self,
        hm: &Heightmap,
    ) -> Result<AreaComposer, Box<dyn std::error::Error>> {
        let (tree_grid, _) = voxelize(&tree(&self.tree)?, &self.voxel, &|_, _| {})?;
        let instances = scatter_forest(hm, self.count, self.lo, self.size, self.scale, self.seed);
        let terrain = Terrain {
            heightmap: hm.clone(),
            colour: GroundColour::Uniform(self.ground),
        };
        Ok(AreaComposer::new(
            vec![tree_grid],
            &instances,
            Some(terrain),
            ComposeParams::default(),
        )?)
    }
}

/// The shipped Jacksboro DEM (`assets/dem-jacksboro`) at 4 m a pixel with
/// heights × 0.05: 1.6 km × 1.4 km, 12–54 m of relief.
pub(crate) fn jacksboro(assets: &Path) -> Result<Heightmap, GridError> {
    load_heightmap_png(
        assets.join("dem-jacksboro/jacksboro_fault_dem_u16.png"),
        Vec2::ZERO,
        4.0,
        0.05,
        0.0,
    )
}

/// `count` instances of model 0 scattered uniformly over the square `lo .. lo + size`
/// (world x, z), standing on the ground (0.3 m sunk), turned at random, scaled in
/// `scale.0 .. scale.1`. Deterministic for a seed.
pub(crate) fn scatter_forest(
    hm: &Heightmap,
    count: usize,
    lo: Vec2,
    size: f32,
    scale: (f32, f32),
    seed: u64,
) -> Vec<Instance> {
    // xorshift64, kept rather than `lightgrid_core::SeededRng`: this stream defines the
    // measured fly-through scenes (the figures in terrain-lod's docs, the seam test's
    // bounds). Drawn from SeededRng, seed 99's forest puts trees on node edges and the
    // seam test's coarse/fine bias goes from -0.034 to -0.081: a different scene, not a
    // refactor.
    let mut s = seed.max(1);
    let mut rng = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 40) as f32 / (1u64 << 24) as f32
    };
    (0..count)
        .map(|_| {
            let (x, z) = (lo.x + rng() * size, lo.y + rng() * size);
            Instance {
                model: 0,
                position: Vec3::new(x, hm.height_at(x, z) - 0.3, z),
                rotation: Quat::from_rotation_y(rng() * std::f32::consts::TAU),
                scale: scale.0 + rng() * (scale.1 - scale.0),
            }
        })
        .collect()
}

/// The folder of the shipped test data, beside the repository.
pub(crate) fn assets_dir() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets")
}
