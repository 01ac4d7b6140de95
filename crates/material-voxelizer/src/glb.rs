//! Binary glTF (`.glb`) output: a [`Model`] written so that [`Model::load_gltf`] (and any
//! glTF viewer) reads it back, for the procedural models the demo and the tests ship.

use std::path::Path;

use gltf::json;
use json::validation::{Checked::Valid, USize64};
use lightgrid_core::GridError;
use lightgrid_core::glam::Vec3;

use crate::model::{AlphaMode, Model, Triangle};

/// Writes `model` as a binary glTF (`.glb`): one primitive per material (non-indexed
/// triangles with POSITION and TEXCOORD_0), base colour factors, textures embedded as
/// PNG (sRGB), alpha modes. Written atomically.
pub fn write_glb(model: &Model, path: impl AsRef<Path>) -> Result<(), GridError> {
    let path = path.as_ref();
    model
        .validate()
        .map_err(|e| GridError::invalid("model", e.to_string(), "is invalid"))?;
    let mut glb = Glb::new();
    let primitives = glb.primitives(model);
    glb.textures(model, path)?;
    glb.align();
    glb.materials(model);
    glb.finish(primitives, path)
}

/// A glTF document being built and its one binary buffer.
struct Glb {
    root: json::Root,
    bin: Vec<u8>,
}

impl Glb {
    fn new() -> Self {
        let root = json::Root {
            asset: json::Asset {
                copyright: None,
                extensions: None,
                extras: Default::default(),
                generator: Some("lightgrid material-voxelizer".into()),
                min_version: None,
                version: "2.0".into(),
            },
            ..Default::default()
        };
        Self {
            root,
            bin: Vec::new(),
        }
    }

    /// Pads the buffer to a multiple of 4 bytes.
    fn align(&mut self) {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
    }

    /// A view of `len` bytes at `offset` in the one buffer.
    fn view(&mut self, offset: usize, len: usize) -> json::Index<json::buffer::View> {
        self.root.push(json::buffer::View {
            buffer: json::Index::new(0),
            byte_length: USize64(len as u64),
            byte_offset: Some(USize64(offset as u64)),
            byte_stride: None,
            name: None,
            target: None,
            extensions: None,
            extras: Default::default(),
        })
    }

    /// An accessor of `count` floats vectors of `type_` in `view` (with their bounds).
    fn accessor(
        &mut self,
        view: json::Index<json::buffer::View>,
        count: usize,
        type_: json::accessor::Type,
        bounds: Option<(Vec3, Vec3)>,
    ) -> json::Index<json::Accessor> {
        self.root.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: None,
            count: USize64(count as u64),
            component_type: Valid(json::accessor::GenericComponentType(
                json::accessor::ComponentType::F32,
            )),
            extensions: None,
            extras: Default::default(),
            type_: Valid(type_),
            min: bounds.map(|b| json::Value::from(b.0.to_array().to_vec())),
            max: bounds.map(|b| json::Value::from(b.1.to_array().to_vec())),
            name: None,
            normalized: false,
            sparse: None,
        })
    }

    /// One primitive per material with triangles: positions (with bounds) and UVs.
    fn primitives(&mut self, model: &Model) -> Vec<json::mesh::Primitive> {
        let mut primitives = Vec::new();
        for (mi, _) in model.materials.iter().enumerate() {
            let tris: Vec<&Triangle> = model
                .triangles
                .iter()
                .filter(|t| t.material as usize == mi)
                .collect();
            if tris.is_empty() {
                continue;
            }
            let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
            self.align();
            let pos_off = self.bin.len();
            for t in &tris {
                for p in t.positions {
                    lo = lo.min(p);
                    hi = hi.max(p);
                    for x in p.to_array() {
                        self.bin.extend_from_slice(&x.to_le_bytes());
                    }
                }
            }
            let uv_off = self.bin.len();
            for t in &tris {
                for uv in t.uvs {
                    for x in uv.to_array() {
                        self.bin.extend_from_slice(&x.to_le_bytes());
                    }
                }
            }
            let n = tris.len() * 3;
            let v = self.view(pos_off, n * 12);
            let positions = self.accessor(v, n, json::accessor::Type::Vec3, Some((lo, hi)));
            let v = self.view(uv_off, n * 8);
            let uvs = self.accessor(v, n, json::accessor::Type::Vec2, None);
            primitives.push(json::mesh::Primitive {
                attributes: [
                    (Valid(json::mesh::Semantic::Positions), positions),
                    (Valid(json::mesh::Semantic::TexCoords(0)), uvs),
                ]
                .into(),
                extensions: None,
                extras: Default::default(),
                indices: None,
                material: Some(json::Index::new(mi as u32)),
                mode: Valid(json::mesh::Mode::Triangles),
                targets: None,
            });
        }
        primitives
    }

    /// Every texture as an embedded PNG (sRGB colour, linear alpha), with one repeating
    /// sampler.
    fn textures(&mut self, model: &Model, path: &Path) -> Result<(), GridError> {
        for t in &model.textures {
            let mut rgba = Vec::with_capacity(t.texels.len() * 4);
            for c in &t.texels {
                rgba.extend([
                    lightgrid_core::pack::linear_to_srgb8(c.x),
                    lightgrid_core::pack::linear_to_srgb8(c.y),
                    lightgrid_core::pack::linear_to_srgb8(c.z),
                    (c.w.clamp(0.0, 1.0) * 255.0 + 0.5) as u8,
                ]);
            }
            let mut png = Vec::new();
            image::ImageEncoder::write_image(
                image::codecs::png::PngEncoder::new(&mut png),
                &rgba,
                t.width,
                t.height,
                image::ExtendedColorType::Rgba8,
            )
            .map_err(|e| GridError::Io {
                path: path.to_path_buf(),
                source: std::io::Error::other(e),
            })?;
            self.align();
            let v = self.view(self.bin.len(), png.len());
            self.bin.extend_from_slice(&png);
            let source = self.root.push(json::Image {
                buffer_view: Some(v),
                mime_type: Some(json::image::MimeType("image/png".into())),
                name: None,
                uri: None,
                extensions: None,
                extras: Default::default(),
            });
            if self.root.samplers.is_empty() {
                self.root.push(json::texture::Sampler {
                    wrap_s: Valid(json::texture::WrappingMode::Repeat),
                    wrap_t: Valid(json::texture::WrappingMode::Repeat),
                    ..Default::default()
                });
            }
            self.root.push(json::Texture {
                name: None,
                sampler: Some(json::Index::new(0)),
                source,
                extensions: None,
                extras: Default::default(),
            });
        }
        Ok(())
    }

    /// The materials: base colour (factor and texture), alpha mode, double sided,
    /// rough and not metallic.
    fn materials(&mut self, model: &Model) {
        for m in &model.materials {
            let (alpha_mode, alpha_cutoff) = match m.alpha {
                AlphaMode::Opaque => (json::material::AlphaMode::Opaque, None),
                AlphaMode::Mask(c) => (
                    json::material::AlphaMode::Mask,
                    Some(json::material::AlphaCutoff(c)),
                ),
                AlphaMode::Blend => (json::material::AlphaMode::Blend, None),
            };
            self.root.push(json::Material {
                alpha_cutoff,
                alpha_mode: Valid(alpha_mode),
                double_sided: true,
                pbr_metallic_roughness: json::material::PbrMetallicRoughness {
                    base_color_factor: json::material::PbrBaseColorFactor(m.base_colour.to_array()),
                    base_color_texture: m.texture.map(|t| json::texture::Info {
                        index: json::Index::new(t as u32),
                        tex_coord: 0,
                        extensions: None,
                        extras: Default::default(),
                    }),
                    metallic_factor: json::material::StrengthFactor(0.0),
                    roughness_factor: json::material::StrengthFactor(1.0),
                    ..Default::default()
                },
                ..Default::default()
            });
        }
    }

    /// The mesh of `primitives` in one node of one scene, the buffer, and the file: the
    /// container (header, JSON chunk padded with spaces, BIN chunk) by the gltf crate.
    fn finish(
        mut self,
        primitives: Vec<json::mesh::Primitive>,
        path: &Path,
    ) -> Result<(), GridError> {
        let root = &mut self.root;
        let mesh = root.push(json::Mesh {
            extensions: None,
            extras: Default::default(),
            name: None,
            primitives,
            weights: None,
        });
        let node = root.push(json::Node {
            mesh: Some(mesh),
            ..Default::default()
        });
        let scene = root.push(json::Scene {
            extensions: None,
            extras: Default::default(),
            name: None,
            nodes: vec![node],
        });
        root.scene = Some(scene);
        root.push(json::Buffer {
            byte_length: USize64(self.bin.len() as u64),
            name: None,
            uri: None,
            extensions: None,
            extras: Default::default(),
        });
        let io = |e: &dyn std::fmt::Display| GridError::Io {
            path: path.to_path_buf(),
            source: std::io::Error::other(e.to_string()),
        };
        let json = json::serialize::to_vec(&self.root).map_err(|e| io(&e))?;
        let out = gltf::binary::Glb {
            header: gltf::binary::Header {
                magic: *b"glTF",
                version: 2,
                length: 0, // to_vec computes it
            },
            json: json.into(),
            bin: Some(self.bin.into()),
        }
        .to_vec()
        .map_err(|e| io(&e))?;
        lightgrid_core::file::write_atomic(path, &out)
    }
}
