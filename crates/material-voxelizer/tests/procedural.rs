//! Procedural assets: deterministic, written and read back as glTF, voxelized sensibly.

use lightgrid_core::glam::Vec3;
use lightgrid_material_voxelizer::model::{AlphaMode, Model};
use lightgrid_material_voxelizer::procedural::{TreeParams, bush, rock, tree, write_glb};
use lightgrid_material_voxelizer::voxelize::{VoxelizeParams, voxelize};

#[test]
fn same_seed_same_tree_other_seed_other_tree() {
    let a = tree(&TreeParams::young(1)).unwrap();
    assert_eq!(a, tree(&TreeParams::young(1)).unwrap());
    assert_ne!(a, tree(&TreeParams::young(2)).unwrap());
    assert!(
        tree(&TreeParams {
            height: f32::NAN,
            ..TreeParams::young(1)
        })
        .unwrap_err()
        .to_string()
        .contains("height")
    );
}

#[test]
fn glb_round_trip_keeps_geometry_materials_and_leaf_mask() {
    let dir = std::env::temp_dir().join(format!("procedural-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for (name, model) in [
        ("tree", tree(&TreeParams::young(5)).unwrap()),
        ("bush", bush(3, 0.8).unwrap()),
        ("rock", rock(9, 1.0).unwrap()),
    ] {
        let path = dir.join(format!("{name}.glb"));
        write_glb(&model, &path).unwrap();
        let back = Model::load_gltf(&path).unwrap();
        assert_eq!(back.triangles.len(), model.triangles.len(), "{name}");
        // Positions survive exactly (f32 in, f32 out), grouped by material.
        let mut a: Vec<[u32; 9]> = model.triangles.iter().map(key).collect();
        let mut b: Vec<[u32; 9]> = back.triangles.iter().map(key).collect();
        a.sort_unstable();
        b.sort_unstable();
        assert_eq!(a, b, "{name}");
        assert_eq!(back.textures.len(), model.textures.len());
        if name != "rock" {
            assert_eq!(back.materials[1].alpha, AlphaMode::Mask(0.5));
            // The leaf texture's alpha (0 or 1) survives 8-bit sRGB storage exactly.
            let (t0, t1) = (&model.textures[0], &back.textures[0]);
            assert!(t0.texels.iter().zip(&t1.texels).all(|(x, y)| x.w == y.w));
            assert!(
                t0.texels
                    .iter()
                    .zip(&t1.texels)
                    .all(|(x, y)| (x.truncate() - y.truncate()).abs().max_element() < 0.01)
            );
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

fn key(t: &lightgrid_material_voxelizer::model::Triangle) -> [u32; 9] {
    let p = t.positions;
    [
        p[0].x.to_bits(),
        p[0].y.to_bits(),
        p[0].z.to_bits(),
        p[1].x.to_bits(),
        p[1].y.to_bits(),
        p[1].z.to_bits(),
        p[2].x.to_bits(),
        p[2].y.to_bits(),
        p[2].z.to_bits(),
    ]
}

#[test]
fn voxelized_tree_has_a_solid_trunk_and_a_leaky_crown() {
    let params = TreeParams::broadleaf(11);
    let model = tree(&params).unwrap();
    let (g, stats) = voxelize(&model, &VoxelizeParams::standard(0.5), &|_, _| {}).unwrap();
    assert!(stats.closed_triangles > 0);
    // The trunk's axis at 1 m up: solid bark.
    let c = g
        .desc()
        .to_grid(Vec3::new(0.0, 1.0, 0.0))
        .round()
        .as_uvec3();
    let trunk = g.get(c).unwrap();
    assert!(trunk.pass < 0.5, "{trunk:?}");
    assert!(
        trunk.reflectance.x > trunk.reflectance.z,
        "bark is brown: {trunk:?}"
    );
    // Crown cells let some light through and are green.
    let crown: Vec<_> = g
        .data()
        .iter()
        .filter(|m| m.pass < 1.0 && m.reflectance.y > m.reflectance.x)
        .collect();
    assert!(crown.len() > 20);
    let mean_pass = crown.iter().map(|m| m.pass).sum::<f32>() / crown.len() as f32;
    assert!(mean_pass > 0.3 && mean_pass < 0.99, "{mean_pass}");
    // The leaf texture's holes matter: the same cards fully opaque block more.
    let mut opaque = model.clone();
    opaque.materials[1].alpha = AlphaMode::Opaque;
    let (go, _) = voxelize(&opaque, &VoxelizeParams::standard(0.5), &|_, _| {}).unwrap();
    let sum = |g: &lightgrid_core::MaterialGrid| g.data().iter().map(|m| 1.0 - m.pass).sum::<f32>();
    assert!(sum(&go) > sum(&g) * 1.2, "{} vs {}", sum(&go), sum(&g));
}

#[test]
fn rock_is_closed_and_solid() {
    let model = rock(4, 1.0).unwrap();
    let (g, stats) = voxelize(&model, &VoxelizeParams::preview(0.25), &|_, _| {}).unwrap();
    assert_eq!(stats.closed_triangles as usize, model.triangles.len());
    let centre = g
        .desc()
        .to_grid((model.bounds().unwrap().0 + model.bounds().unwrap().1) * 0.5)
        .round()
        .as_uvec3();
    assert_eq!(g.get(centre).unwrap().pass, 0.0);
}
