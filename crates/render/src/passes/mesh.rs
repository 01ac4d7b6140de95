//! The mesh pass: terrain and instanced meshes lit by the light grids into the linear
//! HDR target. Its vertex formats ([`Vertex`], [`MeshInstance`]), uniforms
//! ([`FrameUniforms`], [`MeshUniforms`]), lighting kinds ([`Lighting`],
//! [`LightingMode`]), bind group layouts, pipelines and shader (`shaders/mesh.wgsl`,
//! shading as `crate::shading` specifies it). [`crate::Renderer`] owns the buffers.

use lightgrid_core::glam::{Mat4, Vec4};
use lightgrid_gpu::bind;
use std::fmt::Write;

/// The HDR target's format where the adapter can render to it (linear, read back as
/// `f32`): everywhere on Vulkan, Metal and DX12.
pub const HDR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;
/// The HDR target's format where [`HDR_FORMAT`] is not renderable (OpenGL ES without
/// `EXT_color_buffer_float`, Mesa's llvmpipe through GL): half floats, read back
/// widened to `f32` (one step is 2^-10 relative; range up to 65504).
pub const HDR_FALLBACK_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;

/// Whether `adapter` can render to `format`.
pub fn renderable(adapter: &wgpu::Adapter, format: wgpu::TextureFormat) -> bool {
    adapter
        .get_texture_format_features(format)
        .allowed_usages
        .contains(wgpu::TextureUsages::RENDER_ATTACHMENT)
}

/// The HDR target's format on `adapter`: [`HDR_FORMAT`] where it can be rendered to,
/// else [`HDR_FALLBACK_FORMAT`].
pub fn hdr_format(adapter: &wgpu::Adapter) -> wgpu::TextureFormat {
    if renderable(adapter, HDR_FORMAT) {
        HDR_FORMAT
    } else {
        HDR_FALLBACK_FORMAT
    }
}
/// The depth buffer's format.
pub(crate) const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// The mesh shader's WGSL: the prelude, the lighting kinds and modes, the uniforms, the
/// dynamic lights' shading and `shaders/mesh.wgsl`.
pub fn wgsl() -> String {
    let mut kinds = String::new();
    let _ = writeln!(
        kinds,
        "const LIGHTING_VERTEX: u32 = {}u;\nconst LIGHTING_SURFACE: u32 = {}u;\nconst LIGHTING_FOLIAGE: u32 = {}u;\nconst LIGHTING_EMISSIVE: u32 = {}u;\nconst LIGHTING_FLAT: u32 = {}u;",
        Lighting::Vertex as u32,
        Lighting::Surface as u32,
        Lighting::Foliage as u32,
        Lighting::Emissive as u32,
        Lighting::Flat as u32,
    );
    let _ = writeln!(
        kinds,
        "const MODE_GRID: u32 = {}u;\nconst MODE_NO_GRID: u32 = {}u;",
        LightingMode::Grid as u32,
        LightingMode::NoGrid as u32
    );
    format!(
        "{}\n{}\n{}\n{}\n{}\n{}",
        crate::wgsl::prelude(),
        kinds,
        FrameUniforms::wgsl(),
        MeshUniforms::wgsl(),
        super::dynamic::common_wgsl(),
        include_str!("../shaders/mesh.wgsl")
    )
}

lightgrid_gpu::gpu_struct! {
    /// Per-frame uniforms of the mesh shader.
    pub struct FrameUniforms {
        /// Projection × view.
        pub view_proj: [[f32; 4]; 4] => "mat4x4<f32>",
        /// Camera position (xyz).
        pub eye: [f32; 4] => "vec4<f32>",
        /// The way sunlight travels (xyz, unit), for the view without the grid.
        pub sun_direction: [f32; 4] => "vec4<f32>",
        /// Sun irradiance on a surface facing it (rgb), for the view without the grid.
        pub sun_colour: [f32; 4] => "vec4<f32>",
        /// Mean sky radiance (rgb), for the view without the grid.
        pub sky_ambient: [f32; 4] => "vec4<f32>",
        /// Irradiance of the sun kept apart from the grids' bins (rgb; along
        /// `sun_direction`, times the transmittance the volume holds), 0 when the bins
        /// hold the sun.
        pub direct_sun: [f32; 4] => "vec4<f32>",
        /// Water level (x) and attenuation per metre (y; 0 = no water).
        pub water: [f32; 4] => "vec4<f32>",
        /// Light volume origin (xyz) and cell size (w).
        pub volume_origin_h: [f32; 4] => "vec4<f32>",
        /// Light volume dims (xyz).
        pub volume_dims: [u32; 4] => "vec4<u32>",
        /// Normal bias of volume lookups in metres (x), ground-blend height (y).
        pub volume_params: [f32; 4] => "vec4<f32>",
        /// Ground light origin x, z (xy) and spacing (z).
        pub ground_origin: [f32; 4] => "vec4<f32>",
        /// Ground light nodes along x, z (xy); z = 1 when ground light is set.
        pub ground_dims: [u32; 4] => "vec4<u32>",
        /// Lighting mode (x).
        pub mode: [u32; 4] => "vec4<u32>",
        /// Dynamic-light grid origin (xyz) and cell size (w).
        pub dyn_origin_cell: [f32; 4] => "vec4<f32>",
        /// Dynamic-light grid cells (xyz) and light count (w; 0 = none).
        pub dyn_dims: [u32; 4] => "vec4<u32>",
    }
}

lightgrid_gpu::gpu_struct! {
    /// Per-mesh uniforms of the mesh shader.
    pub struct MeshUniforms {
        /// Base colour factor (linear RGBA).
        pub base_colour: [f32; 4] => "vec4<f32>",
        /// Has a texture, alpha mask on, lighting kind, double-sided.
        pub flags: [u32; 4] => "vec4<u32>",
        /// Alpha cutoff, specular strength, shininess.
        pub params: [f32; 4] => "vec4<f32>",
        /// Turned to face the eye (x: 1, see `MeshMaterial::billboard`).
        pub shape: [u32; 4] => "vec4<u32>",
    }
}

/// How a mesh is lit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum Lighting {
    /// The light stored in each vertex by a sampling buffer (irradiance from the 26 bins):
    /// stationary diffuse surfaces such as the terrain.
    Vertex = 0,
    /// Average light and dominant direction read per pixel from the light volume, with a
    /// specular term from the dominant direction: moving objects, rocks, trunks.
    Surface = 1,
    /// Average light only (π × average), per pixel: leaves and bushes, as the seed does.
    Foliage = 2,
    /// The tint is the HDR colour (debug: light grid points as balls).
    Emissive = 3,
    /// A fixed key light on the tint (debug: material cells as cubes).
    Flat = 4,
}

/// Whether the grids light the frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum LightingMode {
    /// Light from the grids (sun shadowed and bounced by the sweep).
    Grid = 0,
    /// Without the grids: the unshadowed sun plus a constant sky ambient.
    NoGrid = 1,
}

/// One vertex: position, normal, texture coordinate and the sampled light
/// ([`Lighting::Vertex`] meshes read `light.xyz`).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Vertex {
    /// Model-space position.
    pub position: [f32; 3],
    /// Model-space normal.
    pub normal: [f32; 3],
    /// Texture coordinate.
    pub uv: [f32; 2],
    /// Irradiance (xyz) for [`Lighting::Vertex`].
    pub light: [f32; 4],
}

/// One instance of a mesh as the GPU draws it: model matrix and a colour multiplier.
/// (A model's *placement* in a scene, with model index, position, rotation and scale, is
/// `lightgrid_material_voxelizer::compose::Instance`; the viewer turns placements into these.)
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct MeshInstance {
    /// Model to world (column major).
    pub model: [[f32; 4]; 4],
    /// Multiplies the base colour; for [`Lighting::Emissive`], the HDR colour.
    pub tint: [f32; 4],
}

impl MeshInstance {
    /// An instance from a matrix and a tint.
    pub fn new(model: Mat4, tint: Vec4) -> Self {
        Self {
            model: model.to_cols_array_2d(),
            tint: tint.to_array(),
        }
    }
}

/// The bind group layouts: per frame (uniforms, light volume, ground, dynamic lights)
/// and per mesh (uniforms, base colour texture and sampler).
pub(crate) fn layouts(device: &wgpu::Device) -> (wgpu::BindGroupLayout, wgpu::BindGroupLayout) {
    let fragment = wgpu::ShaderStages::FRAGMENT;
    let storage = |binding| bind::storage(binding, fragment, true);
    let frame = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("frame"),
        entries: &[
            bind::uniform(0, wgpu::ShaderStages::VERTEX_FRAGMENT),
            storage(1),
            storage(2),
            storage(3),
            storage(4),
            storage(5),
        ],
    });
    let mesh = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("mesh"),
        entries: &[
            bind::uniform(0, wgpu::ShaderStages::VERTEX_FRAGMENT),
            bind::texture_2d(1, fragment, true),
            bind::sampler(2, fragment),
        ],
    });
    (frame, mesh)
}

/// The mesh pipelines, back faces culled and double-sided: drawing into one HDR target
/// (`fs_main`, the frame's lighting mode) and, for [`crate::Renderer::render_pair`],
/// into two at once (`fs_pair`: lit by the grids, and without them).
pub(crate) struct MeshPipelines {
    pub(crate) single: [wgpu::RenderPipeline; 2],
    pub(crate) pair: [wgpu::RenderPipeline; 2],
}

/// [`MeshPipelines`] for HDR targets of `hdr_format`.
pub(crate) fn pipelines(
    device: &wgpu::Device,
    frame_layout: &wgpu::BindGroupLayout,
    mesh_layout: &wgpu::BindGroupLayout,
    hdr_format: wgpu::TextureFormat,
) -> MeshPipelines {
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("mesh"),
        source: wgpu::ShaderSource::Wgsl(wgsl().into()),
    });
    let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("mesh"),
        bind_group_layouts: &[Some(frame_layout), Some(mesh_layout)],
        immediate_size: 0,
    });
    let vertex_attrs =
        wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Float32x2, 3 => Float32x4];
    let instance_attrs = wgpu::vertex_attr_array![4 => Float32x4, 5 => Float32x4, 6 => Float32x4, 7 => Float32x4, 8 => Float32x4];
    let single = [Some(hdr_format.into())];
    let pair = [Some(hdr_format.into()), Some(hdr_format.into())];
    let mesh_pipeline = |cull: Option<wgpu::Face>, (entry, targets): (&str, &[_])| {
        device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("mesh"),
            layout: Some(&layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_main"),
                compilation_options: Default::default(),
                buffers: &[
                    Some(wgpu::VertexBufferLayout {
                        array_stride: std::mem::size_of::<Vertex>() as u64,
                        step_mode: wgpu::VertexStepMode::Vertex,
                        attributes: &vertex_attrs,
                    }),
                    Some(wgpu::VertexBufferLayout {
                        array_stride: std::mem::size_of::<MeshInstance>() as u64,
                        step_mode: wgpu::VertexStepMode::Instance,
                        attributes: &instance_attrs,
                    }),
                ],
            },
            primitive: wgpu::PrimitiveState {
                cull_mode: cull,
                ..Default::default()
            },
            depth_stencil: Some(wgpu::DepthStencilState {
                format: DEPTH_FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Less),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                targets,
            }),
            multiview_mask: None,
            cache: None,
        })
    };
    let both = |shader| {
        [
            mesh_pipeline(Some(wgpu::Face::Back), shader),
            mesh_pipeline(None, shader),
        ]
    };
    MeshPipelines {
        single: both(("fs_main", &single)),
        pair: both(("fs_pair", &pair)),
    }
}
