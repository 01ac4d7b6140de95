//! Loads a lightgrid export into Bevy: every volume of the sidecar becomes a
//! `LightProbe` + `IrradianceVolume` with the sidecar's transform and intensity (the KTX2
//! file through Bevy's own loader: the sidecar loaded as a [`lightgrid_bevy::BakedVolumes`]
//! asset, its probes spawned by the plugin), and a grid of white spheres is lit by
//! nothing else.
//!
//! ```text
//! cargo run --release --example baked -- <sidecar.json> [screenshot.png]
//! ```
//!
//! With a screenshot path it saves one frame after the textures are loaded and exits
//! (what `run.sh --baked` does under Xvfb and lavapipe); without, it stays open.

use std::path::PathBuf;

use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::light::{GlobalAmbientLight, IrradianceVolume};
use bevy::prelude::*;
use bevy::render::view::screenshot::{Screenshot, ScreenshotCaptured};

#[derive(Resource)]
struct Job {
    /// The sidecar's file name (in the asset folder: its own).
    file: String,
    sidecar: lightgrid_export::Sidecar,
    screenshot: Option<PathBuf>,
}

fn main() {
    let mut args = std::env::args().skip(1);
    let Some(path) = args.next().map(PathBuf::from) else {
        eprintln!("usage: baked <sidecar.json> [screenshot.png]");
        std::process::exit(2);
    };
    let text = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("reading {}: {e}", path.display()));
    let sidecar: lightgrid_export::Sidecar =
        serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let dir = path
        .parent()
        .map(|p| p.canonicalize().expect("the sidecar's folder"))
        .unwrap_or_else(|| std::env::current_dir().expect("a current folder"));
    App::new()
        .insert_resource(Job {
            file: path
                .file_name()
                .expect("a file")
                .to_string_lossy()
                .into_owned(),
            sidecar,
            screenshot: args.next().map(PathBuf::from),
        })
        .insert_resource(ClearColor(Color::BLACK))
        // No light but the volumes.
        .insert_resource(GlobalAmbientLight {
            brightness: 0.0,
            ..default()
        })
        .add_plugins(
            DefaultPlugins
                .set(AssetPlugin {
                    file_path: dir.to_string_lossy().into_owned(),
                    ..default()
                })
                .set(WindowPlugin {
                    primary_window: Some(Window {
                        resolution: (640, 360).into(),
                        title: "lightgrid irradiance volumes in Bevy".into(),
                        ..default()
                    }),
                    ..default()
                }),
        )
        .add_plugins(lightgrid_bevy::LightgridPlugin::default())
        .add_systems(Startup, setup)
        .add_systems(Update, shoot)
        .run();
}

fn setup(
    mut commands: Commands,
    job: Res<Job>,
    assets: Res<AssetServer>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    // The sidecar as an asset: the plugin spawns its probes once it and its textures
    // have loaded.
    commands.spawn(lightgrid_bevy::BakedProbes(assets.load(job.file.clone())));
    let brightest = job
        .sidecar
        .volumes
        .iter()
        .map(|v| v.intensity * 16384.0)
        .fold(0.0f32, f32::max);
    // Spheres across the finest volume (the last), a quarter of its box apart.
    let last = &job
        .sidecar
        .volumes
        .last()
        .expect("at least one volume")
        .transform;
    let (centre, size) = (
        Vec3::from_array(last.translation),
        Vec3::from_array(last.scale),
    );
    let radius = size.x.min(size.z) / 16.0;
    let mesh = meshes.add(Sphere::new(radius).mesh().uv(32, 16));
    let white = materials.add(StandardMaterial {
        base_color: Color::WHITE,
        perceptual_roughness: 1.0,
        reflectance: 0.0,
        ..default()
    });
    for i in -1..=1 {
        for k in -1..=1 {
            let p = centre + Vec3::new(i as f32 * size.x / 4.0, 0.0, k as f32 * size.z / 4.0);
            commands.spawn((
                Mesh3d(mesh.clone()),
                MeshMaterial3d(white.clone()),
                Transform::from_translation(p),
            ));
        }
    }
    let eye = centre + Vec3::new(0.0, size.x.min(size.z) * 0.35, size.z * 0.6);
    commands.spawn((
        Camera3d::default(),
        Tonemapping::AcesFitted,
        // A white surface facing the brightest texel renders its value (texel x
        // intensity x albedo): map it to 1 with the exposure 1 / (1.2 * 2^ev100).
        bevy::camera::Exposure {
            ev100: (brightest.max(1e-6) / 1.2).log2(),
        },
        Transform::from_translation(eye).looking_at(centre, Vec3::Y),
    ));
}

/// What the screenshot found: nothing yet, a frame with nothing drawn (Bevy compiles
/// its pipelines in the background: on a software driver the spheres can take a
/// second to appear), or a saved frame.
#[derive(Resource, Default, Clone)]
struct Shot(std::sync::Arc<std::sync::Mutex<Option<bool>>>);

/// Saves a screenshot once every volume texture is loaded and the spheres are drawn (a
/// frame with no lit pixel is taken again later), then exits.
fn shoot(
    mut commands: Commands,
    job: Res<Job>,
    assets: Res<AssetServer>,
    volumes: Query<&IrradianceVolume>,
    mut frames: Local<u32>,
    shot: Local<Shot>,
    mut exit: MessageWriter<AppExit>,
) {
    let Some(path) = &job.screenshot else { return };
    let loaded = !volumes.is_empty()
        && volumes
            .iter()
            .all(|v| assets.is_loaded_with_dependencies(&v.voxels));
    if !loaded {
        if let Some(v) = volumes
            .iter()
            .find(|v| assets.load_state(&v.voxels).is_failed())
        {
            panic!(
                "loading {:?} failed: {:?}",
                v.voxels.path(),
                assets.load_state(&v.voxels)
            );
        }
        return;
    }
    *frames += 1;
    let seen = shot.0.lock().unwrap().take();
    match seen {
        Some(true) => {
            exit.write(AppExit::Success);
            return;
        }
        Some(false) | None if *frames % 30 != 10 => return,
        _ => {}
    }
    if *frames > 3000 {
        panic!("nothing was drawn in {} frames", *frames);
    }
    let (slot, path) = (shot.0.clone(), path.clone());
    commands.spawn(Screenshot::primary_window()).observe(
        move |captured: On<ScreenshotCaptured>| {
            let img = captured.event().image.clone();
            let drawn = img
                .data
                .as_ref()
                .is_some_and(|d| d.chunks(4).any(|p| p[..3].iter().any(|&c| c > 0)));
            if drawn {
                let rgb = img.try_into_dynamic().expect("an 8-bit frame").to_rgb8();
                rgb.save(&path).expect("writing the screenshot");
                info!("wrote {}", path.display());
            }
            *slot.lock().unwrap() = Some(drawn);
        },
    );
}
