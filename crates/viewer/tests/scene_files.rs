//! A user's scene with every kind of input: a PNG heightmap (the shipped DEM), glTF
//! models (the shipped Kenney models), a ground texture, an EXR sky and a time of day.
//! Builds the world and the grids around a view on the CPU (no GPU needed).

use std::path::PathBuf;

use lightgrid_core::LightField;
use lightgrid_core::glam::Vec3;
use lightgrid_sky::ClearSky;
use lightgrid_viewer::{SceneFile, SweeperChoice, World};

#[test]
fn scene_with_heightmap_gltf_texture_and_exr_sky_builds() {
    let assets = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../assets");
    let dir = std::env::temp_dir().join(format!("viewer-scene-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    ClearSky::blue(Vec3::new(0.3, 0.8, 0.2))
        .env_map(64, 32)
        .unwrap()
        .save_exr(dir.join("sky.exr"))
        .unwrap();
    let ground: Vec<u8> = (0..16 * 16)
        .flat_map(|i| [90 + (i % 7) as u8 * 10, 80, 50])
        .collect();
    image::save_buffer(
        dir.join("ground.png"),
        &ground,
        16,
        16,
        image::ColorType::Rgb8,
    )
    .unwrap();
    let text = format!(
        r#"
[terrain]
heightmap = "{dem}"
spacing = 4.0
height_scale = 0.05
ground_texture = "ground.png"

[sky]
kind = "exr"
file = "sky.exr"

[sun]
time_of_day = 10.0

[grid]
node_points = 16
passes = 1

[[models]]
name = "trees"
gltf = "{trees}"
voxel_size = 0.25

[[models]]
name = "house"
gltf = "{house}"
voxel_size = 0.25

[[instances]]
model = "house"
position = [520.0, 520.0]
scale = 4.0

[[scatter]]
model = "trees"
count = 40
centre = [510.0, 530.0]
radius = 20.0
scale = [3.0, 4.0]

[dynamic_lights]
count = 50
centre = [520.0, 520.0]
radius = 30.0
height = [1.0, 3.0]

[[views]]
name = "town"
position = [540.0, 500.0]
height = 10.0
target = [520.0, 520.0]
"#,
        dem = assets
            .join("dem-jacksboro/jacksboro_fault_dem_u16.png")
            .display(),
        trees = assets.join("kenney-city-builder/grass-trees.glb").display(),
        house = assets
            .join("kenney-city-builder/building-small-a.glb")
            .display(),
    );
    let path = dir.join("scene.toml");
    std::fs::write(&path, text).unwrap();
    let scene = SceneFile::load(&path).unwrap();
    let mut world = World::build(scene, SweeperChoice::Cpu).unwrap();
    assert_eq!(world.models.len(), 2);
    assert_eq!(world.instances.len(), 41);
    // Dynamic lights stand 1–3 m above the ground.
    assert_eq!(world.dynamic.lights.len(), 50);
    for l in &world.dynamic.lights {
        let p = match l.kind {
            lightgrid_core::LightKind::Point { position }
            | lightgrid_core::LightKind::Spot { position, .. } => position,
            lightgrid_core::LightKind::Line { a, .. } => a,
            lightgrid_core::LightKind::Area { .. } => panic!("no area lights are scattered"),
        };
        let above = p.y - world.heightmap.height_at(p.x, p.z);
        assert!((0.99..=3.01).contains(&above), "{above}");
    }
    // The EXR sky lights the top; at 10 h the sun is up, in the east-south-east.
    assert!(world.sky_top.total().min_element() > 0.0);
    assert!(world.sun.1.min_element() > 0.0 && world.sun.0.y < 0.0);
    let (eye, target) = world.view_points(0);
    let (_, swept, stats) = world.prepare_view(eye, "test").unwrap();
    assert!(swept > 0 && stats.pending == 0, "swept {swept} {stats:?}");
    // Light above the house roof is brighter than light inside it; all finite.
    let inside = world
        .hierarchy
        .average(target + Vec3::new(0.0, 1.0, 0.0))
        .unwrap();
    let above = world
        .hierarchy
        .average(target + Vec3::new(0.0, 30.0, 0.0))
        .unwrap();
    assert!(inside.is_finite() && above.is_finite());
    assert!(above.x > inside.x, "above {above} inside {inside}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The shipped town scene with `[probes]`: probes over the instances (columns and
/// along walls), and in the open street, away from the walls, the light on a surface
/// facing up (sky and scattered sun; the direct sun is kept apart in all three):
/// the hierarchy's equals one full-resolution sweep of the street's region within 3 %
/// (the nesting error at one point; issue 43's target over regions is 1 % bias, 2 %
/// RMSE), both read through their horizon halves, and that sweep's agrees with the
/// probes' within 16 %: two different discretisations of the same sky, probes 4 m apart
/// interpolated against the true meshes, the sweep's 26 bins through voxels. Against a
/// Monte Carlo reference of the sweep's own voxel region (`lightgrid_measure::points`,
/// 1 M paths, standard error 0.05 %: 1.198, 1.683, 3.072) the sweep read through its
/// halves is 0.4–0.9 % below it (read as even across the horizon, 4.6–5.8 % below) and
/// the probes 10.6–14.7 % below (per colour); the bound is those two distances added,
/// rounded up. (An earlier reference, of a 32 m region, put the even read 3.3–4.0 %
/// above it and the probes 3.0–7.0 % below.) Inside a house the probes hold no light.
#[test]
fn the_town_scene_lights_with_probes_beside_the_sweep() {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/town.toml");
    let scene = SceneFile::load(&path).unwrap();
    let mut world = World::build(scene, SweeperChoice::Cpu).unwrap();
    let probes = world.probes.as_ref().expect("[probes] in town.toml");
    assert!(probes.wall_probes > 0 && probes.set.probes().len() > probes.wall_probes);
    let (eye, _) = world.view_points(0);
    world.prepare_view(eye, "test").unwrap();
    let probes = world.probes.as_ref().unwrap();
    let resolved = probes.resolved().unwrap();
    let open = Vec3::new(48.0, 2.0, 33.0);
    assert_eq!(resolved.coverage(open).unwrap(), 1.0);
    let e_probes = resolved.irradiance(open, Vec3::Y).unwrap();
    let e_hierarchy = world.hierarchy.irradiance(open, Vec3::Y).unwrap();
    let e_sweep = single_sweep_irradiance(&world, open, Vec3::Y);
    let nesting = (e_hierarchy - e_sweep).abs() / e_sweep;
    let rel = (e_probes - e_sweep).abs() / e_sweep;
    eprintln!(
        "open street, facing up: probes {e_probes}, one sweep {e_sweep}, hierarchy {e_hierarchy}: \
         probes {rel}, nesting {nesting}"
    );
    assert!(nesting.max_element() < 0.03, "{e_hierarchy} vs {e_sweep}");
    assert!(rel.max_element() < 0.16, "{e_probes} vs {e_sweep}");
    let inside = Vec3::new(42.0, 1.0, 44.0);
    assert_eq!(
        resolved.cube_at(inside).unwrap().irradiance(Vec3::Y),
        Vec3::ZERO
    );
    // The surfels' sun from the sweep's transmittance instead of shadow rays: the same
    // sunlit share of surfels to within the voxels' blur at shadow edges (measured 8 %
    // less with the sweep: a voxel half in shadow dims the surfels on its lit side).
    let to_sun = -world.sun.0;
    let scene = lightgrid_material_voxelizer::voxelize::RayScene::new(
        &probes.model,
        obvhs::BvhBuildParams::fast_build(),
    );
    let rays = probes.set.sun_visibility(&scene, to_sun);
    let sweep = probes
        .set
        .sun_visibility_from(&world.hierarchy, to_sun)
        .unwrap();
    let (r, s): (f32, f32) = (rays.iter().sum(), sweep.iter().sum());
    eprintln!("sunlit surfels: rays {r}, sweep {s} of {}", rays.len());
    assert!((r - s).abs() < 0.15 * r, "rays {r} sweep {s}");
}

/// Irradiance at `p` on normal `n` (sky and scattered sun, as the hierarchy reads it)
/// from one sweep of a 48 m square around `p` at the hierarchy's finest cell, open sky
/// around it, with the hierarchy's options, sky and sun.
fn single_sweep_irradiance(world: &World, p: Vec3, n: Vec3) -> Vec3 {
    use lightgrid_core::glam::UVec3;
    use lightgrid_core::{BinLight, Boundary, GridDesc, MaterialSource, SunBoundary, Sweeper};
    let params = *world.hierarchy.params();
    let h = params.cell(params.depths());
    let wd = *world.hierarchy.world().desc();
    let half = 24.0;
    let n_xz = (2.0 * half / h) as u32 + 1;
    let ny = ((wd.dims().y - 1) as f32 * wd.h() / h) as u32 + 1;
    let desc = GridDesc::new(
        Vec3::new(p.x - half, wd.origin().y, p.z - half),
        h,
        UVec3::new(n_xz, ny, n_xz),
    )
    .unwrap();
    let m = world.composer.material(&desc).unwrap();
    let mut o = params.sweep;
    o.outputs.bins = true;
    let mut sweeper = lightgrid_sweep_cpu::CpuSweeper::new();
    let out = sweeper
        .sweep(&m, &Boundary::open_sky(world.sky_top), &o)
        .unwrap();
    let sky = out.bins.unwrap();
    let (travel, irradiance) = world.sun;
    let outside = |_: Vec3| 1.0f32;
    let sun = sweeper
        .sweep_sun(
            &m,
            &SunBoundary {
                to_sun: -travel,
                scattered: Boundary::open_sky(BinLight::ZERO),
                outside: &outside,
            },
            &o,
        )
        .unwrap();
    // Read as the hierarchy reads it: through the halves where its options keep them.
    let read = |bins: &lightgrid_core::LightGrid, halves: Option<&lightgrid_core::HorizonGrid>| {
        let b = bins.sample(p).unwrap();
        match halves {
            Some(h) => b.irradiance_split(n, &h.sample(p).unwrap()),
            None => b.irradiance(n),
        }
    };
    read(&sky, out.horizon.as_ref()) * world.hierarchy.sky_scale()
        + read(&sun.scattered, sun.horizon.as_ref()) * irradiance
}
