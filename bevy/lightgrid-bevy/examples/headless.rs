//! The plugin's headless test: a white sphere above a flat ground, lit by one live
//! irradiance volume and nothing else, rendered by Bevy; the centre pixel (the sphere's
//! point facing the camera) must show the volume's `+Z` face times its intensity and the
//! camera's exposure, within 3 %, under a high sun and again after the sun moves low
//! (the volume swept again by the plugin and its texture replaced), and the two must
//! differ. Then the low sun's volume is written as `lightgrid bake` writes it (KTX2 and
//! sidecar), the live one removed, and the files loaded through Bevy's asset server
//! ([`lightgrid_bevy::spawn_baked_volumes`]): the pixel must hold the same value within
//! 3 % again. Exits 0 when all hold, 1 otherwise; `--save DIR` also writes the frames.
//!
//! `xvfb-run -a cargo run --release --example headless` (what `run.sh` does: Bevy
//! renders through Vulkan, Mesa's lavapipe on a machine without a GPU).

use std::sync::{Arc, Mutex};

use bevy::camera::Exposure;
use bevy::core_pipeline::tonemapping::{DebandDither, Tonemapping};
use bevy::light::{GlobalAmbientLight, IrradianceVolume};
use bevy::prelude::*;
use bevy::render::view::Msaa;
use bevy::render::view::screenshot::{Screenshot, ScreenshotCaptured};
use lightgrid_bevy::{Daylight, LightgridPlugin, LiveSource, LiveStats, LiveVolume};
use lightgrid_core::SideBoundary;

/// The grid point the sphere's centre sits on, and the grid's spacing.
const POINT: [u32; 3] = [4, 5, 4];
const SPACING: f32 = 1.0;
/// Window size; the centre pixel is read.
const SIZE: (u32, u32) = (320, 240);
/// Most frames before the test gives up.
const MAX_FRAMES: u32 = 3000;
/// The `+Z` face (ambient-cube order `+X, -X, +Y, -Y, +Z, -Z`).
const FACE_Z: usize = 4;

fn high() -> Daylight {
    Daylight::at(70.0, 40.0, Vec3::splat(3.0), Vec3::splat(0.3))
}

fn low() -> Daylight {
    Daylight::at(12.0, 40.0, Vec3::splat(3.0), Vec3::splat(0.3))
}

/// What the test has seen.
#[derive(Resource, Default)]
struct Check {
    /// Frames so far, and the frame the current phase began.
    frame: u32,
    phase_start: u32,
    phase: Phase,
    /// The captured centre pixel (linear RGB), once the screenshot arrives.
    captured: Arc<Mutex<Option<Vec3>>>,
    /// Exposure multiplier of the camera.
    exposure: f32,
    /// (expected, rendered) under the high and the low sun, and from the baked files.
    results: Vec<(f32, f32)>,
    save: Option<std::path::PathBuf>,
    /// The asset folder the baked volume is written to.
    assets: std::path::PathBuf,
}

#[derive(Default, Clone, Copy, PartialEq, Debug)]
enum Phase {
    #[default]
    WaitHigh,
    ShotHigh,
    WaitLow,
    ShotLow,
    WaitBaked,
    ShotBaked,
    Done,
}

fn main() {
    let mut args = std::env::args().skip(1);
    let save = match (args.next().as_deref(), args.next()) {
        (Some("--save"), Some(dir)) => Some(std::path::PathBuf::from(dir)),
        (None, _) => None,
        _ => {
            eprintln!("usage: headless [--save DIR]");
            std::process::exit(2);
        }
    };
    // The folder Bevy's asset server reads, where the baked volume goes.
    let assets =
        std::env::temp_dir().join(format!("lightgrid-bevy-headless-{}", std::process::id()));
    std::fs::create_dir_all(&assets).expect("a temporary folder");
    let exit = App::new()
        .insert_resource(ClearColor(Color::BLACK))
        // No light but the volume's.
        .insert_resource(GlobalAmbientLight {
            brightness: 0.0,
            ..default()
        })
        .insert_resource(high())
        .insert_resource(Check {
            save,
            assets: assets.clone(),
            ..default()
        })
        .add_plugins((
            DefaultPlugins
                .set(WindowPlugin {
                    primary_window: Some(Window {
                        resolution: SIZE.into(),
                        title: "lightgrid-bevy headless check".into(),
                        ..default()
                    }),
                    ..default()
                })
                .set(AssetPlugin {
                    file_path: assets.to_string_lossy().into_owned(),
                    ..default()
                }),
            LightgridPlugin::default(),
        ))
        .add_systems(Startup, setup)
        .add_systems(Update, check)
        .run();
    let _ = std::fs::remove_dir_all(&assets);
    if exit.is_error() {
        std::process::exit(1);
    }
}

fn setup(
    mut commands: Commands,
    mut images: ResMut<Assets<Image>>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    daylight: Res<Daylight>,
    mut check: ResMut<Check>,
) {
    let material = lightgrid_bevy::flat_ground(9, 2, SPACING, 0.5).expect("a valid grid");
    let mut source = LiveSource::new(material, 1.0);
    // A tile of an endless flat ground: the light is the same along x and z.
    source.sides = SideBoundary::Periodic;
    // The exposure that puts the high sun's expected value near 0.4 (linear).
    let volume = lightgrid_bevy::bake(&source, &daylight).expect("the first sweep");
    let value = volume.texel(grid_point(), FACE_Z).x * volume.intensity();
    let ev100 = (value / 0.4 / 1.2).log2();
    check.exposure = Exposure { ev100 }.exposure();
    let e = lightgrid_bevy::spawn_live_volume(&mut commands, &mut images, source, &daylight)
        .expect("the first sweep");
    info!("volume entity {e:?}: +Z face {value:.4}, ev100 {ev100:.2}");
    let centre = Vec3::new(POINT[0] as f32, POINT[1] as f32, POINT[2] as f32) * SPACING;
    commands.spawn((
        Mesh3d(meshes.add(Sphere::new(0.3 * SPACING).mesh().uv(64, 32))),
        MeshMaterial3d(materials.add(StandardMaterial {
            base_color: Color::WHITE,
            perceptual_roughness: 1.0,
            reflectance: 0.0,
            metallic: 0.0,
            ..default()
        })),
        Transform::from_translation(centre),
    ));
    commands.spawn((
        Camera3d::default(),
        Tonemapping::None,
        DebandDither::Disabled,
        Msaa::Off,
        Exposure { ev100 },
        Transform::from_translation(centre + Vec3::Z * 2.5 * SPACING).looking_at(centre, Vec3::Y),
    ));
}

fn grid_point() -> lightgrid_core::glam::UVec3 {
    lightgrid_core::glam::UVec3::from_array(POINT)
}

/// The `+Z` face of the volume's point under the sphere, times its intensity.
fn expected(live: &LiveVolume) -> f32 {
    let v = live.volume().expect("swept");
    v.texel(grid_point(), FACE_Z).x * v.intensity() * live.source().unit_scale
}

fn shoot(commands: &mut Commands, check: &Check, name: &str) {
    let slot = check.captured.clone();
    let path = check.save.as_ref().map(|d| d.join(name));
    commands
        .spawn(Screenshot::primary_window())
        .observe(move |shot: On<ScreenshotCaptured>| {
            let img = &shot.event().image;
            let c = img
                .get_color_at(SIZE.0 / 2, SIZE.1 / 2)
                .expect("a 2D screenshot");
            let l = LinearRgba::from(c);
            *slot.lock().unwrap() = Some(Vec3::new(l.red, l.green, l.blue));
            if let Some(path) = &path
                && let Ok(d) = img.clone().try_into_dynamic()
            {
                let _ = d.to_rgb8().save(path);
            }
        });
}

#[allow(clippy::too_many_arguments)]
fn check(
    mut commands: Commands,
    mut check: ResMut<Check>,
    mut daylight: ResMut<Daylight>,
    volumes: Query<(Entity, &LiveVolume)>,
    baked: Query<&IrradianceVolume, Without<LiveVolume>>,
    assets: Res<AssetServer>,
    stats: Res<LiveStats>,
    mut exit: MessageWriter<AppExit>,
) {
    check.frame += 1;
    let since = check.frame - check.phase_start;
    if check.frame > MAX_FRAMES {
        error!(
            "gave up after {MAX_FRAMES} frames in {:?} ({stats:?})",
            check.phase
        );
        exit.write(AppExit::error());
        return;
    }
    let mut taken = check.captured.lock().unwrap().take();
    // Bevy compiles its pipelines in the background (on a software driver the sphere
    // can take a second to appear): a frame with nothing drawn is taken again.
    if taken == Some(Vec3::ZERO) {
        taken = None;
        let back = match check.phase {
            Phase::ShotHigh => Phase::WaitHigh,
            Phase::ShotLow => Phase::WaitLow,
            _ => Phase::WaitBaked,
        };
        next(&mut check, back);
    }
    match check.phase {
        Phase::WaitHigh if since >= 30 => {
            shoot(&mut commands, &check, "high.png");
            next(&mut check, Phase::ShotHigh);
        }
        Phase::ShotHigh => {
            if let Some(px) = taken {
                let (_, live) = volumes.single().expect("one live volume");
                let want = expected(live) * check.exposure;
                check.results.push((want, px.x));
                *daylight = low();
                next(&mut check, Phase::WaitLow);
            }
        }
        Phase::WaitLow => {
            let (_, live) = volumes.single().expect("one live volume");
            if live.shown() == Some(low()) && !live.sweeping() && since >= 30 {
                shoot(&mut commands, &check, "low.png");
                next(&mut check, Phase::ShotLow);
            }
        }
        Phase::ShotLow => {
            if let Some(px) = taken {
                let (e, live) = volumes.single().expect("one live volume");
                let want = expected(live) * check.exposure;
                check.results.push((want, px.x));
                // The same volume as `lightgrid bake` writes it, loaded as assets.
                let v = live.volume().expect("swept").clone();
                lightgrid_export::write_volumes(
                    &check.assets,
                    "baked",
                    &[v],
                    lightgrid_export::Content::Indirect,
                    live.source().unit_scale,
                    None,
                )
                .expect("writing the baked volume");
                let json =
                    std::fs::read_to_string(check.assets.join("baked.json")).expect("the sidecar");
                commands.entity(e).despawn();
                lightgrid_bevy::spawn_baked_volumes(&mut commands, &assets, &json, "")
                    .expect("a valid sidecar");
                next(&mut check, Phase::WaitBaked);
            }
        }
        Phase::WaitBaked => {
            if let Ok(probe) = baked.single() {
                if let Some(bevy::asset::LoadState::Failed(e)) =
                    assets.get_load_state(&probe.voxels)
                {
                    error!("loading the baked volume failed: {e}");
                    exit.write(AppExit::error());
                } else if assets.is_loaded_with_dependencies(&probe.voxels) && since >= 30 {
                    shoot(&mut commands, &check, "baked.png");
                    next(&mut check, Phase::ShotBaked);
                }
            }
        }
        Phase::ShotBaked => {
            if let Some(px) = taken {
                let want = check.results[1].0;
                check.results.push((want, px.x));
                next(&mut check, Phase::Done);
                let ok = report(&check.results, &stats);
                exit.write(if ok {
                    AppExit::Success
                } else {
                    AppExit::error()
                });
            }
        }
        _ => {}
    }
}

fn next(check: &mut Check, phase: Phase) {
    check.phase = phase;
    check.phase_start = check.frame;
}

/// Prints the results; whether each is within 3 % and the sun move changed the light.
fn report(results: &[(f32, f32)], stats: &LiveStats) -> bool {
    let mut ok = results.len() == 3;
    for ((want, got), name) in results
        .iter()
        .zip(["high sun", "low sun", "low sun, baked"])
    {
        let err = got / want - 1.0;
        let pass = err.abs() <= 0.03;
        ok &= pass;
        println!(
            "{name}: centre pixel {got:.4} (linear), the volume's +Z face {want:.4}: {:+.2} % {}",
            err * 100.0,
            if pass { "ok" } else { "OVER 3 %" }
        );
    }
    if let [(a, _), (b, _), _] = results {
        let moved = (a / b - 1.0).abs();
        let pass = moved > 0.06;
        ok &= pass;
        println!(
            "the sun move changed the face by {:+.1} % {}",
            (b / a - 1.0) * 100.0,
            if pass {
                "ok"
            } else {
                "(too little to tell the textures apart)"
            }
        );
    }
    println!("plugin: {stats:?}");
    println!("{}", if ok { "PASS" } else { "FAIL" });
    ok
}
