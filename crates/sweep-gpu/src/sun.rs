//! The sun transmittance march on the GPU: `lightgrid_sweep_cpu::SunTransmittance::march` with one
//! thread per point (`shaders/sun.wgsl`), equal to it within `f32` rounding of `log` and
//! `exp` (property-tested on lavapipe). What arrives where a ray leaves the grid is one
//! constant here (1 for open sky); the CPU march also takes a function of the exit point.

use std::sync::Arc;

use lightgrid_core::glam::Vec3;
use lightgrid_core::{GridError, MaterialGrid};
use lightgrid_gpu::kernel::{Binding, Kernel, buffer};
use lightgrid_sweep_cpu::SunTransmittance;

use crate::{GpuContext, GpuError};

lightgrid_gpu::gpu_struct! {
    /// Uniforms of the sun march.
    pub struct SunParams {
        /// Grid dims (xyz), 1 for periodic sides (w).
        pub dims: [u32; 4] => "vec4<u32>",
        /// Unit direction toward the sun (xyz) and the transmittance beyond the grid (w).
        pub dir_outside: [f32; 4] => "vec4<f32>",
        /// Most cell steps of one ray (x).
        pub steps: [u32; 4] => "vec4<u32>",
    }
}

/// The compiled march.
pub struct GpuSunTransmittance {
    ctx: Arc<GpuContext>,
    kernel: Kernel,
}

/// Errors of the GPU march.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SunError {
    /// Invalid input (names the field and value).
    #[error(transparent)]
    Grid(#[from] GridError),
    /// The GPU failed.
    #[error(transparent)]
    Gpu(#[from] GpuError),
}

impl GpuSunTransmittance {
    /// Compiles the kernel on `ctx`.
    pub fn new(ctx: Arc<GpuContext>) -> Self {
        use Binding::{Read, ReadWrite, Uniform};
        let kernel = Kernel::new(
            &ctx.device,
            "sun transmittance",
            &crate::wgsl::sun_kernel(),
            &[Uniform, Read, ReadWrite],
        );
        Self { ctx, kernel }
    }

    /// The march toward `to_sun` (periodic sides wrapping, as sweep-cpu's) with
    /// transmittance `outside` beyond the grid (clamped to `[0, 1]`, NaN as 0), read
    /// back.
    pub fn march(
        &self,
        material: &MaterialGrid,
        to_sun: Vec3,
        periodic: bool,
        outside: f32,
    ) -> Result<SunTransmittance, SunError> {
        let desc = *material.desc();
        let Some(dir) = lightgrid_sweep_cpu::sun::sun_direction(to_sun)? else {
            return Ok(SunTransmittance::zero(desc));
        };
        let outside = if outside.is_nan() {
            0.0
        } else {
            outside.clamp(0.0, 1.0)
        };
        let n = desc.point_count();
        let bytes = n as u64 * 4;
        if bytes > self.ctx.max_binding() {
            return Err(GpuError::TooLarge {
                what: "sun transmittance",
                bytes,
                limit: self.ctx.max_binding(),
            }
            .into());
        }
        let d = desc.dims();
        let params = SunParams {
            dims: d.extend(periodic as u32).to_array(),
            dir_outside: dir.extend(outside).to_array(),
            steps: [
                lightgrid_sweep_cpu::sun::MAX_STEPS_PER_CELL * (d.x + d.y + d.z),
                0,
                0,
                0,
            ],
        };
        let pass: Vec<f32> = material.data().iter().map(|m| m.pass).collect();
        let storage = wgpu::BufferUsages::STORAGE;
        let uniform = buffer(
            &self.ctx,
            "sun params",
            bytemuck::bytes_of(&params),
            wgpu::BufferUsages::UNIFORM,
        );
        let cells = buffer(&self.ctx, "cell pass", bytemuck::cast_slice(&pass), storage);
        // A sentinel (-1, outside [0, 1]) so an unwritten point cannot pass.
        let out = buffer(
            &self.ctx,
            "sun transmittance",
            bytemuck::cast_slice(&vec![-1.0f32; n]),
            storage | wgpu::BufferUsages::COPY_SRC,
        );
        let bind = self
            .kernel
            .bind(&self.ctx.device, &[&uniform, &cells, &out]);
        self.kernel.dispatch(&self.ctx, &bind, n as u32);
        let values: Vec<f32> = bytemuck::pod_collect_to_vec(&self.ctx.read_back(&out)?);
        Ok(SunTransmittance::from_values(desc, values[..n].to_vec())?)
    }
}

#[cfg(test)]
mod tests {
    use super::SunParams;

    /// `SunParams` and its generated WGSL declaration agree in naga's layout.
    #[test]
    fn sun_params_match_the_wgsl_struct() {
        lightgrid_gpu::check::layout(
            &crate::wgsl::sun_kernel(),
            "SunParams",
            &SunParams::offsets(),
            std::mem::size_of::<SunParams>(),
        )
        .unwrap();
    }
}
