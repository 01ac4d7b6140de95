//! The rasteriser: terrain and instanced meshes lit by the light grids, drawn into a
//! linear HDR target and tone-mapped to sRGB, headless (read back as an [`Image`]) or
//! into any texture view (a window's surface).

use std::sync::Arc;

use lightgrid_core::glam::{Mat4, Vec2, Vec3, Vec4};
use lightgrid_core::{GridDesc, GridError};
use lightgrid_gpu::{GpuContext, GpuError, bind};
use wgpu::util::DeviceExt;

use crate::RenderError;
use crate::cull::{Bound, Frustum};
use crate::dynamic::DynamicLights;
use crate::passes::mesh::{self, DEPTH_FORMAT, FrameUniforms, MeshUniforms};
use crate::passes::sample::GpuSamples;
use crate::passes::scatter::LightScatter;
use crate::passes::tonemap::Tonemap;
use crate::sampling::LightVolume;

mod readback;
pub use readback::PendingImages;

pub use crate::passes::mesh::{
    HDR_FALLBACK_FORMAT, HDR_FORMAT, Lighting, LightingMode, MeshInstance, Vertex, hdr_format,
    renderable,
};

/// The tone-mapped target's format for headless images.
pub const LDR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;

/// An RGBA8 texture in sRGB encoding (what PNG files and glTF base colours hold).
#[derive(Debug, Clone, PartialEq)]
pub struct TextureRgba8 {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// `width × height` texels, rows top to bottom.
    pub texels: Vec<[u8; 4]>,
}

/// The surface of a mesh.
#[derive(Debug, Clone, PartialEq)]
pub struct MeshMaterial {
    /// Base colour factor (linear RGBA).
    pub base_colour: Vec4,
    /// Base colour texture.
    pub texture: Option<TextureRgba8>,
    /// Alpha mask: fragments with alpha below this are discarded.
    pub alpha_cutoff: Option<f32>,
    /// How it is lit.
    pub lighting: Lighting,
    /// Both faces drawn, the normal flipped on the back face (leaves).
    pub double_sided: bool,
    /// Specular strength (0 = none) for [`Lighting::Surface`].
    pub specular: f32,
    /// Blinn-Phong exponent of the specular term.
    pub shininess: f32,
    /// Each instance draws the mesh's xy plane turned to face the eye at the instance's
    /// origin, each vertex moved its z toward the eye, all scaled by the length of its
    /// model matrix's x axis (its own rotation ignored), its normal towards the eye. For
    /// markers of one flat colour ([`Lighting::Emissive`]): a polygon looks as a ball
    /// does for a fraction of its triangles, and a software rasteriser's cost is per
    /// triangle; and for a far model's picture ([`crate::impostor`]).
    pub billboard: bool,
}

impl Default for MeshMaterial {
    fn default() -> Self {
        Self {
            base_colour: Vec4::ONE,
            texture: None,
            alpha_cutoff: None,
            lighting: Lighting::Surface,
            double_sided: false,
            specular: 0.0,
            shininess: 32.0,
            billboard: false,
        }
    }
}

/// Handle of a mesh added to a [`Renderer`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct MeshId(usize);

/// A perspective camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Eye position.
    pub position: Vec3,
    /// Point looked at.
    pub target: Vec3,
    /// Vertical field of view, radians.
    pub fov_y: f32,
    /// Near plane distance.
    pub near: f32,
    /// Far plane distance.
    pub far: f32,
}

impl Camera {
    /// A camera at `position` looking at `target`, 60° field of view, 0.1 m to 5 km.
    pub fn look_at(position: Vec3, target: Vec3) -> Self {
        Self {
            position,
            target,
            fov_y: 60f32.to_radians(),
            near: 0.1,
            far: 5000.0,
        }
    }

    /// Projection × view for an aspect ratio (width / height), wgpu's depth range.
    pub fn view_proj(&self, aspect: f32) -> Mat4 {
        use lightgrid_core::glam::camera::rh::{proj::directx::perspective, view::look_at_mat4};
        // Up is Y unless the camera looks straight up or down.
        let dir = (self.target - self.position).normalize_or_zero();
        let up = if dir.cross(Vec3::Y).length_squared() < 1e-8 {
            Vec3::Z
        } else {
            Vec3::Y
        };
        perspective(self.fov_y, aspect, self.near, self.far)
            * look_at_mat4(self.position, self.target, up)
    }

    fn validate(&self) -> Result<(), GridError> {
        if !(self.position.is_finite() && self.target.is_finite()) {
            return Err(GridError::invalid(
                "camera",
                self.position,
                "position and target must be finite",
            ));
        }
        if (self.target - self.position).length_squared() == 0.0 {
            return Err(GridError::invalid(
                "camera.target",
                self.target,
                "must differ from the position",
            ));
        }
        if !(self.fov_y > 0.0 && self.fov_y < std::f32::consts::PI) {
            return Err(GridError::invalid(
                "camera.fov_y",
                self.fov_y,
                "must be in (0, π)",
            ));
        }
        if !(self.near > 0.0 && self.far > self.near && self.far.is_finite()) {
            return Err(GridError::invalid(
                "camera.near",
                self.near,
                "need 0 < near < far < ∞",
            ));
        }
        Ok(())
    }
}

/// Water: light below `level` falls as `exp(-attenuation · depth)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Water {
    /// Water surface height, metres.
    pub level: f32,
    /// Attenuation per metre of depth.
    pub attenuation: f32,
}

/// What one frame shows and how.
#[derive(Debug, Clone, PartialEq)]
pub struct View {
    /// The camera.
    pub camera: Camera,
    /// Grid light or the no-grid comparison.
    pub mode: LightingMode,
    /// The way sunlight travels (for [`LightingMode::NoGrid`]).
    pub sun_direction: Vec3,
    /// Sun irradiance facing it (for [`LightingMode::NoGrid`]).
    pub sun_colour: Vec3,
    /// Mean sky radiance (for [`LightingMode::NoGrid`], and the background).
    pub sky_ambient: Vec3,
    /// In [`LightingMode::Grid`], the irradiance of a sun the grids keep apart from their
    /// bins (issue 14: `lightgrid_terrain_lod::Hierarchy::set_sun`), travelling along
    /// `sun_direction` and shadowed by the transmittance the light volume holds
    /// ([`crate::SampledLight::sun`]): surfaces and foliage read volume light add it
    /// with its specular; vertex light must hold it already. Zero (the default in
    /// spirit) when the bins hold all light.
    pub direct_sun: Vec3,
    /// HDR multiplier before tone mapping.
    pub exposure: f32,
    /// Optional water.
    pub water: Option<Water>,
    /// Height over which objects' light blends from the ground's to their own, metres.
    pub ground_blend: f32,
    /// Background colour (linear HDR).
    pub background: Vec3,
    /// The meshes to draw.
    pub meshes: Vec<MeshId>,
}

/// A rendered frame, read back.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Linear HDR RGBA, rows top to bottom.
    pub hdr: Vec<[f32; 4]>,
    /// Tone-mapped sRGB RGBA8.
    pub srgb: Vec<[u8; 4]>,
}

/// Ground light for the ground blend: per heightmap node, the ground's irradiance and
/// height.
#[derive(Debug, Clone, PartialEq)]
pub struct GroundLight {
    /// World (x, z) of node (0, 0).
    pub origin: Vec2,
    /// Node spacing, metres.
    pub spacing: f32,
    /// Nodes along x.
    pub width: u32,
    /// Nodes along z.
    pub depth: u32,
    /// `(irradiance rgb, height)` per node, x fastest.
    pub nodes: Vec<[f32; 4]>,
}

struct GpuMesh {
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    index_count: u32,
    bind: wgpu::BindGroup,
    instances: Option<Instances>,
    double_sided: bool,
    /// The sphere around the vertices ([`crate::cull`]).
    bound: Bound,
    /// Distances from the eye to an instance's origin at which it is drawn
    /// ([`Renderer::set_draw_range`]).
    range: std::ops::Range<f32>,
}

/// A mesh's instances: all of them on the device and here, and a buffer as large for
/// those a view may see ([`Renderer::render_to`] culls per view).
struct Instances {
    all: wgpu::Buffer,
    list: Vec<MeshInstance>,
    /// Each instance's bounding sphere, placed.
    bounds: Vec<Bound>,
    seen: wgpu::Buffer,
}

/// What one mesh's draw reads: every instance, or the first `n` of its `seen` buffer
/// (written for this view).
#[derive(Clone, Copy)]
enum Drawn {
    All,
    Seen(u32),
    Nothing,
}

/// Draws meshes lit by light grids. Create once; add meshes, set instances, the light
/// volume and the ground light; render views.
pub struct Renderer {
    ctx: Arc<GpuContext>,
    width: u32,
    height: u32,
    /// [`HDR_FORMAT`], or [`HDR_FALLBACK_FORMAT`] where the adapter cannot render to it.
    hdr_format: wgpu::TextureFormat,
    mesh_pipelines: mesh::MeshPipelines,
    frame_layout: wgpu::BindGroupLayout,
    mesh_layout: wgpu::BindGroupLayout,
    tonemap: Tonemap,
    frame_uniform: wgpu::Buffer,
    volume: VolumeBuffers,
    scatter: LightScatter,
    ground: GroundBuffers,
    dynamic: DynamicBuffers,
    frame_bind: wgpu::BindGroup,
    sampler: wgpu::Sampler,
    white: wgpu::TextureView,
    targets: Targets,
    meshes: Vec<GpuMesh>,
    /// Readback buffers of earlier images, mapped no more, for the next ones
    /// ([`readback`]): a fresh buffer's pages are faulted in and zeroed again.
    spare_readback: std::sync::Mutex<Vec<wgpu::Buffer>>,
    /// The light volume [`Renderer::set_light_volume`] last wrote (storage) and its
    /// staging buffer (mappable), kept for the next volume of the same size: fresh
    /// ones cost their pages' faults (51 MB each at 1.6 M points).
    own_volume: Option<(wgpu::Buffer, wgpu::Buffer)>,
}

#[derive(Clone, Copy)]
struct LightVolumeInfo {
    origin_h: [f32; 4],
    dims: [u32; 4],
}

#[derive(Clone, Copy)]
struct GroundInfo {
    origin: [f32; 4],
    dims: [u32; 4],
}

struct DynamicBuffers {
    lights: wgpu::Buffer,
    cells: wgpu::Buffer,
    indices: wgpu::Buffer,
    origin_cell: [f32; 4],
    dims: [u32; 4],
}

struct Targets {
    hdr: wgpu::Texture,
    hdr_view: wgpu::TextureView,
    /// The second image of [`Renderer::render_pair`] (without the grids).
    hdr_pair: wgpu::Texture,
    hdr_pair_view: wgpu::TextureView,
    tonemap_pair_bind: wgpu::BindGroup,
    depth_view: wgpu::TextureView,
    ldr: wgpu::Texture,
    ldr_view: wgpu::TextureView,
    tonemap_bind: wgpu::BindGroup,
}

/// The light volume (average and dominant direction interleaved, two `vec4` a point) and
/// its placement.
type VolumeBuffers = (wgpu::Buffer, LightVolumeInfo);
/// The ground light buffer and its placement (none until a scene sets it).
type GroundBuffers = (wgpu::Buffer, Option<GroundInfo>);

impl Renderer {
    /// A renderer drawing `width × height` images, into [`HDR_FORMAT`] where the adapter
    /// can render to it and else [`HDR_FALLBACK_FORMAT`] ([`hdr_format`]).
    pub fn new(ctx: Arc<GpuContext>, width: u32, height: u32) -> Result<Self, RenderError> {
        let format = hdr_format(ctx.adapter());
        if format != HDR_FORMAT {
            tracing::info!(
                adapter = %ctx.info.name,
                format = ?format,
                "the adapter cannot render to {HDR_FORMAT:?}: the HDR image is drawn in half floats"
            );
        }
        Self::with_hdr_format(ctx, width, height, format)
    }

    /// [`Renderer::new`] with the HDR target's format chosen: [`HDR_FORMAT`] or
    /// [`HDR_FALLBACK_FORMAT`] (half the memory and bandwidth, steps of 2^-10 relative).
    /// Any other format, or one the adapter cannot render to, is an error naming
    /// `hdr_format`.
    pub fn with_hdr_format(
        ctx: Arc<GpuContext>,
        width: u32,
        height: u32,
        hdr_format: wgpu::TextureFormat,
    ) -> Result<Self, RenderError> {
        if ![HDR_FORMAT, HDR_FALLBACK_FORMAT].contains(&hdr_format)
            || !renderable(ctx.adapter(), hdr_format)
        {
            return Err(GridError::invalid(
                "hdr_format",
                hdr_format,
                "must be HDR_FORMAT or HDR_FALLBACK_FORMAT, one the adapter can render to",
            )
            .into());
        }
        let device = &ctx.device;
        let (frame_layout, mesh_layout) = mesh::layouts(device);
        let mesh_pipelines = mesh::pipelines(device, &frame_layout, &mesh_layout, hdr_format);
        let tonemap = Tonemap::new(device);
        let frame_uniform = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("frame"),
            size: std::mem::size_of::<FrameUniforms>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let (volume, ground, dynamic) = Self::placeholders(device);
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("base colour"),
            address_mode_u: wgpu::AddressMode::Repeat,
            address_mode_v: wgpu::AddressMode::Repeat,
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            ..Default::default()
        });
        let white = Self::upload_texture(
            &ctx,
            &TextureRgba8 {
                width: 1,
                height: 1,
                texels: vec![[255; 4]],
            },
        )?;
        let frame_bind = Self::frame_bind_group(
            &ctx,
            &frame_layout,
            &frame_uniform,
            &volume,
            &ground,
            &dynamic,
        );
        let targets = Self::targets(&ctx, &tonemap, hdr_format, width, height)?;
        let scatter = LightScatter::new(device);
        Ok(Self {
            ctx,
            width,
            height,
            hdr_format,
            mesh_pipelines,
            frame_layout,
            mesh_layout,
            tonemap,
            frame_uniform,
            volume,
            ground,
            dynamic,
            frame_bind,
            sampler,
            white,
            targets,
            meshes: Vec::new(),
            spare_readback: std::sync::Mutex::new(Vec::new()),
            own_volume: None,
            scatter,
        })
    }

    /// Small placeholder buffers for the light volume, the ground light and the dynamic
    /// lights until a scene sets them (bindings may not be empty).
    fn placeholders(device: &wgpu::Device) -> (VolumeBuffers, GroundBuffers, DynamicBuffers) {
        let placeholder = |label| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: &[0u8; 16],
                usage: wgpu::BufferUsages::STORAGE,
            })
        };
        let volume = (
            placeholder("light volume"),
            LightVolumeInfo {
                origin_h: [0.0, 0.0, 0.0, 1.0],
                dims: [1, 1, 1, 0],
            },
        );
        let ground = (placeholder("ground"), None);
        let dynamic = DynamicBuffers {
            // One zero light's worth of bytes (the binding's minimum size).
            lights: device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("dynamic lights"),
                contents: bytemuck::bytes_of(&crate::passes::dynamic::DynLightGpu::default()),
                usage: wgpu::BufferUsages::STORAGE,
            }),
            cells: placeholder("dynamic cells"),
            indices: placeholder("dynamic indices"),
            origin_cell: [0.0, 0.0, 0.0, 1.0],
            dims: [1, 1, 1, 0],
        };
        (volume, ground, dynamic)
    }

    /// The HDR target's format: [`HDR_FORMAT`] or [`HDR_FALLBACK_FORMAT`].
    pub fn hdr_format(&self) -> wgpu::TextureFormat {
        self.hdr_format
    }

    /// The GPU context.
    pub fn context(&self) -> &Arc<GpuContext> {
        &self.ctx
    }

    /// Image size.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Changes the image size (recreates the targets).
    pub fn resize(&mut self, width: u32, height: u32) -> Result<(), RenderError> {
        self.targets = Self::targets(&self.ctx, &self.tonemap, self.hdr_format, width, height)?;
        self.width = width;
        self.height = height;
        Ok(())
    }

    fn targets(
        ctx: &GpuContext,
        tonemap: &Tonemap,
        hdr_format: wgpu::TextureFormat,
        width: u32,
        height: u32,
    ) -> Result<Targets, RenderError> {
        let max = ctx.device.limits().max_texture_dimension_2d;
        for (field, v) in [("width", width), ("height", height)] {
            if v == 0 || v > max {
                return Err(GridError::invalid(
                    field,
                    v,
                    "must be between 1 and the device's largest texture size",
                )
                .into());
            }
        }
        let texture = |label, format, usage| {
            ctx.device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: wgpu::Extent3d {
                    width,
                    height,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
        };
        let attach = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC;
        let hdr = texture(
            "hdr",
            hdr_format,
            attach | wgpu::TextureUsages::TEXTURE_BINDING,
        );
        let depth = texture(
            "depth",
            DEPTH_FORMAT,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
        );
        let hdr_pair = texture(
            "hdr (pair)",
            hdr_format,
            attach | wgpu::TextureUsages::TEXTURE_BINDING,
        );
        let ldr = texture("ldr", LDR_FORMAT, attach);
        let hdr_view = hdr.create_view(&Default::default());
        let tonemap_bind = tonemap.bind(&ctx.device, &hdr_view);
        let hdr_pair_view = hdr_pair.create_view(&Default::default());
        let tonemap_pair_bind = tonemap.bind(&ctx.device, &hdr_pair_view);
        Ok(Targets {
            hdr_view,
            hdr_pair,
            hdr_pair_view,
            tonemap_pair_bind,
            depth_view: depth.create_view(&Default::default()),
            ldr_view: ldr.create_view(&Default::default()),
            hdr,
            ldr,
            tonemap_bind,
        })
    }

    fn frame_bind_group(
        ctx: &GpuContext,
        layout: &wgpu::BindGroupLayout,
        uniform: &wgpu::Buffer,
        volume: &VolumeBuffers,
        ground: &GroundBuffers,
        dynamic: &DynamicBuffers,
    ) -> wgpu::BindGroup {
        bind::group(
            &ctx.device,
            "frame",
            layout,
            [
                uniform,
                &volume.0,
                &ground.0,
                &dynamic.lights,
                &dynamic.cells,
                &dynamic.indices,
            ]
            .map(|b| b.as_entire_binding()),
        )
    }

    fn upload_texture(
        ctx: &GpuContext,
        t: &TextureRgba8,
    ) -> Result<wgpu::TextureView, RenderError> {
        if t.width == 0 || t.height == 0 || t.texels.len() != (t.width * t.height) as usize {
            return Err(GridError::invalid(
                "texture.texels.len()",
                t.texels.len(),
                "must be width × height (both > 0)",
            )
            .into());
        }
        let tex = ctx.device.create_texture_with_data(
            &ctx.queue,
            &wgpu::TextureDescriptor {
                label: Some("base colour"),
                size: wgpu::Extent3d {
                    width: t.width,
                    height: t.height,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: wgpu::TextureFormat::Rgba8UnormSrgb,
                usage: wgpu::TextureUsages::TEXTURE_BINDING,
                view_formats: &[],
            },
            wgpu::util::TextureDataOrder::LayerMajor,
            bytemuck::cast_slice(&t.texels),
        );
        Ok(tex.create_view(&Default::default()))
    }

    fn storage(&self, label: &'static str, data: &[u8]) -> Result<wgpu::Buffer, RenderError> {
        self.check_binding(label, data.len() as u64)?;
        Ok(self
            .ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: data,
                usage: wgpu::BufferUsages::STORAGE,
            }))
    }

    /// An error unless one storage binding may hold `bytes` bytes.
    fn check_binding(&self, what: &'static str, bytes: u64) -> Result<(), RenderError> {
        let limit = self.ctx.max_binding();
        if bytes > limit {
            return Err(GpuError::TooLarge { what, bytes, limit }.into());
        }
        Ok(())
    }

    /// Adds a mesh (drawn once per instance; see [`Renderer::set_instances`]).
    pub fn add_mesh(
        &mut self,
        vertices: &[Vertex],
        indices: &[u32],
        material: &MeshMaterial,
    ) -> Result<MeshId, RenderError> {
        if vertices.is_empty() || indices.is_empty() || !indices.len().is_multiple_of(3) {
            return Err(GridError::invalid(
                "indices.len()",
                indices.len(),
                "need vertices and a non-zero multiple of 3 indices",
            )
            .into());
        }
        if let Some(i) = indices.iter().find(|&&i| i as usize >= vertices.len()) {
            return Err(GridError::invalid("indices", i, "index past the vertices").into());
        }
        let finite = |v: &Vertex| {
            v.position
                .iter()
                .chain(&v.normal)
                .chain(&v.uv)
                .chain(&v.light)
                .all(|x| x.is_finite())
        };
        if let Some(v) = vertices.iter().find(|v| !finite(v)) {
            return Err(GridError::invalid("vertices", v.position[0], "must be finite").into());
        }
        let device = &self.ctx.device;
        let view = match &material.texture {
            Some(t) => Some(Self::upload_texture(&self.ctx, t)?),
            None => None,
        };
        let uniforms = MeshUniforms {
            base_colour: material.base_colour.to_array(),
            flags: [
                material.texture.is_some() as u32,
                material.alpha_cutoff.is_some() as u32,
                material.lighting as u32,
                material.double_sided as u32,
            ],
            params: [
                material.alpha_cutoff.unwrap_or(0.0),
                material.specular,
                material.shininess,
                0.0,
            ],
            shape: [material.billboard as u32, 0, 0, 0],
        };
        let uniform = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("mesh"),
            contents: bytemuck::bytes_of(&uniforms),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let bind = bind::group(
            device,
            "mesh",
            &self.mesh_layout,
            [
                uniform.as_entire_binding(),
                wgpu::BindingResource::TextureView(view.as_ref().unwrap_or(&self.white)),
                wgpu::BindingResource::Sampler(&self.sampler),
            ],
        );
        let init = |label, contents: &[u8], usage| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage,
            })
        };
        self.meshes.push(GpuMesh {
            vertices: init(
                "vertices",
                bytemuck::cast_slice(vertices),
                // STORAGE: set_vertex_light_samples writes the light on the device.
                wgpu::BufferUsages::VERTEX
                    | wgpu::BufferUsages::COPY_DST
                    | wgpu::BufferUsages::STORAGE,
            ),
            indices: init(
                "indices",
                bytemuck::cast_slice(indices),
                wgpu::BufferUsages::INDEX,
            ),
            index_count: indices.len() as u32,
            bind,
            instances: None,
            double_sided: material.double_sided,
            range: 0.0..f32::INFINITY,
            bound: if material.billboard {
                // Turned about the instance's origin, each vertex moved its z toward the
                // eye: the sphere there holding every vertex's (x, y, z).
                Bound::around_origin(vertices.iter().map(|v| Vec3::from_array(v.position)))
            } else {
                Bound::of(vertices.iter().map(|v| Vec3::from_array(v.position)))
            },
        });
        Ok(MeshId(self.meshes.len() - 1))
    }

    /// Replaces a mesh's vertices (same count), e.g. its light after the grids changed.
    pub fn update_vertices(
        &mut self,
        mesh: MeshId,
        vertices: &[Vertex],
    ) -> Result<(), RenderError> {
        let Some(m) = self.meshes.get(mesh.0) else {
            return Err(GridError::invalid("mesh", mesh.0, "no such mesh").into());
        };
        let bytes: &[u8] = bytemuck::cast_slice(vertices);
        if bytes.len() as u64 != m.vertices.size() {
            return Err(GridError::invalid(
                "vertices.len()",
                vertices.len(),
                "must equal the mesh's vertex count",
            )
            .into());
        }
        self.ctx.queue.write_buffer(&m.vertices, 0, bytes);
        Ok(())
    }

    /// Draws `mesh`'s instances only where the distance from the eye to an instance's
    /// origin lies in `range` (at first `0..∞`: every one). A model's meshes drawn
    /// within a distance and its [`crate::impostor::Impostor`] beyond it, both with the
    /// same instances, draw each instance once, whole near the eye and as a picture
    /// far from it. `range.start` must be finite and at least 0, `range.end` above it
    /// (it may be infinite).
    pub fn set_draw_range(
        &mut self,
        mesh: MeshId,
        range: std::ops::Range<f32>,
    ) -> Result<(), RenderError> {
        let Some(m) = self.meshes.get_mut(mesh.0) else {
            return Err(GridError::invalid("mesh", mesh.0, "no such mesh").into());
        };
        if !(range.start >= 0.0 && range.start.is_finite()) {
            return Err(GridError::invalid(
                "range.start",
                range.start,
                "must be finite and at least 0",
            )
            .into());
        }
        if range.end.partial_cmp(&range.start) != Some(std::cmp::Ordering::Greater) {
            return Err(
                GridError::invalid("range.end", range.end, "must exceed range.start").into(),
            );
        }
        m.range = range;
        Ok(())
    }

    /// Sets the instances of a mesh (replacing earlier ones; none hides it).
    pub fn set_instances(
        &mut self,
        mesh: MeshId,
        instances: &[MeshInstance],
    ) -> Result<(), RenderError> {
        let Some(m) = self.meshes.get_mut(mesh.0) else {
            return Err(GridError::invalid("mesh", mesh.0, "no such mesh").into());
        };
        if let Some(bad) = instances.iter().find(|i| {
            !i.model
                .iter()
                .flatten()
                .chain(&i.tint)
                .all(|x| x.is_finite())
        }) {
            return Err(GridError::invalid("instances", bad.tint[0], "must be finite").into());
        }
        m.instances = if instances.is_empty() {
            None
        } else {
            let device = &self.ctx.device;
            Some(Instances {
                all: device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("instances"),
                    contents: bytemuck::cast_slice(instances),
                    usage: wgpu::BufferUsages::VERTEX,
                }),
                bounds: instances
                    .iter()
                    .map(|i| m.bound.placed(&Mat4::from_cols_array_2d(&i.model)))
                    .collect(),
                list: instances.to_vec(),
                seen: device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("instances seen"),
                    size: std::mem::size_of_val(instances) as u64,
                    usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                }),
            })
        };
        Ok(())
    }

    /// Uploads the light volume that [`Lighting::Surface`] and [`Lighting::Foliage`] read.
    pub fn set_light_volume(&mut self, volume: &LightVolume) -> Result<(), RenderError> {
        let n = volume.desc.point_count();
        if volume.average.len() != n || volume.dominant.len() != n {
            return Err(GridError::invalid(
                "volume.average.len()",
                volume.average.len(),
                "must equal the volume's point count",
            )
            .into());
        }
        // Interleaved straight into a staging buffer's mapped memory (no 51 MB copy
        // first at 1.6 M points), then copied on the device; both kept for the next.
        let bytes = (n * 2 * std::mem::size_of::<[f32; 4]>()) as u64;
        self.check_binding("light volume", bytes)?;
        let size = bytes.max(32);
        let (buffer, staging) = match self.own_volume.take() {
            Some((b, s)) if b.size() == size => {
                let (tx, rx) = std::sync::mpsc::channel();
                s.slice(..)
                    .map_async(wgpu::MapMode::Write, move |r| drop(tx.send(r)));
                self.ctx
                    .device
                    .poll(wgpu::PollType::wait_indefinitely())
                    .map_err(|e| GpuError::Upload(e.to_string()))?;
                rx.recv()
                    .map_err(|e| GpuError::Upload(e.to_string()))?
                    .map_err(|e| GpuError::Upload(e.to_string()))?;
                (b, s)
            }
            _ => {
                let device = &self.ctx.device;
                let buffer = device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("light volume"),
                    size,
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                });
                let staging = device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("light volume staging"),
                    size,
                    usage: wgpu::BufferUsages::MAP_WRITE | wgpu::BufferUsages::COPY_SRC,
                    mapped_at_creation: true,
                });
                (buffer, staging)
            }
        };
        {
            let mut mapped = (staging.slice(..).get_mapped_range_mut())
                .map_err(|e| GpuError::Upload(e.to_string()))?;
            // A chunk at a time through a small buffer that stays in cache (mapped
            // memory is written, never read).
            const CHUNK: usize = 1 << 14;
            let mut chunk: Vec<[[f32; 4]; 2]> = Vec::with_capacity(CHUNK);
            let pairs = volume
                .average
                .chunks(CHUNK)
                .zip(volume.dominant.chunks(CHUNK));
            let mut at = 0;
            for (a, d) in pairs {
                chunk.clear();
                chunk.extend(a.iter().zip(d).map(|(a, d)| [*a, *d]));
                let b: &[u8] = bytemuck::cast_slice(&chunk);
                mapped.slice(at..at + b.len()).copy_from_slice(b);
                at += b.len();
            }
        }
        staging.unmap();
        let mut enc = (self.ctx.device).create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("light volume upload"),
        });
        enc.copy_buffer_to_buffer(&staging, 0, &buffer, 0, size);
        self.ctx.queue.submit([enc.finish()]);
        self.set_volume_buffer(volume.desc, buffer.clone());
        self.own_volume = Some((buffer, staging));
        Ok(())
    }

    /// Draws the light volume from samples already on the device: `samples` lit the
    /// lattice `desc` (`GpuLightSampler::sample_layers` with `GpuPoints::Lattice(desc)`)
    /// and is used where it lies, with no copy.
    pub fn set_light_volume_samples(
        &mut self,
        desc: GridDesc,
        samples: &GpuSamples,
    ) -> Result<(), RenderError> {
        self.check_samples(
            samples,
            desc.point_count(),
            "must equal the volume's point count",
        )?;
        self.set_volume_buffer(desc, samples.buffer().clone());
        Ok(())
    }

    /// Writes sampled light (irradiance on the vertex normals) into `light.xyz` of a
    /// mesh's vertices, on the device: `samples` lit the mesh's vertices in order.
    pub fn set_vertex_light_samples(
        &mut self,
        mesh: MeshId,
        samples: &GpuSamples,
    ) -> Result<(), RenderError> {
        let Some(m) = self.meshes.get(mesh.0) else {
            return Err(GridError::invalid("mesh", mesh.0, "no such mesh").into());
        };
        let floats = (std::mem::size_of::<Vertex>() / 4) as u32;
        let count = m.vertices.size() as usize / std::mem::size_of::<Vertex>();
        self.check_samples(samples, count, "must equal the mesh's vertex count")?;
        let offset = (std::mem::offset_of!(Vertex, light) / 4) as u32;
        self.scatter.run(samples, &m.vertices, floats, offset);
        Ok(())
    }

    /// Writes sampled light into the ground light's rgb (heights stay), on the device:
    /// `samples` lit the ground nodes of the last [`Renderer::set_ground`] in order.
    pub fn set_ground_light_samples(&mut self, samples: &GpuSamples) -> Result<(), RenderError> {
        let Some(info) = self.ground.1 else {
            return Err(GridError::invalid("ground", "none", "set_ground first").into());
        };
        let count = (info.dims[0] * info.dims[1]) as usize;
        self.check_samples(samples, count, "must equal the ground's node count")?;
        self.scatter.run(samples, &self.ground.0, 4, 0);
        Ok(())
    }

    fn check_samples(
        &self,
        samples: &GpuSamples,
        count: usize,
        what: &'static str,
    ) -> Result<(), RenderError> {
        if !Arc::ptr_eq(samples.context(), &self.ctx) {
            return Err(GridError::invalid(
                "samples",
                "another device",
                "must live on the renderer's device",
            )
            .into());
        }
        if samples.count() != count {
            return Err(GridError::invalid("samples.count()", samples.count(), what).into());
        }
        Ok(())
    }

    fn set_volume_buffer(&mut self, d: GridDesc, buffer: wgpu::Buffer) {
        self.volume = (
            buffer,
            LightVolumeInfo {
                origin_h: d.origin().extend(d.h()).to_array(),
                dims: d.dims().extend(1).to_array(),
            },
        );
        self.rebind();
    }

    /// Uploads the ground light used by the ground blend.
    pub fn set_ground(&mut self, ground: &GroundLight) -> Result<(), RenderError> {
        if ground.width == 0
            || ground.depth == 0
            || ground.nodes.len() != (ground.width * ground.depth) as usize
        {
            return Err(GridError::invalid(
                "ground.nodes.len()",
                ground.nodes.len(),
                "must be width × depth (both > 0)",
            )
            .into());
        }
        if !(ground.spacing > 0.0 && ground.spacing.is_finite() && ground.origin.is_finite()) {
            return Err(GridError::invalid(
                "ground.spacing",
                ground.spacing,
                "must be finite and > 0",
            )
            .into());
        }
        self.ground = (
            self.storage("ground light", bytemuck::cast_slice(&ground.nodes))?,
            Some(GroundInfo {
                origin: [ground.origin.x, ground.origin.y, ground.spacing, 0.0],
                dims: [ground.width, ground.depth, 1, 0],
            }),
        );
        self.rebind();
        Ok(())
    }

    /// Uploads this frame's dynamic lights and their culling grid (rebuilt on the CPU
    /// each frame: [`DynamicLights::build`]).
    pub fn set_dynamic_lights(&mut self, lights: &DynamicLights) -> Result<(), RenderError> {
        // Bindings need at least one element (64 bytes for a light).
        let nonempty = |v: Vec<u8>| if v.is_empty() { vec![0u8; 64] } else { v };
        let (origin_cell, dims) = lights.gpu_placement();
        self.dynamic = DynamicBuffers {
            lights: self.storage(
                "dynamic lights",
                &nonempty(bytemuck::cast_slice(&lights.gpu_lights()).to_vec()),
            )?,
            cells: self.storage(
                "dynamic cells",
                &nonempty(bytemuck::cast_slice(&lights.cells).to_vec()),
            )?,
            indices: self.storage(
                "dynamic indices",
                &nonempty(bytemuck::cast_slice(&lights.indices).to_vec()),
            )?,
            origin_cell,
            dims,
        };
        self.rebind();
        Ok(())
    }

    fn rebind(&mut self) {
        self.frame_bind = Self::frame_bind_group(
            &self.ctx,
            &self.frame_layout,
            &self.frame_uniform,
            &self.volume,
            &self.ground,
            &self.dynamic,
        );
    }

    fn frame_uniforms(&self, view: &View) -> Result<FrameUniforms, RenderError> {
        view.camera.validate()?;
        if !(view.exposure.is_finite() && view.exposure > 0.0) {
            return Err(
                GridError::invalid("exposure", view.exposure, "must be finite and > 0").into(),
            );
        }
        for (field, v) in [
            ("sun_direction", view.sun_direction),
            ("sun_colour", view.sun_colour),
            ("sky_ambient", view.sky_ambient),
            ("direct_sun", view.direct_sun),
            ("background", view.background),
        ] {
            if !v.is_finite() {
                return Err(GridError::invalid(field, v, "must be finite").into());
            }
        }
        if let Some(m) = view.meshes.iter().find(|m| m.0 >= self.meshes.len()) {
            return Err(GridError::invalid("meshes", m.0, "no such mesh").into());
        }
        let (water, ground) = (
            view.water
                .map(|w| [w.level, w.attenuation.max(0.0), 0.0, 0.0])
                .unwrap_or([0.0; 4]),
            self.ground.1.unwrap_or(GroundInfo {
                origin: [0.0, 0.0, 1.0, 0.0],
                dims: [1, 1, 0, 0],
            }),
        );
        Ok(FrameUniforms {
            view_proj: view
                .camera
                .view_proj(self.width as f32 / self.height as f32)
                .to_cols_array_2d(),
            eye: view.camera.position.extend(1.0).to_array(),
            sun_direction: view
                .sun_direction
                .normalize_or_zero()
                .extend(0.0)
                .to_array(),
            sun_colour: view.sun_colour.extend(0.0).to_array(),
            sky_ambient: view.sky_ambient.extend(0.0).to_array(),
            direct_sun: view.direct_sun.max(Vec3::ZERO).extend(0.0).to_array(),
            water,
            volume_origin_h: self.volume.1.origin_h,
            volume_dims: self.volume.1.dims,
            volume_params: [0.5 * self.volume.1.origin_h[3], view.ground_blend, 0.0, 0.0],
            ground_origin: ground.origin,
            ground_dims: ground.dims,
            mode: [view.mode as u32, 0, 0, 0],
            dyn_origin_cell: self.dynamic.origin_cell,
            dyn_dims: self.dynamic.dims,
        })
    }

    /// What each of `view`'s meshes draws: the instances whose bounding spheres the
    /// camera may see at a distance in the mesh's draw range, written into their `seen`
    /// buffers where some are not.
    fn cull(&self, view: &View, enc: &mut wgpu::CommandEncoder) -> Vec<Drawn> {
        let frustum = Frustum::of(
            &view
                .camera
                .view_proj(self.width as f32 / self.height as f32),
        );
        let eye = view.camera.position;
        view.meshes
            .iter()
            .map(|id| {
                let m = &self.meshes[id.0];
                let Some(inst) = &m.instances else {
                    return Drawn::Nothing;
                };
                let seen: Vec<MeshInstance> = inst
                    .list
                    .iter()
                    .zip(&inst.bounds)
                    .filter(|(i, b)| {
                        frustum.may_see(b) && m.range.contains(&crate::cull::distance(i, eye))
                    })
                    .map(|(i, _)| *i)
                    .collect();
                if seen.len() == inst.list.len() {
                    Drawn::All
                } else if seen.is_empty() {
                    Drawn::Nothing
                } else {
                    self.write_in(enc, &inst.seen, bytemuck::cast_slice(&seen));
                    Drawn::Seen(seen.len() as u32)
                }
            })
            .collect()
    }

    /// Writes `bytes` at the start of `buffer` as a command of `enc` (a copy from a new
    /// buffer), where `queue.write_buffer` would land before the whole next submission.
    fn write_in(&self, enc: &mut wgpu::CommandEncoder, buffer: &wgpu::Buffer, bytes: &[u8]) {
        let src = self
            .ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("write in order"),
                contents: bytes,
                usage: wgpu::BufferUsages::COPY_SRC,
            });
        enc.copy_buffer_to_buffer(&src, 0, buffer, 0, bytes.len() as u64);
    }

    /// Draws `view` into the HDR target and tone-maps it into `target` (a texture view of
    /// `format`, e.g. a window's surface, sized like the renderer).
    pub fn render_to(
        &mut self,
        view: &View,
        target: &wgpu::TextureView,
        format: wgpu::TextureFormat,
    ) -> Result<(), RenderError> {
        let mut enc = self.draw_meshes(view, false)?;
        self.tonemap_into(&mut enc, target, format, false);
        self.ctx.queue.submit([enc.finish()]);
        Ok(())
    }

    /// The mesh pass of `view` into the HDR target, or (`pair`) into it lit by the grids
    /// and into the pair's target without them, whatever `view.mode` says; the encoder,
    /// not yet submitted.
    fn draw_meshes(
        &mut self,
        view: &View,
        pair: bool,
    ) -> Result<wgpu::CommandEncoder, RenderError> {
        let uniforms = self.frame_uniforms(view)?;
        let mut enc = self.ctx.device.create_command_encoder(&Default::default());
        // Written in the encoder, so that views recorded before a submission keep theirs.
        self.write_in(&mut enc, &self.frame_uniform, bytemuck::bytes_of(&uniforms));
        let exposure = [view.exposure, 0.0, 0.0, 0.0];
        self.write_in(
            &mut enc,
            self.tonemap.uniform(),
            bytemuck::bytes_of(&exposure),
        );
        let drawn = self.cull(view, &mut enc);
        let bg = view.background;
        let colour = |view| {
            Some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color {
                        r: bg.x as f64,
                        g: bg.y as f64,
                        b: bg.z as f64,
                        a: 1.0,
                    }),
                    store: wgpu::StoreOp::Store,
                },
            })
        };
        let attachments = [
            colour(&self.targets.hdr_view),
            colour(&self.targets.hdr_pair_view),
        ];
        let (attachments, pipelines) = if pair {
            (&attachments[..], &self.mesh_pipelines.pair)
        } else {
            (&attachments[..1], &self.mesh_pipelines.single)
        };
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("meshes"),
            color_attachments: attachments,
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &self.targets.depth_view,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Store,
                }),
                stencil_ops: None,
            }),
            ..Default::default()
        });
        pass.set_bind_group(0, &self.frame_bind, &[]);
        for (id, drawn) in view.meshes.iter().zip(drawn) {
            let m = &self.meshes[id.0];
            let (instances, count) = match (&m.instances, drawn) {
                (Some(i), Drawn::All) => (&i.all, i.list.len() as u32),
                (Some(i), Drawn::Seen(n)) => (&i.seen, n),
                _ => continue,
            };
            // Double-sided meshes use the pipeline without culling.
            pass.set_pipeline(&pipelines[m.double_sided as usize]);
            pass.set_bind_group(1, &m.bind, &[]);
            pass.set_vertex_buffer(0, m.vertices.slice(..));
            pass.set_vertex_buffer(1, instances.slice(..));
            pass.set_index_buffer(m.indices.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(0..m.index_count, 0, 0..count);
        }
        drop(pass);
        Ok(enc)
    }

    /// Tone-maps the HDR target (`pair`: the pair's) into `target` of `format`.
    fn tonemap_into(
        &mut self,
        enc: &mut wgpu::CommandEncoder,
        target: &wgpu::TextureView,
        format: wgpu::TextureFormat,
        pair: bool,
    ) {
        let tonemap = self.tonemap.pipeline(&self.ctx.device, format).clone();
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("tonemap"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: target,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                    store: wgpu::StoreOp::Store,
                },
            })],
            ..Default::default()
        });
        pass.set_pipeline(&tonemap);
        let bind = if pair {
            &self.targets.tonemap_pair_bind
        } else {
            &self.targets.tonemap_bind
        };
        pass.set_bind_group(0, bind, &[]);
        pass.draw(0..3, 0..1);
    }

    /// Draws `view` headless and reads back the HDR and sRGB images
    /// ([`Renderer::record`] and [`Renderer::finish`] at once).
    pub fn render(&mut self, view: &View) -> Result<Image, RenderError> {
        let pending = self.record(view)?;
        Ok(self.finish(pending)?.remove(0))
    }

    /// Draws `view` headless twice over from one pass over its geometry: lit by the
    /// grids ([`LightingMode::Grid`]) and without them ([`LightingMode::NoGrid`]),
    /// whatever `view.mode` says; each image equal to [`Renderer::render`] of the view
    /// in that mode. Where drawing the geometry is most of a frame (a software
    /// rasteriser, a dense forest) the pair costs little more than one image.
    pub fn render_pair(&mut self, view: &View) -> Result<[Image; 2], RenderError> {
        let pending = self.record_pair(view)?;
        let [grid, plain]: [Image; 2] = self
            .finish(pending)?
            .try_into()
            .expect("a pair is two images");
        Ok([grid, plain])
    }
}
