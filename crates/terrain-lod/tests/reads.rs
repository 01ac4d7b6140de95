//! What a point reads from the hierarchy. Across the seam between two nodes of one
//! depth (`lightgrid_core::seam`): the strip one cell wide between their outermost
//! points reads the trilinear interpolation of both nodes' points, as one grid over
//! both would, not the serving node's points clamped. And a new node whose sun
//! responses wait for a later frame shows its own transmittance at once.

use lightgrid_core::glam::Vec3;
use lightgrid_core::{BinLight, LightField, VolumeSample};
use lightgrid_sweep_cpu::CpuSweeper;
use lightgrid_terrain_lod::{Hierarchy, HierarchyParams};

#[path = "field/mod.rs"]
mod field;

/// The seam between the finest nodes over 16..32 m and 32..48 m in x and z (2 m cells,
/// 8 points: their outermost points at 31 and 33).
const LAST: f32 = 31.0;
const FIRST: f32 = 33.0;
const CELL: f32 = 2.0;

/// A flat ground under a layer of medium 2 to 8 m up whose density changes across x
/// and z (so every node has objects and finer children, and the light changes along
/// the seams), every node of a 64 m square built in one frame: world grid 8 m, nodes
/// of 8 points down to 2 m; a sun kept apart.
fn hierarchy() -> Hierarchy {
    let mut h = unbuilt(u64::MAX / 4, HierarchyParams::default().max_levels);
    h.update(CAMERA).unwrap();
    h
}

const CAMERA: Vec3 = Vec3::new(32.0, 5.0, 32.0);

/// [`hierarchy`] before its first frame, with a budget of `budget_points` and nodes of
/// `max_levels` at most.
fn unbuilt(budget_points: u64, max_levels: u32) -> Hierarchy {
    let params = HierarchyParams {
        max_levels,
        ..field::small_params(budget_points)
    };
    field::over_varying_layer(Vec3::splat(0.5), Box::new(CpuSweeper::new()), params)
}

fn total(b: &BinLight) -> f32 {
    b.total().element_sum()
}

#[test]
fn across_a_seam_the_read_is_continuous_and_linear_between_the_two_nodes_points() {
    let h = hierarchy();
    let (y, z) = (5.0, 36.0);
    let at = |x: f32| Vec3::new(x, y, z);
    // Both sides are finest nodes, and they differ: the node 16..32 serves x < 32.
    let (a, b) = (h.grid_at(at(31.9)), h.grid_at(at(32.1)));
    assert!(!std::ptr::eq(a, b));
    assert_eq!((a.desc().h(), b.desc().h()), (CELL, CELL));
    let (la, lb) = (
        h.light(at(LAST), None).unwrap(),
        h.light(at(FIRST), None).unwrap(),
    );
    // The light changes across the strip (else nothing here could fail): the serving
    // node read alone, clamped, would jump by this at x = 32.
    let jump = (total(&la) - total(&lb)).abs();
    assert!(jump > 1e-3 * total(&la), "{} {}", total(&la), total(&lb));
    // Continuous at the rectangles' edge.
    let (l, r) = (
        h.light(at(31.999), None).unwrap(),
        h.light(at(32.001), None).unwrap(),
    );
    assert!(
        (total(&l) - total(&r)).abs() <= 0.01 * jump,
        "{} | {} against a jump of {jump}",
        total(&l),
        total(&r)
    );
    // Linear between the two outermost points, bin by bin.
    for f in [0.1f32, 0.25, 0.5, 0.75, 0.9] {
        let got = h.light(at(LAST + CELL * f), None).unwrap();
        let want = la * (1.0 - f) + lb * f;
        for (g, w) in got.0.iter().zip(want.0.iter()) {
            assert!(
                (*g - *w).abs().max_element() <= 1e-5 * total(&la),
                "{f}: {g} {w}"
            );
        }
    }
    // A surface read half a cell along its normal reads the same place across the
    // seam whichever node serves it.
    for x in [31.2f32, 31.6, 31.95] {
        let biased = h.light(at(x), Some(Vec3::X)).unwrap();
        let moved = h.light(at(x + 0.5 * CELL), None).unwrap();
        assert!(
            (total(&biased) - total(&moved)).abs() <= 1e-5 * total(&moved),
            "{x}: {} {}",
            total(&biased),
            total(&moved)
        );
    }
    // The light volume's sampler reads across the seam as the bins do.
    let read = h.volume_sampler().unwrap();
    for x in [31.0f32, 31.5, 31.99, 32.01, 32.5, 33.0] {
        let (v, b) = (read(at(x)).unwrap(), VolumeSample::read(&h, at(x)).unwrap());
        assert!(
            (v.average - b.average).abs().max_element() <= 1e-5 * b.average.max_element()
                && (v.sun - b.sun).abs() <= 1e-5,
            "{x}: {v:?} {b:?}"
        );
    }
    // The sun's transmittance too: linear between the two nodes' points.
    let t = |x: f32| h.sun_transmittance(at(x), None).unwrap();
    let (ta, tb) = (t(LAST), t(FIRST));
    assert!((ta - tb).abs() > 1e-3, "{ta} {tb}");
    for f in [0.0f32, 0.3, 0.5, 0.9999] {
        let want = ta * (1.0 - f) + tb * f;
        assert!(
            (t(LAST + CELL * f) - want).abs() <= 1e-5,
            "{f}: {} {want}",
            t(LAST + CELL * f)
        );
    }
}

/// At a corner where four nodes meet the read is the bilinear blend of their four
/// nearest points, and continuous across both edges.
#[test]
fn where_four_nodes_meet_the_read_blends_all_four() {
    let h = hierarchy();
    let y = 5.0;
    let l = |x: f32, z: f32| total(&h.light(Vec3::new(x, y, z), None).unwrap());
    // The finest nodes meet at (32, 32); their nearest points are at 31 and 33.
    for (x, z) in [(31.0, 31.0), (33.0, 31.0), (31.0, 33.0), (33.0, 33.0)] {
        assert_eq!(h.grid_at(Vec3::new(x, y, z)).desc().h(), CELL);
    }
    let corners = [
        l(LAST, LAST),
        l(FIRST, LAST),
        l(LAST, FIRST),
        l(FIRST, FIRST),
    ];
    for (fx, fz) in [(0.5f32, 0.5f32), (0.2, 0.7), (0.9, 0.1)] {
        let want = corners[0] * (1.0 - fx) * (1.0 - fz)
            + corners[1] * fx * (1.0 - fz)
            + corners[2] * (1.0 - fx) * fz
            + corners[3] * fx * fz;
        let got = l(LAST + CELL * fx, LAST + CELL * fz);
        assert!((got - want).abs() <= 1e-5 * want, "{fx} {fz}: {got} {want}");
    }
    // Continuous across both edges: a step of a thousandth of a metre changes the
    // read by a small part of what separates the four points (which the serving
    // node's read alone would jump by).
    let spread = corners.iter().copied().fold(f32::MIN, f32::max)
        - corners.iter().copied().fold(f32::MAX, f32::min);
    assert!(spread > 1e-3 * corners[0], "{corners:?}");
    let e = 1e-3;
    for (a, b) in [
        ((32.0 - e, 32.0 - e), (32.0 + e, 32.0 + e)),
        ((32.0 - e, 31.5), (32.0 + e, 31.5)),
        ((31.5, 32.0 - e), (31.5, 32.0 + e)),
    ] {
        let (u, v) = (l(a.0, a.1), l(b.0, b.1));
        assert!(
            (u - v).abs() <= 0.01 * spread,
            "{a:?} {b:?}: {u} {v}, the points {spread} apart"
        );
    }
}

/// A new node whose sun responses do not fit the frame's budget shows its own
/// transmittance at once (the one its responses bring when swept: the same march) and
/// the coarser grid's scattered sun at its points meanwhile; a later frame sweeps its
/// responses, and they end as those of a hierarchy built in one frame.
#[test]
fn a_new_node_marches_its_sun_at_once_and_sweeps_it_later() {
    use lightgrid_terrain_lod::NodeKey;
    // Nodes of depth 1 hold 8 x 8 points and 5 levels here: a budget of one such node
    // has room for one node's sky and not its sun as well.
    let levels = 5;
    let mut full = unbuilt(u64::MAX / 4, levels);
    full.update(CAMERA).unwrap();
    let mut h = unbuilt(8 * 8 * levels as u64, levels);
    let s = h.update(CAMERA).unwrap();
    assert_eq!((s.built, s.sun_built), (1, 0), "{s:?}");
    let key: NodeKey = h.ready_nodes()[0];
    fn layer_of(h: &Hierarchy, key: NodeKey) -> lightgrid_terrain_lod::Layer<'_> {
        h.layers()
            .into_iter()
            .find(|l| {
                l.owner
                    .is_some_and(|o| o.index == key.index && o.size == 32.0)
            })
            .unwrap()
    }
    let (early, swept) = (layer_of(&h, key), layer_of(&full, key));
    let (a, b) = (early.sun.unwrap(), swept.sun.unwrap());
    // The transmittance is the swept responses' own, to rounding.
    let worst = a
        .transmittance
        .data()
        .iter()
        .zip(b.transmittance.data())
        .map(|(x, y)| (x - y).abs())
        .fold(0.0f32, f32::max);
    assert!(worst <= 1e-6, "transmittance off by {worst}");
    assert!(b.transmittance.data().iter().any(|&t| t > 0.05 && t < 0.95));
    // The scattered sun is the world grid's at the node's points until swept.
    let world = h.layers()[0].sun.unwrap().scattered.unwrap();
    let desc = *a.scattered.unwrap().desc();
    let mut apart = 0.0f32;
    for i in (0..desc.point_count()).step_by(7) {
        let p = desc.position(desc.coords(i).unwrap());
        let w = world.light(p, None).unwrap();
        assert_eq!(a.scattered.unwrap().data()[i].0, w.0, "{p}");
        apart = apart.max(
            (total(&a.scattered.unwrap().data()[i]) - total(&b.scattered.unwrap().data()[i])).abs(),
        );
    }
    assert!(
        apart > 1e-3,
        "the swept scattered sun differs from the world grid's"
    );
    // Later frames sweep the node's responses: as built in one frame.
    for _ in 0..200 {
        if h.update(CAMERA).unwrap().pending == 0 {
            break;
        }
    }
    let late = layer_of(&h, key).sun.unwrap();
    let worst = late
        .scattered
        .unwrap()
        .data()
        .iter()
        .zip(b.scattered.unwrap().data())
        .map(|(x, y)| (total(x) - total(y)).abs())
        .fold(0.0f32, f32::max);
    assert!(
        worst <= 1e-5 * total(&b.scattered.unwrap().data()[0]).max(1.0),
        "{worst}"
    );
}

/// Beside a neighbour not built (here beyond the world's edges), a node swept over an
/// apron reads the light its sweep computed one cell beyond it (`HierarchyParams::apron`,
/// its ring), and the sun's transmittance marched there: linear from its outermost
/// points, as across a seam; without an apron the read is clamped there. The light
/// volume's sampler reads the same.
#[test]
fn beside_a_neighbour_not_built_a_node_reads_its_apron_ring() {
    // Under the layer, on the level of clear cells above the ground (the volume gives
    // points in dense cells their neighbours' light).
    let (y, z) = (0.0, 36.0);
    let at = |x: f32| Vec3::new(x, y, z);
    for apron in [0, 1] {
        let params = HierarchyParams {
            apron,
            ..field::small_params(u64::MAX / 4)
        };
        let mut h =
            field::over_varying_layer(Vec3::splat(0.5), Box::new(CpuSweeper::new()), params);
        h.update(CAMERA).unwrap();
        let mut sun_moved = false;
        let volume = h.volume_sampler().unwrap();
        // The finest nodes over 0..16 and 48..64 m: their outermost points at 1 and 63,
        // the world's edges at 0 and 64.
        for (last, out) in [(63.0f32, 1.0f32), (1.0, -1.0)] {
            assert_eq!(h.grid_at(at(last + 0.4 * out)).desc().h(), CELL);
            let la = h.light(at(last), None).unwrap();
            let read = |f: f32| h.light(at(last + out * CELL * f), None).unwrap();
            let ta = h.sun_transmittance(at(last), None).unwrap();
            let t = |f: f32| {
                h.sun_transmittance(at(last + out * CELL * f), None)
                    .unwrap()
            };
            let t_ring = (t(0.25) - ta * 0.75) * 4.0;
            assert!((0.0..=1.0).contains(&t_ring), "{t_ring}");
            if apron == 0 {
                assert!((t_ring - ta).abs() <= 1e-6, "clamped: {t_ring} {ta}");
            }
            // (Beyond −x the sun's rays cross the layer there: a third as much.)
            sun_moved |= (t_ring - ta).abs() > 0.1 * ta;
            // The ring's light, from the read a quarter of the way out.
            let ring = (read(0.25) - la * 0.75) * 4.0;
            let moved = (total(&ring) - total(&la)).abs();
            if apron == 0 {
                assert!(moved <= 1e-6 * total(&la), "clamped: {moved}");
            } else {
                assert!(
                    moved > 1e-3 * total(&la),
                    "the ring's light is the outermost's"
                );
            }
            for f in [0.1f32, 0.4, 0.4999] {
                let want = ta * (1.0 - f) + t_ring * f;
                assert!(
                    (t(f) - want).abs() <= 1e-5,
                    "{apron} {last} {f}: {} {want}",
                    t(f)
                );
                let want = la * (1.0 - f) + ring * f;
                for (g, w) in read(f).0.iter().zip(want.0.iter()) {
                    assert!(
                        (*g - *w).abs().max_element() <= 1e-4 * total(&la),
                        "{apron} {last} {f}: {g} {w}"
                    );
                }
                let p = at(last + out * CELL * f);
                let (v, b) = (volume(p).unwrap(), VolumeSample::read(&h, p).unwrap());
                assert!(
                    (v.average - b.average).abs().max_element() <= 1e-5 * b.average.max_element()
                        && (v.sun - b.sun).abs() <= 1e-5,
                    "{apron} {p}: {v:?} {b:?}"
                );
            }
        }
        assert_eq!(sun_moved, apron > 0, "the sun's ring read beyond the node");
    }
}
