//! A low sun's rays leave the built nodes soon; the nodes they cross are composed for
//! the march (the sun's casters), so a node's direct sun is what one march through
//! the full-resolution material gives.

use lightgrid_core::glam::{UVec3, Vec2, Vec3};
use lightgrid_core::{
    BinLight, GridDesc, GridError, Heightmap, LightField, Material, MaterialGrid, MaterialSource,
};
use lightgrid_sweep_cpu::CpuSweeper;
use lightgrid_sweep_cpu::sun::SunTransmittance;
use lightgrid_terrain_lod::{Hierarchy, HierarchyParams, NodeKey, SunLight};

/// Extinction of the patches' medium, per metre.
const SIGMA: f32 = 0.35;
/// Height of the patches above the flat ground at 0.
const PATCH_TOP: f32 = 9.0;

mod field;

fn patch(x: f32, z: f32) -> bool {
    let (i, k) = ((x / 3.0).floor() as i64, (z / 3.0).floor() as i64);
    let h = (i.wrapping_mul(73_856_093) ^ k.wrapping_mul(19_349_663)).rem_euclid(97);
    h < 33
}

/// Flat ground below 0 and patches of medium 3 m square on about a third of a 3 m
/// lattice, up to [`PATCH_TOP`]; each cell takes the material at its centre, its
/// pass-through over its own size.
fn patches() -> field::Field<fn(Vec3, f32) -> Material> {
    field::Field(|p: Vec3, h: f32| {
        if p.y < 0.0 {
            Material::opaque(Vec3::splat(0.3))
        } else if p.y < PATCH_TOP && patch(p.x, p.z) {
            Material {
                reflectance: Vec3::splat(0.5),
                pass: (-SIGMA * h).exp(),
            }
        } else {
            Material::EMPTY
        }
    })
}

/// A hierarchy over a flat 512 m square of `source` (world grid 16 m, nodes of 16
/// points at 8, 4 and 2 m, one pass, no point budget to speak of; `with` changes the
/// parameters) under a 10° sun 20° off the x axis; the sun's direction and the
/// parameters.
fn under_a_low_sun(
    source: Box<dyn MaterialSource + Send + Sync>,
    with: impl FnOnce(&mut HierarchyParams),
) -> (Hierarchy, Vec3, HierarchyParams) {
    let hm = Heightmap::from_fn(Vec2::ZERO, 4.0, 129, 129, |_, _| 0.0).unwrap();
    let mut params = HierarchyParams {
        world_cell: 16.0,
        finest_cell: 2.0, // depths: 8, 4, 2 m; finest nodes 32 m
        node_points: 16,
        max_levels: 40,
        budget_points: u64::MAX / 4,
        ..Default::default()
    };
    params.sweep.max_passes = 1;
    with(&mut params);
    let sky = BinLight::uniform(Vec3::ONE).split_vertical().0;
    let mut h = Hierarchy::new(&hm, source, Box::new(CpuSweeper::new()), sky, params).unwrap();
    let (e, a) = (10f32.to_radians(), 20f32.to_radians());
    let to_sun = Vec3::new(e.cos() * a.cos(), e.sin(), e.cos() * a.sin());
    h.set_sun(Some(SunLight {
        to_sun,
        irradiance: Vec3::ONE,
    }))
    .unwrap();
    (h, to_sun, params)
}

/// What [`march_against_full_resolution`] found.
struct Outcome {
    /// Mean and largest difference of the node's transmittance from the reference.
    mean: f64,
    worst: f32,
    /// Points of the node above the ground, and those the reference has in shade.
    points: u32,
    shaded: u32,
    /// Casters composed while the hierarchy settled, and their bytes held then and
    /// ten idle frames later.
    casters: u32,
    held: u64,
    held_later: u64,
    /// The most materials and casters one frame composed.
    most_composed: u32,
    /// Frames in which a ready node of the finest depth showed no sun of its own (its
    /// points read a coarser grid's).
    without_sun: u32,
}

/// A 10° sun over the patches: the finest node farthest toward the sun, its direct
/// sun against one march through the full-resolution material 128 m toward the sun,
/// once the hierarchy settled (under a time budget of `budget_ms` if given).
fn march_against_full_resolution(skip_casters: bool, budget_ms: Option<f32>) -> Outcome {
    march_with(skip_casters, budget_ms, false)
}

/// [`march_against_full_resolution`], `march_before_casters` as given
/// (`HierarchyParams::march_before_casters`).
fn march_with(skip_casters: bool, budget_ms: Option<f32>, march_before_casters: bool) -> Outcome {
    let (mut h, to_sun, params) = under_a_low_sun(Box::new(patches()), |params| {
        params.skip.sun_casters = skip_casters;
        params.budget_ms = budget_ms;
        params.march_before_casters = march_before_casters;
    });
    let cam = Vec3::new(256.0, 10.0, 256.0);
    let mut casters = 0;
    let mut held = 0;
    let mut most_composed = 0;
    let frames = if budget_ms.is_some() { 5000 } else { 40 };
    let mut without_sun = 0;
    let finest = params.depths();
    for f in 0..frames {
        let s = h.update(cam).unwrap();
        casters += s.casters;
        held = s.caster_bytes;
        most_composed = most_composed.max(s.composed + s.casters);
        // (Layers come as the world grid, then the ready nodes in key order.)
        let keys = h.ready_nodes();
        let layers = h.layers();
        assert_eq!(layers.len(), keys.len() + 1);
        for (k, l) in keys.iter().zip(&layers[1..]) {
            let o = l.owner.expect("a node's layer has its owner");
            assert_eq!((o.index, o.size), (k.index, params.node_size(k.depth)));
        }
        without_sun += keys
            .iter()
            .zip(&layers[1..])
            .any(|(k, l)| k.depth == finest && l.sun.is_none()) as u32;
        if s.pending == 0 {
            break;
        }
        assert!(f + 1 < frames, "not settled after {frames} frames: {s:?}");
    }
    // The finest node farthest toward the sun: its rays leave the built nodes first.
    let u = Vec2::new(to_sun.x, to_sun.z).normalize();
    let key = h
        .ready_nodes()
        .into_iter()
        .filter(|k| k.depth == finest)
        .max_by(|a, b| {
            let c = |k| {
                let (lo, hi) = h.node_rect(k);
                u.dot(0.5 * (lo + hi))
            };
            c(*a).total_cmp(&c(*b)).then(a.cmp(b))
        })
        .unwrap();
    let node = *h.node(key).unwrap().desc();
    // One march through the full-resolution material of the node and 128 m toward the
    // sun (a ray from the ground rises past the patches within 52 m), open sky beyond.
    let cell = node.h();
    let reach = (128.0 / cell) as u32;
    let pad = 4u32;
    let d = node.dims();
    let region = GridDesc::new(
        node.origin() - Vec3::new(pad as f32, 0.0, pad as f32) * cell,
        cell,
        UVec3::new(d.x + reach + pad, d.y + 8, d.z + reach + pad),
    )
    .unwrap();
    let material = patches().material(&region).unwrap();
    let reference = SunTransmittance::march(&material, to_sun, false, &|_| 1.0).unwrap();
    let (mut sum, mut worst, mut n, mut shaded) = (0.0f64, 0.0f32, 0, 0);
    for j in 0..d.y {
        for z in 0..d.z {
            for x in 0..d.x {
                let q = UVec3::new(x, j, z);
                let p = node.position(q);
                if p.y < 0.0 {
                    continue; // inside the ground
                }
                let t = h.sun_transmittance(p, None).unwrap();
                let r = reference.values()[region.index(UVec3::new(x + pad, j, z + pad)).unwrap()];
                sum += (t - r).abs() as f64;
                worst = worst.max((t - r).abs());
                n += 1;
                shaded += (r < 0.5) as u32;
            }
        }
    }
    // Ten frames that light nothing new.
    let mut held_later = held;
    for _ in 0..10 {
        held_later = h.update(cam).unwrap().caster_bytes;
    }
    Outcome {
        mean: sum / n as f64,
        worst,
        points: n,
        shaded,
        casters,
        held,
        held_later,
        most_composed,
        without_sun,
    }
}

/// The node's march equals the one through the full-resolution material.
fn assert_full_resolution(o: &Outcome) {
    assert!(
        o.mean < 1e-4 && o.worst < 0.01,
        "mean {}, worst {} over {} points",
        o.mean,
        o.worst,
        o.points
    );
}

#[test]
fn a_low_suns_march_crosses_the_nodes_beyond_the_built_ones_at_full_resolution() {
    let o = march_against_full_resolution(false, None);
    assert!(
        o.shaded > o.points / 10,
        "the patches shade {} of {} points",
        o.shaded,
        o.points
    );
    assert!(
        o.casters > 0 && o.held > 0,
        "casters {}, {} bytes",
        o.casters,
        o.held
    );
    assert_full_resolution(&o);
    // Once no frame needs them, the casters go.
    assert_eq!(o.held_later, 0);
}

/// With the casters skipped (`LodSkips::sun_casters`) none is composed, and the march
/// past the built nodes crosses the coarser grids' material: the shadows there differ.
#[test]
fn without_the_casters_the_march_crosses_coarser_material() {
    let o = march_against_full_resolution(true, None);
    assert_eq!((o.casters, o.held), (0, 0));
    assert!(
        o.mean > 1e-2 && o.worst > 0.3,
        "mean {}, worst {}",
        o.mean,
        o.worst
    );
}

/// Under a time budget a frame composes one batch (a material or caster a thread) once
/// its time is spent, a job's casters included (they were all composed at once: 19 in
/// one frame of the frame bench at 10°), and those composed before a job waits are
/// kept for it: the march ends the same as without a budget.
#[test]
fn under_a_time_budget_the_casters_come_a_batch_a_frame() {
    let o = march_against_full_resolution(false, Some(1e-3));
    let threads = rayon::current_num_threads() as u32;
    assert!(
        o.most_composed <= threads,
        "{} composed in one frame",
        o.most_composed
    );
    let free = march_against_full_resolution(false, None);
    assert!(free.most_composed > threads, "{}", free.most_composed);
    assert!(o.casters > 0, "{}", o.casters);
    assert_full_resolution(&o);
}

/// Under a time budget with `march_before_casters`, a new node whose casters are not
/// all composed marches its direct sun at once through those held: no ready node of the
/// finest depth ever shows a coarser grid's sun (without it some do, for frames), and
/// once its casters are held it is marched again: the march ends the same as without
/// a budget.
#[test]
fn marched_before_its_casters_a_node_shows_its_own_sun_and_ends_the_same() {
    let o = march_with(false, Some(1e-3), true);
    assert_eq!(o.without_sun, 0);
    assert!(o.casters > 0, "{}", o.casters);
    assert_full_resolution(&o);
    let waited = march_with(false, Some(1e-3), false);
    assert!(waited.without_sun > 0, "{}", waited.without_sun);
    assert_full_resolution(&waited);
}

/// [`patches`] whose shadow material (what the casters are composed from) scatters
/// nothing: the same shadows, and light of its own wherever a sweep used it.
struct DarkShadows(field::Field<fn(Vec3, f32) -> Material>);

impl MaterialSource for DarkShadows {
    fn material(&self, desc: &GridDesc) -> Result<MaterialGrid, GridError> {
        self.0.material(desc)
    }
    fn shadow_material(&self, desc: &GridDesc) -> Result<MaterialGrid, GridError> {
        lightgrid_core::NoScatter(&self.0).material(desc)
    }
}

/// Every ready node's light after a flight toward a 10° sun, from a source whose shadow
/// material is `dark` or plain, and the casters composed on the way.
fn lit_after_a_flight(dark: bool) -> (Vec<(NodeKey, Vec<BinLight>)>, u32) {
    let source: Box<dyn MaterialSource + Send + Sync> = if dark {
        Box::new(DarkShadows(patches()))
    } else {
        Box::new(patches())
    };
    let (mut h, to_sun, _) = under_a_low_sun(source, |_| {});
    let mut casters = 0;
    // Toward the sun: the nodes the first cameras' rays crossed (casters) are built.
    for step in 0..4 {
        let cam = Vec3::new(192.0, 10.0, 192.0)
            + 40.0 * step as f32 * Vec3::new(to_sun.x, 0.0, to_sun.z).normalize();
        for _ in 0..40 {
            let s = h.update(cam).unwrap();
            casters += s.casters;
            if s.pending == 0 {
                break;
            }
        }
    }
    let lit = h
        .ready_nodes()
        .into_iter()
        .map(|k| {
            let g = h.node(k).unwrap();
            let d = *g.desc();
            let light = (0..d.point_count())
                .map(|i| h.light(d.position(d.coords(i).unwrap()), None).unwrap())
                .collect();
            (k, light)
        })
        .collect();
    (lit, casters)
}

/// The casters are composed from the source's shadow material (`MaterialSource::
/// shadow_material`, coarser with the area composer) and a node built where a caster
/// lay composes its own: with a source whose shadow material scatters nothing, every
/// node's light after a flight toward a low sun (over the casters of the first frames)
/// is the plain source's bit for bit. (A node that took its caster's material would
/// scatter nothing of its own.)
#[test]
fn casters_come_from_the_shadow_material_and_nodes_never_take_it() {
    let (dark, casters) = lit_after_a_flight(true);
    let (plain, plain_casters) = lit_after_a_flight(false);
    assert!(
        casters > 0 && casters == plain_casters,
        "{casters}, {plain_casters}"
    );
    assert_eq!(dark.len(), plain.len());
    for ((k, a), (l, b)) in dark.iter().zip(&plain) {
        assert_eq!(k, l);
        assert!(a == b, "node {k:?}'s light differs");
    }
}
