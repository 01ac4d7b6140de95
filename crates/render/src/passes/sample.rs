//! The light sampling pass: a batch of points lit from one grid or from a grid
//! hierarchy as layers (the finest owning layer winning, read across the seams between
//! layers that tile, `lightgrid_core::seam`), with or without normals and the sun kept
//! apart. `crate::sampling` is the CPU
//! specification; `shaders/sample.wgsl` implements it.

use std::sync::Arc;

use lightgrid_core::glam::{IVec2, UVec3, Vec2, Vec3};
use lightgrid_core::{GridDesc, GridError, LightGrid};
use lightgrid_gpu::kernel::{Binding, Kernel, buffer};
use lightgrid_gpu::{GpuContext, GpuError, GpuLightGrid};
use wgpu::util::DeviceExt;

use crate::RenderError;
use crate::sampling::{IrradianceTable, SamplePoints, SampledLight};

/// The sampling kernel's WGSL: the prelude, [`SampleParams`], `shaders/sample.wgsl`.
pub fn wgsl() -> String {
    format!(
        "{}\n{}\n{}",
        crate::wgsl::prelude(),
        SampleParams::wgsl(),
        include_str!("../shaders/sample.wgsl")
    )
}

lightgrid_gpu::gpu_struct! {
    /// Uniforms of the sampling kernel (one dispatch per layer).
    pub struct SampleParams {
        /// Grid origin (xyz) and cell size (w).
        pub origin_h: [f32; 4] => "vec4<f32>",
        /// Grid dims (xyz) and the irradiance table's nodes per side (w).
        pub dims: [u32; 4] => "vec4<u32>",
        /// Ownership: quadtree corner (xy), node side (z), 1 if the layer is owned (w).
        pub own: [f32; 4] => "vec4<f32>",
        /// Ownership: the node's cell (xy).
        pub own_index: [i32; 4] => "vec4<i32>",
        /// Lattice points: origin (xyz) and spacing (w).
        pub lattice_origin_h: [f32; 4] => "vec4<f32>",
        /// Lattice points: dims (xyz), 1 if the points are the lattice's (w).
        pub lattice_dims: [u32; 4] => "vec4<u32>",
        /// Invocations of the dispatch: the listed points, or the lattice's points in
        /// its box `sub_lo .. sub_lo + sub_dims`.
        pub count: u32 => "u32",
        /// The layer's horizon halves ([`GpuHorizon`]): 0 none (its horizontal bins read
        /// as even), 1 the sky's (the sun's bins read as even), 2 the sky's and then the
        /// sun's scattered light's.
        pub horizon: u32 => "u32",
        /// The step: 0 claim the points the layer owns, 1 add its share of the points
        /// it or a neighbour of its depth owns, 2 finish every point (one dispatch).
        pub mode: u32 => "u32",
        /// The layer's index in hierarchy order + 1 (what its claims hold).
        pub layer: u32 => "u32",
        /// Multiplier of the layer's bins (rgb): the sky's scale when the sun is kept
        /// apart ([`LayerLight`]), 1 otherwise.
        pub sky_scale: [f32; 4] => "vec4<f32>",
        /// The sun kept apart: irradiance (rgb), w = 1 when the layer has its responses.
        pub sun: [f32; 4] => "vec4<f32>",
        /// Direction toward the sun (xyz).
        pub to_sun: [f32; 4] => "vec4<f32>",
        /// The layers of its depth around it, `(dz + 1) × 3 + (dx + 1)` for the node
        /// `(dx, dz)` away ([`seam_neighbours`]): their lowest and highest levels' heights
        /// and index + 1 (0: none there that tiles with it).
        pub near: [[f32; 4]; 9] => "array<vec4<f32>, 9>",
        /// Lattice points: the first corner (xyz) of the box of them the dispatch
        /// visits ([`lattice_box`]).
        pub sub_lo: [u32; 4] => "vec4<u32>",
        /// Lattice points: the points along each axis (xyz) of that box. Listed
        /// points: 1 in `w` where the dispatch visits those named in its index list
        /// ([`listed_near`]), else every one.
        pub sub_dims: [u32; 4] => "vec4<u32>",
    }
}

/// The light of a layered sampling: the sky's scale, and the sun kept apart from the
/// bins (`lightgrid_terrain_lod::Hierarchy::set_sun`) whose responses every layer then carries
/// ([`GpuSampleLayer::sun`]). The default: scale 1, no sun (the bins hold all light).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LayerLight {
    /// Multiplies every layer's bins.
    pub sky_scale: Vec3,
    /// Direction toward the sun and its irradiance.
    pub sun: Option<(Vec3, Vec3)>,
}

impl Default for LayerLight {
    fn default() -> Self {
        Self {
            sky_scale: Vec3::ONE,
            sun: None,
        }
    }
}

/// A layer's sun responses on the device (for unit sun irradiance).
#[derive(Debug, Clone, Copy)]
pub struct GpuLayerSun<'a> {
    /// The sun's scattered light (26 bins), on the layer grid's points.
    pub scattered: &'a GpuLightGrid,
    /// The beam's transmittance, one `f32` a point ([`transmittance_buffer`]).
    pub transmittance: &'a wgpu::Buffer,
}

/// A transmittance grid's values in a storage buffer, for [`GpuLayerSun`].
pub fn transmittance_buffer(ctx: &GpuContext, values: &[f32]) -> wgpu::Buffer {
    buffer(
        ctx,
        "sun transmittance",
        bytemuck::cast_slice(values),
        wgpu::BufferUsages::STORAGE,
    )
}

/// A layer's horizon halves on the device ([`lightgrid_core::LightField::horizon`]): the
/// downward halves of its grid's horizontal bins, 8 RGB a point in grid order, and
/// after them those of the sun's scattered light if given. Where a layer has them its
/// points' irradiance reads each horizontal bin in its two halves
/// ([`IrradianceTable::irradiance_split`]), as the CPU sampler does.
pub struct GpuHorizon {
    ctx: Arc<GpuContext>,
    buffer: wgpu::Buffer,
    desc: GridDesc,
    sun: bool,
}

impl GpuHorizon {
    /// Uploads the sky's halves and, with the sun kept apart, its scattered light's
    /// (`None`: that light's bins read as even). Both on one grid.
    pub fn new(
        ctx: Arc<GpuContext>,
        sky: &lightgrid_core::HorizonGrid,
        scattered: Option<&lightgrid_core::HorizonGrid>,
    ) -> Result<Self, RenderError> {
        let desc = *sky.desc();
        if let Some(s) = scattered
            && *s.desc() != desc
        {
            return Err(GridError::invalid(
                "scattered.desc()",
                format!("{:?}", s.desc()),
                "must equal the sky halves' descriptor",
            )
            .into());
        }
        fn floats(g: &lightgrid_core::HorizonGrid) -> &[f32] {
            bytemuck::cast_slice(g.data())
        }
        let bytes = (desc.point_count() * 24 * (1 + scattered.is_some() as usize) * 4) as u64;
        let limit = ctx.max_binding();
        if bytes > limit {
            return Err(GpuError::TooLarge {
                what: "horizon halves",
                bytes,
                limit,
            }
            .into());
        }
        let mut data = floats(sky).to_vec();
        if let Some(s) = scattered {
            data.extend_from_slice(floats(s));
        }
        let buffer = buffer(
            &ctx,
            "horizon halves",
            bytemuck::cast_slice(&data),
            wgpu::BufferUsages::STORAGE,
        );
        Ok(Self {
            ctx,
            buffer,
            desc,
            sun: scattered.is_some(),
        })
    }

    /// The grid the halves lie on.
    pub fn desc(&self) -> &GridDesc {
        &self.desc
    }
}

impl std::fmt::Debug for GpuHorizon {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuHorizon")
            .field("desc", &self.desc)
            .field("sun", &self.sun)
            .finish_non_exhaustive()
    }
}

/// Which points a layer lights, as `lightgrid_terrain_lod::Owner` states it: those whose `(x, z)`
/// fall in quadtree cell `index` (`floor((p.xz - origin) / size) == index`) and whose
/// height lies within the layer grid's levels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LayerOwner {
    /// World `(x, z)` of the quadtree's corner.
    pub origin: Vec2,
    /// Node side, metres.
    pub size: f32,
    /// The node's cell.
    pub index: IVec2,
}

/// One grid of a layered sampling: points take their light from the last layer that
/// owns them (a layer without owner owns every point), and where a point's read falls
/// between the owner's outermost points and those of a layer that tiles with it (one
/// quadtree, one cell size and points across, in the neighbouring cell), from the
/// layers holding the lookup's corners, each by its share (`lightgrid_core::seam`, as
/// `lightgrid_terrain_lod::Hierarchy` reads them).
#[derive(Debug, Clone, Copy)]
pub struct GpuSampleLayer<'a> {
    /// The grid, on the sampler's device.
    pub grid: &'a GpuLightGrid,
    /// Which points it lights; `None`: all.
    pub owner: Option<LayerOwner>,
    /// Its sun responses, when the sun is kept apart ([`LayerLight::sun`]).
    pub sun: Option<GpuLayerSun<'a>>,
    /// Its horizon halves, if it keeps them (`None`: its horizontal bins read as even).
    pub horizon: Option<&'a GpuHorizon>,
}

impl<'a> GpuSampleLayer<'a> {
    /// A layer of `grid`'s bins alone lighting the points `owner` gives it (`None`:
    /// all): no sun kept apart, its horizontal bins read as even.
    pub const fn bins(grid: &'a GpuLightGrid, owner: Option<LayerOwner>) -> Self {
        Self {
            grid,
            owner,
            sun: None,
            horizon: None,
        }
    }
}

/// The points a GPU sampling lights.
#[derive(Debug, Clone, Copy)]
pub enum GpuPoints<'a> {
    /// Given positions (and normals), uploaded.
    List(SamplePoints<'a>),
    /// Every point of a lattice (a light volume), generated on the device: nothing is
    /// uploaded.
    Lattice(GridDesc),
}

/// Sampled light left on the device: two `vec4` a point, `(light, 0)` and
/// `(dominant, 1)` (`w` = 1 once a layer wrote the point; 0 for points no layer owns),
/// the layout of [`SampledLight`] and of the renderer's light volume.
pub struct GpuSamples {
    ctx: Arc<GpuContext>,
    buffer: wgpu::Buffer,
    count: usize,
}

impl GpuSamples {
    /// The buffer (STORAGE | COPY_SRC).
    pub fn buffer(&self) -> &wgpu::Buffer {
        &self.buffer
    }

    /// Points sampled.
    pub fn count(&self) -> usize {
        self.count
    }

    /// The device it lives on.
    pub fn context(&self) -> &Arc<GpuContext> {
        &self.ctx
    }

    /// Reads the samples back (non-finite values, which finite grids cannot give,
    /// would read as zero).
    pub fn read(&self) -> Result<Vec<SampledLight>, RenderError> {
        let bytes = self.ctx.read_back(&self.buffer)?;
        let mut result: Vec<SampledLight> = bytemuck::pod_collect_to_vec(&bytes[..self.count * 32]);
        for r in &mut result {
            // The kernel's "written" flag.
            r._pad1 = 0.0;
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

/// Samples light grids for batches of points on the GPU: the same results as
/// [`crate::sample_points`] on that grid (within f32 rounding).
pub struct GpuLightSampler {
    ctx: Arc<GpuContext>,
    kernel: Kernel,
    table: wgpu::Buffer,
}

impl GpuLightSampler {
    /// Compiles the kernel and uploads the irradiance table.
    pub fn new(ctx: Arc<GpuContext>) -> Self {
        let device = &ctx.device;
        use Binding::{Read, ReadWrite, Uniform};
        let kernel = Kernel::new(
            device,
            "sample",
            &wgsl(),
            &[
                Uniform, Read, Read, Read, Read, Read, ReadWrite, Read, ReadWrite, Read,
            ],
        );
        // The 26 bins' kernel, then the horizon term.
        let t = IrradianceTable::get();
        let table = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("irradiance table"),
            contents: bytemuck::cast_slice(&[t.weights.as_slice(), &t.horizon].concat()),
            usage: wgpu::BufferUsages::STORAGE,
        });
        Self { ctx, kernel, table }
    }

    /// Lights `points` from `grid` (uploaded for this call) in one dispatch.
    pub fn sample(
        &self,
        grid: &LightGrid,
        points: SamplePoints<'_>,
    ) -> Result<Vec<SampledLight>, RenderError> {
        points.validate()?;
        if points.positions.is_empty() {
            return Ok(Vec::new());
        }
        let grid = GpuLightGrid::new(self.ctx.clone(), grid)?;
        self.sample_layers(
            &[GpuSampleLayer::bins(&grid, None)],
            GpuPoints::List(points),
        )?
        .read()
    }

    /// Lights `points` from grids already on the device, each point from the last layer
    /// owning it, read across the seams between layers that tile ([`GpuSampleLayer`];
    /// two dispatches a layer and one more: the claims, finest first, the shares, the
    /// finish), and leaves the result there: the light grids of a GPU sweep are sampled, and drawn
    /// ([`crate::Renderer::set_light_volume_samples`]), without a copy through the CPU.
    /// Every grid must live on this sampler's device; points no layer owns read zero.
    pub fn sample_layers(
        &self,
        layers: &[GpuSampleLayer<'_>],
        points: GpuPoints<'_>,
    ) -> Result<GpuSamples, RenderError> {
        self.sample_layers_lit(layers, points, &LayerLight::default())
    }

    /// [`GpuLightSampler::sample_layers`] with the sky scaled and a sun kept apart, as
    /// `lightgrid_terrain_lod::Hierarchy`'s `LightField` reads it: the light is
    /// `bins × sky_scale + scattered × irradiance`, the first `vec4`'s `w` the sun's
    /// transmittance (read like the light, with the normal bias), and points with
    /// normals get the direct sun `E T max(0, n · s)` added to their irradiance (what
    /// vertex and ground light hold). Every layer must carry its sun responses when a
    /// sun is given.
    pub fn sample_layers_lit(
        &self,
        layers: &[GpuSampleLayer<'_>],
        points: GpuPoints<'_>,
        light: &LayerLight,
    ) -> Result<GpuSamples, RenderError> {
        let device = &self.ctx.device;
        let sun = self.check_layers(layers, light)?;
        let limit = self.ctx.max_binding();
        let (count, packed, lattice) = pack_points(points)?;
        let point_bytes = count.max(1) as u64 * 32;
        for (what, bytes) in [
            ("sample points", packed.len() as u64 * 4),
            ("sampled light", point_bytes),
        ] {
            if bytes > limit {
                return Err(GpuError::TooLarge { what, bytes, limit }.into());
            }
        }
        let pts = buffer(
            &self.ctx,
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
        let claims = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("sample claims"),
            size: count.max(1) as u64 * 4,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        let near = seam_neighbours(layers);
        // Listed points: each owned layer's claims and shares visit only the points
        // it can own or share, named in an index list (as a lattice's box, below).
        let lists: Vec<Option<(wgpu::Buffer, u32)>> = match points {
            GpuPoints::List(list) => layers
                .iter()
                .map(|layer| {
                    let o = layer.owner.as_ref()?;
                    let idx = listed_near(list.positions, layer.grid.desc(), o);
                    let n = idx.len() as u32;
                    let b = buffer(
                        &self.ctx,
                        "sample indices",
                        bytemuck::cast_slice(&idx),
                        wgpu::BufferUsages::STORAGE,
                    );
                    Some((b, n))
                })
                .collect(),
            GpuPoints::Lattice(_) => vec![None; layers.len()],
        };
        // One dispatch of layer `i` at step `mode` (the kernel's `SampleParams::mode`).
        let dispatch = |i: usize, mode: u32| {
            let layer = &layers[i];
            let mut params = layer_params(layer, (count, lattice), light.sky_scale, sun);
            params.mode = mode;
            params.layer = i as u32 + 1;
            params.near = near[i];
            if let Some(l) = lattice {
                // Only the lattice's points an owned layer can own or share visit it
                // (every point the finish and a layer owning everywhere): on lavapipe
                // a visit costs though it returns at once (0.4 µs to claim nothing), and
                // a dispatch over every point for each of 17 layers took twice the time
                // (`cargo run --release -p lightgrid-render --example layered_sampling`).
                let (lo, dims) = match (mode, &layer.owner) {
                    (0 | 1, Some(o)) => lattice_box(&l, layer.grid.desc(), o),
                    _ => (UVec3::ZERO, l.dims()),
                };
                params.sub_lo = lo.extend(0).to_array();
                params.sub_dims = dims.extend(0).to_array();
                params.count = dims.x * dims.y * dims.z;
                if params.count == 0 {
                    return;
                }
            }
            let mut indices = &self.table;
            if let (0 | 1, Some((list, n))) = (mode, &lists[i]) {
                params.sub_dims[3] = 1;
                params.count = *n;
                indices = list;
                if params.count == 0 {
                    return;
                }
            }
            let uniform = buffer(
                &self.ctx,
                "sample params",
                bytemuck::bytes_of(&params),
                wgpu::BufferUsages::UNIFORM,
            );
            // Without a sun the sky's buffers stand in for the unread sun bindings.
            let (scattered, transmittance) = match (sun, layer.sun) {
                (Some(_), Some(ls)) => (ls.scattered.buffer(), ls.transmittance),
                _ => (layer.grid.buffer(), &pts),
            };
            let halves = layer.horizon.map_or(layer.grid.buffer(), |h| &h.buffer);
            let bind = self.kernel.bind(
                device,
                &[
                    &uniform,
                    layer.grid.buffer(),
                    scattered,
                    transmittance,
                    &pts,
                    &self.table,
                    &out,
                    halves,
                    &claims,
                    indices,
                ],
            );
            self.kernel.dispatch(&self.ctx, &bind, params.count);
        };
        // Claims finest first (the last layer in `layers` order owning a point wins),
        // then every layer's shares, then one finish.
        for i in (0..layers.len()).rev() {
            dispatch(i, 0);
        }
        for i in 0..layers.len() {
            dispatch(i, 1);
        }
        if !layers.is_empty() {
            dispatch(0, 2);
        }
        Ok(GpuSamples {
            ctx: self.ctx.clone(),
            buffer: out,
            count,
        })
    }

    /// The light's sky scale and sun checked, and the layers against them: every grid
    /// on this device, with a sun every layer's sun responses on this device and on its
    /// grid's points, every owner's corner finite and its side finite and positive.
    /// Returns the checked sun.
    fn check_layers(
        &self,
        layers: &[GpuSampleLayer<'_>],
        light: &LayerLight,
    ) -> Result<Option<(Vec3, Vec3)>, RenderError> {
        if !light.sky_scale.is_finite() || light.sky_scale.min_element() < 0.0 {
            return Err(GridError::invalid(
                "sky_scale",
                light.sky_scale,
                "must be finite and >= 0",
            )
            .into());
        }
        let sun = match light.sun {
            Some((s, e)) => {
                let s = lightgrid_core::light::check_sun(s, e)?;
                if let Some(i) = layers.iter().position(|l| {
                    l.sun.is_none_or(|ls| {
                        !Arc::ptr_eq(ls.scattered.context(), &self.ctx)
                            || ls.scattered.desc() != l.grid.desc()
                            || ls.transmittance.size() < l.grid.desc().point_count() as u64 * 4
                    })
                }) {
                    return Err(GridError::invalid(
                        format!("layers[{i}].sun"),
                        "missing or unlike its grid",
                        "every layer needs sun responses on this device, on its grid's points",
                    )
                    .into());
                }
                Some((s, e))
            }
            None => None,
        };
        if let Some(i) = layers.iter().position(|l| {
            l.owner
                .is_some_and(|o| !(o.origin.is_finite() && o.size.is_finite() && o.size > 0.0))
        }) {
            return Err(GridError::invalid(
                format!("layers[{i}].owner"),
                format!("{:?}", layers[i].owner),
                "origin must be finite and size finite and > 0",
            )
            .into());
        }
        if let Some(i) = layers.iter().position(|l| {
            l.horizon.is_some_and(|h| {
                !Arc::ptr_eq(&h.ctx, &self.ctx)
                    || h.desc != *l.grid.desc()
                    || (h.sun && sun.is_none())
            })
        }) {
            return Err(GridError::invalid(
                format!("layers[{i}].horizon"),
                "unlike its grid",
                "must live on the sampler's device, on its grid's points, with the sun's halves only where a sun is given",
            )
            .into());
        }
        if let Some(i) = layers
            .iter()
            .position(|l| !Arc::ptr_eq(l.grid.context(), &self.ctx))
        {
            return Err(GridError::invalid(
                format!("layers[{i}].grid"),
                "another device",
                "must live on the sampler's device",
            )
            .into());
        }
        Ok(sun)
    }
}

/// Per layer, [`SampleParams::near`]: the layers that tile with it around it, as
/// `lightgrid_core::seam` reads across their seams. A layer tiles with another where
/// both are owned with the same quadtree (corner and node side), their cells are
/// neighbours (or the same), and their grids are of one lattice across (the same cell
/// size and points across, the other's points one node side further), with the same
/// kinds of horizon halves and sun responses; of several such layers in one cell, the
/// last in order (the one owning its points).
fn seam_neighbours(layers: &[GpuSampleLayer<'_>]) -> Vec<[[f32; 4]; 9]> {
    let key = |o: &LayerOwner, index: IVec2| {
        (
            o.origin.x.to_bits(),
            o.origin.y.to_bits(),
            o.size.to_bits(),
            index.x,
            index.y,
        )
    };
    let mut by_cell = std::collections::HashMap::new();
    for (j, l) in layers.iter().enumerate() {
        if let Some(o) = &l.owner {
            by_cell.insert(key(o, o.index), j);
        }
    }
    let kind = |l: &GpuSampleLayer<'_>| (l.horizon.map(|h| h.sun), l.sun.is_some());
    layers
        .iter()
        .map(|l| {
            let mut near = [[0.0f32; 4]; 9];
            let Some(o) = &l.owner else {
                return near;
            };
            let d = l.grid.desc();
            for dz in -1..=1 {
                for dx in -1..=1 {
                    let step = IVec2::new(dx, dz);
                    let Some(&j) = by_cell.get(&key(o, o.index + step)) else {
                        continue;
                    };
                    let m = &layers[j];
                    let e = m.grid.desc();
                    let shift = step.as_vec2() * o.size;
                    let expect = Vec2::new(d.origin().x, d.origin().z) + shift;
                    let tiles = e.h() == d.h()
                        && e.dims().x == d.dims().x
                        && e.dims().z == d.dims().z
                        && (Vec2::new(e.origin().x, e.origin().z) - expect)
                            .abs()
                            .max_element()
                            <= 1e-3 * d.h()
                        && kind(m) == kind(l);
                    if tiles {
                        let (lo, hi) = e.point_bounds();
                        near[((dz + 1) * 3 + dx + 1) as usize] = [lo.y, hi.y, (j + 1) as f32, 0.0];
                    }
                }
            }
            near
        })
        .collect()
}

/// The world box holding every point a layer on grid `grid` owning `owner` can own or
/// read a share of: its quadtree cell at its levels' heights (what it owns), and the
/// points within two of its cells of its grid's points (a neighbour's read across their
/// seam falls within a cell beyond them).
fn layer_reach(grid: &GridDesc, owner: &LayerOwner) -> (Vec3, Vec3) {
    let (lo, hi) = grid.point_bounds();
    let margin = Vec3::splat(2.0 * grid.h());
    let cell_lo = owner.origin + owner.index.as_vec2() * owner.size;
    let cell_hi = cell_lo + Vec2::splat(owner.size);
    (
        (lo - margin).min(Vec3::new(cell_lo.x, lo.y, cell_lo.y)),
        (hi + margin).max(Vec3::new(cell_hi.x, hi.y, cell_hi.y)),
    )
}

/// The box of `lattice`'s points (its first corner and its points along each axis; none
/// along an axis where empty) within [`layer_reach`] of a layer on grid `grid` owning
/// `owner` (the whole lattice where that is not finite).
fn lattice_box(lattice: &GridDesc, grid: &GridDesc, owner: &LayerOwner) -> (UVec3, UVec3) {
    let (lo, hi) = layer_reach(grid, owner);
    let g = |w: Vec3| (w - lattice.origin()) / lattice.h();
    let last = lattice.dims().as_vec3() - Vec3::ONE;
    let a = g(lo).floor().max(Vec3::ZERO);
    let b = g(hi).ceil().min(last);
    if !(a.is_finite() && b.is_finite()) {
        return (UVec3::ZERO, lattice.dims());
    }
    if a.cmpgt(b).any() {
        return (UVec3::ZERO, UVec3::ZERO);
    }
    (a.as_uvec3(), (b - a).as_uvec3() + UVec3::ONE)
}

/// The listed `positions` that a layer on grid `grid` owning `owner` can own or read a
/// share of ([`lattice_box`]'s rule: its quadtree cell, and within two of its cells of
/// its grid's points; a read moved along a normal moves half a cell).
fn listed_near(positions: &[Vec3], grid: &GridDesc, owner: &LayerOwner) -> Vec<u32> {
    let (lo, hi) = layer_reach(grid, owner);
    positions
        .iter()
        .enumerate()
        .filter(|(_, p)| p.cmpge(lo).all() && p.cmple(hi).all())
        .map(|(i, _)| i as u32)
        .collect()
}

/// The points to sample: their count, and either their positions and normals packed as
/// two `vec4` a point (`w` of the first: 1 where a normal is given), or a lattice's
/// descriptor (and a placeholder buffer: the device generates them).
fn pack_points(points: GpuPoints<'_>) -> Result<(usize, Vec<f32>, Option<GridDesc>), RenderError> {
    let (count, packed, lattice) = match points {
        GpuPoints::List(points) => {
            points.validate()?;
            let mut packed = Vec::with_capacity(points.positions.len() * 8);
            for (i, p) in points.positions.iter().enumerate() {
                let n = points.normals.map(|n| n[i]);
                packed.extend_from_slice(&[p.x, p.y, p.z, if n.is_some() { 1.0 } else { 0.0 }]);
                let n = n.unwrap_or(Vec3::Y);
                packed.extend_from_slice(&[n.x, n.y, n.z, 0.0]);
            }
            (points.positions.len(), packed, None)
        }
        GpuPoints::Lattice(d) => (d.point_count(), vec![0.0; 16], Some(d)),
    };
    if count > (u32::MAX / 2) as usize {
        return Err(GridError::invalid("points", count, "too many points").into());
    }
    Ok((count, packed, lattice))
}

/// The sampling kernel's parameters for one layer: its grid, what it owns, the points
/// (`count`, on `lattice` if given), the sky's scale and the sun.
fn layer_params(
    layer: &GpuSampleLayer<'_>,
    (count, lattice): (usize, Option<GridDesc>),
    sky_scale: Vec3,
    sun: Option<(Vec3, Vec3)>,
) -> SampleParams {
    let d = layer.grid.desc();
    let (own, own_index) = match layer.owner {
        Some(o) => (
            [o.origin.x, o.origin.y, o.size, 1.0],
            [o.index.x, o.index.y, 0, 0],
        ),
        None => ([0.0; 4], [0; 4]),
    };
    let (lattice_origin_h, lattice_dims) = match lattice {
        Some(l) => (
            l.origin().extend(l.h()).to_array(),
            l.dims().extend(1).to_array(),
        ),
        None => ([0.0; 4], [0; 4]),
    };
    SampleParams {
        origin_h: d.origin().extend(d.h()).to_array(),
        dims: d.dims().extend(IrradianceTable::get().size).to_array(),
        own,
        own_index,
        lattice_origin_h,
        lattice_dims,
        count: count as u32,
        horizon: match layer.horizon {
            None => 0,
            Some(h) if h.sun => 2,
            Some(_) => 1,
        },
        sky_scale: sky_scale.extend(0.0).to_array(),
        sun: match sun {
            Some((_, e)) => e.extend(1.0).to_array(),
            None => [0.0; 4],
        },
        to_sun: sun.map_or([0.0; 4], |(s, _)| s.extend(0.0).to_array()),
        ..Default::default()
    }
}
