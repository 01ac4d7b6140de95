//! Sectors stream around the camera within the memory budget, nearest first; a sector
//! bakes the same probes whether streamed or baked alone; relighting runs per sector.

use lightgrid_core::BinLight;
use lightgrid_core::glam::{Vec2, Vec3, Vec4};
use lightgrid_light_probes::{Lighting, ProbeParams, ProbeSet, Sectors};
use lightgrid_material_voxelizer::model::{Model, SurfaceMaterial, Triangle};
use lightgrid_material_voxelizer::voxelize::RayScene;

fn ground(size: f32) -> Model {
    let t = |a: Vec3, b: Vec3, c: Vec3| Triangle {
        positions: [a, b, c],
        uvs: [Vec2::ZERO; 3],
        material: 0,
        part: 0,
    };
    let v = |x: f32, z: f32| Vec3::new(x, 0.0, z);
    Model {
        triangles: vec![
            t(v(0.0, 0.0), v(0.0, size), v(size, size)),
            t(v(0.0, 0.0), v(size, size), v(size, 0.0)),
        ],
        materials: vec![SurfaceMaterial {
            base_colour: Vec4::new(0.4, 0.4, 0.4, 1.0),
            ..Default::default()
        }],
        textures: vec![],
    }
}

#[test]
fn sectors_stream_within_the_budget() {
    let m = ground(96.0);
    let scene = RayScene::new(&m, obvhs::BvhBuildParams::fast_build());
    let params = ProbeParams {
        spacing: 8.0,
        rays: 64,
        ..ProbeParams::preview()
    };
    let (lo, hi) = (Vec3::ZERO, Vec3::new(96.0, 0.0, 96.0));
    let mut s = Sectors::new(&scene, lo, hi, &params, 32.0, 25.0).unwrap();
    assert_eq!(s.sector_count(), 9);
    // Near a corner: its sector and the two beside it (22 m) are within reach, the
    // diagonal one (31 m) is not.
    let cam = Vec3::new(10.0, 5.0, 10.0);
    let st = s.update(cam, usize::MAX).unwrap();
    assert_eq!((st.loaded, st.evicted, st.over_budget), (3, 0, 0), "{st:?}");
    let one = s.resident().next().unwrap().1.set.bytes();
    // A budget of two sectors keeps the nearest two: the camera's own first.
    let st = s.update(cam, 2 * one + one / 2).unwrap();
    assert_eq!(st.resident, 2, "{st:?}");
    assert!(st.bytes <= 2 * one + one / 2);
    let keys: Vec<_> = s.resident().map(|(k, _)| k).collect();
    assert!(keys.contains(&s.sector_at(cam)), "{keys:?}");
    // Flying toward the far corner: the old sectors go, four new ones come.
    let far = Vec3::new(70.0, 5.0, 70.0);
    let st = s.update(far, usize::MAX).unwrap();
    assert_eq!((st.evicted, st.loaded, st.resident), (2, 4, 4), "{st:?}");
    assert!(s.resident().all(|(k, _)| k.x >= 1 && k.y >= 1));
    // The streamed sector equals the same probes baked alone.
    let (key, sector) = s.resident().find(|(k, _)| *k == s.sector_at(far)).unwrap();
    let alone = ProbeSet::bake(
        &scene,
        &sector
            .set
            .probes()
            .iter()
            .map(|p| p.position)
            .collect::<Vec<_>>(),
        &params,
        &|_, _| {},
    )
    .unwrap();
    assert_eq!(alone, sector.set, "sector {key}");
    // Relighting every resident sector: an open ground's probes see the sky above.
    let lighting = Lighting {
        sky: BinLight::uniform(Vec3::ONE),
        sun: Some((Vec3::new(0.3, 1.0, 0.2), Vec3::splat(3.0))),
    };
    for _ in 0..3 {
        s.frame(&lighting).unwrap();
    }
    for (_, sector) in s.resident() {
        for cube in sector.light.probes() {
            assert!(
                (cube.0[2].x - std::f32::consts::PI).abs() < 0.05,
                "{:?}",
                cube.0[2]
            );
            assert!(cube.0[3].x > 0.0);
        }
    }
    assert!(
        s.update(Vec3::NAN, 1)
            .unwrap_err()
            .to_string()
            .contains("camera")
    );
}
