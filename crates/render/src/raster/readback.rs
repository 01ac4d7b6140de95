//! Images drawn now and read back later. [`Renderer::record`] and
//! [`Renderer::record_pair`] record a view's drawing and the copy of its targets into
//! buffers the CPU can map, [`Renderer::send`] submits them, [`Renderer::finish`] waits
//! for them and decodes the images. In between the CPU is free while the device draws
//! (a software rasteriser such as lavapipe draws on threads of its own). `finish` takes
//! `&self`: the viewer reads a view's images back and writes them on a thread of its
//! own while the next view's grids are built. The readback buffers are kept for the
//! next images (at most [`SPARE_READBACK_BYTES`]).

use super::*;

/// Most bytes of readback buffers a renderer keeps for its next images (four 1080p
/// images' HDR and sRGB copies).
pub(crate) const SPARE_READBACK_BYTES: u64 = 4 * 1920 * 1088 * (16 + 4);

/// Images recorded by [`Renderer::record`] or [`Renderer::record_pair`], not yet read
/// back: [`Renderer::finish`] returns them in the order they were recorded.
#[must_use = "the images are read back by Renderer::finish"]
#[derive(Debug, Default)]
pub struct PendingImages {
    /// Commands recorded and not yet submitted ([`Renderer::send`]).
    commands: Vec<wgpu::CommandBuffer>,
    /// Per image: the copies of its targets.
    images: Vec<Copies>,
}

/// One image's targets copied into mappable buffers.
#[derive(Debug)]
struct Copies {
    hdr: wgpu::Buffer,
    srgb: wgpu::Buffer,
}

impl PendingImages {
    /// Images recorded.
    pub fn len(&self) -> usize {
        self.images.len()
    }

    /// Whether none is.
    pub fn is_empty(&self) -> bool {
        self.images.is_empty()
    }

    /// `other`'s images after these (sent and read back together).
    pub fn append(&mut self, other: PendingImages) {
        self.commands.extend(other.commands);
        self.images.extend(other.images);
    }
}

impl Renderer {
    /// Records the drawing of `view` and the copy of its image, to be sent to the device
    /// with others ([`Renderer::send`]) and read back by [`Renderer::finish`]. Views
    /// recorded one after the other each keep their own camera and lighting.
    ///
    /// ```no_run
    /// # use lightgrid_render::{RenderError, Renderer, View};
    /// # fn shots(r: &mut Renderer, a: &View, b: &View) -> Result<(), RenderError> {
    /// let mut pending = r.record(a)?;
    /// pending.append(r.record_pair(b)?); // `b` lit by the grids, then without them
    /// r.send(&mut pending); // one submission: the device draws, the CPU goes on
    /// let images = r.finish(pending)?; // `a`, then `b`'s two
    /// assert_eq!(images.len(), 3);
    /// # Ok(())
    /// # }
    /// ```
    pub fn record(&mut self, view: &View) -> Result<PendingImages, RenderError> {
        let ldr_view = self.targets.ldr_view.clone();
        let mut enc = self.draw_meshes(view, false)?;
        self.tonemap_into(&mut enc, &ldr_view, LDR_FORMAT, false);
        let image = self.copy_out(&mut enc, false);
        Ok(PendingImages {
            commands: vec![enc.finish()],
            images: vec![image],
        })
    }

    /// [`Renderer::record`] for [`Renderer::render_pair`]'s two images (lit by the
    /// grids, then without them) from one pass over the geometry.
    pub fn record_pair(&mut self, view: &View) -> Result<PendingImages, RenderError> {
        let ldr_view = self.targets.ldr_view.clone();
        let mut enc = self.draw_meshes(view, true)?;
        self.tonemap_into(&mut enc, &ldr_view, LDR_FORMAT, false);
        let grid = self.copy_out(&mut enc, false);
        self.tonemap_into(&mut enc, &ldr_view, LDR_FORMAT, true);
        let plain = self.copy_out(&mut enc, true);
        Ok(PendingImages {
            commands: vec![enc.finish()],
            images: vec![grid, plain],
        })
    }

    /// Submits what `pending` recorded, in one submission: the device starts drawing
    /// while the caller goes on. (A software rasteriser such as lavapipe draws a
    /// submission on threads of its own, but the next submission waits for it: one
    /// submission for all of a view's images leaves the CPU free until then.)
    pub fn send(&self, pending: &mut PendingImages) {
        if !pending.commands.is_empty() {
            self.ctx.queue.submit(pending.commands.drain(..));
        }
    }

    /// Sends what `pending` recorded if it was not, waits for its images and reads
    /// them back, in their order.
    pub fn finish(&self, mut pending: PendingImages) -> Result<Vec<Image>, RenderError> {
        self.send(&mut pending);
        let (tx, rx) = std::sync::mpsc::channel();
        for c in &pending.images {
            for b in [&c.hdr, &c.srgb] {
                let tx = tx.clone();
                b.slice(..)
                    .map_async(wgpu::MapMode::Read, move |r| drop(tx.send(r)));
            }
        }
        drop(tx);
        self.ctx
            .device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| GpuError::Readback(e.to_string()))?;
        for r in rx.iter() {
            r.map_err(|e| GpuError::Readback(e.to_string()))?;
        }
        pending
            .images
            .iter()
            .map(|c| self.decode(c))
            .collect::<Result<_, GpuError>>()
            .map_err(RenderError::from)
    }

    /// Bytes a pixel of the HDR target.
    fn hdr_bytes(&self) -> u32 {
        if self.hdr_format == HDR_FORMAT { 16 } else { 8 }
    }

    /// Copies the HDR target (`pair`: the pair's) and the sRGB target into new
    /// mappable buffers, in `enc`.
    fn copy_out(&self, enc: &mut wgpu::CommandEncoder, pair: bool) -> Copies {
        let hdr = if pair {
            &self.targets.hdr_pair
        } else {
            &self.targets.hdr
        };
        Copies {
            hdr: self.copy_texture(enc, hdr, self.hdr_bytes()),
            srgb: self.copy_texture(enc, &self.targets.ldr, 4),
        }
    }

    /// Rows of `bpp` bytes a pixel, padded to the copy's alignment.
    fn padded_row(&self, bpp: u32) -> u32 {
        (self.width * bpp).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT)
            * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT
    }

    fn copy_texture(
        &self,
        enc: &mut wgpu::CommandEncoder,
        tex: &wgpu::Texture,
        bpp: u32,
    ) -> wgpu::Buffer {
        let padded = self.padded_row(bpp);
        let size = (padded * self.height) as u64;
        let spare = self.spare_readback.lock().ok().and_then(|mut spare| {
            let at = spare.iter().position(|b| b.size() == size)?;
            Some(spare.swap_remove(at))
        });
        let buffer = spare.unwrap_or_else(|| {
            self.ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("image readback"),
                size,
                usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                mapped_at_creation: false,
            })
        });
        enc.copy_texture_to_buffer(
            tex.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &buffer,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(padded),
                    rows_per_image: Some(self.height),
                },
            },
            tex.size(),
        );
        buffer
    }

    /// Keeps an unmapped readback buffer for the next images, within
    /// [`SPARE_READBACK_BYTES`].
    fn keep(&self, buffer: &wgpu::Buffer) {
        if let Ok(mut spare) = self.spare_readback.lock() {
            let held: u64 = spare.iter().map(wgpu::Buffer::size).sum();
            if held + buffer.size() <= SPARE_READBACK_BYTES {
                spare.push(buffer.clone());
            }
        }
    }

    /// The pixels of a mapped copy of `bpp` bytes a pixel, each decoded by `pixel`
    /// (padding dropped); the buffer is unmapped and kept for the next images.
    fn pixels<T>(
        &self,
        buffer: &wgpu::Buffer,
        bpp: u32,
        pixel: impl Fn(&[u8]) -> T,
    ) -> Result<Vec<T>, GpuError> {
        let row = (self.width * bpp) as usize;
        let mut out = Vec::with_capacity((self.width * self.height) as usize);
        {
            let mapped = buffer
                .slice(..)
                .get_mapped_range()
                .map_err(|e| GpuError::Readback(e.to_string()))?;
            for r in mapped.chunks(self.padded_row(bpp) as usize) {
                out.extend(r[..row].chunks_exact(bpp as usize).map(&pixel));
            }
        }
        buffer.unmap();
        self.keep(buffer);
        Ok(out)
    }

    /// One image from its mapped copies (non-finite HDR values read as 0).
    fn decode(&self, c: &Copies) -> Result<Image, GpuError> {
        let finite = |c: f32| if c.is_finite() { c } else { 0.0 };
        let hdr: Vec<[f32; 4]> = if self.hdr_format == HDR_FORMAT {
            self.pixels(&c.hdr, 16, |p| {
                let v: [f32; 4] = bytemuck::pod_read_unaligned(p);
                v.map(finite)
            })?
        } else {
            self.pixels(&c.hdr, 8, |p| {
                let v: [u16; 4] = bytemuck::pod_read_unaligned(p);
                v.map(|h| finite(half::f16::from_bits(h).to_f32()))
            })?
        };
        let srgb: Vec<[u8; 4]> = self.pixels(&c.srgb, 4, bytemuck::pod_read_unaligned)?;
        Ok(Image {
            width: self.width,
            height: self.height,
            hdr,
            srgb,
        })
    }
}
