//! A world baked task by task (`lightgrid_terrain_lod::bake`) against the live hierarchy,
//! and its results carried between tasks as bytes.

use std::sync::Arc;

use lightgrid_core::glam::{Vec2, Vec3};
use lightgrid_core::{BinLight, GridError};
use lightgrid_material_voxelizer::compose::{
    AreaComposer, ComposeParams, GroundColour, Heightmap, Instance, Terrain,
};
use lightgrid_material_voxelizer::procedural::{TreeParams, tree};
use lightgrid_material_voxelizer::voxelize::{VoxelizeParams, voxelize};
use lightgrid_sweep_cpu::CpuSweeper;
use lightgrid_terrain_lod::bake::{BakedGrid, WorldBake};
use lightgrid_terrain_lod::{Hierarchy, HierarchyParams, NodeKey, SunLight};

/// 96 m of hills with a handful of trees; 8 m world grid, nodes of 4 and 2 m.
fn world() -> (Heightmap, Arc<AreaComposer>, HierarchyParams) {
    world_of(49, 3.0)
}

/// [`world`] over `n × n` heights 2 m apart, hills of `relief` metres.
fn world_of(n: u32, relief: f32) -> (Heightmap, Arc<AreaComposer>, HierarchyParams) {
    let hm = Heightmap::from_fn(Vec2::ZERO, 2.0, n, n, |x, z| {
        relief * (x * 0.05).sin() * (z * 0.04).cos()
    })
    .unwrap();
    let (tree_grid, _) = voxelize(
        &tree(&TreeParams::young(3)).unwrap(),
        &VoxelizeParams::preview(0.5),
        &|_, _| {},
    )
    .unwrap();
    let instances: Vec<Instance> = [(30.0, 40.0), (50.0, 52.0), (61.0, 35.0), (44.0, 70.0)]
        .iter()
        .map(|&(x, z)| Instance {
            model: 0,
            position: Vec3::new(x, hm.height_at(x, z) - 0.2, z),
            rotation: Default::default(),
            scale: 1.5,
        })
        .collect();
    let terrain = Terrain {
        heightmap: hm.clone(),
        colour: GroundColour::Uniform(Vec3::splat(0.3)),
    };
    let composer = AreaComposer::new(
        vec![tree_grid],
        &instances,
        Some(terrain),
        ComposeParams::default(),
    )
    .unwrap();
    let mut p = HierarchyParams {
        world_cell: 8.0,
        finest_cell: 2.0,
        node_points: 8,
        // An apron wider than the boundary halo's margin: a node's reads and its
        // column's world tile reach past it.
        apron: 6,
        max_levels: 40,
        lod_factor: 100.0,
        evict_factor: 200.0,
        budget_points: u64::MAX / 4,
        ..Default::default()
    };
    p.sweep.max_passes = 2;
    (hm, Arc::new(composer), p)
}

/// A bake of the world over `hm` with the CPU sweeper and [`sky`].
fn new_bake(
    hm: &Heightmap,
    c: &Arc<AreaComposer>,
    sun: Option<SunLight>,
    p: HierarchyParams,
) -> WorldBake {
    WorldBake::new(
        hm,
        Box::new(c.clone()),
        Box::new(CpuSweeper::new()),
        sky(),
        sun,
        p,
    )
    .unwrap()
}

fn sky() -> BinLight {
    BinLight::uniform(Vec3::new(0.6, 0.7, 1.0))
        .split_vertical()
        .0
}

/// Every task in the plan's order, each on a fresh `WorldBake` fed its inputs as bytes
/// (as separate processes would be): the results by node.
fn bake_all(
    hm: &Heightmap,
    c: &Arc<AreaComposer>,
    p: HierarchyParams,
    sun: Option<SunLight>,
    tiles: bool,
) -> (BakedGrid, Vec<(NodeKey, BakedGrid)>) {
    bake_depths(hm, c, p, sun, tiles, u32::MAX)
}

/// [`bake_all`] down to `depths`.
fn bake_depths(
    hm: &Heightmap,
    c: &Arc<AreaComposer>,
    p: HierarchyParams,
    sun: Option<SunLight>,
    tiles: bool,
    depths: u32,
) -> (BakedGrid, Vec<(NodeKey, BakedGrid)>) {
    let fresh = || new_bake(hm, c, sun, p);
    let through_bytes = |g: &BakedGrid| BakedGrid::from_bytes(&g.to_bytes()).unwrap();
    let world = through_bytes(&fresh().world().unwrap());
    let tiles = if tiles {
        fresh().world_tiles(&world).unwrap()
    } else {
        Vec::new()
    };
    let mut done: Vec<(NodeKey, BakedGrid)> = Vec::new();
    for n in fresh().plan(depths).unwrap() {
        let reads: Vec<(NodeKey, &BakedGrid)> = done
            .iter()
            .filter(|(k, _)| n.reads.contains(k))
            .map(|(k, g)| (*k, g))
            .collect();
        assert_eq!(
            reads.len(),
            n.reads.len(),
            "{:?} reads a node not yet baked",
            n.key
        );
        let top = n
            .key
            .index
            .div_euclid(lightgrid_core::glam::IVec2::splat(1 << (n.key.depth - 1)));
        let w = tiles
            .iter()
            .find(|(i, _)| *i == top)
            .map_or(&world, |(_, t)| t);
        let g = fresh().node(n.key, w, &reads).unwrap();
        assert!(g.light.desc().point_count() as u64 <= n.max_points);
        done.push((n.key, through_bytes(&g)));
    }
    (world, done)
}

/// Without the sun apart, a node's light depends only on the coarser grids its boundary
/// reads: the bake's nodes equal, bit for bit, those of a live hierarchy that holds every
/// node (a camera that wants them all).
#[test]
fn baked_nodes_equal_the_live_hierarchys_bit_for_bit() {
    let (hm, c, p) = world();
    baked_equal_live(&hm, &c, p);
}

/// The same with side halos that read the nodes of their depth before them
/// (`HierarchyParams::neighbour_halo`): a node's task reads those too, and the plan
/// has them first.
#[test]
fn baked_nodes_reading_neighbours_equal_the_live_hierarchys_bit_for_bit() {
    let (hm, c, mut p) = world();
    p.neighbour_halo = true;
    baked_equal_live(&hm, &c, p);
    let plain = bake_all(&hm, &c, world().2, None, false).1;
    let read = bake_all(&hm, &c, p, None, false).1;
    assert!(
        plain.iter().zip(&read).any(|(a, b)| a.1.light != b.1.light),
        "no node read a neighbour"
    );
}

/// Every baked node of the world over `hm` under `p` equals the live hierarchy's.
fn baked_equal_live(hm: &Heightmap, c: &Arc<AreaComposer>, p: HierarchyParams) {
    let (hm, c) = (hm.clone(), c.clone());
    let (world, nodes) = bake_all(&hm, &c, p, None, false);
    // From the world grid's tiles: the same bits.
    assert_eq!(bake_all(&hm, &c, p, None, true).1, nodes);
    let mut h = Hierarchy::new(
        &hm,
        Box::new(c.clone()),
        Box::new(CpuSweeper::new()),
        sky(),
        p,
    )
    .unwrap();
    h.update(Vec3::new(48.0, 10.0, 48.0)).unwrap();
    assert_eq!(h.world(), &world.light);
    let live = h.ready_nodes();
    let baked: Vec<NodeKey> = nodes.iter().map(|(k, _)| *k).collect();
    let mut sorted = baked.clone();
    sorted.sort();
    assert_eq!(live, sorted, "the plan is every node the terrain holds");
    assert!(nodes.len() >= 4 + 9, "{}", nodes.len());
    for (k, g) in &nodes {
        assert_eq!(h.node(*k).unwrap(), &g.light, "{k:?}");
    }
}

/// With the sun apart every task is a function of its inputs: baking twice (fresh
/// processes, results through bytes) gives the same bits, sun responses included, and
/// the sun's scattered light is there, finite and not all zero.
#[test]
fn a_bake_with_the_sun_apart_repeats_bit_for_bit() {
    let (hm, c, p) = world();
    let sun = Some(SunLight {
        to_sun: Vec3::new(0.5, 0.6, 0.3),
        irradiance: Vec3::splat(5.0),
    });
    let a = bake_all(&hm, &c, p, sun, true);
    let b = bake_all(&hm, &c, p, sun, true);
    assert_eq!(a, b);
    let (_, nodes) = a;
    for (k, g) in &nodes {
        let s = g.sun.as_ref().unwrap_or_else(|| panic!("{k:?} has no sun"));
        assert!(
            s.transmittance
                .data()
                .iter()
                .all(|t| (0.0..=1.0).contains(t))
        );
        assert!(s.scattered.data().iter().all(|b| b.is_valid()));
    }
    assert!(nodes.iter().any(|(_, g)| {
        g.sun
            .as_ref()
            .unwrap()
            .scattered
            .data()
            .iter()
            .any(|b| b.0.iter().any(|c| c.max_element() > 0.0))
    }));
}

/// A low sun's beam crosses much of the world beyond a node: a world tile holds its
/// path (the depth-1 nodes' sun responses as from the whole world grid, but where a
/// ray grazes a cell's corner, which f32 rounding of the tile's shifted coordinates may
/// decide the other way), and is smaller than the world.
#[test]
fn world_tiles_hold_the_suns_path() {
    // 320 m of hills 30 m high: their shadows fall far.
    let (hm, c, p) = world_of(161, 15.0);
    for to_sun in [Vec3::new(0.9, 0.35, 0.2), Vec3::new(-0.3, 0.35, -0.9)] {
        let sun = Some(SunLight {
            to_sun,
            irradiance: Vec3::ONE,
        });
        let (world, whole) = bake_depths(&hm, &c, p, sun, false, 1);
        let (_, tiled) = bake_depths(&hm, &c, p, sun, true, 1);
        let b = new_bake(&hm, &c, sun, p);
        let tiles = b.world_tiles(&world).unwrap();
        let n = world.light.desc().point_count();
        assert!(
            tiles
                .iter()
                .all(|(_, t)| 3 * t.light.desc().point_count() < 2 * n)
        );
        let (mut differ, mut shade, mut all) = (0, 0, 0);
        for ((_, a), (_, b)) in whole.iter().zip(&tiled) {
            let (sa, sb) = (a.sun.as_ref().unwrap(), b.sun.as_ref().unwrap());
            for (x, y) in sa.transmittance.data().iter().zip(sb.transmittance.data()) {
                differ += ((x - y).abs() > 1e-3) as usize;
                shade += (*x < 0.5) as usize;
                all += 1;
            }
        }
        eprintln!("{to_sun}: {differ} of {all} points differ, {shade} in shade");
        assert!(
            shade > all / 10,
            "{shade} points in shade: a test that cannot fail"
        );
        assert!(
            differ * 1000 < all,
            "{differ} of {all} points differ at {to_sun}"
        );
    }
}

#[test]
fn a_node_without_its_reads_or_outside_the_plan_is_refused() {
    let (hm, c, p) = world();
    let mut b = new_bake(&hm, &c, None, p);
    let world = b.world().unwrap();
    let plan = b.plan(u32::MAX).unwrap();
    let deep = plan.iter().find(|n| n.key.depth == 2).unwrap();
    let e = b.node(deep.key, &world, &[]).unwrap_err().to_string();
    assert!(e.contains("reads"), "{e}");
    let outside = NodeKey {
        depth: 1,
        index: lightgrid_core::glam::IVec2::new(40, 0),
    };
    let e = b.node(outside, &world, &[]).unwrap_err().to_string();
    assert!(e.contains("key"), "{e}");
    // A world grid of another world.
    let mut other = world.clone();
    other.light = lightgrid_core::LightGrid::filled(
        lightgrid_core::GridDesc::new(Vec3::ZERO, 1.0, lightgrid_core::glam::UVec3::splat(2))
            .unwrap(),
        BinLight::ZERO,
    )
    .unwrap();
    let e = b.node(plan[0].key, &other, &[]).unwrap_err().to_string();
    assert!(e.contains("world"), "{e}");
}

#[test]
fn baked_grid_bytes_round_trip_and_refuse_damage() {
    let (hm, c, p) = world();
    let sun = Some(SunLight {
        to_sun: Vec3::new(0.5, 0.6, 0.3),
        irradiance: Vec3::ONE,
    });
    let mut b = new_bake(&hm, &c, sun, p);
    let g = b.world().unwrap();
    let bytes = g.to_bytes();
    assert_eq!(BakedGrid::from_bytes(&bytes).unwrap(), g);
    for cut in [0, 5, 9, bytes.len() / 2, bytes.len() - 1] {
        let e: GridError = BakedGrid::from_bytes(&bytes[..cut]).unwrap_err();
        assert!(!e.to_string().is_empty());
    }
    let mut bad = bytes.clone();
    bad[0] ^= 0xff;
    assert!(BakedGrid::from_bytes(&bad).is_err());
    // The horizon halves, kept by default, travel with it; a grid of the earlier format
    // (LGBAKE01: no halves sections) reads as one without them.
    assert!(g.horizon.is_some() && g.sun.as_ref().unwrap().horizon.is_some());
    let mut plain = g.clone();
    plain.horizon = None;
    plain.sun.as_mut().unwrap().horizon = None;
    let mut old = plain.to_bytes();
    old.truncate(old.len() - 16);
    old[..8].copy_from_slice(b"LGBAKE01");
    assert_eq!(BakedGrid::from_bytes(&old).unwrap(), plain);
}

/// One `WorldBake` running every task in turn (as one process does) gives what a fresh
/// one per task gives, on a world whose tiles are smaller than the world grid.
#[test]
fn one_bake_for_every_task_equals_one_per_task() {
    let (hm, c, p) = world_of(161, 15.0);
    let sun = Some(SunLight {
        to_sun: Vec3::new(0.3, 0.8, 0.2),
        irradiance: Vec3::ONE,
    });
    let (_, per_task) = bake_depths(&hm, &c, p, sun, true, 1);
    let mut b = new_bake(&hm, &c, sun, p);
    let world = b.world().unwrap();
    let tiles = b.world_tiles(&world).unwrap();
    assert!(
        tiles
            .iter()
            .all(|(_, t)| t.light.desc() != world.light.desc())
    );
    for (n, (k, want)) in b.plan(1).unwrap().into_iter().zip(&per_task) {
        assert_eq!(n.key, *k);
        let tile = &tiles.iter().find(|(i, _)| *i == n.key.index).unwrap().1;
        assert_eq!(&b.node(n.key, tile, &[]).unwrap(), want, "{k:?}");
    }
}
