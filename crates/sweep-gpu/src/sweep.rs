//! The GPU sweeper: sweep-cpu's semantics, one dispatch pair per level.

use lightgrid_core::dirs::HORIZONTAL_BINS;
use lightgrid_core::glam::Vec3;
use lightgrid_core::{
    BinLight, Boundary, CellSource, Grid, HALO_WIDTH, HaloLayout, HorizonLight, MaterialGrid,
    NUM_DIRS, PackedBins, PackedLightGrid, Resident, SideBoundary, SweepError, SweepOptions,
    SweepOutput, SweepStats, Sweeper,
};
use lightgrid_sweep_cpu::sweep::{CHANNELS, channel_value_halves, channels, virtual_level_light};
use wgpu::util::DeviceExt;

use std::sync::Arc;

use lightgrid_gpu::{GpuLightGrid, bind};

use crate::{GpuContext, GpuError, wgsl};

lightgrid_gpu::gpu_struct! {
    /// Parameters of one level (read-only storage at a dynamic offset); its WGSL
    /// declaration is generated from this list (`LevelParams::wgsl`), and a test
    /// compares the two layouts with naga.
    pub struct LevelParams {
        /// Points along x.
        pub nx: u32 => "u32",
        /// Points along z.
        pub nz: u32 => "u32",
        /// Points in a level.
        pub level_len: u32 => "u32",
        /// The level computed.
        pub j: u32 => "u32",
        /// The level light comes from (-1 or `ny`: the boundary).
        pub src_level: i32 => "i32",
        /// 1 when the source is the virtual boundary level.
        pub from_virtual: u32 => "u32",
        /// 1 on upward passes.
        pub up: u32 => "u32",
        /// 1 with periodic sides.
        pub periodic: u32 => "u32",
        /// 1 with given (halo) sides.
        pub given: u32 => "u32",
        /// Levels.
        pub ny: u32 => "u32",
        /// Smoothing weight.
        pub smoothing: f32 => "f32",
        /// The medium emission rule: 0 a slab's escape, 2 the flat source rule
        /// (`lightgrid_sweep_cpu::medium`), 3 its quadratic source in height
        /// (`lightgrid_sweep_cpu::profile`, the default).
        pub medium: u32 => "u32",
        /// 1 when the horizon halves are asked for (`Outputs::horizon`).
        pub horizon: u32 => "u32",
        /// Where they start in the light buffer (floats): after the bins.
        pub horizon_base: u32 => "u32",
    }
}

const PARAM_STRIDE: u64 = 256;
use crate::wgsl::SCRATCH;

/// The sweep as wgpu compute: device, pipelines and layouts are created once and reused
/// across sweeps. Implements [`Sweeper`]: outputs equal `sweep-cpu`'s within `f32`
/// rounding (relative 1e-4 plus an absolute floor; see the crate docs).
pub struct GpuSweeper {
    ctx: Arc<GpuContext>,
    phase1: wgpu::ComputePipeline,
    phase2: wgpu::ComputePipeline,
    phase3: wgpu::ComputePipeline,
    clamp: wgpu::ComputePipeline,
    layout1: wgpu::BindGroupLayout,
    layout2: wgpu::BindGroupLayout,
    surface_w: wgpu::Buffer,
    /// `wgsl::table_floats` (the profile's and the sweep's tables), uploaded once.
    tables: wgpu::Buffer,
    packer: crate::GpuPacker,
    keep_resident: bool,
}

/// A compute-stage storage buffer.
fn storage(binding: u32, read_only: bool) -> wgpu::BindGroupLayoutEntry {
    bind::storage(binding, wgpu::ShaderStages::COMPUTE, read_only)
}

/// The per-level parameters at dynamic offsets (storage, not uniform: see the crate docs).
fn params_dynamic() -> wgpu::BindGroupLayoutEntry {
    bind::storage_dynamic(
        0,
        wgpu::ShaderStages::COMPUTE,
        std::mem::size_of::<LevelParams>() as u64,
    )
}

impl GpuSweeper {
    /// Finds an adapter and compiles the kernels. `Err(GpuError::NoAdapter)` without one.
    pub fn new() -> Result<Self, GpuError> {
        Ok(Self::with_context(GpuContext::new()?))
    }

    /// The sweeper on an existing context: pass the renderer's `Arc` to share one device
    /// (swept grids then live on the device that draws them).
    pub fn with_context(ctx: impl Into<Arc<GpuContext>>) -> Self {
        let ctx = ctx.into();
        let d = &ctx.device;
        let layout1 = d.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("sweep phase 1"),
            entries: &[
                params_dynamic(),
                storage(1, true),
                storage(2, false),
                storage(3, false),
                storage(4, false),
                storage(5, false),
                storage(6, true),
                storage(7, true),
                storage(8, false),
                storage(9, true),
            ],
        });
        let layout2 = d.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("sweep phase 2"),
            entries: &[
                params_dynamic(),
                storage(1, true),
                storage(2, true),
                storage(3, false),
                storage(4, true),
                storage(5, false),
                storage(6, false),
                storage(7, false),
                storage(8, false),
                wgpu::BindGroupLayoutEntry {
                    binding: 9,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                storage(10, false),
                storage(11, true),
            ],
        });
        let module = |name: &str, src: String| {
            d.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(name),
                source: wgpu::ShaderSource::Wgsl(src.into()),
            })
        };
        // Phase 2's module (parsed and validated once) holds three entry points.
        let pipeline = |name: &str,
                        module: &wgpu::ShaderModule,
                        layout: &wgpu::BindGroupLayout,
                        entry: &str| {
            let pl = d.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some(name),
                bind_group_layouts: &[Some(layout)],
                immediate_size: 0,
            });
            d.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(name),
                layout: Some(&pl),
                module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        };
        let m1 = module("sweep phase 1", wgsl::sweep_phase1());
        let m2 = module("sweep phase 2", wgsl::sweep_phase2());
        let phase1 = pipeline("sweep phase 1", &m1, &layout1, "phase1");
        let phase2 = pipeline("sweep phase 2", &m2, &layout2, "phase2");
        let phase3 = pipeline("sweep phase 3", &m2, &layout2, "phase3");
        let clamp = pipeline("sweep clamp", &m2, &layout2, "clamp_light");
        let tables = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("sweep tables"),
            contents: bytemuck::cast_slice(&wgsl::table_floats()),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let surface_w = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("surface weights"),
            contents: bytemuck::cast_slice(&wgsl::surface_weight_table()),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let packer = crate::GpuPacker::new(&ctx);
        Self {
            packer,
            keep_resident: false,
            surface_w,
            ctx,
            phase1,
            phase2,
            phase3,
            clamp,
            layout1,
            layout2,
            tables,
        }
    }

    /// The context (device and queue), shareable with a renderer.
    pub fn context(&self) -> &Arc<GpuContext> {
        &self.ctx
    }

    /// Whether sweeps through the [`Sweeper`] trait also return the grid as it lies on
    /// the device (`SweepOutput::resident`, a [`GpuLightGrid`]), besides the CPU copy.
    /// Off by default; a viewer drawing on this sweeper's device turns it on and samples
    /// and draws the grids where they are.
    pub fn keep_resident(&mut self, keep: bool) {
        self.keep_resident = keep;
    }

    /// The sweep with its 26-bin result left on the device: nothing is read back but
    /// the largest value (to refuse NaN and infinity). Sample or draw it on the same
    /// context (`lightgrid_render::GpuLightSampler::sample_layers`), or
    /// [`GpuLightGrid::read`] it.
    pub fn run_on_device(
        &self,
        material: &MaterialGrid,
        boundary: &Boundary,
        options: &SweepOptions,
    ) -> Result<(GpuLightGrid, SweepStats), SweepError> {
        let (g, stats, _) = self.execute(material, boundary, None, options)?;
        self.largest_finite(&g, material)?;
        let grid = GpuLightGrid::from_buffer(self.ctx.clone(), g, *material.desc())
            .map_err(gpu_backend)?;
        Ok((grid, stats))
    }

    fn buffer(&self, label: &str, data: &[f32], extra: wgpu::BufferUsages) -> wgpu::Buffer {
        let data: &[f32] = if data.is_empty() { &[0.0] } else { data };
        self.ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: bytemuck::cast_slice(data),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST | extra,
            })
    }

    fn check_size(&self, what: &'static str, floats: usize) -> Result<(), GpuError> {
        let bytes = floats as u64 * 4;
        if bytes > self.ctx.max_binding() {
            return Err(GpuError::TooLarge {
                what,
                bytes,
                limit: self.ctx.max_binding(),
            });
        }
        Ok(())
    }

    fn read_f32(&self, b: &wgpu::Buffer) -> Result<Vec<f32>, GpuError> {
        Ok(bytemuck::cast_slice::<u8, f32>(&self.ctx.read_back(b)?).to_vec())
    }

    /// Runs the sweep; see `sweep-cpu`'s docs for the semantics.
    pub fn run(
        &self,
        material: &MaterialGrid,
        boundary: &Boundary,
        options: &SweepOptions,
    ) -> Result<SweepOutput, SweepError> {
        Ok(self.run_timed(material, boundary, options)?.0)
    }

    /// [`GpuSweeper::run`] with light already deposited in cells
    /// (`lightgrid_sweep_cpu::run_with_source`: the sun's first collisions), their first
    /// scatterings gathered on the CPU where `options.gather` asks
    /// (`lightgrid_sweep_cpu::gather::sweep_gathered`: the output then keeps no device
    /// copy of the bins).
    pub fn run_with_source(
        &self,
        material: &MaterialGrid,
        boundary: &Boundary,
        source: Option<&CellSource>,
        options: &SweepOptions,
    ) -> Result<SweepOutput, SweepError> {
        match source {
            Some(src) if options.gather.for_source().is_on() => {
                lightgrid_sweep_cpu::gather::sweep_gathered(
                    material,
                    boundary,
                    src,
                    options,
                    |s, o| Ok(self.timed(material, boundary, Some(s), o)?.0),
                )
            }
            _ => Ok(self.timed(material, boundary, source, options)?.0),
        }
    }

    /// [`GpuSweeper::run`], with the time spent uploading, computing and reading back.
    pub fn run_timed(
        &self,
        material: &MaterialGrid,
        boundary: &Boundary,
        options: &SweepOptions,
    ) -> Result<(SweepOutput, GpuTimings), SweepError> {
        self.timed(material, boundary, None, options)
    }

    fn timed(
        &self,
        material: &MaterialGrid,
        boundary: &Boundary,
        source: Option<&CellSource>,
        options: &SweepOptions,
    ) -> Result<(SweepOutput, GpuTimings), SweepError> {
        let (g, stats, mut timings) = self.execute(material, boundary, source, options)?;
        let n = material.desc().point_count();
        let readback_start = std::time::Instant::now();
        let gd = self.read_f32(&g).map_err(gpu_backend)?;
        timings.readback = readback_start.elapsed();
        let bins: Vec<BinLight> = (0..n)
            .map(|i| {
                BinLight(std::array::from_fn(|b| {
                    Vec3::from_slice(&gd[(i * 26 + b) * 3..(i * 26 + b) * 3 + 3])
                }))
            })
            .collect();
        if bins.iter().any(|b| !b.is_valid()) {
            return Err(overflow());
        }
        let horizon = options.outputs.horizon.then(|| {
            let h = &gd[n * NUM_DIRS * 3..];
            let down: Vec<HorizonLight> = (0..n)
                .map(|i| {
                    HorizonLight(std::array::from_fn(|k| {
                        let o = (i * HORIZONTAL_BINS + k) * 3;
                        Vec3::from_slice(&h[o..o + 3])
                    }))
                    .within(&bins[i])
                })
                .collect();
            Grid::from_trusted(*material.desc(), down)
        });
        let grid = Grid::from_trusted(*material.desc(), bins);
        let resident = if self.keep_resident {
            let g = GpuLightGrid::from_buffer(self.ctx.clone(), g, *material.desc())
                .map_err(gpu_backend)?;
            Some(Resident(Arc::new(g)))
        } else {
            None
        };
        Ok((
            SweepOutput {
                average: options.outputs.average.then(|| grid.average_grid()),
                dominant: options.outputs.dominant.then(|| grid.dominant_grid()),
                bins: options.outputs.bins.then_some(grid),
                horizon,
                stats,
                resident,
            },
            timings,
        ))
    }

    /// The sweep with the final grid packed to R11G11B10 on the GPU: the exposure is
    /// chosen as `LightGrid::pack` does (from the largest value, found on the GPU), and
    /// only the packed words (a third of the `f32` bytes) are read back.
    pub fn run_packed(
        &self,
        material: &MaterialGrid,
        boundary: &Boundary,
        options: &SweepOptions,
    ) -> Result<PackedLightGrid, SweepError> {
        let (g, _, _) = self.execute(material, boundary, None, options)?;
        let max = self.largest_finite(&g, material)?;
        let count = material.desc().point_count() * 26;
        let exposure = lightgrid_core::pack::exposure_for(max);
        let words = self
            .packer
            .pack_buffer(&self.ctx, &g, count, exposure)
            .map_err(gpu_backend)?;
        let bins = words
            .chunks_exact(26)
            .map(|w| PackedBins(w.try_into().expect("26 words")))
            .collect();
        PackedLightGrid::new(Grid::new(*material.desc(), bins)?, exposure).map_err(SweepError::from)
    }

    /// The largest value of a swept grid on the device (found there); an overflow error
    /// if it is not finite.
    fn largest_finite(&self, g: &wgpu::Buffer, material: &MaterialGrid) -> Result<f32, SweepError> {
        let count = material.desc().point_count() * 26;
        let max = self
            .packer
            .max_of(&self.ctx, g, count)
            .map_err(gpu_backend)?;
        if !max.is_finite() {
            return Err(overflow());
        }
        Ok(max)
    }

    fn execute(
        &self,
        material: &MaterialGrid,
        boundary: &Boundary,
        source: Option<&CellSource>,
        options: &SweepOptions,
    ) -> Result<(wgpu::Buffer, SweepStats, GpuTimings), SweepError> {
        let start = std::time::Instant::now();
        let mut timings = GpuTimings::default();
        lightgrid_sweep_cpu::sweep::validate_inputs(material, boundary, options)?;
        if options.halo_paths && boundary.sides.halo().is_some() {
            return Err(SweepError::Backend {
                backend: "gpu",
                message: "SweepOptions::halo_paths: the GPU sweeper does not trace the \
                          halo's paths (Sweeper::carries_halo_paths); set it off"
                    .into(),
            });
        }
        // The halo's light carried through its given cells, as on the CPU.
        let carried =
            lightgrid_core::halo_carry::carried_boundary(boundary, material.desc().dims());
        let boundary = &*carried;
        let backend = |e: GpuError| SweepError::Backend {
            backend: "gpu",
            message: e.to_string(),
        };
        let shape = Shape::of(material, boundary);
        // Which opaque faces are surfaces, as sweep-cpu finds them (once a sweep).
        let exposed =
            lightgrid_sweep_cpu::sweep::exposure_of(material, shape.periodic, shape.given);
        let bufs = self
            .buffers(material, (&shape, &exposed), options.outputs.horizon)
            .map_err(backend)?;
        let source_in = match source {
            Some(src) => self.upload_source(&bufs, material, (src, &exposed), options.medium)?,
            None => [0.0; 3],
        };
        let groups = self.bind_groups(&bufs);
        let workgroups = (shape.level_len as u32).div_ceil(64);
        let mut stats = SweepStats::default();
        timings.upload = start.elapsed();
        let compute_start = std::time::Instant::now();
        for pass in 0..options.max_passes {
            let up = pass % 2 == 1;
            // Boundary light enters on the first downward and the first upward pass only.
            self.upload_boundary(&bufs, &shape, boundary, up, pass < 2);
            let params = level_params(&shape, up, options);
            self.ctx.queue.write_buffer(&bufs.params, 0, &params);
            let sources = matches!(
                options.medium,
                lightgrid_core::MediumEmission::Source | lightgrid_core::MediumEmission::Profile
            );
            self.encode_pass(&groups, shape.ny, (up, sources), workgroups);
            stats.passes += 1;
            stats.levels_computed += shape.ny as u64;
            if options.tolerance > 0.0 && pass >= 1 {
                let pending: f64 = sum_max(&self.read_f32(&bufs.pend_flux).map_err(backend)?);
                let input: f64 = sums(&self.read_f32(&bufs.flux_in).map_err(backend)?)
                    .iter()
                    .zip(source_in)
                    .map(|(a, b)| a + b)
                    .fold(0.0, f64::max);
                if pending <= options.tolerance as f64 * input {
                    break;
                }
            }
        }
        if options.medium == lightgrid_core::MediumEmission::Profile {
            // A quadratic source may send light below 0: clamped, as sweep-cpu does.
            let mut enc = self.ctx.device.create_command_encoder(&Default::default());
            {
                let mut cp = enc.begin_compute_pass(&Default::default());
                cp.set_pipeline(&self.clamp);
                for li in 0..shape.ny {
                    let off = (li as u64 * PARAM_STRIDE) as u32;
                    cp.set_bind_group(0, &groups.phase2[0][0], &[off]);
                    cp.dispatch_workgroups(workgroups, 1, 1);
                }
            }
            self.ctx.queue.submit([enc.finish()]);
        }
        self.ctx
            .device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| backend(GpuError::Readback(e.to_string())))?;
        timings.compute = compute_start.elapsed();
        Ok((bufs.light, stats, timings))
    }

    /// Step 4 for a cell source, as sweep-cpu does it: `a × removed` waits in both
    /// pending buffers with its moment along the beam. Returns the flux it brings (RGB).
    fn upload_source(
        &self,
        bufs: &Buffers,
        material: &MaterialGrid,
        (src, exposed): (&CellSource, &[u8]),
        rule: lightgrid_core::MediumEmission,
    ) -> Result<[f64; 3], SweepError> {
        if src.removed().len() != material.data().len() {
            return Err(lightgrid_core::GridError::invalid(
                "source",
                src.removed().len(),
                "must lie on the material grid's descriptor",
            )
            .into());
        }
        let d = src.dir();
        let mut input = [0f64; 3];
        let pend: Vec<f32> = src
            .removed()
            .iter()
            .zip(material.data())
            .zip(exposed)
            .enumerate()
            .flat_map(|(i, ((&r, m), &e))| {
                for k in 0..3 {
                    input[k] += r[k] as f64;
                }
                if r != Vec3::ZERO && lightgrid_sweep_cpu::medium::profiled(rule, m.pass) {
                    // The profile rule: the beam's collisions as source coefficients,
                    // computed as sweep-cpu computes them.
                    let heights = src.heights().map(|h| h[i]);
                    let (j, _) = lightgrid_sweep_cpu::profile::beam_source(m, d, r, heights);
                    let z = 0.0;
                    return [
                        j[0].x, j[0].y, j[0].z, j[1].x, j[1].y, j[1].z, j[2].x, j[2].y, j[2].z, z,
                        z, z,
                    ];
                }
                // As sweep-cpu books it: an enclosed opaque cell absorbs (a beam from
                // beyond a given side may reach a ground's edge cell, which is no
                // surface there).
                let s = r * lightgrid_sweep_cpu::sweep::swept_reflectance(m, e);
                let (a, b, c) = (s * d.x, s * d.y, s * d.z);
                [s.x, s.y, s.z, a.x, a.y, a.z, b.x, b.y, b.z, c.x, c.y, c.z]
            })
            .collect();
        for p in &bufs.pend {
            self.ctx
                .queue
                .write_buffer(p, 0, bytemuck::cast_slice(&pend));
        }
        Ok(input)
    }

    /// Every buffer of one sweep, sized and checked against the binding limit; material
    /// and exposure uploaded, the rest zero.
    fn buffers(
        &self,
        material: &MaterialGrid,
        (shape, masks): (&Shape, &[u8]),
        horizon: bool,
    ) -> Result<Buffers, GpuError> {
        let (n, level_len) = (shape.n, shape.level_len);
        // The bins, then the horizon halves if asked for.
        let light = n * (NUM_DIRS + if horizon { HORIZONTAL_BINS } else { 0 }) * 3;
        for (what, floats) in [
            ("light grid", light),
            ("pending light", n * 12),
            ("halo", shape.halo.len() * CHANNELS * 3),
            ("level scratch", level_len * SCRATCH),
        ] {
            self.check_size(what, floats)?;
        }
        // Enclosed opaque cells absorb what reaches them, as on the CPU.
        let cells: Vec<f32> = material
            .data()
            .iter()
            .zip(masks)
            .flat_map(|(m, &e)| {
                let r = lightgrid_sweep_cpu::sweep::swept_reflectance(m, e);
                [r.x, r.y, r.z, m.pass]
            })
            .collect();
        let exposed: Vec<u32> = masks.iter().map(|&m| m as u32).collect();
        let d = &self.ctx.device;
        let zeros =
            |label: &str, floats: usize, extra| self.buffer(label, &vec![0.0; floats], extra);
        let none = wgpu::BufferUsages::empty();
        let src = wgpu::BufferUsages::COPY_SRC;
        let level = level_len * CHANNELS * 3;
        Ok(Buffers {
            cells: self.buffer("cells", &cells, none),
            exposed: d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("exposed"),
                contents: bytemuck::cast_slice(&exposed),
                usage: wgpu::BufferUsages::STORAGE,
            }),
            ping: [zeros("level A", level, none), zeros("level B", level, none)],
            scratch: zeros("scratch", level_len * SCRATCH, none),
            light: zeros("light", light, src),
            virt: zeros("virtual level", shape.padded * CHANNELS * 3, none),
            halo: zeros("halo", (shape.halo.len() * CHANNELS * 3).max(1), none),
            flux_in: zeros("input flux", level_len * 3, src),
            pend: [
                zeros("pending down", n * 12, none),
                zeros("pending up", n * 12, none),
            ],
            pend_flux: zeros("pending flux", n * 3, src),
            srcj: zeros("level sources", level_len * 9, none),
            params: d.create_buffer(&wgpu::BufferDescriptor {
                label: Some("level params"),
                size: PARAM_STRIDE * shape.ny as u64,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
        })
    }

    /// Phase 1 bind groups by `k` (previous level = `ping[k]`, current = `ping[1 - k]`);
    /// phase 2 by current level and direction (pending of this direction, of the other).
    fn bind_groups(&self, b: &Buffers) -> BindGroups {
        let d = &self.ctx.device;
        let pbind = wgpu::BindingResource::Buffer(wgpu::BufferBinding {
            buffer: &b.params,
            offset: 0,
            size: wgpu::BufferSize::new(std::mem::size_of::<LevelParams>() as u64),
        });
        let phase1 = |k: usize| {
            bind::group(
                d,
                "phase 1",
                &self.layout1,
                [
                    pbind.clone(),
                    b.cells.as_entire_binding(),
                    b.ping[k].as_entire_binding(),
                    b.ping[1 - k].as_entire_binding(),
                    b.scratch.as_entire_binding(),
                    b.light.as_entire_binding(),
                    b.virt.as_entire_binding(),
                    b.halo.as_entire_binding(),
                    b.flux_in.as_entire_binding(),
                    self.tables.as_entire_binding(),
                ],
            )
        };
        let phase2 = |c: usize, up: usize| {
            bind::group(
                d,
                "phase 2",
                &self.layout2,
                [
                    pbind.clone(),
                    b.cells.as_entire_binding(),
                    b.exposed.as_entire_binding(),
                    b.ping[c].as_entire_binding(),
                    b.scratch.as_entire_binding(),
                    b.light.as_entire_binding(),
                    b.pend[up].as_entire_binding(),
                    b.pend[1 - up].as_entire_binding(),
                    b.pend_flux.as_entire_binding(),
                    self.surface_w.as_entire_binding(),
                    b.srcj.as_entire_binding(),
                    self.tables.as_entire_binding(),
                ],
            )
        };
        BindGroups {
            phase1: [phase1(0), phase1(1)],
            phase2: [[phase2(0, 0), phase2(0, 1)], [phase2(1, 0), phase2(1, 1)]],
        }
    }

    /// The boundary light of one pass as channel light: the virtual level (padded
    /// columns), the halo of given sides, and the first level's "previous" buffer. On
    /// passes after the first two (`active` false) all of it is zero.
    fn upload_boundary(
        &self,
        b: &Buffers,
        shape: &Shape,
        boundary: &Boundary,
        up: bool,
        active: bool,
    ) {
        let (nx, nz, w) = (shape.nx, shape.nz, HALO_WIDTH as usize);
        let ch = channels(up);
        let mut v = vec![0.0f32; shape.padded * CHANNELS * 3];
        if active {
            for pz in 0..nz + 2 * w {
                for px in 0..nx + 2 * w {
                    let (x, z) = (px as i32 - w as i32, pz as i32 - w as i32);
                    let light = virtual_level_light(boundary, up, x, z, shape.dims);
                    for (c, chn) in ch.iter().enumerate() {
                        let i = ((pz * (nx + 2 * w) + px) * CHANNELS + c) * 3;
                        v[i..i + 3].copy_from_slice(&light.0[chn.bin].to_array());
                    }
                }
            }
        }
        self.ctx
            .queue
            .write_buffer(&b.virt, 0, bytemuck::cast_slice(&v));
        if let Some(h) = boundary.sides.halo() {
            let down = boundary.sides.halo_down();
            let mut hv = vec![0.0f32; shape.halo.len() * CHANNELS * 3];
            if active {
                for (i, l) in h.iter().enumerate() {
                    let d = down.map(|d| &d[i]);
                    for (c, chn) in ch.iter().enumerate() {
                        let o = (i * CHANNELS + c) * 3;
                        hv[o..o + 3]
                            .copy_from_slice(&channel_value_halves(l, d, chn, true).to_array());
                    }
                }
            }
            self.ctx
                .queue
                .write_buffer(&b.halo, 0, bytemuck::cast_slice(&hv));
        }
        // The first level gathers from the virtual level: fill the "previous" buffer.
        let mut first = vec![0.0f32; shape.level_len * CHANNELS * 3];
        for z in 0..nz {
            for x in 0..nx {
                let src = (((z + w) * (nx + 2 * w) + x + w) * CHANNELS) * 3;
                let dst = ((z * nx + x) * CHANNELS) * 3;
                first[dst..dst + CHANNELS * 3].copy_from_slice(&v[src..src + CHANNELS * 3]);
            }
        }
        self.ctx
            .queue
            .write_buffer(&b.ping[0], 0, bytemuck::cast_slice(&first));
    }

    /// One pass in one command buffer: per level, phase 1 then phase 2 (and phase 3
    /// under the source rule, `sources`), each level's parameters at its dynamic offset.
    fn encode_pass(&self, g: &BindGroups, ny: usize, (up, sources): (bool, bool), workgroups: u32) {
        let mut enc = self.ctx.device.create_command_encoder(&Default::default());
        // One compute pass for the whole sweep pass: each dispatch is a usage scope of
        // its own, so a level's writes are visible to the next dispatch.
        let mut cp = enc.begin_compute_pass(&Default::default());
        for li in 0..ny {
            let k = li % 2; // prev = ping[k], cur = ping[1 - k]
            let off = (li as u64 * PARAM_STRIDE) as u32;
            cp.set_pipeline(&self.phase1);
            cp.set_bind_group(0, &g.phase1[k], &[off]);
            cp.dispatch_workgroups(workgroups, 1, 1);
            cp.set_pipeline(&self.phase2);
            cp.set_bind_group(0, &g.phase2[1 - k][usize::from(up)], &[off]);
            cp.dispatch_workgroups(workgroups, 1, 1);
            if sources {
                cp.set_pipeline(&self.phase3);
                cp.dispatch_workgroups(workgroups, 1, 1);
            }
        }
        drop(cp);
        self.ctx.queue.submit([enc.finish()]);
    }
}

/// Sizes of one sweep.
struct Shape {
    dims: lightgrid_core::glam::UVec3,
    nx: usize,
    ny: usize,
    nz: usize,
    level_len: usize,
    n: usize,
    /// Points of a level padded by the halo width on every side.
    padded: usize,
    periodic: bool,
    given: bool,
    halo: HaloLayout,
}

impl Shape {
    fn of(material: &MaterialGrid, boundary: &Boundary) -> Self {
        let dims = material.desc().dims();
        let (nx, ny, nz) = (dims.x as usize, dims.y as usize, dims.z as usize);
        let w = HALO_WIDTH as usize;
        Self {
            dims,
            nx,
            ny,
            nz,
            level_len: nx * nz,
            n: material.desc().point_count(),
            padded: (nx + 2 * w) * (nz + 2 * w),
            periodic: matches!(boundary.sides, SideBoundary::Periodic),
            given: boundary.sides.halo().is_some(),
            halo: HaloLayout::new(dims),
        }
    }
}

/// The GPU buffers of one sweep.
struct Buffers {
    cells: wgpu::Buffer,
    exposed: wgpu::Buffer,
    /// Two level buffers, ping-ponged.
    ping: [wgpu::Buffer; 2],
    scratch: wgpu::Buffer,
    /// The output: 26 bins × RGB a point.
    light: wgpu::Buffer,
    virt: wgpu::Buffer,
    halo: wgpu::Buffer,
    flux_in: wgpu::Buffer,
    /// Pending light, downward and upward.
    pend: [wgpu::Buffer; 2],
    pend_flux: wgpu::Buffer,
    /// The source rule's source per cell of the level.
    srcj: wgpu::Buffer,
    params: wgpu::Buffer,
}

struct BindGroups {
    phase1: [wgpu::BindGroup; 2],
    phase2: [[wgpu::BindGroup; 2]; 2],
}

/// The per-level parameters of one pass, at [`PARAM_STRIDE`]-byte strides, in the order the
/// levels are computed.
fn level_params(shape: &Shape, up: bool, options: &SweepOptions) -> Vec<u8> {
    let ny = shape.ny;
    let mut bytes = vec![0u8; PARAM_STRIDE as usize * ny];
    for li in 0..ny {
        let j = if up { li } else { ny - 1 - li };
        let p = LevelParams {
            nx: shape.nx as u32,
            nz: shape.nz as u32,
            level_len: shape.level_len as u32,
            j: j as u32,
            src_level: if up { j as i32 - 1 } else { j as i32 + 1 },
            from_virtual: u32::from(li == 0),
            up: u32::from(up),
            periodic: u32::from(shape.periodic),
            given: u32::from(shape.given),
            ny: ny as u32,
            smoothing: options.smoothing,
            medium: match options.medium {
                lightgrid_core::MediumEmission::Escape => 0,
                lightgrid_core::MediumEmission::Source => 2,
                lightgrid_core::MediumEmission::Profile => 3,
            },
            horizon: u32::from(options.outputs.horizon),
            horizon_base: (shape.n * NUM_DIRS * 3) as u32,
        };
        let o = li * PARAM_STRIDE as usize;
        bytes[o..o + std::mem::size_of::<LevelParams>()].copy_from_slice(bytemuck::bytes_of(&p));
    }
    bytes
}

fn gpu_backend(e: GpuError) -> SweepError {
    SweepError::Backend {
        backend: "gpu",
        message: e.to_string(),
    }
}

fn overflow() -> SweepError {
    SweepError::Backend {
        backend: "gpu",
        message: "light overflowed f32 (boundary light too large for this grid)".into(),
    }
}

/// Where a GPU sweep's time went.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct GpuTimings {
    /// Creating and filling buffers.
    pub upload: std::time::Duration,
    /// Per-pass boundary uploads, dispatches and waiting for the GPU (and the stopping
    /// test's readbacks when `tolerance > 0`).
    pub compute: std::time::Duration,
    /// Reading the light grid back.
    pub readback: std::time::Duration,
}

/// The largest RGB channel of a sum of RGB triples, in `f64`.
fn sums(v: &[f32]) -> [f64; 3] {
    let mut s = [0f64; 3];
    for t in v.chunks_exact(3) {
        for k in 0..3 {
            s[k] += t[k] as f64;
        }
    }
    s
}

fn sum_max(v: &[f32]) -> f64 {
    sums(v).iter().copied().fold(0.0, f64::max)
}

/// `Sweeper` for the GPU sweeper, owned or shared (its methods take `&self`, so a
/// shared one sweeps too).
macro_rules! gpu_sweeper_impl {
    ($t:ty) => {
        impl Sweeper for $t {
            fn name(&self) -> &'static str {
                "gpu"
            }
            fn sweep(
                &mut self,
                material: &MaterialGrid,
                boundary: &Boundary,
                options: &SweepOptions,
            ) -> Result<SweepOutput, SweepError> {
                let _span = tracing::debug_span!(
                    "gpu sweep",
                    points = material.desc().point_count(),
                    passes = options.max_passes
                )
                .entered();
                self.run(material, boundary, options)
            }
            fn sweep_with_source(
                &mut self,
                material: &MaterialGrid,
                boundary: &Boundary,
                source: &CellSource,
                options: &SweepOptions,
            ) -> Result<SweepOutput, SweepError> {
                self.run_with_source(material, boundary, Some(source), options)
            }
            fn sweep_sun(
                &mut self,
                material: &MaterialGrid,
                sun: &lightgrid_core::SunBoundary<'_>,
                options: &SweepOptions,
            ) -> Result<lightgrid_core::SunResponse, SweepError> {
                lightgrid_sweep_cpu::sun::sweep_sun(self, material, sun, options)
            }
            fn sweep_with_sun(
                &mut self,
                material: &MaterialGrid,
                boundary: &Boundary,
                sun: &lightgrid_core::SunBeam<'_>,
                options: &SweepOptions,
            ) -> Result<SweepOutput, SweepError> {
                lightgrid_sweep_cpu::sun::sweep_with_sun(self, material, boundary, sun, options)
            }
            fn sun_transmittance(
                &mut self,
                material: &MaterialGrid,
                sun: &lightgrid_core::SunBoundary<'_>,
            ) -> Result<lightgrid_core::Grid<f32>, SweepError> {
                Ok(lightgrid_sweep_cpu::sun::transmittance(material, sun)?)
            }
            fn crop_resident(
                &self,
                resident: &lightgrid_core::Resident,
                inner: &lightgrid_core::GridDesc,
                offset: lightgrid_core::glam::UVec3,
            ) -> Option<lightgrid_core::Resident> {
                let g = resident.get::<GpuLightGrid>()?.crop(*inner, offset).ok()?;
                Some(lightgrid_core::Resident(Arc::new(g)))
            }
        }
    };
}

gpu_sweeper_impl!(GpuSweeper);
gpu_sweeper_impl!(&GpuSweeper);

#[cfg(test)]
mod tests {
    use super::LevelParams;

    /// `LevelParams` and its generated WGSL declaration have the same fields at the same
    /// offsets in naga's layout of the compiled phase-1 shader.
    #[test]
    fn level_params_match_the_wgsl_struct() {
        lightgrid_gpu::check::layout(
            &crate::wgsl::sweep_phase1(),
            "LevelParams",
            &LevelParams::offsets(),
            std::mem::size_of::<LevelParams>(),
        )
        .unwrap();
    }
}
