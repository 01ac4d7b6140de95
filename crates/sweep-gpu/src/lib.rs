//! # sweep-gpu
//!
//! The light-flow sweep of `sweep-cpu` as wgpu compute shaders (WGSL), so light grids can
//! be rebuilt on the GPU around a moving camera. [`GpuSweeper`] implements
//! `lightgrid_core::Sweeper`: callers cannot tell which sweeper runs.
//!
//! ```no_run
//! use lightgrid_core::{Sweeper, SweepOptions};
//! use lightgrid_measure::scenes::Scene;
//! use lightgrid_sweep_gpu::GpuSweeper;
//!
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! // Err(GpuError::NoAdapter) without a GPU or lavapipe: fall back to
//! // lightgrid_sweep_cpu::CpuSweeper.
//! let mut gpu = GpuSweeper::new()?;
//! let (material, boundary) = Scene::Canopy.build(32);
//! let light = gpu.sweep(&material, &boundary, &SweepOptions::multi_bounce())?;
//! assert!(light.bins.is_some());
//! # Ok(())
//! # }
//! ```
//!
//! ## How it maps sweep-cpu's steps
//!
//! Per level, two dispatches (one thread per point): `phase1` gathers (step 1) and
//! transmits along each channel's path (step 2), recording removals and `T_after` in a
//! level scratch buffer; `phase2` collects, absorbs, emits and re-absorbs (steps 3–7) and
//! updates the two pending buffers (downward, upward). Levels ping-pong between two level
//! buffers; per-level parameters sit at 256-byte dynamic offsets of a read-only storage
//! buffer, so one command buffer holds a whole pass. (Not a uniform buffer: Mesa's
//! lavapipe compiles a shader again whenever a uniform that steers its control flow
//! changes, at every level of every pass; that made a sweep on lavapipe twice as slow.)
//! The device, layouts and pipelines are created once ([`GpuSweeper::new`]) and
//! reused; grids whose buffers exceed the device's storage
//! binding limit are refused with [`GpuError::TooLarge`] naming the buffer and the limit.
//!
//! [`GpuSunTransmittance`] is sweep-cpu's exact sun march (`SunTransmittance::march`)
//! with one thread per point, equal to it within 1e-4 relative.
//!
//! [`GpuSweeper::run_packed`] packs the final grid to R11G11B10 on the GPU (the exposure
//! from the largest value, found with an atomic max) and reads back only the words;
//! they equal `LightGrid::pack` of sweep-cpu's grid within one code per channel.
//!
//! **One source for shared constants.** The direction tables, channel steps, flux
//! factors, bins, stencils, path exponents and surface weights are generated from
//! `grid-core` and `sweep-cpu` ([`wgsl`]): scalars as WGSL constants, tables as one
//! buffer uploaded once (`wgsl::table_floats`) with a generated accessor per table;
//! nothing is copied by hand. Every
//! WGSL source is validated by naga in a plain `cargo test`.
//!
//! **Tolerance.** Outputs equal sweep-cpu's within relative 1e-4 of the larger value plus
//! 1e-5 of the grid's largest value (the GPU sums in another order and its `exp`/`log`
//! differ in the last bits); tested on random grids of 1 to 40 points a side, every
//! boundary mode, with `tolerance = 0`. With `tolerance > 0` the stopping test sums `f32`
//! on the GPU where sweep-cpu sums `f64`, so the two may stop one pass apart when the
//! light still to transport lies within rounding of the threshold. The GPU computes the
//! levels above all material that sweep-cpu copies in a downward pass and carries once
//! for all upward passes (the same values up to rounding; sweep-cpu books their input
//! as the GPU does, so both stopping tests divide by the same input), so `SweepStats`
//! differ.
//!
//! **Acceleration.** `SweepOptions::acceleration` is not implemented on the GPU: the
//! passes run plain (`SweepStats::corrections` is 0), which for thick, bright media
//! takes more passes to the tolerance than sweep-cpu's diffusion acceleration
//! (`lightgrid_sweep_cpu::accel`); both converge to the same light.
//!
//! **The halo's paths.** `SweepOptions::halo_paths` (off by default) is not
//! implemented either: with given sides the GPU sweeper returns an error for it, and
//! `Sweeper::carries_halo_paths` is false, so a hierarchy does not ask it.
//!
//! **Speed** (`cargo bench -p lightgrid-sweep-gpu`): on the CI machine the adapter is
//! lavapipe, Mesa's software Vulkan on the same two cores (a 2-core Intel Xeon VM,
//! 2026-12-05): 32³ canopy, 4 passes, 1.62 s against sweep-cpu's 22 ms (upload 23 ms,
//! readback 18 ms); 64³: 12.7 s against 0.13 s. On an NVIDIA H200 a level costs about
//! 150–200 µs whatever its size, so the 32³ canopy took 49 ms against 34 ms on its 16
//! CPU cores (measured before the tables left WGSL `const` arrays; the repository's
//! `docs/measurements.md`): the GPU sweeper does not win on small grids.
//!
//! GPU tests need an adapter; in CI that is lavapipe. Without one they fail, unless
//! `LIGHTGRID_ALLOW_NO_GPU=1` is set, in which case they say loudly that they did not run.
//!
//! ## Map
//!
//! - [`sweep`]: [`GpuSweeper`], sweep-cpu's semantics with one dispatch pair per level.
//! - [`sun`]: the sun's transmittance march on the GPU.
//! - [`wgsl`]: the WGSL sources, their constants and tables generated from sweep-cpu.

pub mod sun;
pub mod sweep;
pub mod wgsl;

pub use sun::GpuSunTransmittance;
pub use sweep::{GpuSweeper, GpuTimings};

use lightgrid_core::glam::Vec3;
use wgpu::util::DeviceExt;

use lightgrid_gpu::kernel::{Binding, Kernel};
pub use lightgrid_gpu::{GpuContext, GpuError, GpuLightGrid};

/// Packs light to R11G11B10 on the GPU, and finds the largest value for the exposure;
/// the pipelines are created once.
pub struct GpuPacker {
    pack: Kernel,
    max: Kernel,
}

impl GpuPacker {
    /// Compiles the kernels.
    pub fn new(ctx: &GpuContext) -> Self {
        use Binding::{Read, ReadWrite, Uniform};
        let make = |name: &str, src: String| {
            Kernel::new(&ctx.device, name, &src, &[Uniform, Read, ReadWrite])
        };
        Self {
            pack: make("pack", wgsl::pack_kernel()),
            max: make("max", wgsl::max_kernel()),
        }
    }

    /// `values × exposure`, packed. The output buffer starts filled with `u32::MAX` (an
    /// impossible word: its exponents are 31), so an unwritten word cannot pass a test.
    pub fn pack(
        &self,
        ctx: &GpuContext,
        values: &[Vec3],
        exposure: f32,
    ) -> Result<Vec<u32>, GpuError> {
        let bytes = (values.len().max(1) * 12) as u64;
        if bytes > ctx.max_binding() {
            return Err(GpuError::TooLarge {
                what: "input light",
                bytes,
                limit: ctx.max_binding(),
            });
        }
        let mut flat: Vec<f32> = values.iter().flat_map(|v| v.to_array()).collect();
        flat.resize(values.len().max(1) * 3, 0.0);
        let input = ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("pack input"),
                contents: bytemuck::cast_slice(&flat),
                usage: wgpu::BufferUsages::STORAGE,
            });
        self.pack_buffer(ctx, &input, values.len(), exposure)
    }

    fn run(
        &self,
        ctx: &GpuContext,
        kernel: &Kernel,
        input: &wgpu::Buffer,
        count: usize,
        exposure: f32,
        output: &wgpu::Buffer,
    ) {
        let params = lightgrid_gpu::kernel::buffer(
            ctx,
            "pack params",
            bytemuck::cast_slice(&[count as u32, exposure.to_bits()]),
            wgpu::BufferUsages::UNIFORM,
        );
        let bind = kernel.bind(&ctx.device, &[&params, input, output]);
        kernel.dispatch(ctx, &bind, count as u32);
    }

    /// Packs the first `count` RGB triples of a GPU buffer of `f32`.
    pub fn pack_buffer(
        &self,
        ctx: &GpuContext,
        input: &wgpu::Buffer,
        count: usize,
        exposure: f32,
    ) -> Result<Vec<u32>, GpuError> {
        let sentinel = vec![u32::MAX; count.max(1)];
        let output = ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("pack output"),
                contents: bytemuck::cast_slice(&sentinel),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            });
        self.run(ctx, &self.pack, input, count, exposure, &output);
        let data = ctx.read_back(&output)?;
        Ok(bytemuck::cast_slice::<u8, u32>(&data)[..count].to_vec())
    }

    /// The largest channel value among the first `count` RGB triples (0 if none is > 0;
    /// infinity if one is).
    pub fn max_of(
        &self,
        ctx: &GpuContext,
        input: &wgpu::Buffer,
        count: usize,
    ) -> Result<f32, GpuError> {
        let output = ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("max output"),
                contents: bytemuck::cast_slice(&[0u32]),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            });
        self.run(ctx, &self.max, input, count, 1.0, &output);
        let data = ctx.read_back(&output)?;
        Ok(f32::from_bits(bytemuck::cast_slice::<u8, u32>(&data)[0]))
    }
}
