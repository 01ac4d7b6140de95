//! `.gltf` with external and embedded buffers, node transforms, unsupported features.

use lightgrid_material_voxelizer::model::Model;
use lightgrid_material_voxelizer::procedural::{rock, write_glb};

/// Splits a GLB into its JSON and binary chunks.
fn split_glb(bytes: &[u8]) -> (serde_json::Value, Vec<u8>) {
    let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let json: serde_json::Value = serde_json::from_slice(&bytes[20..20 + json_len]).unwrap();
    let bin_start = 20 + json_len + 8;
    (json, bytes[bin_start..].to_vec())
}

#[test]
fn gltf_with_external_and_embedded_buffers_and_node_transforms() {
    let dir = std::env::temp_dir().join(format!("gltf-forms-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let model = rock(1, 1.0).unwrap();
    write_glb(&model, dir.join("rock.glb")).unwrap();
    let (mut json, bin) = split_glb(&std::fs::read(dir.join("rock.glb")).unwrap());
    // External buffer, and a node translated by (1, 2, 3) under a parent scaled by 2.
    std::fs::write(dir.join("rock.bin"), &bin).unwrap();
    json["buffers"][0]["uri"] = "rock.bin".into();
    json["nodes"] = serde_json::json!([{"children": [1], "scale": [2.0, 2.0, 2.0]}, {"mesh": 0, "translation": [1.0, 2.0, 3.0]}]);
    std::fs::write(
        dir.join("external.gltf"),
        serde_json::to_vec(&json).unwrap(),
    )
    .unwrap();
    let ext = Model::load_gltf(dir.join("external.gltf")).unwrap();
    assert_eq!(ext.triangles.len(), model.triangles.len());
    let want =
        (model.triangles[0].positions[0] + lightgrid_core::glam::Vec3::new(1.0, 2.0, 3.0)) * 2.0;
    assert!((ext.triangles[0].positions[0] - want).length() < 1e-5);
    // Embedded (data URI) buffer.
    json["buffers"][0]["uri"] = format!(
        "data:application/octet-stream;base64,{}",
        base64::encode(&bin)
    )
    .into();
    std::fs::write(
        dir.join("embedded.gltf"),
        serde_json::to_vec(&json).unwrap(),
    )
    .unwrap();
    assert_eq!(Model::load_gltf(dir.join("embedded.gltf")).unwrap(), ext);
    // Lines are not triangles: a clear message, not a panic.
    json["meshes"][0]["primitives"][0]["mode"] = 1.into();
    std::fs::write(dir.join("lines.gltf"), serde_json::to_vec(&json).unwrap()).unwrap();
    let e = Model::load_gltf(dir.join("lines.gltf"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("unsupported") && e.contains("lines.gltf"), "{e}");
    // Not a glTF at all.
    std::fs::write(dir.join("junk.glb"), b"junk").unwrap();
    assert!(Model::load_gltf(dir.join("junk.glb")).is_err());
    std::fs::remove_dir_all(&dir).unwrap();
}
