//! Halo points near bare ground (`HierarchyParams::halo_ground_lift`): over flat bare
//! ground composed as the area composer composes terrain (a band of partly covered
//! cells where the surface cuts a cell), under a uniform sky, the finest nodes' light
//! near the ground against one sweep at their cell of the same ground, infinite
//! (periodic sides) and cut by its cells as theirs are. The light that travels
//! sideways near bare ground enters a node through its sides from the coarser grids,
//! whose own light within a cell or so of their band is their cell's, not the finest:
//! read clear of the band, it nests.

use lightgrid_core::glam::{UVec3, Vec2, Vec3};
use lightgrid_core::{
    BinLight, Boundary, GridDesc, LightField, MaterialSource, SideBoundary, Sweeper,
};
use lightgrid_material_voxelizer::compose::{
    AreaComposer, ComposeParams, GroundColour, Heightmap, Terrain,
};
use lightgrid_sweep_cpu::CpuSweeper;
use lightgrid_terrain_lod::{Hierarchy, HierarchyParams};

/// The terrain's height: inside a cell of every grid (1, 2, 4 and 8 m), 0.3 m above
/// the finest cell's bottom face.
const GROUND: f32 = 10.3;
/// The world's side, metres.
const SIDE: f32 = 256.0;

fn composer() -> AreaComposer {
    let hm = Heightmap::from_fn(Vec2::ZERO, 4.0, 65, 65, |_, _| GROUND).unwrap();
    let terrain = Terrain {
        heightmap: hm,
        colour: GroundColour::Uniform(Vec3::splat(0.3)),
    };
    AreaComposer::new(Vec::new(), &[], Some(terrain), ComposeParams::default()).unwrap()
}

fn sky() -> BinLight {
    BinLight::uniform(Vec3::ONE).split_vertical().0
}

/// 8-point nodes (an apron of 2 cells) under an 8 m world grid, down to 1 m cells,
/// every node near the middle built; the ground lift `lift`.
fn hierarchy(lift: bool) -> Hierarchy {
    let params = HierarchyParams {
        world_cell: 8.0,
        node_points: 8,
        finest_cell: 1.0,
        max_levels: 16,
        apron: 2,
        budget_points: u64::MAX / 4,
        halo_ground_lift: lift,
        ..Default::default()
    };
    let hm = lightgrid_core::Heightmap::from_fn(Vec2::ZERO, 4.0, 65, 65, |_, _| GROUND).unwrap();
    let mut h = Hierarchy::new(
        &hm,
        Box::new(composer()),
        Box::new(CpuSweeper::new()),
        sky(),
        params,
    )
    .unwrap();
    h.update(Vec3::new(SIDE / 2.0, GROUND + 4.0, SIDE / 2.0))
        .unwrap();
    h
}

/// The horizontal bins' light summed (the bins of directions within the horizontal
/// band), luminance.
fn horizontal(l: &BinLight) -> f32 {
    let first = lightgrid_core::dirs::FIRST_HORIZONTAL;
    l.0[first..first + 8]
        .iter()
        .map(|c| lightgrid_core::light::luminance(*c))
        .sum()
}

/// Per level of the finest node serving the camera above its lowest (the band's, then
/// 1 and 2 m above the ground), the finest nodes' horizontal light near the camera
/// over one periodic sweep's at its cell, the farthest from 1 over the points read.
fn ratios(h: &Hierarchy) -> Vec<f32> {
    let centre = SIDE / 2.0;
    let finest = h.grid_at(Vec3::new(centre, GROUND + 1.0, centre)).desc();
    assert_eq!(finest.h(), 1.0, "a finest node serves the camera");
    // The same ground under 16 × 16 columns at the finest node's levels, periodic.
    let desc = GridDesc::new(
        Vec3::new(0.5, finest.origin().y, 0.5),
        1.0,
        UVec3::new(16, finest.dims().y, 16),
    )
    .unwrap();
    let m = composer().material(&desc).unwrap();
    let options = HierarchyParams::default().sweep;
    let boundary = Boundary {
        sides: SideBoundary::Periodic,
        ..Boundary::open_sky(sky())
    };
    let reference = CpuSweeper::new().sweep(&m, &boundary, &options).unwrap();
    let reference = reference.bins.unwrap();
    (1..desc.dims().y)
        .map(|j| {
            let want = horizontal(reference.get(UVec3::new(4, j, 4)).unwrap());
            let mut worst = 1.0f32;
            for dx in [-6.0f32, -2.0, 3.0, 7.0] {
                for dz in [-5.0f32, 1.0, 6.0] {
                    let p = Vec3::new(
                        centre + dx,
                        desc.position(UVec3::new(0, j, 0)).y,
                        centre + dz,
                    );
                    let got = horizontal(&h.light(p, None).unwrap());
                    let r = got / want;
                    if (r - 1.0).abs() > (worst - 1.0).abs() {
                        worst = r;
                    }
                }
            }
            worst
        })
        .collect()
}

/// Over bare ground the finest nodes' sideways light 1 and 2 m above the ground nests
/// within 2 % of one sweep at their cell (the nesting target as a bound at
/// every point read); read where the halo points are, the coarser grids' band leaves it
/// 2.0–3.2 % short (6.3 % in the band's own cell; 4.5–6.5 % and 7.4 % while a ground's
/// edge cells were surfaces through a node's sides, before 2026-12-07).
#[test]
fn near_bare_ground_the_sideways_light_nests() {
    let with = ratios(&hierarchy(true));
    let without = ratios(&hierarchy(false));
    assert!(
        with[1..].iter().all(|r| (r - 1.0).abs() <= 0.02),
        "with the lift {with:?} (without {without:?})"
    );
    // In the band's own cell within 4 %.
    assert!((with[0] - 1.0).abs() <= 0.04, "{with:?}");
    // (Else the lift could do nothing here: without it the bound fails.)
    assert!(
        without[1..].iter().any(|r| (r - 1.0).abs() > 0.02),
        "without the lift {without:?}"
    );
}
