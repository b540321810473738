//! Bringing textures and buffers back to the CPU: row-padded copies, mapped and unpadded.

use super::gpu::Gpu;
use super::RenderError;

pub struct Pending {
    buffer: wgpu::Buffer,
    row_bytes: usize,
    padded: usize,
    rows: usize,
}

impl Pending {
    /// Queue a copy of a whole 2D texture with `bpp` bytes per pixel.
    pub fn texture(
        gpu: &Gpu,
        enc: &mut wgpu::CommandEncoder,
        tex: &wgpu::Texture,
        bpp: u32,
    ) -> Pending {
        let (w, h) = (tex.width(), tex.height());
        let row_bytes = w * bpp;
        let padded = row_bytes.div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT)
            * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
        let buffer = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size: padded as u64 * h as u64,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        enc.copy_texture_to_buffer(
            tex.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &buffer,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(padded),
                    rows_per_image: Some(h),
                },
            },
            tex.size(),
        );
        Pending {
            buffer,
            row_bytes: row_bytes as usize,
            padded: padded as usize,
            rows: h as usize,
        }
    }

    /// Queue a copy of a whole buffer.
    pub fn buffer(gpu: &Gpu, enc: &mut wgpu::CommandEncoder, src: &wgpu::Buffer) -> Pending {
        let size = src.size();
        let buffer = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        enc.copy_buffer_to_buffer(src, 0, &buffer, 0, size);
        Pending {
            buffer,
            row_bytes: size as usize,
            padded: size as usize,
            rows: 1,
        }
    }

    /// A whole buffer (MAP_READ) already filled by the caller's own copy.
    pub fn whole(buffer: wgpu::Buffer) -> Pending {
        let size = buffer.size() as usize;
        Pending {
            buffer,
            row_bytes: size,
            padded: size,
            rows: 1,
        }
    }

    /// Wait for the copy and return the bytes without row padding.
    pub fn finish(self, gpu: &Gpu) -> Result<Vec<u8>, RenderError> {
        let slice = self.buffer.slice(..);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        gpu.wait()?;
        rx.recv()
            .map_err(|e| RenderError::Readback(e.to_string()))?
            .map_err(|e| RenderError::Readback(e.to_string()))?;
        let data = slice
            .get_mapped_range()
            .map_err(|e| RenderError::Readback(e.to_string()))?;
        let mut out = Vec::with_capacity(self.row_bytes * self.rows);
        for r in 0..self.rows {
            out.extend_from_slice(&data[r * self.padded..r * self.padded + self.row_bytes]);
        }
        drop(data);
        self.buffer.unmap();
        Ok(out)
    }
}

/// An Rgba16Float texture's read-back bytes as linear RGBA per texel (any alignment).
pub fn rgba16f(raw: &[u8]) -> Vec<[f32; 4]> {
    let half = |b: &[u8]| half::f16::from_le_bytes([b[0], b[1]]).to_f32();
    raw.chunks_exact(8)
        .map(|t| {
            [
                half(&t[0..2]),
                half(&t[2..4]),
                half(&t[4..6]),
                half(&t[6..8]),
            ]
        })
        .collect()
}
