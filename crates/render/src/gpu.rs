//! The light sampling buffer as a wgpu compute pass.

use std::sync::Arc;

use grid_core::glam::Vec3;
use grid_core::{GridError, LightGrid, NUM_DIRS};
use sweep_gpu::{GpuContext, GpuError};
use wgpu::util::DeviceExt;

use crate::RenderError;
use crate::sampling::{IrradianceTable, SamplePoints, SampledLight};

crate::gpu_struct! {
    /// Uniforms of the sampling kernel.
    pub struct SampleParams {
        /// Grid origin (xyz) and cell size (w).
        pub origin_h: [f32; 4] => "vec4<f32>",
        /// Grid dims (xyz) and the irradiance table's nodes per side (w).
        pub dims: [u32; 4] => "vec4<u32>",
        /// Points in the batch.
        pub count: u32 => "u32",
        /// Padding.
        pub pad0: u32 => "u32",
        /// Padding.
        pub pad1: u32 => "u32",
        /// Padding.
        pub pad2: u32 => "u32",
    }
}

/// Samples light grids for batches of points on the GPU: the same results as
/// [`crate::sample_points`] on that grid (within f32 rounding).
pub struct GpuLightSampler {
    ctx: Arc<GpuContext>,
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    table: wgpu::Buffer,
}

const WORKGROUP: u32 = 64;

impl GpuLightSampler {
    /// Compiles the kernel and uploads the irradiance table.
    pub fn new(ctx: Arc<GpuContext>) -> Self {
        let device = &ctx.device;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("sample"),
            source: wgpu::ShaderSource::Wgsl(crate::wgsl::sample_kernel().into()),
        });
        let storage = |binding, read_only| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("sample"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                storage(1, true),
                storage(2, true),
                storage(3, true),
                storage(4, false),
            ],
        });
        let pl = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("sample"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("sample"),
            layout: Some(&pl),
            module: &module,
            entry_point: Some("main"),
            compilation_options: Default::default(),
            cache: None,
        });
        let table = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("irradiance table"),
            contents: bytemuck::cast_slice(&IrradianceTable::get().weights),
            usage: wgpu::BufferUsages::STORAGE,
        });
        Self {
            ctx,
            pipeline,
            layout,
            table,
        }
    }

    /// Lights `points` from `grid` in one dispatch.
    pub fn sample(
        &self,
        grid: &LightGrid,
        points: SamplePoints<'_>,
    ) -> Result<Vec<SampledLight>, RenderError> {
        points.validate()?;
        let count = points.positions.len();
        if count == 0 {
            return Ok(Vec::new());
        }
        if count > (u32::MAX / 2) as usize {
            return Err(GridError::invalid("positions.len()", count, "too many points").into());
        }
        let device = &self.ctx.device;
        let limit = self.ctx.max_binding();
        let bin_bytes = grid.data().len() as u64 * NUM_DIRS as u64 * 12;
        let point_bytes = count as u64 * 32;
        for (what, bytes) in [("light grid", bin_bytes), ("sample points", point_bytes)] {
            if bytes > limit {
                return Err(GpuError::TooLarge { what, bytes, limit }.into());
            }
        }
        let flat: Vec<f32> = grid
            .data()
            .iter()
            .flat_map(|b| b.0.iter().flat_map(|v| v.to_array()))
            .collect();
        let mut packed = Vec::with_capacity(count * 8);
        for (i, p) in points.positions.iter().enumerate() {
            let n = points.normals.map(|n| n[i]);
            packed.extend_from_slice(&[p.x, p.y, p.z, if n.is_some() { 1.0 } else { 0.0 }]);
            let n = n.unwrap_or(Vec3::Y);
            packed.extend_from_slice(&[n.x, n.y, n.z, 0.0]);
        }
        let d = grid.desc();
        let params = SampleParams {
            origin_h: d.origin().extend(d.h()).to_array(),
            dims: d.dims().extend(IrradianceTable::get().size).to_array(),
            count: count as u32,
            ..Default::default()
        };
        let init = |label, contents: &[u8], usage| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage,
            })
        };
        let uniform = init(
            "sample params",
            bytemuck::bytes_of(&params),
            wgpu::BufferUsages::UNIFORM,
        );
        let bins = init(
            "sample bins",
            bytemuck::cast_slice(&flat),
            wgpu::BufferUsages::STORAGE,
        );
        let pts = init(
            "sample points",
            bytemuck::cast_slice(&packed),
            wgpu::BufferUsages::STORAGE,
        );
        let out = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("sampled light"),
            size: point_bytes,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("sample"),
            layout: &self.layout,
            entries: &[
                (0, &uniform),
                (1, &bins),
                (2, &pts),
                (3, &self.table),
                (4, &out),
            ]
            .map(|(binding, b)| wgpu::BindGroupEntry {
                binding,
                resource: b.as_entire_binding(),
            }),
        });
        let mut enc = device.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups((count as u32).div_ceil(WORKGROUP), 1, 1);
        }
        self.ctx.queue.submit([enc.finish()]);
        let bytes = self.ctx.read_back(&out)?;
        let mut result: Vec<SampledLight> = bytemuck::pod_collect_to_vec(&bytes);
        for r in &mut result {
            if !r.light.is_finite() {
                r.light = Vec3::ZERO;
            }
            if !r.dominant.is_finite() {
                r.dominant = Vec3::ZERO;
            }
        }
        Ok(result)
    }
}
