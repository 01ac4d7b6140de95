//! The tone-mapping pass: the linear HDR target into any colour target (sRGB images,
//! a window's surface) through ACES and the exposure (`shaders/tonemap.wgsl`;
//! `crate::shading::tonemap_aces` is the specification). One pipeline per target format,
//! made when first asked for.

use std::collections::HashMap;

use lightgrid_gpu::bind;

/// The tone-mapping shader's WGSL: the prelude and `shaders/tonemap.wgsl`.
pub fn wgsl() -> String {
    format!(
        "{}\n{}",
        crate::wgsl::prelude(),
        include_str!("../shaders/tonemap.wgsl")
    )
}

/// The pass: its layout, shader, exposure uniform and a pipeline per target format.
pub(crate) struct Tonemap {
    layout: wgpu::BindGroupLayout,
    module: wgpu::ShaderModule,
    uniform: wgpu::Buffer,
    pipelines: HashMap<wgpu::TextureFormat, wgpu::RenderPipeline>,
}

impl Tonemap {
    pub(crate) fn new(device: &wgpu::Device) -> Self {
        let fragment = wgpu::ShaderStages::FRAGMENT;
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("tonemap"),
            entries: &[
                bind::texture_2d(0, fragment, false),
                bind::uniform(1, fragment),
            ],
        });
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("tonemap"),
            source: wgpu::ShaderSource::Wgsl(wgsl().into()),
        });
        let uniform = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("tonemap"),
            size: 16,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Self {
            layout,
            module,
            uniform,
            pipelines: HashMap::new(),
        }
    }

    /// The bind group reading `hdr` (made again with the targets).
    pub(crate) fn bind(&self, device: &wgpu::Device, hdr: &wgpu::TextureView) -> wgpu::BindGroup {
        bind::group(
            device,
            "tonemap",
            &self.layout,
            [
                wgpu::BindingResource::TextureView(hdr),
                self.uniform.as_entire_binding(),
            ],
        )
    }

    /// The uniform buffer: the exposure, then three zeros (`vec4<f32>`).
    pub(crate) fn uniform(&self) -> &wgpu::Buffer {
        &self.uniform
    }

    /// The pipeline drawing into targets of `format`.
    pub(crate) fn pipeline(
        &mut self,
        device: &wgpu::Device,
        format: wgpu::TextureFormat,
    ) -> &wgpu::RenderPipeline {
        let (layout, module) = (&self.layout, &self.module);
        self.pipelines.entry(format).or_insert_with(|| {
            let pl = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("tonemap"),
                bind_group_layouts: &[Some(layout)],
                immediate_size: 0,
            });
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some("tonemap"),
                layout: Some(&pl),
                vertex: wgpu::VertexState {
                    module,
                    entry_point: Some("vs_main"),
                    compilation_options: Default::default(),
                    buffers: &[],
                },
                primitive: Default::default(),
                depth_stencil: None,
                multisample: Default::default(),
                fragment: Some(wgpu::FragmentState {
                    module,
                    entry_point: Some("fs_main"),
                    compilation_options: Default::default(),
                    targets: &[Some(format.into())],
                }),
                multiview_mask: None,
                cache: None,
            })
        })
    }
}
