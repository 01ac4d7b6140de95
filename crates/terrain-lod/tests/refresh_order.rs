//! A refresh round's order across depths: a finer node the round rebuilt before a
//! coarser node whose light it reads is checked again once that coarser node is
//! rebuilt (its boundary changed), so the round ends where one unbudgeted refresh
//! does.
//!
//! The scene makes it happen: a tall pillar in the depth-1 node farthest from the
//! camera makes that node cost more points than the frame has left after its
//! nearer, flat neighbours, while the finer nodes near the camera still fit. So the
//! round's first frame rebuilds finer nodes (the pillar's node still holding the old
//! sky's light) before its later frame rebuilds the pillar's node.

use lightgrid_core::glam::{Vec2, Vec3};
use lightgrid_core::{BinLight, Heightmap, Material};
use lightgrid_sweep_cpu::CpuSweeper;
use lightgrid_terrain_lod::{Hierarchy, HierarchyParams};

mod field;

/// Height of the pillar standing in the 64 m square's corner `x, z >= 56`.
const PILLAR: f32 = 160.0;

fn ground(x: f32, z: f32) -> f32 {
    if x >= 56.0 && z >= 56.0 { PILLAR } else { 0.0 }
}

/// The ground of [`ground`] (albedo 0.3) under [`field::varying_layer`]'s medium (2 to
/// 8 m up) where it is flat.
fn pillar_scene() -> field::Field<impl Fn(Vec3, f32) -> Material + Send + Sync> {
    let layer = field::varying_layer(Vec3::new(0.3, 0.6, 0.3));
    field::Field(move |p: Vec3, h: f32| {
        let g = ground(p.x, p.z);
        if p.y < g {
            Material::opaque(Vec3::splat(0.3))
        } else if g > 0.0 {
            Material::EMPTY
        } else {
            (layer.0)(p, h)
        }
    })
}

fn hierarchy(params: HierarchyParams) -> Hierarchy {
    let hm = Heightmap::from_fn(Vec2::ZERO, 2.0, 33, 33, ground).expect("valid");
    let sky = BinLight::uniform(Vec3::new(0.6, 0.7, 1.0))
        .split_vertical()
        .0;
    let mut params = params;
    params.sweep.max_passes = 1;
    Hierarchy::new(
        &hm,
        Box::new(pillar_scene()),
        Box::new(CpuSweeper::new()),
        sky,
        params,
    )
    .expect("valid")
}

/// Under a budget of one largest node a frame, a new sky's refresh round rebuilds
/// some finer node twice (before and after the pillar's node, whose light its side
/// halo reads) and ends with the light of an unbudgeted refresh and of a hierarchy
/// built under the new sky, bit for bit. With the finer nodes left checked after the
/// coarser rebuild, the round rebuilds each node once and a finer node keeps the old
/// sky's light in its halo.
#[test]
fn finer_nodes_are_checked_again_after_a_coarser_rebuild() {
    // Depths 1 and 2 (4 and 2 m cells, nodes of 32 and 16 m), every node wanted.
    let small = field::small_params(8 * 8 * 48);
    let mut big = small;
    big.budget_points = u64::MAX / 4;
    let cam = Vec3::new(4.0, 20.0, 4.0);
    let mut h = hierarchy(small);
    assert!(
        (0..60).any(|_| h.update(cam).unwrap().pending == 0),
        "frames until nothing waits"
    );
    let mut all = hierarchy(big);
    assert_eq!(all.update(cam).unwrap().pending, 0);
    let mut nodes = h.ready_nodes();
    nodes.sort();
    let mut a = all.ready_nodes();
    a.sort();
    assert_eq!(nodes, a);
    assert_eq!(nodes.len(), 4 + 16, "every node of both depths");

    let sky = BinLight::uniform(Vec3::new(0.4, 0.8, 0.6))
        .split_vertical()
        .0;
    h.set_sky(sky).unwrap();
    all.set_sky(sky).unwrap();
    let old: Vec<_> = nodes.iter().map(|k| h.node(*k).cloned()).collect();
    let (mut frames, mut built) = (0, 0);
    loop {
        let s = h.refresh(cam).unwrap();
        assert_eq!(
            h.ready_nodes().len(),
            nodes.len(),
            "a refresh evicts nothing"
        );
        frames += 1;
        built += s.built;
        if frames == 1 {
            // The first frame leaves a depth-1 node (the pillar's) as it was, yet
            // rebuilds finer ones.
            let changed = |depth| {
                let mut n = nodes.iter().zip(&old).filter(|(k, _)| k.depth == depth);
                (
                    n.clone().any(|(k, o)| h.node(*k) != o.as_ref()),
                    n.any(|(k, o)| h.node(*k) == o.as_ref()),
                )
            };
            let ((_, coarse_waits), (finer_rebuilt, _)) = (changed(1), changed(2));
            assert!(
                coarse_waits && finer_rebuilt,
                "the scene must rebuild finer nodes first: {s:?}"
            );
        }
        if s.pending == 0 {
            break;
        }
        assert!(frames < 60, "still pending after {frames} frames: {s:?}");
    }
    assert!(
        built as usize > nodes.len(),
        "a finer node rebuilt again after its coarser neighbour: {built} builds of {} nodes",
        nodes.len()
    );
    assert_eq!(all.refresh(cam).unwrap().pending, 0);
    let mut fresh = hierarchy(big);
    fresh.set_sky(sky).unwrap();
    fresh.update(cam).unwrap();
    for k in &nodes {
        assert!(
            h.node(*k) == all.node(*k),
            "{k:?} against one unbudgeted refresh"
        );
        assert!(
            fresh.node(*k) == all.node(*k),
            "{k:?} as built under the new sky"
        );
    }
}
