//! A frame marched at a fraction of its output size and enlarged the way the window's CPU path
//! does it (issue 30: `render --render-scale`): the march at the smaller size, then the present
//! pass draws it into a target of the full size (`Renderer::encode` with the target's width),
//! so a headless picture shows exactly what the window shows at that render scale.

use std::time::Instant;

use crate::render::readback::Pending;
use crate::render::{RenderError, Renderer, Settings, View};

/// The headless target's format (the present pass encodes sRGB itself, as into the window's).
const FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;

/// The march size the window uses for an output of `size` at render scale `scale`.
pub fn march_size((w, h): (u32, u32), scale: f32) -> (u32, u32) {
    let scale = scale.clamp(0.05, 1.0);
    (
        ((w as f32 * scale) as u32).max(1),
        ((h as f32 * scale) as u32).max(1),
    )
}

/// One frame: marched at `march` and enlarged to `out`. Returns the tone-mapped sRGB RGBA8
/// pixels at `out` and the wall time (ms).
pub fn render(
    r: &mut Renderer,
    view: &View,
    march: (u32, u32),
    out: (u32, u32),
    settings: &Settings,
) -> Result<(image::RgbaImage, f64), RenderError> {
    let max = r.max_side();
    if out.0 == 0 || out.1 == 0 || out.0 > max || out.1 > max {
        return Err(RenderError::BadSize(out.0, out.1, max));
    }
    let start = Instant::now();
    let dev = r.gpu.device.clone();
    let scope = dev.push_error_scope(wgpu::ErrorFilter::Validation);
    let target = dev.create_texture(&wgpu::TextureDescriptor {
        label: Some("scaled frame"),
        size: wgpu::Extent3d {
            width: out.0,
            height: out.1,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: FORMAT,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    });
    let tv = target.create_view(&Default::default());
    let mut enc = dev.create_command_encoder(&Default::default());
    r.encode(
        &mut enc, view, march.0, march.1, settings, &tv, FORMAT, out.0,
    )?;
    let rb = Pending::texture(&r.gpu, &mut enc, &target, 4);
    r.gpu.queue.submit([enc.finish()]);
    let pixels = rb.finish(&r.gpu)?;
    if let Some(e) = pollster::block_on(scope.pop()) {
        return Err(RenderError::Gpu(e.to_string()));
    }
    let ms = start.elapsed().as_secs_f64() * 1e3;
    let img = image::RgbaImage::from_raw(out.0, out.1, pixels)
        .ok_or_else(|| RenderError::Readback("short read-back".into()))?;
    Ok((img, ms))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn march_size_is_the_windows() {
        assert_eq!(march_size((1280, 720), 0.25), (320, 180));
        assert_eq!(march_size((1280, 720), 1.0), (1280, 720));
        assert_eq!(march_size((10, 10), 0.01), (1, 1));
    }
}
