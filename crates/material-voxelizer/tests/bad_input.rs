//! Hand-made bad inputs for every reader of the voxelizer: malformed GLB headers, node
//! cycles and explosive node graphs, references outside the model's folder, buffer views
//! and accessors out of range, huge image headers, FIFOs and devices, wrapping sizes.
//! Each must be a typed error naming the file, quickly, without a panic.

use std::path::{Path, PathBuf};

use lightgrid_core::glam::{Quat, Vec2, Vec3};
use lightgrid_material_voxelizer::compose::{AreaComposer, ComposeParams, Heightmap, Instance};
use lightgrid_material_voxelizer::model::Model;
use lightgrid_material_voxelizer::voxelize::{VoxelizeParams, voxelize};
use serde_json::json;

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("voxelizer-bad-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// One triangle: positions (36 bytes) then UVs (24 bytes).
fn triangle_bin() -> Vec<u8> {
    [0f32, 0., 0., 1., 0., 0., 0., 1., 0., 0., 0., 1., 0., 0., 1.]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect()
}

/// A one-triangle document whose buffer is `uri` (or an embedded data URI).
fn triangle_doc(uri: Option<&str>) -> serde_json::Value {
    let uri = uri.map(str::to_string).unwrap_or_else(|| {
        format!(
            "data:application/octet-stream;base64,{}",
            base64::encode(triangle_bin())
        )
    });
    json!({
        "asset": {"version": "2.0"},
        "scene": 0, "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}}]}],
        "buffers": [{"byteLength": 60, "uri": uri}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 36},
            {"buffer": 0, "byteOffset": 36, "byteLength": 24}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
             "min": [0, 0, 0], "max": [1, 1, 0]},
            {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC2"}
        ]
    })
}

fn load(doc: &serde_json::Value) -> Result<Model, String> {
    Model::from_gltf_slice(&serde_json::to_vec(doc).unwrap(), "test.gltf")
        .map_err(|e| e.to_string())
}

fn glb(json: &[u8], bin: &[u8]) -> Vec<u8> {
    let mut j = json.to_vec();
    while !j.len().is_multiple_of(4) {
        j.push(b' ');
    }
    let mut out = b"glTF".to_vec();
    out.extend(2u32.to_le_bytes());
    out.extend(0u32.to_le_bytes());
    out.extend((j.len() as u32).to_le_bytes());
    out.extend(0x4E4F_534Au32.to_le_bytes());
    out.extend(&j);
    out.extend((bin.len() as u32).to_le_bytes());
    out.extend(0x004E_4942u32.to_le_bytes());
    out.extend(bin);
    let n = out.len() as u32;
    out[8..12].copy_from_slice(&n.to_le_bytes());
    out
}

#[test]
fn the_control_documents_load() {
    // Positive controls: the same documents without the fault load.
    assert_eq!(load(&triangle_doc(None)).unwrap().triangles.len(), 1);
    let mut d = triangle_doc(None);
    d["buffers"][0] = json!({"byteLength": 60});
    let g = glb(&serde_json::to_vec(&d).unwrap(), &triangle_bin());
    assert!(Model::from_gltf_slice(&g, "t.glb").is_ok());
}

#[test]
fn malformed_glb_headers_are_errors() {
    let mut d = triangle_doc(None);
    d["buffers"][0] = json!({"byteLength": 60});
    let good = glb(&serde_json::to_vec(&d).unwrap(), &triangle_bin());
    let with = |f: &dyn Fn(&mut Vec<u8>)| {
        let mut b = good.clone();
        f(&mut b);
        Model::from_gltf_slice(&b, "bad.glb")
            .unwrap_err()
            .to_string()
    };
    // Total length below the header size (the gltf crate subtracts and underflows).
    assert!(with(&|b| b[8..12].copy_from_slice(&4u32.to_le_bytes())).contains("bad.glb"));
    // Total length of 4 GiB (the gltf crate's reader allocates it).
    assert!(with(&|b| b[8..12].copy_from_slice(&u32::MAX.to_le_bytes())).contains("header says"));
    // JSON and BIN chunk lengths past the end.
    assert!(with(&|b| b[12..16].copy_from_slice(&u32::MAX.to_le_bytes())).contains("past the end"));
    let bin_at = good.len() - 60 - 8;
    assert!(
        with(&|b| b[bin_at..bin_at + 4].copy_from_slice(&1_000_000u32.to_le_bytes()))
            .contains("past the end")
    );
    // Truncated anywhere.
    for cut in (0..good.len()).step_by(7) {
        assert!(
            Model::from_gltf_slice(&good[..cut], "cut.glb").is_err(),
            "cut at {cut}"
        );
    }
}

#[test]
fn node_cycles_and_explosive_graphs_are_errors() {
    let mut d = triangle_doc(None);
    d["nodes"] = json!([{"mesh": 0, "children": [1]}, {"children": [0]}]);
    let e = load(&d).unwrap_err();
    assert!(e.contains("test.gltf") && e.contains("(a cycle)"), "{e}");
    // Self-child.
    d["nodes"] = json!([{"mesh": 0, "children": [0]}]);
    let e = load(&d).unwrap_err();
    assert!(e.contains("node 0 is its own descendant"), "{e}");
    // 24 levels, each node's two children the same next node, a mesh at the leaf:
    // 2^24 copies of the mesh.
    let mut nodes: Vec<serde_json::Value> = (0..24)
        .map(|i| json!({"children": [i + 1, i + 1]}))
        .collect();
    nodes.push(json!({"mesh": 0}));
    d["nodes"] = json!(nodes);
    let e = load(&d).unwrap_err();
    assert!(e.contains("more than"), "{e}");
}

#[test]
fn references_outside_the_folder_and_bad_uris_are_refused() {
    let dir = scratch("uris");
    let inner = dir.join("model");
    std::fs::create_dir_all(&inner).unwrap();
    std::fs::write(dir.join("secret.bin"), triangle_bin()).unwrap();
    std::fs::write(inner.join("tri.bin"), triangle_bin()).unwrap();
    let write = |uri: &str| -> PathBuf {
        let p = inner.join("m.gltf");
        std::fs::write(&p, serde_json::to_vec(&triangle_doc(Some(uri))).unwrap()).unwrap();
        p
    };
    // Control: a relative file inside the folder, also percent-encoded.
    assert!(Model::load_gltf(write("tri.bin")).is_ok());
    assert!(Model::load_gltf(write("tr%69.bin")).is_ok());
    let secret = dir.join("secret.bin");
    for uri in [
        "../secret.bin".to_string(),
        format!("file://{}", secret.display()),
        format!("file:{}", secret.display()),
        secret.display().to_string(),
        "%FF.bin".to_string(),
        "%2e%2e/secret.bin".to_string(),
        "http://example.invalid/tri.bin".to_string(),
    ] {
        let e = Model::load_gltf(write(&uri)).unwrap_err().to_string();
        assert!(e.contains("m.gltf") && e.contains("buffer 0"), "{uri}: {e}");
    }
    // From memory, no file may be referenced at all.
    let e = load(&triangle_doc(Some("tri.bin"))).unwrap_err();
    assert!(e.contains("from memory"), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn views_and_accessors_out_of_range_are_errors() {
    let base = triangle_doc(None);
    type Edit = Box<dyn Fn(&mut serde_json::Value)>;
    let cases: Vec<(&str, Edit)> = vec![
        (
            "view past its buffer",
            Box::new(|d| d["bufferViews"][1]["byteLength"] = json!(1 << 30)),
        ),
        (
            "accessor offset",
            Box::new(|d| d["accessors"][0]["byteOffset"] = json!(32)),
        ),
        (
            "accessor count",
            Box::new(|d| d["accessors"][0]["count"] = json!(u32::MAX)),
        ),
        (
            "accessor stride",
            Box::new(|d| d["bufferViews"][0]["byteStride"] = json!(252)),
        ),
        (
            "position type",
            Box::new(|d| d["accessors"][0]["type"] = json!("VEC2")),
        ),
        (
            "position component",
            Box::new(|d| d["accessors"][0]["componentType"] = json!(5121)),
        ),
        (
            "sparse",
            Box::new(|d| {
                d["accessors"][0]["sparse"] = json!({"count": 1,
            "indices": {"bufferView": 0, "componentType": 5125},
            "values": {"bufferView": 0}})
            }),
        ),
        (
            "buffer shorter than declared",
            Box::new(|d| d["buffers"][0]["byteLength"] = json!(600)),
        ),
        (
            "image view out of range",
            Box::new(|d| {
                d["images"] = json!([{"bufferView": 1, "mimeType": "image/png"}]);
                d["bufferViews"][1]["byteLength"] = json!(1000);
            }),
        ),
    ];
    for (what, f) in cases {
        let mut d = base.clone();
        f(&mut d);
        assert!(load(&d).is_err(), "{what} accepted");
    }
}

/// A PNG whose header claims `w × h` pixels (with an empty IDAT).
fn png_header(w: u32, h: u32) -> Vec<u8> {
    let mut b = vec![0x89, b'P', b'N', b'G', 0x0D, 0x0A, 0x1A, 0x0A];
    let mut ihdr = b"IHDR".to_vec();
    ihdr.extend(w.to_be_bytes());
    ihdr.extend(h.to_be_bytes());
    ihdr.extend([16, 0, 0, 0, 0]); // 16-bit greyscale
    b.extend(13u32.to_be_bytes());
    b.extend(&ihdr);
    b.extend(crc32fast::hash(&ihdr).to_be_bytes());
    for name in [b"IDAT", b"IEND"] {
        b.extend(0u32.to_be_bytes());
        b.extend(name);
        b.extend(crc32fast::hash(name).to_be_bytes());
    }
    b
}

#[test]
fn huge_image_headers_are_refused_before_decoding() {
    let e = lightgrid_material_voxelizer::compose::decode_limited(
        &png_header(100_000, 100_000),
        1 << 16,
        8,
    )
    .unwrap_err();
    assert!(e.contains("100000 x 100000"), "{e}");
    let e = lightgrid_material_voxelizer::gltf_read::decode_texture(&png_header(40_000, 2))
        .unwrap_err();
    assert!(e.contains("40000 x 2"), "{e}");
    // Within the sides but over the memory limit: 60000² × 8 bytes = 27 GiB.
    lightgrid_core::limits::set_memory_limit(1 << 30);
    let e = lightgrid_material_voxelizer::compose::decode_limited(
        &png_header(60_000, 60_000),
        1 << 16,
        8,
    )
    .unwrap_err();
    lightgrid_core::limits::set_memory_limit(0);
    assert!(e.contains("memory"), "{e}");
    // Heightmaps from files: devices, FIFOs and folders are errors, not hangs.
    let dir = scratch("png");
    let p = dir.join("huge.png");
    std::fs::write(&p, png_header(100_000, 100_000)).unwrap();
    let mut bad: Vec<PathBuf> = vec![p, dir.clone()];
    if Path::new("/dev/zero").exists() {
        bad.push("/dev/zero".into());
    }
    let fifo = dir.join("fifo.png");
    if std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .is_ok_and(|s| s.success())
    {
        bad.push(fifo);
    }
    for p in bad {
        let e = lightgrid_material_voxelizer::compose::load_heightmap_png(
            &p,
            Vec2::ZERO,
            1.0,
            1.0,
            0.0,
        )
        .unwrap_err()
        .to_string();
        assert!(!e.is_empty(), "{}", p.display());
    }
    // Sizes whose product would wrap in u32.
    assert!(Heightmap::new(Vec2::ZERO, 1.0, u32::MAX, u32::MAX, vec![]).is_err());
    assert!(Heightmap::from_fn(Vec2::ZERO, 1.0, 1 << 20, 1 << 20, |_, _| 0.0).is_err());
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn padding_near_two_to_the_31_is_an_error_not_a_wrap() {
    let m = load(&triangle_doc(None)).unwrap();
    for padding in [1 << 20, (1 << 31) - 1, u32::MAX] {
        let mut p = VoxelizeParams::preview(0.1);
        p.padding = padding;
        let e = voxelize(&m, &p, &|_, _| {}).unwrap_err().to_string();
        assert!(e.contains("max_cells"), "{padding}: {e}");
    }
}

#[test]
fn huge_instances_do_not_fill_the_tile_table() {
    let rock = lightgrid_material_voxelizer::procedural::rock(2, 1.0).unwrap();
    let (grid, _) = voxelize(&rock, &VoxelizeParams::preview(0.25), &|_, _| {}).unwrap();
    // Scale 1e6 covers about 10^10 tiles of 16 m: it must go to the unbinned list.
    let inst = |scale: f32| Instance {
        model: 0,
        position: Vec3::ZERO,
        rotation: Quat::IDENTITY,
        scale,
    };
    let c = AreaComposer::new(
        vec![grid.clone()],
        &[inst(1e6), inst(1.0)],
        None,
        ComposeParams::default(),
    )
    .unwrap();
    let d = lightgrid_core::GridDesc::new(
        Vec3::splat(-2.0),
        1.0,
        lightgrid_core::glam::UVec3::splat(4),
    )
    .unwrap();
    let (m, stats) = c.compose(&d).unwrap();
    assert_eq!(stats.overlapping, 2);
    assert!(m.data().iter().all(|x| x.pass.is_finite()));
    // Tiny tiles: every instance covers more tiles than the cap, so none is binned, and
    // the composed grid is the same as with the default tiles.
    let p = ComposeParams {
        tile: 1e-3,
        ..Default::default()
    };
    let many: Vec<Instance> = (0..20)
        .map(|i| Instance {
            position: Vec3::X * i as f32 * 0.7,
            ..inst(1.0)
        })
        .collect();
    let tiny = AreaComposer::new(vec![grid.clone()], &many, None, p).unwrap();
    let normal = AreaComposer::new(vec![grid], &many, None, ComposeParams::default()).unwrap();
    let d = lightgrid_core::GridDesc::new(
        Vec3::new(-2.0, -2.0, -2.0),
        0.5,
        lightgrid_core::glam::UVec3::new(24, 8, 8),
    )
    .unwrap();
    let (a, sa) = tiny.compose(&d).unwrap();
    let (b, sb) = normal.compose(&d).unwrap();
    assert_eq!(sa.overlapping, sb.overlapping);
    assert!(sa.overlapping > 1);
    assert_eq!(a, b);
}
