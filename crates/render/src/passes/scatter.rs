//! The scatter pass: sampled light ([`GpuSamples`]) written on the device into the rgb
//! of strided `f32` buffers (vertex light, ground light), so that it is drawn where it
//! was sampled.

use lightgrid_gpu::kernel::{Binding, Kernel, buffer};

use super::sample::GpuSamples;

/// The scatter kernel's WGSL: [`ScatterParams`] and `shaders/scatter.wgsl`.
pub fn wgsl() -> String {
    format!(
        "{}\n{}",
        ScatterParams::wgsl(),
        include_str!("../shaders/scatter.wgsl")
    )
}

lightgrid_gpu::gpu_struct! {
    /// Uniforms of the scatter kernel (sampled light into strided `f32` arrays).
    pub struct ScatterParams {
        /// Points.
        pub count: u32 => "u32",
        /// Floats from one destination element to the next.
        pub stride: u32 => "u32",
        /// Float offset of the light within an element.
        pub offset: u32 => "u32",
        /// Padding.
        pub pad0: u32 => "u32",
    }
}

/// Writes the light of [`GpuSamples`] into the rgb of a strided `f32` buffer on the
/// device (vertex light, ground light).
pub(crate) struct LightScatter {
    kernel: Kernel,
}

impl LightScatter {
    pub(crate) fn new(device: &wgpu::Device) -> Self {
        use Binding::{Read, ReadWrite, Uniform};
        Self {
            kernel: Kernel::new(device, "scatter", &wgsl(), &[Uniform, Read, ReadWrite]),
        }
    }

    /// `dst[i * stride + offset + k] = light[i][k]` for `k < 3`. The caller checked that
    /// `dst` holds `samples.count()` elements of `stride` floats.
    pub(crate) fn run(&self, samples: &GpuSamples, dst: &wgpu::Buffer, stride: u32, offset: u32) {
        let ctx = samples.context();
        let params = ScatterParams {
            count: samples.count() as u32,
            stride,
            offset,
            pad0: 0,
        };
        let uniform = buffer(
            ctx,
            "scatter params",
            bytemuck::bytes_of(&params),
            wgpu::BufferUsages::UNIFORM,
        );
        let bind = self
            .kernel
            .bind(&ctx.device, &[&uniform, samples.buffer(), dst]);
        self.kernel.dispatch(ctx, &bind, samples.count() as u32);
    }
}
