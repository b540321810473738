//! Texture helpers every stage shares: a 2D or 3D texture of one level (or a mipped 3D one), a sampled 2D texture
//! the CPU fills ([`map_texture`], [`write`]).

use super::gpu::Gpu;

/// A single-level 2D texture.
pub fn texture_2d(
    dev: &wgpu::Device,
    label: &str,
    (width, height): (u32, u32),
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> wgpu::Texture {
    let size = (width, height, 1);
    single_level(dev, label, size, wgpu::TextureDimension::D2, format, usage)
}

/// A single-level 3D texture.
pub fn texture_3d(
    dev: &wgpu::Device,
    label: &str,
    size: (u32, u32, u32),
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> wgpu::Texture {
    single_level(dev, label, size, wgpu::TextureDimension::D3, format, usage)
}

/// A 3D texture with `levels` mip levels (the caller fills each).
pub fn texture_3d_mipped(
    dev: &wgpu::Device,
    label: &str,
    size: (u32, u32, u32),
    levels: u32,
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> wgpu::Texture {
    let dim = wgpu::TextureDimension::D3;
    with_levels(dev, label, size, levels, dim, format, usage)
}

/// A texture of one mip level and one sample; `depth` is the array layers of a 2D texture.
fn single_level(
    dev: &wgpu::Device,
    label: &str,
    size: (u32, u32, u32),
    dimension: wgpu::TextureDimension,
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> wgpu::Texture {
    with_levels(dev, label, size, 1, dimension, format, usage)
}

fn with_levels(
    dev: &wgpu::Device,
    label: &str,
    (width, height, depth): (u32, u32, u32),
    levels: u32,
    dimension: wgpu::TextureDimension,
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> wgpu::Texture {
    dev.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: depth,
        },
        mip_level_count: levels,
        sample_count: 1,
        dimension,
        format,
        usage,
        view_formats: &[],
    })
}

/// A sampled 2D texture the CPU fills ([`write`]): the map's, the tables'.
pub fn map_texture(
    gpu: &Gpu,
    label: &str,
    (w, h): (usize, usize),
    format: wgpu::TextureFormat,
) -> wgpu::Texture {
    texture_2d(
        &gpu.device,
        label,
        (w as u32, h as u32),
        format,
        wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
    )
}

/// Fill the whole of a 2D texture with tightly packed texels.
pub fn write(gpu: &Gpu, tex: &wgpu::Texture, bytes: &[u8], bytes_per_texel: usize) {
    let (w, h) = (tex.width(), tex.height());
    gpu.queue.write_texture(
        tex.as_image_copy(),
        bytes,
        wgpu::TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some(w * bytes_per_texel as u32),
            rows_per_image: Some(h),
        },
        tex.size(),
    );
}
