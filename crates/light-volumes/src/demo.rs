//! A small town of the shipped CC0 Kenney models for the example, benchmark and tests:
//! two buildings and trees, scaled ×8 (the tiles are 1 m), on a 40 m ground square.

use std::path::Path;

use lightgrid_core::glam::{Vec2, Vec3, Vec4};
use lightgrid_material_voxelizer::model::{Model, ModelError, SurfaceMaterial, Triangle};

/// Appends `part` to `model`, scaled by `scale` and moved by `offset`
/// ([`Model::append`]).
pub fn append(model: &mut Model, part: &Model, scale: f32, offset: Vec3) {
    model.append(
        part,
        lightgrid_core::glam::Mat4::from_scale_rotation_translation(
            Vec3::splat(scale),
            Default::default(),
            offset,
        ),
    );
}

/// The town: `assets` is the shipped `assets` folder.
pub fn town(assets: &Path) -> Result<Model, ModelError> {
    let dir = assets.join("kenney-city-builder");
    let mut model = Model::default();
    // Ground: two triangles, grey-green.
    let g = |x: f32, z: f32| Vec3::new(x, 0.0, z);
    model.materials.push(SurfaceMaterial {
        base_colour: Vec4::new(0.35, 0.38, 0.3, 1.0),
        ..Default::default()
    });
    for tri in [
        [g(-20.0, -20.0), g(20.0, 20.0), g(20.0, -20.0)],
        [g(-20.0, -20.0), g(-20.0, 20.0), g(20.0, 20.0)],
    ] {
        model.triangles.push(Triangle {
            positions: tri,
            uvs: [Vec2::ZERO; 3],
            material: 0,
            part: 0,
        });
    }
    for (file, offset) in [
        ("building-small-a.glb", Vec3::new(-6.0, 0.0, -4.0)),
        ("building-small-c.glb", Vec3::new(6.0, 0.0, -4.0)),
        ("grass-trees.glb", Vec3::new(-6.0, 0.0, 6.0)),
        ("grass-trees-tall.glb", Vec3::new(6.0, 0.0, 6.0)),
    ] {
        let part = Model::load_gltf(dir.join(file))?;
        append(&mut model, &part, 8.0, offset);
    }
    model.validate()?;
    Ok(model)
}

/// The repository's `assets/` folder (CC0 Kenney models, the Jacksboro DEM; see its
/// `LICENSES.md`). It exists in a clone of the workspace, not in a published crate.
pub fn assets_dir() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets")
}
