//! The dynamic-light pass: point, spot and line lights culled through the grid bag
//! ([`crate::dynamic`], the CPU specification), as the shaders read them
//! ([`DynLightGpu`], the grid's placement), the WGSL both the mesh shader and the
//! compute kernel use (`shaders/dynamic.wgsl`), and [`GpuDynamicShader`], the kernel that
//! shades a batch of points (tests compare it with the CPU).

use std::sync::Arc;

use lightgrid_core::LightKind;
use lightgrid_core::glam::Vec3;
use lightgrid_gpu::GpuContext;
use lightgrid_gpu::kernel::{Binding, Kernel, buffer};

use crate::RenderError;
use crate::dynamic::{DynamicLights, DynamicShade};

/// The dynamic-light structs and shading functions (shared with the mesh shader).
pub(crate) fn common_wgsl() -> String {
    format!(
        "{}\nconst DYN_FALLOFF_EPSILON: f32 = {:?};\n{}",
        DynLightGpu::wgsl(),
        crate::dynamic::FALLOFF_EPSILON,
        include_str!("../shaders/dynamic.wgsl")
    )
}

/// The dynamic-light compute kernel's WGSL (a batch of points).
pub fn wgsl() -> String {
    format!(
        "{}\n{}\n{}\n{}",
        crate::wgsl::prelude(),
        DynParams::wgsl(),
        common_wgsl(),
        include_str!("../shaders/dynamic_kernel.wgsl")
    )
}

lightgrid_gpu::gpu_struct! {
    /// One dynamic light as the shaders read it.
    pub struct DynLightGpu {
        /// Position (or a line's first end), range.
        pub position_range: [f32; 4] => "vec4<f32>",
        /// Colour, kind (0 point, 1 spot, 2 line).
        pub colour_kind: [f32; 4] => "vec4<f32>",
        /// Spot axis, cosine of the cut-off.
        pub dir_cos_outer: [f32; 4] => "vec4<f32>",
        /// A line's second end, a spot's cosine of full intensity.
        pub end_cos_inner: [f32; 4] => "vec4<f32>",
    }
}

lightgrid_gpu::gpu_struct! {
    /// The culling grid's placement, for the compute kernel.
    pub struct DynParams {
        /// Origin (xyz) and cell size (w).
        pub origin_cell: [f32; 4] => "vec4<f32>",
        /// Cells (xyz) and light count (w).
        pub dims: [u32; 4] => "vec4<u32>",
        /// Points in the batch (x).
        pub count: [u32; 4] => "vec4<u32>",
    }
}

impl DynamicLights {
    /// The lights as the shaders read them.
    pub fn gpu_lights(&self) -> Vec<DynLightGpu> {
        self.lights
            .iter()
            .map(|l| {
                let (p, kind, dir, cos_outer, end, cos_inner) = match l.kind {
                    LightKind::Spot { position, .. } => {
                        let (axis, ci, co) = l.kind.spot_cone().unwrap_or((Vec3::Y, 1.0, 0.0));
                        (position, 1.0, axis, co, Vec3::ZERO, ci)
                    }
                    LightKind::Line { a, b } => (a, 2.0, Vec3::ZERO, 0.0, b, 1.0),
                    // Area lights never get here (validation refuses them); a point is
                    // the harmless fallback.
                    LightKind::Point { position }
                    | LightKind::Area {
                        centre: position, ..
                    } => (position, 0.0, Vec3::ZERO, 0.0, Vec3::ZERO, 1.0),
                };
                DynLightGpu {
                    position_range: p.extend(l.range).to_array(),
                    colour_kind: l.colour.extend(kind).to_array(),
                    dir_cos_outer: dir.extend(cos_outer).to_array(),
                    end_cos_inner: end.extend(cos_inner).to_array(),
                }
            })
            .collect()
    }

    /// Origin and cell size, dims and light count, as the shaders read them.
    pub fn gpu_placement(&self) -> ([f32; 4], [u32; 4]) {
        (
            self.origin.extend(self.cell).to_array(),
            self.dims.extend(self.lights.len() as u32).to_array(),
        )
    }
}

/// Dynamic-light shading of a batch of points on the GPU, through the same WGSL the mesh
/// shader uses (tests compare it with [`crate::dynamic`]).
pub struct GpuDynamicShader {
    ctx: Arc<GpuContext>,
    kernel: Kernel,
}

impl GpuDynamicShader {
    /// Compiles the kernel.
    pub fn new(ctx: Arc<GpuContext>) -> Self {
        use Binding::{Read, ReadWrite, Uniform};
        let kernel = Kernel::new(
            &ctx.device,
            "dynamic lights",
            &wgsl(),
            &[Uniform, Read, Read, Read, Read, ReadWrite],
        );
        Self { ctx, kernel }
    }

    /// Diffuse and specular light at each `(position, normal, to_eye)` with `shininess`.
    pub fn shade(
        &self,
        lights: &DynamicLights,
        points: &[(Vec3, Vec3, Vec3)],
        shininess: f32,
    ) -> Result<Vec<DynamicShade>, RenderError> {
        if points.is_empty() {
            return Ok(Vec::new());
        }
        let (origin_cell, dims) = lights.gpu_placement();
        let params = DynParams {
            origin_cell,
            dims,
            count: [points.len() as u32, 0, 0, 0],
        };
        let packed: Vec<f32> = points
            .iter()
            .flat_map(|(p, n, v)| {
                [
                    p.x, p.y, p.z, shininess, n.x, n.y, n.z, 0.0, v.x, v.y, v.z, 0.0,
                ]
            })
            .collect();
        let storage = wgpu::BufferUsages::STORAGE;
        let ctx = &*self.ctx;
        let buffers = [
            buffer(
                ctx,
                "params",
                bytemuck::bytes_of(&params),
                wgpu::BufferUsages::UNIFORM,
            ),
            buffer(
                ctx,
                "lights",
                bytemuck::cast_slice(&lights.gpu_lights()),
                storage,
            ),
            buffer(ctx, "cells", bytemuck::cast_slice(&lights.cells), storage),
            buffer(
                ctx,
                "indices",
                bytemuck::cast_slice(&lights.indices),
                storage,
            ),
            buffer(ctx, "points", bytemuck::cast_slice(&packed), storage),
        ];
        let out = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("dynamic out"),
            size: points.len() as u64 * 32,
            usage: storage | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let refs: Vec<&wgpu::Buffer> = buffers.iter().chain([&out]).collect();
        let b = self.kernel.bind(&ctx.device, &refs);
        self.kernel.dispatch(ctx, &b, points.len() as u32);
        let v: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(&ctx.read_back(&out)?);
        Ok(v.chunks(2)
            .map(|c| DynamicShade {
                diffuse: Vec3::new(c[0][0], c[0][1], c[0][2]),
                specular: Vec3::new(c[1][0], c[1][1], c[1][2]),
            })
            .collect())
    }
}
