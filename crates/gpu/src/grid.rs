//! [`GpuLightGrid`]: a 26-bin light grid living on the device, the one GPU form of a
//! light grid. The GPU sweeper writes it, the renderer samples and draws from it, and
//! neither copies it through the CPU on the way.
//!
//! Layout: point `i` (grid order: x fastest, then z, then y) at floats `78 i .. 78 i + 78`,
//! bin `d` (canonical order of `lightgrid_core::dirs`) at `78 i + 3 d` as `r, g, b`: the
//! same bytes as `&[BinLight]` (`BinLight` is `Pod`).

use std::sync::Arc;

use lightgrid_core::glam::UVec3;
use lightgrid_core::{BinLight, Grid, GridDesc, GridError, LightGrid, NUM_DIRS};

use crate::{GpuContext, GpuError};

/// Bytes of one point: 26 bins × RGB × `f32`.
pub const POINT_BYTES: u64 = NUM_DIRS as u64 * 12;

/// A 26-bin light grid in a storage buffer (`array<f32>`, 78 a point; usage STORAGE,
/// COPY_SRC, COPY_DST).
pub struct GpuLightGrid {
    ctx: Arc<GpuContext>,
    buffer: wgpu::Buffer,
    desc: GridDesc,
}

impl std::fmt::Debug for GpuLightGrid {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuLightGrid")
            .field("desc", &self.desc)
            .field("bytes", &self.buffer.size())
            .finish()
    }
}

impl GpuLightGrid {
    /// The usage every grid buffer has.
    pub const USAGE: wgpu::BufferUsages = wgpu::BufferUsages::STORAGE
        .union(wgpu::BufferUsages::COPY_SRC)
        .union(wgpu::BufferUsages::COPY_DST);

    /// Uploads `grid`.
    pub fn new(ctx: Arc<GpuContext>, grid: &LightGrid) -> Result<Self, GpuError> {
        let bytes = Self::bytes_for(&ctx, grid.desc())?;
        let buffer = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("light grid"),
            size: bytes,
            usage: Self::USAGE,
            mapped_at_creation: false,
        });
        ctx.queue
            .write_buffer(&buffer, 0, bytemuck::cast_slice(grid.data()));
        Ok(Self {
            ctx,
            buffer,
            desc: *grid.desc(),
        })
    }

    /// Wraps a buffer a kernel wrote in this layout (the GPU sweeper's output). Errors
    /// when the buffer is smaller than `desc` needs or lacks [`GpuLightGrid::USAGE`].
    pub fn from_buffer(
        ctx: Arc<GpuContext>,
        buffer: wgpu::Buffer,
        desc: GridDesc,
    ) -> Result<Self, GpuError> {
        let need = Self::bytes_for(&ctx, &desc)?;
        if buffer.size() < need {
            return Err(GridError::invalid(
                "buffer.size()",
                buffer.size(),
                "smaller than the grid",
            )
            .into());
        }
        if !buffer.usage().contains(Self::USAGE) {
            return Err(GridError::invalid(
                "buffer.usage()",
                format!("{:?}", buffer.usage()),
                "needs STORAGE | COPY_SRC | COPY_DST",
            )
            .into());
        }
        Ok(Self { ctx, buffer, desc })
    }

    fn bytes_for(ctx: &GpuContext, desc: &GridDesc) -> Result<u64, GpuError> {
        let bytes = desc.point_count() as u64 * POINT_BYTES;
        if bytes > ctx.max_binding() {
            return Err(GpuError::TooLarge {
                what: "light grid",
                bytes,
                limit: ctx.max_binding(),
            });
        }
        Ok(bytes)
    }

    /// The buffer (bind it as `array<f32>`).
    pub fn buffer(&self) -> &wgpu::Buffer {
        &self.buffer
    }

    /// Where the points are.
    pub fn desc(&self) -> &GridDesc {
        &self.desc
    }

    /// The device it lives on.
    pub fn context(&self) -> &Arc<GpuContext> {
        &self.ctx
    }

    /// Writes the points `lo ..= hi` of `grid` (same descriptor) one x-row at a time, as
    /// when one local light toggles; returns the bytes written.
    pub fn upload_region(&self, grid: &LightGrid, lo: UVec3, hi: UVec3) -> Result<u64, GpuError> {
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
                self.ctx.queue.write_buffer(
                    &self.buffer,
                    start as u64 * POINT_BYTES,
                    bytemuck::cast_slice(&grid.data()[start..end]),
                );
                written += (end - start) as u64 * POINT_BYTES;
            }
        }
        Ok(written)
    }

    /// The points of `inner`, a box of this grid's points starting at point `offset`
    /// (the same cell size), as a grid of their own on the device: copied there row by
    /// row (`copy_buffer_to_buffer`), never through the CPU. A node swept over an apron
    /// keeps its own points this way. Errors when `inner` does not lie within the grid at
    /// `offset` or has another cell size.
    pub fn crop(&self, inner: GridDesc, offset: UVec3) -> Result<GpuLightGrid, GpuError> {
        let (big, small) = (self.desc.dims(), inner.dims());
        if (offset + small).cmpgt(big).any() {
            return Err(GridError::invalid(
                "offset",
                (offset, small, big),
                "the box of inner's points from it must lie within the grid's",
            )
            .into());
        }
        if inner.h() != self.desc.h() {
            return Err(
                GridError::invalid("inner.h()", inner.h(), "must be the grid's cell size").into(),
            );
        }
        let bytes = Self::bytes_for(&self.ctx, &inner)?;
        let buffer = self.ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("light grid (cropped)"),
            size: bytes,
            usage: Self::USAGE,
            mapped_at_creation: false,
        });
        let row = small.x as u64 * POINT_BYTES;
        let mut enc = self.ctx.device.create_command_encoder(&Default::default());
        for y in 0..small.y {
            for z in 0..small.z {
                let from = self.desc.index_unchecked(offset + UVec3::new(0, y, z)) as u64;
                let to = inner.index_unchecked(UVec3::new(0, y, z)) as u64;
                enc.copy_buffer_to_buffer(
                    &self.buffer,
                    from * POINT_BYTES,
                    &buffer,
                    to * POINT_BYTES,
                    row,
                );
            }
        }
        self.ctx.queue.submit([enc.finish()]);
        Ok(Self {
            ctx: self.ctx.clone(),
            buffer,
            desc: inner,
        })
    }

    /// Reads the grid back to the CPU; errors if it holds NaN, infinity or negative
    /// light.
    pub fn read(&self) -> Result<LightGrid, GpuError> {
        let bytes = self.ctx.read_back(&self.buffer)?;
        let n = self.desc.point_count();
        let data: Vec<BinLight> = bytemuck::pod_collect_to_vec(&bytes[..n * POINT_BYTES as usize]);
        if let Some(i) = data.iter().position(|b| !b.is_valid()) {
            return Err(GridError::invalid(
                format!("point {i}"),
                "NaN, infinity or negative light",
                "a GPU light grid must hold finite light >= 0",
            )
            .into());
        }
        Ok(Grid::from_trusted(self.desc, data))
    }
}
