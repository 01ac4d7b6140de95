//! Models: triangles with UVs and materials, loaded from glTF 2.0 or built in memory.

use std::path::{Path, PathBuf};

use lightgrid_core::glam::{Mat4, Vec2, Vec3, Vec4};

/// Errors of model loading.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ModelError {
    /// The glTF file could not be read or parsed.
    #[error("{}: {message}", path.display())]
    Gltf {
        /// The file.
        path: PathBuf,
        /// What the glTF reader said.
        message: String,
    },
    /// The model uses something this loader does not support.
    #[error("{}: unsupported: {what}", path.display())]
    Unsupported {
        /// The file.
        path: PathBuf,
        /// What, with where (mesh, primitive, material).
        what: String,
    },
    /// The model has no triangles.
    #[error("{}: the model has no triangles", path.display())]
    Empty {
        /// The file.
        path: PathBuf,
    },
    /// An in-memory model is invalid (the error names the field).
    #[error(transparent)]
    Invalid(#[from] lightgrid_core::GridError),
}

/// How a material's alpha is used (glTF `alphaMode`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AlphaMode {
    /// Alpha ignored: every hit blocks.
    Opaque,
    /// Hits with alpha below the cutoff let light through (leaf cards).
    Mask(f32),
    /// Alpha is the probability that a hit blocks.
    Blend,
}

/// A texture in linear RGBA, with wrapping (repeat) lookups.
#[derive(Debug, Clone, PartialEq)]
pub struct Texture {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// Linear RGBA texels, row-major from the top.
    pub texels: Vec<Vec4>,
}

impl Texture {
    /// Bilinear lookup with repeat wrapping. `uv` (0, 0) is the top-left corner. A
    /// texture without texels, or fewer than `width × height` ([`Model::validate`]
    /// refuses both), reads transparent black.
    pub fn sample(&self, uv: Vec2) -> Vec4 {
        if self.width == 0
            || self.height == 0
            || self.texels.len() as u64 != self.width as u64 * self.height as u64
        {
            return Vec4::ZERO;
        }
        let (w, h) = (self.width as f32, self.height as f32);
        let x = uv.x * w - 0.5;
        let y = uv.y * h - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let at = |xi: f32, yi: f32| {
            let xi = (xi as i64).rem_euclid(self.width as i64) as usize;
            let yi = (yi as i64).rem_euclid(self.height as i64) as usize;
            self.texels[yi * self.width as usize + xi]
        };
        let top = at(x0, y0).lerp(at(x0 + 1.0, y0), fx);
        let bottom = at(x0, y0 + 1.0).lerp(at(x0 + 1.0, y0 + 1.0), fx);
        let v = top.lerp(bottom, fy);
        if v.is_finite() { v } else { Vec4::ZERO }
    }
}

/// The UV transform of `KHR_texture_transform`: `uv' = T · R · S · uv`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UvTransform {
    /// Offset (translation).
    pub offset: Vec2,
    /// Rotation, radians (counter-clockwise in UV space).
    pub rotation: f32,
    /// Scale.
    pub scale: Vec2,
}

impl UvTransform {
    /// The identity.
    pub const IDENTITY: Self = Self {
        offset: Vec2::ZERO,
        rotation: 0.0,
        scale: Vec2::ONE,
    };
    /// Applies the transform.
    pub fn apply(&self, uv: Vec2) -> Vec2 {
        let s = uv * self.scale;
        let (sin, cos) = self.rotation.sin_cos();
        Vec2::new(cos * s.x + sin * s.y, -sin * s.x + cos * s.y) + self.offset
    }
}

/// What a surface looks like: base colour (factor × texture) and alpha use.
#[derive(Debug, Clone, PartialEq)]
pub struct SurfaceMaterial {
    /// Linear RGBA factor.
    pub base_colour: Vec4,
    /// Index into [`Model::textures`] of the base-colour texture.
    pub texture: Option<usize>,
    /// Transform of the texture's UVs.
    pub uv_transform: UvTransform,
    /// How alpha is used.
    pub alpha: AlphaMode,
}

impl Default for SurfaceMaterial {
    fn default() -> Self {
        Self {
            base_colour: Vec4::ONE,
            texture: None,
            uv_transform: UvTransform::IDENTITY,
            alpha: AlphaMode::Opaque,
        }
    }
}

/// One triangle in model space (metres, Y up), with UVs and a material.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Triangle {
    /// Vertex positions.
    pub positions: [Vec3; 3],
    /// Vertex UVs.
    pub uvs: [Vec2; 3],
    /// Index into [`Model::materials`].
    pub material: u32,
    /// Index of the mesh primitive it came from (closedness is decided per primitive).
    pub part: u32,
}

/// A triangle soup with materials: what the voxelizer needs.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Model {
    /// All triangles, node transforms applied.
    pub triangles: Vec<Triangle>,
    /// Materials.
    pub materials: Vec<SurfaceMaterial>,
    /// Textures.
    pub textures: Vec<Texture>,
}

impl Model {
    /// Appends `part` placed by `transform`: its textures and materials after this
    /// model's (indices shifted), its triangles transformed, their parts numbered after
    /// this model's.
    pub fn append(&mut self, part: &Model, transform: Mat4) {
        let (m0, t0) = (self.materials.len() as u32, self.textures.len());
        self.textures.extend(part.textures.iter().cloned());
        self.materials
            .extend(part.materials.iter().cloned().map(|mut m| {
                m.texture = m.texture.map(|t| t + t0);
                m
            }));
        let p0 = self
            .triangles
            .iter()
            .map(|t| t.part)
            .max()
            .map_or(0, |p| p + 1);
        self.triangles
            .extend(part.triangles.iter().map(|t| Triangle {
                positions: t.positions.map(|p| transform.transform_point3(p)),
                uvs: t.uvs,
                material: t.material + m0,
                part: t.part + p0,
            }));
    }

    /// Bounds of all triangles: `(min, max)`; `None` for an empty model.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let mut it = self.triangles.iter().flat_map(|t| t.positions);
        let first = it.next()?;
        Some(it.fold((first, first), |(lo, hi), p| (lo.min(p), hi.max(p))))
    }

    /// Checks every value (finite positions and UVs, material and texture indices in
    /// range, colours in [0, 1]); errors name the element.
    pub fn validate(&self) -> Result<(), ModelError> {
        use lightgrid_core::GridError;
        for (i, t) in self.triangles.iter().enumerate() {
            if t.positions.iter().any(|p| !p.is_finite()) {
                return Err(GridError::invalid(
                    format!("triangles[{i}].positions"),
                    t.positions,
                    "must be finite",
                )
                .into());
            }
            if t.uvs.iter().any(|p| !p.is_finite()) {
                return Err(GridError::invalid(
                    format!("triangles[{i}].uvs"),
                    t.uvs,
                    "must be finite",
                )
                .into());
            }
            if t.material as usize >= self.materials.len() {
                return Err(GridError::invalid(
                    format!("triangles[{i}].material"),
                    t.material,
                    "no such material",
                )
                .into());
            }
        }
        for (i, m) in self.materials.iter().enumerate() {
            if !(m.base_colour.is_finite()
                && m.base_colour.cmpge(Vec4::ZERO).all()
                && m.base_colour.cmple(Vec4::ONE).all())
            {
                return Err(GridError::invalid(
                    format!("materials[{i}].base_colour"),
                    m.base_colour,
                    "must be in [0, 1]",
                )
                .into());
            }
            if m.texture.is_some_and(|t| t >= self.textures.len()) {
                return Err(GridError::invalid(
                    format!("materials[{i}].texture"),
                    m.texture,
                    "no such texture",
                )
                .into());
            }
        }
        for (i, t) in self.textures.iter().enumerate() {
            let want = t.width as u64 * t.height as u64;
            if want == 0 || t.texels.len() as u64 != want {
                return Err(GridError::invalid(
                    format!("textures[{i}]"),
                    format!("{} x {} with {} texels", t.width, t.height, t.texels.len()),
                    "needs width, height >= 1 and width x height texels",
                )
                .into());
            }
        }
        Ok(())
    }

    /// The surface colour and alpha of triangle `tri` at barycentrics `(u, v)` (weights
    /// of vertices 1 and 2).
    pub fn surface_at(&self, tri: &Triangle, u: f32, v: f32) -> Vec4 {
        let m = &self.materials[tri.material as usize];
        let mut c = m.base_colour;
        if let Some(t) = m.texture {
            let uv = tri.uvs[0] * (1.0 - u - v) + tri.uvs[1] * u + tri.uvs[2] * v;
            c *= self.textures[t].sample(m.uv_transform.apply(uv));
        }
        c
    }

    /// Loads a `.gltf` (embedded or external buffers and images) or `.glb` file: every
    /// triangle primitive of the default scene (or the first), node transforms applied.
    ///
    /// Malformed and hostile files are errors naming the file, never panics, hangs or
    /// unbounded allocations: see [`crate::gltf_read`] for every check (bounded reads,
    /// the GLB header, relative references inside the model's folder only, node cycles,
    /// accessor ranges, texture sizes, the memory limit).
    pub fn load_gltf(path: impl AsRef<Path>) -> Result<Self, ModelError> {
        let path = path.as_ref();
        let bytes = lightgrid_core::limits::read_file(path, crate::gltf_read::MAX_MODEL_BYTES)
            .map_err(|e| ModelError::Gltf {
                path: path.to_path_buf(),
                message: e.to_string(),
            })?;
        let base = match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        };
        Self::from_gltf(&bytes, Some(base), path)
    }

    /// Loads a glTF or GLB document from memory; only `data:` URIs can be referenced.
    /// Errors carry `name` as their path.
    pub fn from_gltf_slice(bytes: &[u8], name: impl AsRef<Path>) -> Result<Self, ModelError> {
        Self::from_gltf(bytes, None, name.as_ref())
    }

    fn from_gltf(bytes: &[u8], base: Option<&Path>, path: &Path) -> Result<Self, ModelError> {
        // Every size and index is checked before the gltf crate's accessors run (see
        // `gltf_read`); a panic left in them is still an error, never a crash.
        std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            Self::from_gltf_unguarded(bytes, base, path)
        }))
        .unwrap_or_else(|_| {
            Err(ModelError::Gltf {
                path: path.to_path_buf(),
                message: "malformed glTF (the glTF reader failed on it)".into(),
            })
        })
    }

    fn from_gltf_unguarded(
        bytes: &[u8],
        base: Option<&Path>,
        path: &Path,
    ) -> Result<Self, ModelError> {
        use crate::gltf_read as gr;
        let gr::Loaded {
            doc,
            buffers,
            textures,
        } = gr::load(bytes, base).map_err(|m| gltf_error(path, m))?;
        let mut model = Model {
            textures,
            materials: materials_of(&doc, path)?,
            ..Model::default()
        };
        let default_material = model.materials.len() as u32;
        model.materials.push(SurfaceMaterial::default());
        let scene = doc.default_scene().or_else(|| doc.scenes().next());
        let Some(scene) = scene else {
            return Err(ModelError::Empty {
                path: path.to_path_buf(),
            });
        };
        // The node graph: no cycles, bounded expansion, and a triangle budget checked
        // before any triangle is stored.
        let roots: Vec<usize> = scene.nodes().map(|n| n.index()).collect();
        let instances = gr::node_instances(&doc, &roots).map_err(|m| gltf_error(path, m))?;
        let triangles = triangle_count(&doc, &buffers, &instances, path)?;
        if triangles > gr::MAX_TRIANGLES {
            return Err(gltf_error(
                path,
                format!(
                    "{triangles} triangles after expanding the node graph (at most {})",
                    gr::MAX_TRIANGLES
                ),
            ));
        }
        lightgrid_core::limits::check_memory(
            &format!("{triangles} triangles"),
            triangles * std::mem::size_of::<Triangle>() as u64,
        )?;
        model.triangles.reserve(triangles as usize);
        read_triangles(
            &scene,
            &buffers,
            default_material,
            &mut model.triangles,
            path,
        )?;
        if model.triangles.is_empty() {
            return Err(ModelError::Empty {
                path: path.to_path_buf(),
            });
        }
        model.validate().map_err(|e| ModelError::Gltf {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
        Ok(model)
    }
}

/// A glTF file `path` that does not parse or breaks a rule.
fn gltf_error(path: &Path, message: String) -> ModelError {
    ModelError::Gltf {
        path: path.to_path_buf(),
        message,
    }
}

/// A glTF file `path` that uses a feature the reader does not take.
fn unsupported(path: &Path, what: String) -> ModelError {
    ModelError::Unsupported {
        path: path.to_path_buf(),
        what,
    }
}

/// The document's materials: base colour (factor, texture on TEXCOORD_0 and its
/// transform) and alpha mode.
fn materials_of(doc: &gltf::Document, path: &Path) -> Result<Vec<SurfaceMaterial>, ModelError> {
    let mut materials = Vec::new();
    for (i, mat) in doc.materials().enumerate() {
        let pbr = mat.pbr_metallic_roughness();
        let f = pbr.base_color_factor();
        let (texture, uv_transform) = match pbr.base_color_texture() {
            Some(info) => {
                if info.tex_coord() != 0 {
                    return Err(unsupported(
                        path,
                        format!(
                            "material {i}: base colour texture uses TEXCOORD_{}",
                            info.tex_coord()
                        ),
                    ));
                }
                let tt = info
                    .texture_transform()
                    .map_or(UvTransform::IDENTITY, |t| UvTransform {
                        offset: Vec2::from_array(t.offset()),
                        rotation: t.rotation(),
                        scale: Vec2::from_array(t.scale()),
                    });
                (Some(info.texture().source().index()), tt)
            }
            None => (None, UvTransform::IDENTITY),
        };
        materials.push(SurfaceMaterial {
            base_colour: Vec4::from_array(f),
            texture,
            uv_transform,
            alpha: match mat.alpha_mode() {
                gltf::material::AlphaMode::Opaque => AlphaMode::Opaque,
                gltf::material::AlphaMode::Mask => {
                    AlphaMode::Mask(mat.alpha_cutoff().unwrap_or(0.5))
                }
                gltf::material::AlphaMode::Blend => AlphaMode::Blend,
            },
        });
    }
    Ok(materials)
}

/// The triangles the scene expands to (`instances`: how often each node is drawn),
/// every primitive's accessors checked first (triangles, POSITION, the layouts of
/// TEXCOORD_0 and indices).
fn triangle_count(
    doc: &gltf::Document,
    buffers: &[Vec<u8>],
    instances: &[u64],
    path: &Path,
) -> Result<u64, ModelError> {
    use crate::gltf_read as gr;
    use gltf::accessor::{DataType as T, Dimensions as D};
    let positions_layout = [(D::Vec3, T::F32)];
    let uv_layouts = [(D::Vec2, T::F32), (D::Vec2, T::U8), (D::Vec2, T::U16)];
    let index_layouts = [(D::Scalar, T::U8), (D::Scalar, T::U16), (D::Scalar, T::U32)];
    let mut triangles = 0u64;
    for node in doc.nodes() {
        let Some(mesh) = node.mesh() else { continue };
        for (pi, prim) in mesh.primitives().enumerate() {
            let where_ = format!("mesh {} primitive {pi}", mesh.index());
            let bad = |e: String| gltf_error(path, format!("{where_}: {e}"));
            if prim.mode() != gltf::mesh::Mode::Triangles {
                return Err(unsupported(
                    path,
                    format!("{where_}: mode {:?} (only triangles)", prim.mode()),
                ));
            }
            let Some(pos) = prim.get(&gltf::Semantic::Positions) else {
                return Err(unsupported(path, format!("{where_}: no POSITION")));
            };
            gr::check_accessor(&pos, buffers, &positions_layout).map_err(bad)?;
            if let Some(uv) = prim.get(&gltf::Semantic::TexCoords(0)) {
                gr::check_accessor(&uv, buffers, &uv_layouts).map_err(bad)?;
            }
            let corners = match prim.indices() {
                Some(ix) => {
                    gr::check_accessor(&ix, buffers, &index_layouts).map_err(bad)?;
                    ix.count()
                }
                None => pos.count(),
            };
            triangles = triangles
                .saturating_add((corners as u64 / 3).saturating_mul(instances[node.index()]));
        }
    }
    Ok(triangles)
}

/// The scene's triangles in world space, node by node down the graph (primitives
/// without a material get `default_material`; each primitive is its own part).
fn read_triangles(
    scene: &gltf::Scene,
    buffers: &[Vec<u8>],
    default_material: u32,
    out: &mut Vec<Triangle>,
    path: &Path,
) -> Result<(), ModelError> {
    let mut stack: Vec<(gltf::Node, Mat4)> = scene.nodes().map(|n| (n, Mat4::IDENTITY)).collect();
    let mut part = 0u32;
    while let Some((node, parent)) = stack.pop() {
        let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
        for child in node.children() {
            stack.push((child, world));
        }
        let Some(mesh) = node.mesh() else { continue };
        for (pi, prim) in mesh.primitives().enumerate() {
            let where_ = format!("mesh {} primitive {pi}", mesh.index());
            let reader = prim.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
            let positions: Vec<Vec3> = reader
                .read_positions()
                .ok_or_else(|| unsupported(path, format!("{where_}: no POSITION")))?
                .map(|p| world.transform_point3(Vec3::from_array(p)))
                .collect();
            let uvs: Vec<Vec2> = match reader.read_tex_coords(0) {
                Some(t) => t.into_f32().map(Vec2::from_array).collect(),
                None => vec![Vec2::ZERO; positions.len()],
            };
            let indices: Vec<u32> = match reader.read_indices() {
                Some(i) => i.into_u32().collect(),
                None => (0..positions.len() as u32).collect(),
            };
            let material = prim
                .material()
                .index()
                .map_or(default_material, |i| i as u32);
            for tri in indices.chunks_exact(3) {
                let idx = [tri[0] as usize, tri[1] as usize, tri[2] as usize];
                if idx.iter().any(|&i| i >= positions.len() || i >= uvs.len()) {
                    return Err(unsupported(path, format!("{where_}: index out of range")));
                }
                out.push(Triangle {
                    positions: idx.map(|i| positions[i]),
                    uvs: idx.map(|i| uvs[i]),
                    material,
                    part,
                });
            }
            part += 1;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn textures_without_their_texels_are_refused_and_read_black() {
        for (width, height, n) in [(0, 4, 0), (4, 0, 0), (2, 2, 3), (2, 2, 5)] {
            let t = Texture {
                width,
                height,
                texels: vec![Vec4::ONE; n],
            };
            assert_eq!(t.sample(Vec2::new(0.3, 0.7)), Vec4::ZERO);
            let m = Model {
                textures: vec![t],
                ..Default::default()
            };
            let e = m.validate().unwrap_err().to_string();
            assert!(e.contains("textures[0]"), "{e}");
        }
    }

    /// Appending shifts material, texture and part indices past the model's own and
    /// places the triangles by the transform.
    #[test]
    fn append_shifts_indices_and_transforms() {
        let part = Model {
            triangles: vec![Triangle {
                positions: [Vec3::ZERO, Vec3::X, Vec3::Z],
                uvs: [Vec2::ZERO; 3],
                material: 0,
                part: 0,
            }],
            materials: vec![SurfaceMaterial {
                texture: Some(0),
                ..Default::default()
            }],
            textures: vec![Texture {
                width: 1,
                height: 1,
                texels: vec![Vec4::ONE],
            }],
        };
        let mut m = Model::default();
        m.append(&part, Mat4::IDENTITY);
        let t =
            Mat4::from_scale_rotation_translation(Vec3::splat(2.0), Default::default(), Vec3::Y);
        m.append(&part, t);
        assert_eq!(
            (m.triangles.len(), m.materials.len(), m.textures.len()),
            (2, 2, 2)
        );
        let b = &m.triangles[1];
        assert_eq!((b.material, b.part), (1, 1));
        assert_eq!(m.materials[1].texture, Some(1));
        assert_eq!(
            b.positions,
            [Vec3::Y, Vec3::new(2.0, 1.0, 0.0), Vec3::new(0.0, 1.0, 2.0)]
        );
    }
}
