//! The light sampling buffer as a wgpu compute pass.

use std::sync::Arc;

use lightgrid_core::glam::{UVec3, Vec3};
use lightgrid_core::{GridError, LightGrid, NUM_DIRS};
use lightgrid_gpu::{GpuContext, GpuError, bind};
use wgpu::util::DeviceExt;

use crate::RenderError;
use crate::dynamic::{DynParams, DynamicLights, DynamicShade};
use crate::sampling::{IrradianceTable, SamplePoints, SampledLight};

lightgrid_gpu::gpu_struct! {
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
        use Binding::{Read, ReadWrite, Uniform};
        let (layout, pipeline) = compute(
            device,
            "sample",
            &crate::wgsl::sample_kernel(),
            &[Uniform, Read, Read, Read, ReadWrite],
        );
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
        let flat = flatten(grid.data());
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
        let bind = bind(
            device,
            &self.layout,
            &[&uniform, &bins, &pts, &self.table, &out],
        );
        dispatch(&self.ctx, &self.pipeline, &bind, count as u32);
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

/// How a compute kernel binds a buffer (bindings are numbered in order from 0).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Binding {
    Uniform,
    Read,
    ReadWrite,
}

/// A compute pipeline of `src` (entry point `main`) with one bind group of `bindings`.
fn compute(
    device: &wgpu::Device,
    label: &str,
    src: &str,
    bindings: &[Binding],
) -> (wgpu::BindGroupLayout, wgpu::ComputePipeline) {
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(src.into()),
    });
    let entries: Vec<wgpu::BindGroupLayoutEntry> = bindings
        .iter()
        .enumerate()
        .map(|(i, b)| {
            let stage = wgpu::ShaderStages::COMPUTE;
            match b {
                Binding::Uniform => bind::uniform(i as u32, stage),
                Binding::Read => bind::storage(i as u32, stage, true),
                Binding::ReadWrite => bind::storage(i as u32, stage, false),
            }
        })
        .collect();
    let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(label),
        entries: &entries,
    });
    let pl = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: &[Some(&layout)],
        immediate_size: 0,
    });
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(label),
        layout: Some(&pl),
        module: &module,
        entry_point: Some("main"),
        compilation_options: Default::default(),
        cache: None,
    });
    (layout, pipeline)
}

/// A bind group of `buffers`, bound in order from 0.
fn bind(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    buffers: &[&wgpu::Buffer],
) -> wgpu::BindGroup {
    let entries: Vec<wgpu::BindGroupEntry> = buffers
        .iter()
        .enumerate()
        .map(|(i, b)| wgpu::BindGroupEntry {
            binding: i as u32,
            resource: b.as_entire_binding(),
        })
        .collect();
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: None,
        layout,
        entries: &entries,
    })
}

/// One dispatch of `count` invocations (workgroups of 64).
fn dispatch(
    ctx: &GpuContext,
    pipeline: &wgpu::ComputePipeline,
    bind: &wgpu::BindGroup,
    count: u32,
) {
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    {
        let mut pass = enc.begin_compute_pass(&Default::default());
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, bind, &[]);
        pass.dispatch_workgroups(count.div_ceil(WORKGROUP), 1, 1);
    }
    ctx.queue.submit([enc.finish()]);
}

fn init(ctx: &GpuContext, label: &str, contents: &[u8], usage: wgpu::BufferUsages) -> wgpu::Buffer {
    // Bindings need at least one element (64 bytes covers every struct here).
    let padded;
    let contents = if contents.len() < 64 {
        padded = [contents, &[0u8; 64][..64 - contents.len()]].concat();
        &padded[..]
    } else {
        contents
    };
    ctx.device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents,
            usage,
        })
}

/// Dynamic-light shading of a batch of points on the GPU, through the same WGSL the mesh
/// shader uses (tests compare it with [`crate::dynamic`]).
pub struct GpuDynamicShader {
    ctx: Arc<GpuContext>,
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
}

impl GpuDynamicShader {
    /// Compiles the kernel.
    pub fn new(ctx: Arc<GpuContext>) -> Self {
        use Binding::{Read, ReadWrite, Uniform};
        let (layout, pipeline) = compute(
            &ctx.device,
            "dynamic lights",
            &crate::wgsl::dynamic_kernel(),
            &[Uniform, Read, Read, Read, Read, ReadWrite],
        );
        Self {
            ctx,
            pipeline,
            layout,
        }
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
            init(
                ctx,
                "params",
                bytemuck::bytes_of(&params),
                wgpu::BufferUsages::UNIFORM,
            ),
            init(
                ctx,
                "lights",
                bytemuck::cast_slice(&lights.gpu_lights()),
                storage,
            ),
            init(ctx, "cells", bytemuck::cast_slice(&lights.cells), storage),
            init(
                ctx,
                "indices",
                bytemuck::cast_slice(&lights.indices),
                storage,
            ),
            init(ctx, "points", bytemuck::cast_slice(&packed), storage),
        ];
        let out = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("dynamic out"),
            size: points.len() as u64 * 32,
            usage: storage | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let refs: Vec<&wgpu::Buffer> = buffers.iter().chain([&out]).collect();
        let b = bind(&ctx.device, &self.layout, &refs);
        dispatch(ctx, &self.pipeline, &b, points.len() as u32);
        let v: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(&ctx.read_back(&out)?);
        Ok(v.chunks(2)
            .map(|c| DynamicShade {
                diffuse: Vec3::new(c[0][0], c[0][1], c[0][2]),
                specular: Vec3::new(c[1][0], c[1][1], c[1][2]),
            })
            .collect())
    }
}

/// A 26-bin light grid on the GPU (78 `f32` a point, grid order), updated in place:
/// [`GpuBinGrid::upload_region`] writes only the rows of a changed box, as when one local
/// light toggles.
pub struct GpuBinGrid {
    ctx: Arc<GpuContext>,
    buffer: wgpu::Buffer,
    desc: lightgrid_core::GridDesc,
}

const POINT_BYTES: u64 = NUM_DIRS as u64 * 12;

impl GpuBinGrid {
    /// Uploads the whole grid.
    pub fn new(ctx: Arc<GpuContext>, grid: &LightGrid) -> Result<Self, RenderError> {
        let bytes = grid.data().len() as u64 * POINT_BYTES;
        if bytes > ctx.max_binding() {
            return Err(GpuError::TooLarge {
                what: "light grid",
                bytes,
                limit: ctx.max_binding(),
            }
            .into());
        }
        let buffer = init(
            &ctx,
            "bin grid",
            bytemuck::cast_slice(&flatten(grid.data())),
            wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_DST
                | wgpu::BufferUsages::COPY_SRC,
        );
        Ok(Self {
            ctx,
            buffer,
            desc: *grid.desc(),
        })
    }

    /// The buffer (bind it as `array<f32>`).
    pub fn buffer(&self) -> &wgpu::Buffer {
        &self.buffer
    }

    /// Writes the points `lo ..= hi` of `grid` (same descriptor) one x-row at a time;
    /// returns the bytes written.
    pub fn upload_region(
        &self,
        grid: &LightGrid,
        lo: UVec3,
        hi: UVec3,
    ) -> Result<u64, RenderError> {
        if grid.desc() != &self.desc {
            return Err(GridError::invalid(
                "grid",
                grid.desc(),
                "must have the uploaded grid's descriptor",
            )
            .into());
        }
        if lo.cmpgt(hi).any() || hi.cmpge(self.desc.dims()).any() {
            return Err(GridError::invalid("hi", hi, "need lo <= hi < dims").into());
        }
        let mut written = 0;
        for y in lo.y..=hi.y {
            for z in lo.z..=hi.z {
                let start = self.desc.index_unchecked(UVec3::new(lo.x, y, z));
                let end = start + (hi.x - lo.x + 1) as usize;
                let row = flatten(&grid.data()[start..end]);
                self.ctx.queue.write_buffer(
                    &self.buffer,
                    start as u64 * POINT_BYTES,
                    bytemuck::cast_slice(&row),
                );
                written += (end - start) as u64 * POINT_BYTES;
            }
        }
        Ok(written)
    }

    /// Reads the grid back (tests).
    pub fn read(&self) -> Result<LightGrid, RenderError> {
        let v: Vec<f32> = bytemuck::pod_collect_to_vec(&self.ctx.read_back(&self.buffer)?);
        let data = v
            .chunks(NUM_DIRS * 3)
            .take(self.desc.point_count())
            .map(|c| {
                lightgrid_core::BinLight(std::array::from_fn(|d| {
                    Vec3::new(c[3 * d], c[3 * d + 1], c[3 * d + 2])
                }))
            })
            .collect();
        Ok(lightgrid_core::Grid::from_trusted(self.desc, data))
    }
}

fn flatten(points: &[lightgrid_core::BinLight]) -> Vec<f32> {
    bytemuck::cast_slice(points).to_vec()
}
