//! A frame at a render scale under 1, made the way the window's CPU path makes it (issue 30:
//! `render --render-scale`), so a headless picture shows exactly what the window shows. Owns
//! the rule ([`plan`]): a reprojected perspective marches (scale / n)² of the output's pixels a
//! frame *at the output's size* in cells of n / scale pixels and reprojects the rest there
//! (temporal super-resolution: a still view converges to the full-resolution picture); any
//! other frame is marched at the smaller size and enlarged by the present pass into a target of
//! the full size (`Renderer::encode` with the target's width).

use std::time::Instant;

use crate::render::readback::Pending;
use crate::render::settings::MAX_SUBSET;
use crate::render::{RenderError, Renderer, Reprojection, Settings, View};

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

/// The reprojection cell side at render scale `scale` for a preset whose cell side is `n`:
/// n / scale to the nearest power of two, at most [`MAX_SUBSET`]. A march of the output's
/// size in these cells takes as many rays a frame as one at the render scale in n×n cells (the
/// window's cost before issue 30: render scale ¼, `fast` → 16, one pixel in 256 a frame).
pub fn cell(n: u32, scale: f32) -> u32 {
    let t = n.max(1) as f32 / scale.clamp(0.05, 1.0);
    let p = t
        .log2()
        .round()
        .clamp(0.0, MAX_SUBSET.trailing_zeros() as f32);
    1 << p as u32
}

/// How a frame of `size` at render scale `scale` is made: the march's size and the settings.
/// A perspective with reprojection on and a preset that reprojects is marched at `size` itself
/// in [`cell`]s; anything else at the scale ([`march_size`]), enlarged by the present pass.
pub fn plan(
    size: (u32, u32),
    scale: f32,
    view: &View,
    settings: &Settings,
) -> ((u32, u32), Settings) {
    let n = settings.march.subset;
    let reprojected = matches!(settings.reprojection, Reprojection::On { .. })
        && matches!(view, View::Perspective(_))
        && n > 1;
    if !reprojected || scale >= 1.0 {
        return (march_size(size, scale), settings.clone());
    }
    let mut s = settings.clone();
    s.march.subset = cell(n, scale);
    (size, s)
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
    r.encode(&mut enc, view, march.0, march.1, settings, &tv, FORMAT, out)?;
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

    #[test]
    fn a_reprojected_window_marches_as_many_rays_at_its_own_size() {
        assert_eq!(cell(4, 0.25), 16);
        assert_eq!(cell(4, 0.5), 8);
        assert_eq!(cell(4, 1.0), 4);
        assert_eq!(cell(2, 0.25), 8);
        assert_eq!(cell(4, 0.05), MAX_SUBSET);
        assert_eq!(cell(4, 0.3), 16);
    }
}
