//! Probes against answers that need no probes.
//!
//! **Infinite Lambertian ground** (albedo `a`, a 4 km square, probes 2 m above it) under
//! a uniform sky of radiance `L` all round and a sun of irradiance `E` at elevation `θ`:
//! the ground's irradiance is `E_g = π L + E sin θ` (it sees the whole sky, and nothing
//! of itself), its radiance `a E_g / π`; a probe's irradiance facing up is `π L`, facing
//! down `a E_g`, facing sideways half of each, `(π L + a E_g) / 2`. Errors: the
//! quadrature of 4096 Fibonacci rays on a clipped cosine, and the grazing rays that miss
//! the ground within `max_distance` (they see the sky's `L` instead of the ground);
//! measured together at most 0.05 % on any axis. Stated tolerance 0.2 %. It takes two
//! frames: the first lights the ground, the second the probes from it; later frames
//! change nothing (the ground sees no ground).

use lightgrid_core::BinLight;
use lightgrid_core::glam::Vec3;
use lightgrid_light_probes::{Lighting, ProbeLight, ProbeParams, ProbeSet};
use lightgrid_material_voxelizer::model::Model;
use lightgrid_material_voxelizer::voxelize::RayScene;

mod common;
use common::{ground_triangles, model, quad, room};

const PI: f32 = std::f32::consts::PI;

fn ground(albedo: f32) -> Model {
    model(ground_triangles(2000.0, 0), &[albedo])
}

fn params() -> ProbeParams {
    ProbeParams {
        rays: 4096,
        max_distance: 3000.0,
        ..ProbeParams::standard()
    }
}

fn close(got: f32, want: f32, rel: f32, what: &str) {
    assert!(
        (got - want).abs() <= rel * want.abs().max(1e-6),
        "{what}: {got} vs {want} (rel {})",
        (got - want).abs() / want.abs().max(1e-6)
    );
}

#[test]
fn infinite_lambertian_ground_under_sky_and_sun() {
    let a = 0.4;
    let m = ground(a);
    let scene = RayScene::new(&m, obvhs::BvhBuildParams::fast_build());
    let probes = [
        Vec3::new(0.0, 2.0, 0.0),
        Vec3::new(7.0, 2.0, -3.0),
        Vec3::new(-5.0, 3.5, 4.0),
    ];
    let set = ProbeSet::bake(&scene, &probes, &params(), &|_, _| {}).unwrap();
    let (l, e) = (1.3f32, 5.0f32);
    let theta = 35f32.to_radians();
    let to_sun = Vec3::new(theta.cos() * 0.6, theta.sin(), theta.cos() * 0.8);
    let lighting = Lighting {
        sky: BinLight::uniform(Vec3::splat(l)),
        sun: Some((to_sun, Vec3::splat(e))),
    };
    let vis = set.sun_visibility(&scene, to_sun);
    assert!(vis.iter().all(|v| *v == 1.0), "nothing shades the ground");
    let mut light = ProbeLight::new(&set);
    let ground_e = PI * l + e * theta.sin();
    for frame in 0..4 {
        light.frame(&set, &lighting, &vis).unwrap();
        if frame == 0 {
            continue;
        }
        for (i, cube) in light.probes().iter().enumerate() {
            let c = |k: usize| cube.0[k].x;
            close(c(2), PI * l, 2e-3, &format!("probe {i} up"));
            close(c(3), a * ground_e, 2e-3, &format!("probe {i} down"));
            let side = 0.5 * (PI * l + a * ground_e);
            for k in [0, 1, 4, 5] {
                close(c(k), side, 2e-3, &format!("probe {i} axis {k}"));
            }
        }
    }
}

/// A probe in a closed box sees neither the sky nor the sun: it stays dark, frame
/// after frame, whatever the light outside.
#[test]
fn a_closed_box_stays_dark() {
    let t = room(Vec3::splat(-3.0), Vec3::splat(3.0), None, 0);
    let m = model(t, &[0.9]);
    let scene = RayScene::new(&m, obvhs::BvhBuildParams::fast_build());
    let set = ProbeSet::bake(
        &scene,
        &[Vec3::new(0.5, -1.0, 0.2)],
        &ProbeParams::preview(),
        &|_, _| {},
    )
    .unwrap();
    assert!(
        set.probes()[0].sky.iter().flatten().all(|w| *w == 0.0),
        "no sky inside"
    );
    let to_sun = Vec3::new(0.3, 1.0, 0.2);
    let vis = set.sun_visibility(&scene, to_sun);
    assert!(vis.iter().all(|v| *v == 0.0), "no sun inside");
    let mut light = ProbeLight::new(&set);
    let lighting = Lighting {
        sky: BinLight::uniform(Vec3::splat(10.0)),
        sun: Some((to_sun, Vec3::splat(100.0))),
    };
    for _ in 0..5 {
        light.frame(&set, &lighting, &vis).unwrap();
    }
    assert!(light.probes()[0].0.iter().all(|e| *e == Vec3::ZERO));
    assert!(!set.surfels().is_empty());
}

/// Relighting is linear in the sky and the sun; baking twice gives the same set; bad
/// inputs are refused by name.
#[test]
fn linear_deterministic_and_checked() {
    // Ground and a wall, so that bounce light matters.
    let mut t = ground(0.5).triangles;
    t.extend(quad(
        [
            Vec3::new(-6.0, 0.0, 3.0),
            Vec3::new(6.0, 0.0, 3.0),
            Vec3::new(6.0, 8.0, 3.0),
            Vec3::new(-6.0, 8.0, 3.0),
        ],
        1,
    ));
    let m = model(t, &[0.5, 0.7]);
    let scene = RayScene::new(&m, obvhs::BvhBuildParams::fast_build());
    let lo = Vec3::new(-10.0, 0.0, -10.0);
    let hi = Vec3::new(10.0, 8.0, 10.0);
    let mut params = ProbeParams::preview();
    params.spacing = 5.0;
    let positions = lightgrid_light_probes::place(&scene, lo, hi, &params);
    assert!(positions.len() >= 9, "{}", positions.len());
    let set = ProbeSet::bake(&scene, &positions, &params, &|_, _| {}).unwrap();
    let again = ProbeSet::bake(&scene, &positions, &params, &|_, _| {}).unwrap();
    assert_eq!(set, again);
    let to_sun = Vec3::new(-0.2, 0.6, -0.7);
    let vis = set.sun_visibility(&scene, to_sun);
    assert!(vis.contains(&0.0) && vis.contains(&1.0));
    let run = |sky: Vec3, sun: Vec3| {
        let mut light = ProbeLight::new(&set);
        let lighting = Lighting {
            sky: BinLight::uniform(sky),
            sun: Some((to_sun, sun)),
        };
        for _ in 0..4 {
            light.frame(&set, &lighting, &vis).unwrap();
        }
        light
    };
    let (s1, s2) = (Vec3::new(0.2, 0.4, 0.9), Vec3::new(3.0, 2.5, 2.0));
    let both = run(s1, s2);
    let sky = run(s1, Vec3::ZERO);
    let sun = run(Vec3::ZERO, s2);
    let mut wall_bounce = false;
    for ((b, k), s) in both.probes().iter().zip(sky.probes()).zip(sun.probes()) {
        for axis in 0..6 {
            let want = k.0[axis] + s.0[axis];
            assert!((b.0[axis] - want).abs().max_element() <= 1e-5 * want.max_element().max(1e-3));
        }
        wall_bounce |= s.0[4].x > 0.0; // +Z: facing the wall
    }
    assert!(wall_bounce, "the sunlit wall lights the probes facing it");
    // Bad inputs, by name.
    let mut light = ProbeLight::new(&set);
    let bad = Lighting {
        sky: BinLight::uniform(Vec3::splat(f32::NAN)),
        sun: None,
    };
    assert!(
        light
            .frame(&set, &bad, &vis)
            .unwrap_err()
            .to_string()
            .contains("sky")
    );
    let ok = Lighting {
        sky: BinLight::uniform(Vec3::ONE),
        sun: Some((Vec3::ZERO, Vec3::ONE)),
    };
    assert!(
        light
            .frame(&set, &ok, &vis)
            .unwrap_err()
            .to_string()
            .contains("to_sun")
    );
    let ok = Lighting {
        sky: BinLight::uniform(Vec3::ONE),
        sun: None,
    };
    assert!(
        light
            .frame(&set, &ok, &vis[1..])
            .unwrap_err()
            .to_string()
            .contains("sun_visibility")
    );
    let mut p = params;
    p.spacing = -1.0;
    assert!(
        ProbeSet::bake(&scene, &positions, &p, &|_, _| {})
            .unwrap_err()
            .to_string()
            .contains("spacing")
    );
    assert!(
        ProbeSet::bake(&scene, &[Vec3::NAN], &params, &|_, _| {})
            .unwrap_err()
            .to_string()
            .contains("positions")
    );
}

/// The sun's visibility from a light field's transmittance (the sweep's sun channel):
/// on the infinite ground under a field that lets half the sun through everywhere, a
/// probe's downward irradiance is `a (π L + E sin θ / 2)` (to the ground test's 0.2 %);
/// surfels facing away from the sun get 0; a zero `to_sun` is refused by name.
#[test]
fn sun_visibility_from_a_fields_transmittance() {
    struct Half;
    impl lightgrid_core::LightField for Half {
        fn light(&self, _: Vec3, _: Option<Vec3>) -> Result<BinLight, lightgrid_core::GridError> {
            Ok(BinLight::ZERO)
        }
        fn sun_transmittance(
            &self,
            _: Vec3,
            _: Option<Vec3>,
        ) -> Result<f32, lightgrid_core::GridError> {
            Ok(0.5)
        }
    }
    let a = 0.4;
    let m = ground(a);
    let scene = RayScene::new(&m, obvhs::BvhBuildParams::fast_build());
    let set = ProbeSet::bake(&scene, &[Vec3::new(0.0, 2.0, 0.0)], &params(), &|_, _| {}).unwrap();
    let theta = 35f32.to_radians();
    let to_sun = Vec3::new(theta.cos(), theta.sin(), 0.0);
    let vis = set.sun_visibility_from(&Half, to_sun).unwrap();
    assert!(vis.iter().all(|v| *v == 0.5));
    let below = set.sun_visibility_from(&Half, -to_sun).unwrap();
    assert!(below.iter().all(|v| *v == 0.0), "the ground faces away");
    assert!(
        set.sun_visibility_from(&Half, Vec3::ZERO)
            .unwrap_err()
            .to_string()
            .contains("to_sun")
    );
    let (l, e) = (1.3f32, 5.0f32);
    let lighting = Lighting {
        sky: BinLight::uniform(Vec3::splat(l)),
        sun: Some((to_sun, Vec3::splat(e))),
    };
    let mut light = ProbeLight::new(&set);
    for _ in 0..3 {
        light.frame(&set, &lighting, &vis).unwrap();
    }
    let down = light.probes()[0].0[3].x;
    close(down, a * (PI * l + 0.5 * e * theta.sin()), 2e-3, "down");
}
