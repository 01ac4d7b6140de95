//! Reading glTF safely: every size, offset and reference is checked here before the
//! `gltf` and `image` crates see it, so a malformed or hostile file is an error, never a
//! panic, a hang or an allocation the file's own size does not justify.
//!
//! What is checked, in order:
//!
//! 1. The file is a regular file of at most [`MAX_MODEL_BYTES`] (read once, bounded).
//! 2. A GLB header: magic, version 2, total length equal to the bytes present, the JSON
//!    chunk (and the optional BIN chunk) inside the file. Then the JSON is parsed and
//!    validated by the `gltf` crate (indices in range), with any panic of its parser
//!    turned into an error.
//! 3. Buffers and images: `data:` URIs (base64) or **relative** paths inside the model's
//!    folder (percent-decoded; absolute paths, `..` and other schemes such as `file:` are
//!    refused); each file bounded; each buffer at least its declared length; an image's
//!    buffer view inside its buffer; images decoded with width and height at most
//!    [`MAX_TEXTURE_SIDE`] and within the memory limit.
//! 4. The node graph: no node may be its own descendant (a cycle would loop forever);
//!    shared children are allowed, but the expanded tree may hold at most
//!    [`MAX_NODE_INSTANCES`] nodes and [`MAX_TRIANGLES`] triangles (checked against the
//!    memory limit before any triangle is stored).
//! 5. Each accessor read: a buffer view, element type and component type the reader
//!    expects, stride at least the element size, and `offset + stride (count - 1) + size`
//!    inside the view and the view inside its buffer (checked arithmetic).

use std::path::{Component, Path};

use lightgrid_core::glam::Vec4;

use crate::model::Texture;

/// Largest glTF/GLB file, and largest external buffer or image file, read: 1 GiB.
pub const MAX_MODEL_BYTES: u64 = 1 << 30;
/// Most node instances after expanding shared children.
pub const MAX_NODE_INSTANCES: u64 = 1_000_000;
/// Most triangles in one loaded model.
pub const MAX_TRIANGLES: u64 = 1 << 26;
/// Largest width or height of a texture.
pub const MAX_TEXTURE_SIDE: u32 = 16384;

/// A document with its buffers and decoded textures.
pub(crate) struct Loaded {
    pub doc: gltf::Document,
    pub buffers: Vec<Vec<u8>>,
    pub textures: Vec<Texture>,
}

/// Runs `f`, turning a panic inside a third-party parser into an error message.
fn guarded<T>(what: &str, f: impl FnOnce() -> Result<T, String>) -> Result<T, String> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f))
        .unwrap_or_else(|_| Err(format!("malformed {what} (its reader failed on it)")))
}

fn u32_le(b: &[u8], o: usize) -> u32 {
    u32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]])
}

/// Checks a GLB container's header and chunk table against the bytes present.
pub(crate) fn check_glb(b: &[u8]) -> Result<(), String> {
    if b.len() < 20 {
        return Err(format!(
            "GLB of {} bytes is shorter than its headers",
            b.len()
        ));
    }
    let version = u32_le(b, 4);
    if version != 2 {
        return Err(format!("GLB version {version} (only 2 is read)"));
    }
    let total = u32_le(b, 8) as u64;
    if total != b.len() as u64 {
        return Err(format!(
            "GLB header says {total} bytes, the file has {}",
            b.len()
        ));
    }
    let json_len = u32_le(b, 12) as u64;
    if u32_le(b, 16) != 0x4E4F_534A {
        return Err("GLB: the first chunk is not JSON".into());
    }
    let json_end = 20 + json_len;
    if json_end > total {
        return Err(format!(
            "GLB JSON chunk of {json_len} bytes runs past the end ({total} bytes)"
        ));
    }
    let rest = total - json_end;
    if rest > 0 {
        if rest < 8 {
            return Err(format!("GLB: {rest} stray bytes after the JSON chunk"));
        }
        let at = json_end as usize;
        let bin_len = u32_le(b, at) as u64;
        if u32_le(b, at + 4) != 0x004E_4942 {
            return Err("GLB: the second chunk is not BIN".into());
        }
        if json_end + 8 + bin_len > total {
            return Err(format!(
                "GLB BIN chunk of {bin_len} bytes runs past the end ({total} bytes)"
            ));
        }
    }
    Ok(())
}

/// Reads a buffer or image reference: a base64 `data:` URI, or a relative path inside
/// `base` (none for in-memory models).
fn read_uri(uri: &str, base: Option<&Path>) -> Result<Vec<u8>, String> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let data = rest
            .split_once(";base64,")
            .map(|(_, d)| d)
            .ok_or("data URI without ;base64,")?;
        if data.len() as u64 > MAX_MODEL_BYTES / 3 * 4 + 4 {
            return Err(format!("data URI of {} bytes is too large", data.len()));
        }
        return base64::decode(data).map_err(|e| format!("data URI: {e}"));
    }
    if uri.contains(':') {
        return Err(format!(
            "URI {:?}: only data: URIs and relative paths inside the model's folder are read",
            truncate(uri)
        ));
    }
    let base = base.ok_or_else(|| {
        format!(
            "external reference {:?} in a model read from memory",
            truncate(uri)
        )
    })?;
    let decoded = urlencoding::decode(uri)
        .map_err(|_| format!("URI {:?} is not valid percent-encoded UTF-8", truncate(uri)))?;
    let rel = Path::new(&*decoded);
    if rel.as_os_str().is_empty()
        || !rel
            .components()
            .all(|c| matches!(c, Component::Normal(_) | Component::CurDir))
    {
        return Err(format!(
            "URI {:?} must be a relative path inside the model's folder",
            truncate(uri)
        ));
    }
    lightgrid_core::limits::read_file(&base.join(rel), MAX_MODEL_BYTES).map_err(|e| e.to_string())
}

fn truncate(s: &str) -> String {
    s.chars().take(80).collect()
}

/// Parses and validates a glTF or GLB document and loads its buffers and textures.
pub(crate) fn load(bytes: &[u8], base: Option<&Path>) -> Result<Loaded, String> {
    if bytes.starts_with(b"glTF") {
        check_glb(bytes)?;
    }
    let gltf::Gltf { document, blob } = guarded("glTF", || {
        gltf::Gltf::from_slice_without_validation(bytes).map_err(|e| e.to_string())
    })?;
    // The gltf crate's validation indexes the POSITION accessor before checking that it
    // exists: check every attribute's accessor index first, then validate.
    let root = document.into_json();
    for (mi, mesh) in root.meshes.iter().enumerate() {
        for (pi, prim) in mesh.primitives.iter().enumerate() {
            if let Some(bad) = prim
                .attributes
                .values()
                .find(|a| a.value() >= root.accessors.len())
            {
                return Err(format!(
                    "mesh {mi} primitive {pi}: accessor {} does not exist",
                    bad.value()
                ));
            }
        }
    }
    let document = guarded("glTF", || {
        gltf::Document::from_json(root).map_err(|e| format!("invalid glTF: {e}"))
    })?;
    // The gltf crate unwraps these when an image's source is asked for.
    for (i, img) in document.as_json().images.iter().enumerate() {
        match (&img.buffer_view, &img.uri, &img.mime_type) {
            (Some(_), _, None) => return Err(format!("image {i}: a buffer view needs a mimeType")),
            (None, None, _) => return Err(format!("image {i}: neither a uri nor a buffer view")),
            _ => {}
        }
    }
    let mut blob = blob;
    let mut buffers = Vec::new();
    for b in document.buffers() {
        let data = match b.source() {
            gltf::buffer::Source::Bin => blob
                .take()
                .ok_or_else(|| format!("buffer {}: no BIN chunk", b.index()))?,
            gltf::buffer::Source::Uri(uri) => {
                read_uri(uri, base).map_err(|e| format!("buffer {}: {e}", b.index()))?
            }
        };
        if data.len() < b.length() {
            return Err(format!(
                "buffer {}: {} bytes, the document declares {}",
                b.index(),
                data.len(),
                b.length()
            ));
        }
        buffers.push(data);
    }
    let mut textures = Vec::new();
    for img in document.images() {
        let i = img.index();
        let encoded: std::borrow::Cow<[u8]> = match img.source() {
            gltf::image::Source::View { view, .. } => {
                let buf = &buffers[view.buffer().index()];
                let range = view
                    .offset()
                    .checked_add(view.length())
                    .filter(|&end| end <= buf.len())
                    .map(|end| view.offset()..end)
                    .ok_or_else(|| format!("image {i}: buffer view outside its buffer"))?;
                std::borrow::Cow::Borrowed(&buf[range])
            }
            gltf::image::Source::Uri { uri, .. } => {
                std::borrow::Cow::Owned(read_uri(uri, base).map_err(|e| format!("image {i}: {e}"))?)
            }
        };
        textures.push(decode_texture(&encoded).map_err(|e| format!("image {i}: {e}"))?);
    }
    Ok(Loaded {
        doc: document,
        buffers,
        textures,
    })
}

/// Decodes a PNG or JPEG to linear RGBA (colour from sRGB, alpha linear), refusing
/// images wider or taller than [`MAX_TEXTURE_SIDE`] or over the memory limit before
/// decoding.
pub fn decode_texture(bytes: &[u8]) -> Result<Texture, String> {
    // Decoded RGBA8, then linear RGBA f32: 20 bytes a texel.
    let img = crate::compose::decode_limited(bytes, MAX_TEXTURE_SIDE, 20)?;
    let rgba = img.into_rgba8();
    let lin = lightgrid_core::pack::srgb8_to_linear;
    Ok(Texture {
        width: rgba.width(),
        height: rgba.height(),
        texels: rgba
            .pixels()
            .map(|p| Vec4::new(lin(p[0]), lin(p[1]), lin(p[2]), p[3] as f32 / 255.0))
            .collect(),
    })
}

/// The nodes of `roots` expanded through shared children, with a cycle check and the
/// instance limit. Returns the number of instances of each node.
pub(crate) fn node_instances(doc: &gltf::Document, roots: &[usize]) -> Result<Vec<u64>, String> {
    let n = doc.nodes().len();
    let children: Vec<Vec<usize>> = doc
        .nodes()
        .map(|nd| nd.children().map(|c| c.index()).collect())
        .collect();
    // Cycle check: iterative depth-first colouring (0 new, 1 on the path, 2 done).
    let mut colour = vec![0u8; n];
    for &r in roots {
        if colour[r] != 0 {
            continue;
        }
        let mut stack = vec![(r, 0usize)];
        colour[r] = 1;
        while let Some(top) = stack.last_mut() {
            let (node, next) = *top;
            if let Some(&c) = children[node].get(next) {
                top.1 += 1;
                match colour[c] {
                    0 => {
                        colour[c] = 1;
                        stack.push((c, 0));
                    }
                    1 => return Err(format!("node {c} is its own descendant (a cycle)")),
                    _ => {}
                }
            } else {
                colour[node] = 2;
                stack.pop();
            }
        }
    }
    // Instances: how often each node appears in the expanded tree (roots once each),
    // propagated parents before children (a topological order of the DAG).
    let mut order = Vec::with_capacity(n);
    let mut indegree = vec![0usize; n];
    for cs in &children {
        for &c in cs {
            indegree[c] += 1;
        }
    }
    let mut ready: Vec<usize> = (0..n).filter(|&i| indegree[i] == 0).collect();
    while let Some(i) = ready.pop() {
        order.push(i);
        for &c in &children[i] {
            indegree[c] -= 1;
            if indegree[c] == 0 {
                ready.push(c);
            }
        }
    }
    let mut count = vec![0u64; n];
    for &r in roots {
        count[r] = count[r].saturating_add(1);
    }
    let mut total = 0u64;
    for &i in &order {
        total = total.saturating_add(count[i]);
        if total > MAX_NODE_INSTANCES {
            return Err(format!(
                "the node graph expands to more than {MAX_NODE_INSTANCES} node instances"
            ));
        }
        for &c in &children[i] {
            count[c] = count[c].saturating_add(count[i]);
        }
    }
    Ok(count)
}

/// Checks an accessor before the `gltf` reader slices it: a view, one of the `allowed`
/// element layouts, and every byte it reads inside the view and the buffer.
pub(crate) fn check_accessor(
    acc: &gltf::Accessor,
    buffers: &[Vec<u8>],
    allowed: &[(gltf::accessor::Dimensions, gltf::accessor::DataType)],
) -> Result<(), String> {
    let i = acc.index();
    if acc.sparse().is_some() {
        return Err(format!("accessor {i}: sparse accessors are not supported"));
    }
    if !allowed.contains(&(acc.dimensions(), acc.data_type())) {
        return Err(format!(
            "accessor {i}: {:?} of {:?} is not a layout this reader takes",
            acc.dimensions(),
            acc.data_type()
        ));
    }
    let view = acc
        .view()
        .ok_or_else(|| format!("accessor {i}: no buffer view"))?;
    if acc.count() == 0 {
        return Err(format!("accessor {i}: count 0"));
    }
    let size = acc.size();
    let stride = view.stride().unwrap_or(size);
    if stride < size {
        return Err(format!(
            "accessor {i}: stride {stride} is less than its element size {size}"
        ));
    }
    let end = stride
        .checked_mul(acc.count() - 1)
        .and_then(|v| v.checked_add(size))
        .and_then(|v| v.checked_add(acc.offset()));
    if end.is_none_or(|e| e > view.length()) {
        return Err(format!(
            "accessor {i}: reads past the end of its buffer view"
        ));
    }
    let buf = &buffers[view.buffer().index()];
    if view
        .offset()
        .checked_add(view.length())
        .is_none_or(|e| e > buf.len())
    {
        return Err(format!("buffer view {}: outside its buffer", view.index()));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uris_outside_the_folder_and_other_schemes_are_refused() {
        let base = Path::new("/tmp");
        for uri in [
            "file:///etc/passwd",
            "file:../x.bin",
            "/etc/passwd",
            "../x.bin",
            "a/../../x.bin",
            "http://example.invalid/x.bin",
            "%FF.bin",
            "",
        ] {
            assert!(read_uri(uri, Some(base)).is_err(), "{uri:?} accepted");
        }
        assert!(read_uri("x.bin", None).unwrap_err().contains("from memory"));
        assert_eq!(read_uri("data:;base64,AAEC", None).unwrap(), vec![0, 1, 2]);
        assert!(read_uri("data:,nobase64", None).is_err());
    }

    #[test]
    fn cycles_and_explosive_graphs_are_errors() {
        // Node 0 is its own child: the gltf crate's validation accepts it; we must not.
        let g = gltf::Gltf::from_slice(
            br#"{"asset":{"version":"2.0"},"nodes":[{"children":[0]}],"scenes":[{"nodes":[0]}]}"#,
        )
        .unwrap();
        assert!(
            node_instances(&g.document, &[0])
                .unwrap_err()
                .contains("cycle")
        );
        // 24 levels, each node's two children the same next node: 2^24 instances.
        let mut nodes = String::new();
        for i in 0..24 {
            nodes.push_str(&format!("{{\"children\":[{},{}]}},", i + 1, i + 1));
        }
        nodes.push_str("{}");
        let json = format!(
            r#"{{"asset":{{"version":"2.0"}},"nodes":[{nodes}],"scenes":[{{"nodes":[0]}}]}}"#
        );
        let g = gltf::Gltf::from_slice(json.as_bytes()).unwrap();
        assert!(
            node_instances(&g.document, &[0])
                .unwrap_err()
                .contains("more than")
        );
        // A shared child twice is fine and counted twice.
        let g = gltf::Gltf::from_slice(
            br#"{"asset":{"version":"2.0"},"nodes":[{"children":[1,1]},{}],"scenes":[{"nodes":[0]}]}"#,
        )
        .unwrap();
        assert_eq!(node_instances(&g.document, &[0]).unwrap(), vec![1, 2]);
    }
}
