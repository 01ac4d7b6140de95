//! Interior volumes (The Division's rooms) and the merged probe volume.
//!
//! - **Openings carry the outside's light**: a room's box in empty space under a
//!   uniform sky of radiance `L` (every face an opening): its probes get `π L` on every
//!   axis (quadrature error of 4096 Fibonacci rays: measured under 0.1 %; stated
//!   0.2 %), and so does every point of the merged volume, inside the box, in the blend
//!   and outside.
//! - **A closed room stays dark** inside under sun and sky, and its volume points are
//!   dark.
//! - **A room with a window against the Monte Carlo reference** (walls of albedo 0.7, a
//!   low sun through the window): the merged volume inside the room with the room's
//!   probes is off by a relative RMSE of 0.23 (guarded 10 % above; reference noise 0.031), the exterior probes
//!   alone by 2.2 (they light the room with the street's light through the window).

mod common;

use common::{ground_triangles, model, room, tri};
use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::light::luminance;
use lightgrid_core::{BinLight, GridDesc, LightField};
use lightgrid_light_probes::{
    InteriorBox, Lighting, ProbeLight, ProbeParams, ProbeSet, ProbeVolume,
};
use lightgrid_light_probes::{place, place_walls, reference};
use lightgrid_material_voxelizer::voxelize::RayScene;

const PI: f32 = std::f32::consts::PI;

fn params() -> ProbeParams {
    ProbeParams {
        rays: 4096,
        ..ProbeParams::standard()
    }
}

#[test]
fn openings_carry_uniform_light() {
    // Nothing near: one small triangle far away.
    let far = Vec3::splat(5000.0);
    let m = model(vec![tri(far, far + Vec3::X, far + Vec3::Z, 0)], &[0.5]);
    let scene = RayScene::new(&m, obvhs::BvhBuildParams::fast_build());
    let outside: Vec<Vec3> = (0..27)
        .map(|i| Vec3::new((i % 3) as f32, ((i / 3) % 3) as f32, (i / 9) as f32) * 4.0 - 4.0)
        .filter(|p| p.length() > 2.5)
        .collect();
    let p4 = ProbeParams {
        spacing: 4.0,
        ..params()
    };
    let ext = ProbeSet::bake(&scene, &outside, &p4, &|_, _| {}).unwrap();
    let roomb = InteriorBox {
        lo: Vec3::splat(-1.5),
        hi: Vec3::splat(1.5),
        blend: 1.0,
    };
    let inner = roomb.place(1.0).unwrap();
    assert_eq!(inner.len(), 27);
    let int = ProbeSet::bake_interior(&scene, &inner, &roomb, &ext, &p4, &|_, _| {}).unwrap();
    let l = 0.8f32;
    let lighting = Lighting {
        sky: BinLight::uniform(Vec3::splat(l)),
        sun: None,
    };
    let (mut el, mut il) = (ProbeLight::new(&ext), ProbeLight::new(&int));
    let (ev, iv) = (
        vec![0.0; ext.surfels().len()],
        vec![0.0; int.surfels().len()],
    );
    // An interior set needs its exterior's light, of the right size.
    assert!(
        il.frame(&int, &lighting, &iv)
            .unwrap_err()
            .to_string()
            .contains("frame_interior")
    );
    assert!(
        il.frame_interior(&int, &lighting, &iv, &ProbeLight::new(&int))
            .unwrap_err()
            .to_string()
            .contains("exterior")
    );
    el.frame(&ext, &lighting, &ev).unwrap();
    il.frame_interior(&int, &lighting, &iv, &el).unwrap();
    let worst = |cubes: &[lightgrid_core::AmbientCube]| {
        cubes
            .iter()
            .flat_map(|c| c.0.iter().map(|e| (e.x / (PI * l) - 1.0).abs()))
            .fold(0.0f32, f32::max)
    };
    assert!(worst(el.probes()) < 1e-3, "exterior {}", worst(el.probes()));
    assert!(worst(il.probes()) < 2e-3, "interior {}", worst(il.probes()));
    // The merged volume: every point sees some probe and holds the same light.
    let desc = GridDesc::new(Vec3::splat(-3.0), 0.5, UVec3::splat(13)).unwrap();
    let vol = ProbeVolume::new(&scene, desc, &[&ext, &int], &|_, _| {}).unwrap();
    assert_eq!(vol.covered(), desc.point_count());
    let r = vol.resolve(&[&el, &il]).unwrap();
    assert!(worst(r.cubes()) < 2e-3, "volume {}", worst(r.cubes()));
    // As a light field: irradiance π L facing anywhere, average light L.
    for p in [Vec3::ZERO, Vec3::new(1.2, -0.3, 2.0)] {
        let e = r.irradiance(p, Vec3::new(0.3, 0.9, -0.2)).unwrap();
        assert!((e.x / (PI * l) - 1.0).abs() < 2e-3, "{e}");
        let avg = r.average(p).unwrap();
        assert!((avg.x / l - 1.0).abs() < 2e-3, "{avg}");
    }
    assert!(
        vol.resolve(&[&el])
            .unwrap_err()
            .to_string()
            .contains("lights")
    );
}

/// The room of the last two tests: 6 x 3 x 6 m on the ground, walls of albedo 0.7,
/// optionally a 2 x 1.2 m window in the +X wall.
fn room_scene(window: bool) -> lightgrid_material_voxelizer::model::Model {
    let mut t = ground_triangles(60.0, 0);
    // (The floor a little above the ground, so that no two faces coincide.)
    t.extend(room(
        Vec3::new(0.0, 0.02, 0.0),
        Vec3::new(6.0, 3.0, 6.0),
        window.then_some(([0.9, 2.1], [2.0, 4.0])),
        1,
    ));
    model(t, &[0.4, 0.7])
}

fn room_box() -> InteriorBox {
    InteriorBox {
        lo: Vec3::new(0.05, 0.05, 0.05),
        hi: Vec3::new(5.95, 2.95, 5.95),
        blend: 0.5,
    }
}

fn lighting() -> Lighting {
    // Low sun from +X, through the window onto the floor.
    let e = 25f32.to_radians();
    Lighting {
        sky: BinLight::uniform(Vec3::new(0.3, 0.35, 0.45)),
        sun: Some((
            Vec3::new(e.cos(), e.sin(), -0.15).normalize(),
            Vec3::new(6.0, 5.6, 5.0),
        )),
    }
}

struct Baked {
    ext: ProbeSet,
    int: ProbeSet,
    el: ProbeLight,
    il: ProbeLight,
}

fn bake(scene: &RayScene<'_>) -> Baked {
    let p = ProbeParams {
        spacing: 3.0,
        ..ProbeParams::standard()
    };
    let (lo, hi) = (Vec3::new(-12.0, 0.0, -12.0), Vec3::new(18.0, 3.0, 18.0));
    let mut positions = place(scene, lo, hi, &p);
    let walls = place_walls(scene, &positions, &p);
    assert!(!walls.is_empty(), "the room's outer walls get probes");
    positions.extend(walls);
    let ext = ProbeSet::bake(scene, &positions, &p, &|_, _| {}).unwrap();
    let rb = room_box();
    // Rooms are small: finer surfels, every one its own brick.
    let pi = ProbeParams {
        spacing: 1.5,
        cell: 0.5,
        brick: 1,
        ..p
    };
    let int = ProbeSet::bake_interior(
        scene,
        &rb.place(pi.spacing).unwrap(),
        &rb,
        &ext,
        &pi,
        &|_, _| {},
    )
    .unwrap();
    let lt = lighting();
    let to_sun = lt.sun.unwrap().0;
    let (ev, iv) = (
        ext.sun_visibility(scene, to_sun),
        int.sun_visibility(scene, to_sun),
    );
    let (mut el, mut il) = (ProbeLight::new(&ext), ProbeLight::new(&int));
    for _ in 0..10 {
        el.frame(&ext, &lt, &ev).unwrap();
        il.frame_interior(&int, &lt, &iv, &el).unwrap();
    }
    Baked { ext, int, el, il }
}

fn room_desc() -> GridDesc {
    GridDesc::new(Vec3::new(-1.0, 0.25, -1.0), 0.5, UVec3::new(17, 6, 17)).unwrap()
}

#[test]
fn a_closed_room_stays_dark_inside() {
    let m = room_scene(false);
    let scene = RayScene::new(&m, obvhs::BvhBuildParams::fast_build());
    let b = bake(&scene);
    assert!(
        (0..b.int.surfels().len()).all(|s| !b.int.surfel_outside(s)),
        "a closed room's probes see only the room"
    );
    assert!(
        b.int
            .probes()
            .iter()
            .all(|p| p.sky.iter().flatten().all(|w| *w == 0.0))
    );
    assert!(
        b.il.probes()
            .iter()
            .all(|c| c.0.iter().all(|e| *e == Vec3::ZERO))
    );
    assert!(
        b.el.probes().iter().any(|c| c.0[2].x > 0.0),
        "the outside is lit"
    );
    let vol = ProbeVolume::new(&scene, room_desc(), &[&b.ext, &b.int], &|_, _| {}).unwrap();
    let r = vol.resolve(&[&b.el, &b.il]).unwrap();
    let inner = InteriorBox {
        lo: Vec3::splat(0.6),
        hi: Vec3::new(5.4, 2.4, 5.4),
        blend: 0.0,
    };
    let d = *r.desc();
    let mut inside = 0;
    for (i, c) in r.cubes().iter().enumerate() {
        if inner.contains(d.position(d.coords(i).unwrap())) {
            inside += 1;
            assert!(c.0.iter().all(|e| *e == Vec3::ZERO), "point {i}: {c:?}");
        }
    }
    assert!(inside > 50, "{inside}");
}

/// Relative RMSE (luminance, six axes) of the merged volume at points in the room.
fn room_error(scene: &RayScene<'_>, b: &Baked, with_room: bool) -> (f64, f64) {
    let (sets, lights): (Vec<&ProbeSet>, Vec<&ProbeLight>) = if with_room {
        (vec![&b.ext, &b.int], vec![&b.el, &b.il])
    } else {
        (vec![&b.ext], vec![&b.el])
    };
    let vol = ProbeVolume::new(scene, room_desc(), &sets, &|_, _| {}).unwrap();
    let r = vol.resolve(&lights).unwrap();
    let lt = lighting();
    let (mut num, mut den, mut noise) = (0.0f64, 0.0f64, 0.0f64);
    for (i, p) in [
        Vec3::new(1.5, 1.2, 1.5),
        Vec3::new(4.5, 1.2, 1.5),
        Vec3::new(3.0, 1.2, 3.0),
        Vec3::new(1.5, 1.2, 4.5),
        Vec3::new(4.5, 0.8, 3.0),
        Vec3::new(3.0, 2.2, 4.5),
    ]
    .into_iter()
    .enumerate()
    {
        let got = r.cube_at(p).unwrap();
        let (want, err) = reference::irradiance(scene, &lt, p, 3000, 300.0, 11 + i as u64);
        for k in 0..6 {
            let (g, w) = (luminance(got.0[k]) as f64, luminance(want.0[k]) as f64);
            num += (g - w).powi(2);
            den += w * w;
            noise += (luminance(err.0[k]) as f64).powi(2);
        }
    }
    ((num / den).sqrt(), (noise / den).sqrt())
}

#[test]
fn a_room_with_a_window_against_the_reference() {
    let m = room_scene(true);
    let scene = RayScene::new(&m, obvhs::BvhBuildParams::fast_build());
    let b = bake(&scene);
    let outside = (0..b.int.surfels().len())
        .filter(|s| b.int.surfel_outside(*s))
        .count();
    assert!(outside > 0, "the window shows the outside");
    let (with, noise) = room_error(&scene, &b, true);
    let (without, _) = room_error(&scene, &b, false);
    eprintln!(
        "room with a window: relative RMSE {with:.4} with its probes, {without:.4} with the exterior's alone; reference noise {noise:.4}"
    );
    // Measured 0.23 (reference noise 0.031): surfels are lit by probe cubes evaluated
    // where the probes are, and near a window light changes faster than probes 1.5 m
    // apart see (in a diagnosis, surfels beside the window came out up to 2.5x too
    // bright).
    assert!(with <= 0.23 * 1.1, "{with}");
    assert!(with < 0.2 * without, "{with} vs {without}");
}
