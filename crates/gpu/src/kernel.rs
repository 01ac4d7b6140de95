//! Small compute kernels: one WGSL entry point `main`, one bind group of buffers bound in
//! order from 0, workgroups of [`WORKGROUP`] invocations along x. The sampling, scatter
//! and dynamic-light kernels of the renderer and the packing kernels of the GPU sweeper
//! are built this way (the sweep itself has its own dynamic-offset layouts).

use wgpu::util::DeviceExt;

use crate::{GpuContext, bind};

/// Invocations per workgroup (`@workgroup_size(64)` in every such kernel).
pub const WORKGROUP: u32 = 64;

/// How a kernel binds one buffer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Binding {
    /// `var<uniform>`.
    Uniform,
    /// `var<storage, read>`.
    Read,
    /// `var<storage, read_write>`.
    ReadWrite,
}

/// A compiled kernel and its bind group layout.
#[derive(Debug)]
pub struct Kernel {
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
}

impl Kernel {
    /// Compiles `src` (entry point `main`) with one bind group of `bindings`.
    pub fn new(device: &wgpu::Device, label: &str, src: &str, bindings: &[Binding]) -> Self {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(label),
            source: wgpu::ShaderSource::Wgsl(src.into()),
        });
        let stage = wgpu::ShaderStages::COMPUTE;
        let entries: Vec<wgpu::BindGroupLayoutEntry> = bindings
            .iter()
            .enumerate()
            .map(|(i, b)| match b {
                Binding::Uniform => bind::uniform(i as u32, stage),
                Binding::Read => bind::storage(i as u32, stage, true),
                Binding::ReadWrite => bind::storage(i as u32, stage, false),
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
        Self { layout, pipeline }
    }

    /// A bind group of `buffers`, bound in order from 0.
    pub fn bind(&self, device: &wgpu::Device, buffers: &[&wgpu::Buffer]) -> wgpu::BindGroup {
        crate::bind::group(
            device,
            "kernel",
            &self.layout,
            buffers.iter().map(|b| b.as_entire_binding()),
        )
    }

    /// Submits one dispatch of `count` invocations (at least one workgroup).
    pub fn dispatch(&self, ctx: &GpuContext, bind: &wgpu::BindGroup, count: u32) {
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, bind, &[]);
            pass.dispatch_workgroups(count.max(1).div_ceil(WORKGROUP), 1, 1);
        }
        ctx.queue.submit([enc.finish()]);
    }
}

/// A buffer holding `contents`, padded with zeros to at least 64 bytes (bindings may not
/// be empty, and 64 bytes covers every uniform struct of the kernels).
pub fn buffer(
    ctx: &GpuContext,
    label: &str,
    contents: &[u8],
    usage: wgpu::BufferUsages,
) -> wgpu::Buffer {
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
