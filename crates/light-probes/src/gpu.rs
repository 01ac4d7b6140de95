//! Probe relighting on the GPU (feature `gpu`): [`GpuProbeRelight`] runs
//! [`ProbeLight::frame`](crate::ProbeLight::frame) (the CPU specification) as three
//! compute stages over the same data, uploaded once per probe set; each frame uploads
//! only the sky, the sun and the surfels' sun visibility. Interior sets
//! ([`GpuProbeRelight::frame_interior`]) read the exterior set's probes on the device.
//! `tests/gpu.rs` holds both equal to the CPU; errors are
//! [`GpuError`](lightgrid_gpu::GpuError)s (bad input as its `Grid` variant, by name).

use std::sync::Arc;

use lightgrid_core::GridError;
use lightgrid_core::glam::Vec3;
use lightgrid_core::light::AmbientCube;
use lightgrid_gpu::GpuContext;
use lightgrid_gpu::GpuError;
use lightgrid_gpu::kernel::{Binding, Kernel, buffer};

use crate::{Lighting, ProbeSet};

/// The relighting kernel's WGSL: the direction tables, π, [`RelightParams`] and the
/// three stages (`shaders/relight.wgsl`).
pub fn kernel_wgsl() -> String {
    format!(
        "{}\nconst PI: f32 = {:?};\n{}\n{}",
        lightgrid_gpu::wgsl::prelude(),
        std::f32::consts::PI,
        RelightParams::wgsl(),
        include_str!("shaders/relight.wgsl")
    )
}

lightgrid_gpu::gpu_struct! {
    /// Uniforms of one probe relighting stage.
    pub struct RelightParams {
        /// Stage (0 surfels, 1 bricks, 2 probes), surfels, bricks, probes.
        pub counts: [u32; 4] => "vec4<u32>",
        /// Offsets in the index table: links, brick starts, brick members, probe
        /// factor ranges (the surfels' link ranges start at 0).
        pub offsets: [u32; 4] => "vec4<u32>",
        /// Direction toward the sun (xyz); w = 1 when there is a sun.
        pub to_sun: [f32; 4] => "vec4<f32>",
        /// The sun's irradiance (rgb).
        pub sun_irradiance: [f32; 4] => "vec4<f32>",
    }
}

/// A probe set on the device and its relit state (ping-pong probe buffers).
pub struct GpuProbeRelight {
    ctx: Arc<GpuContext>,
    kernel: Kernel,
    counts: [u32; 4],
    offsets: [u32; 4],
    surfels: wgpu::Buffer,
    index: wgpu::Buffer,
    factors: wgpu::Buffer,
    probe_sky: wgpu::Buffer,
    work: wgpu::Buffer,
    probes: [wgpu::Buffer; 2],
    /// Which of `probes` holds the last frame.
    current: usize,
    /// An interior set: the exterior set's probe count.
    exterior: Option<usize>,
}

impl GpuProbeRelight {
    /// Uploads `set` (its probes start dark, as `ProbeLight::new`).
    pub fn new(ctx: Arc<GpuContext>, set: &ProbeSet) -> Result<Self, GpuError> {
        let storage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST;
        let ns = set.surfels().len();
        let nb = set.brick_count();
        let np = set.probes().len();
        let surfels: Vec<[f32; 4]> = set
            .surfels()
            .iter()
            .flat_map(|s| {
                [
                    s.position.extend(s.hits as f32).to_array(),
                    s.normal.extend(0.0).to_array(),
                    s.albedo.extend(0.0).to_array(),
                ]
            })
            .enumerate()
            .map(|(i, mut v)| {
                // (normal, outside): an interior set's surfels beyond its room.
                if i % 3 == 1 && set.surfel_outside(i / 3) {
                    v[3] = 1.0;
                }
                v
            })
            .collect();
        // The index table: link ranges, links, brick starts, brick members, factor ranges.
        let mut index: Vec<u32> = Vec::new();
        let mut links: Vec<u32> = Vec::new();
        for s in 0..ns {
            let start = links.len() as u32 / 2;
            for &(p, w) in set.surfel_links(s) {
                links.extend([p, w.to_bits()]);
            }
            index.extend([start, links.len() as u32 / 2]);
        }
        let links_off = index.len() as u32;
        index.extend(&links);
        let brick_start_off = index.len() as u32;
        let mut members: Vec<u32> = Vec::new();
        for b in 0..nb {
            index.push(members.len() as u32);
            members.extend_from_slice(set.brick(b));
        }
        index.push(members.len() as u32);
        let members_off = index.len() as u32;
        index.extend(&members);
        let ranges_off = index.len() as u32;
        for p in set.probes() {
            index.extend([p.factors.start, p.factors.end]);
        }
        let factors: Vec<[f32; 4]> = set
            .factors()
            .iter()
            .flat_map(|f| {
                let w = f.weights;
                [
                    [w[0], w[1], w[2], w[3]],
                    [w[4], w[5], f32::from_bits(f.brick), 0.0],
                ]
            })
            .collect();
        let probe_sky: Vec<f32> = set
            .probes()
            .iter()
            .flat_map(|p| p.sky.iter().flatten().copied())
            .collect();
        let dark = vec![[0f32; 4]; 6 * np];
        let kernel = Kernel::new(
            &ctx.device,
            "probe relight",
            &kernel_wgsl(),
            &[
                Binding::Uniform,
                Binding::Read,
                Binding::Read,
                Binding::Read,
                Binding::Read,
                Binding::Read,
                Binding::Read,
                Binding::ReadWrite,
                Binding::ReadWrite,
                Binding::Read,
            ],
        );
        let b = |label: &str, bytes: &[u8]| buffer(&ctx, label, bytes, storage);
        // The probes are read back by `read` and copied by renderers.
        let out = storage | wgpu::BufferUsages::COPY_SRC;
        let p = |label: &str| buffer(&ctx, label, bytemuck::cast_slice(&dark), out);
        Ok(Self {
            surfels: b("probe surfels", bytemuck::cast_slice(&surfels)),
            index: b("probe index", bytemuck::cast_slice(&index)),
            factors: b("probe factors", bytemuck::cast_slice(&factors)),
            probe_sky: b("probe sky", bytemuck::cast_slice(&probe_sky)),
            work: b(
                "probe work",
                bytemuck::cast_slice(&vec![[0f32; 4]; ns + nb]),
            ),
            probes: [p("probes a"), p("probes b")],
            current: 0,
            exterior: set.interior().map(|_| set.exterior_probes()),
            counts: [0, ns as u32, nb as u32, np as u32],
            offsets: [links_off, brick_start_off, members_off, ranges_off],
            kernel,
            ctx,
        })
    }

    /// One frame on the device (as `ProbeLight::frame`): surfels, bricks, probes. An
    /// interior set needs [`GpuProbeRelight::frame_interior`].
    pub fn frame(&mut self, lighting: &Lighting, sun_visibility: &[f32]) -> Result<(), GpuError> {
        if self.exterior.is_some() {
            return Err(GridError::invalid(
                "set",
                "interior set",
                "its outside surfels need the exterior's light: relight it with frame_interior",
            )
            .into());
        }
        self.frame_with(lighting, sun_visibility, None)
    }

    /// One frame of an interior set (as `ProbeLight::frame_interior`): its outside
    /// surfels read `exterior`'s probes (the exterior set on the same device, relit
    /// first this frame).
    pub fn frame_interior(
        &mut self,
        lighting: &Lighting,
        sun_visibility: &[f32],
        exterior: &GpuProbeRelight,
    ) -> Result<(), GpuError> {
        let found = exterior.counts[3] as usize;
        if self.exterior != Some(found) || !Arc::ptr_eq(&self.ctx, &exterior.ctx) {
            return Err(GridError::LengthMismatch {
                field: "exterior",
                expected: self.exterior.unwrap_or(0),
                found,
            }
            .into());
        }
        self.frame_with(lighting, sun_visibility, Some(exterior.buffer()))
    }

    fn frame_with(
        &mut self,
        lighting: &Lighting,
        sun_visibility: &[f32],
        exterior: Option<&wgpu::Buffer>,
    ) -> Result<(), GpuError> {
        let ns = self.counts[1] as usize;
        if sun_visibility.len() != ns {
            return Err(GridError::LengthMismatch {
                field: "sun_visibility",
                expected: ns,
                found: sun_visibility.len(),
            }
            .into());
        }
        if !lighting.sky.is_valid() {
            return Err(
                GridError::invalid("sky", lighting.sky, "light must be finite and >= 0").into(),
            );
        }
        let (to_sun, irr) = match lighting.sun {
            Some((s, e)) => {
                let s = lightgrid_core::light::check_sun(s, e)?;
                (s.extend(1.0), e)
            }
            None => (Vec3::ZERO.extend(0.0), Vec3::ZERO),
        };
        let mut frame_in: Vec<[f32; 4]> = lighting
            .sky
            .0
            .iter()
            .map(|v| v.extend(0.0).to_array())
            .collect();
        for c in sun_visibility.chunks(4) {
            let mut v = [0.0f32; 4];
            v[..c.len()].copy_from_slice(c);
            frame_in.push(v);
        }
        let frame_in = buffer(
            &self.ctx,
            "probe frame",
            bytemuck::cast_slice(&frame_in),
            wgpu::BufferUsages::STORAGE,
        );
        let (last, next) = (self.current, 1 - self.current);
        for stage in 0..3u32 {
            let params = RelightParams {
                counts: [stage, self.counts[1], self.counts[2], self.counts[3]],
                offsets: self.offsets,
                to_sun: to_sun.to_array(),
                sun_irradiance: irr.extend(0.0).to_array(),
            };
            let uniform = buffer(
                &self.ctx,
                "probe params",
                bytemuck::bytes_of(&params),
                wgpu::BufferUsages::UNIFORM,
            );
            let bind = self.kernel.bind(
                &self.ctx.device,
                &[
                    &uniform,
                    &self.surfels,
                    &self.index,
                    &self.factors,
                    &self.probe_sky,
                    &frame_in,
                    &self.probes[last],
                    &self.work,
                    &self.probes[next],
                    exterior.unwrap_or(&self.probes[last]),
                ],
            );
            let count = match stage {
                0 => self.counts[1],
                1 => self.counts[2],
                _ => self.counts[3],
            };
            self.kernel.dispatch(&self.ctx, &bind, count);
        }
        self.current = next;
        Ok(())
    }

    /// The probes' irradiance, read back (for tests and tools; renderers bind the buffer).
    pub fn read(&self) -> Result<Vec<AmbientCube>, GpuError> {
        let bytes = self.ctx.read_back(&self.probes[self.current])?;
        let v: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(&bytes);
        Ok(v.chunks(6)
            .take(self.counts[3] as usize)
            .map(|c| AmbientCube(std::array::from_fn(|k| Vec3::from_slice(&c[k][..3]))))
            .collect())
    }

    /// The device buffer of the probes' irradiance (six `vec4` a probe).
    pub fn buffer(&self) -> &wgpu::Buffer {
        &self.probes[self.current]
    }
}
