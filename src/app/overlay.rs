//! The window's panel and HUD as a layer of their own. egui's primitives are drawn into a
//! texture the window's size, and a primitive is redrawn there only when its mesh changed; each
//! frame the layer is laid over the clouds (shaders/overlay.wgsl).
//!
//! Why: on a CPU adapter egui's pass cost a fifth of the window's frame (about 20 ms of the
//! panel's 7 700 small triangles at 1280×720 on lavapipe), though from one frame to the next
//! only the HUD's numbers change. Laying the layer over the frame costs one texture read and
//! blend per pixel of the panel and HUD, whatever they hold. The picture is what drawing egui
//! onto the frame gives: the same premultiplied blend, applied in two steps (tests/overlay.rs).

use std::collections::hash_map::DefaultHasher;
use std::hash::{Hash, Hasher};

use egui::epaint::{ClippedPrimitive, Primitive};

use crate::render::{pipeline, shader};

/// A rectangle of the window in pixels: x0, y0, x1, y1 (x1, y1 exclusive).
type PixelRect = [u32; 4];

/// What one `draw` did (tests/overlay.rs checks that an unchanged panel is not redrawn).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Drawn {
    /// Primitives egui drew into the layer this frame.
    pub redrawn: usize,
    /// Primitives the layer holds.
    pub total: usize,
}

/// egui's renderer, the layer it draws into, and the two pipelines that lay the layer over a
/// frame and empty a rectangle of it.
pub struct Overlay {
    egui: egui_wgpu::Renderer,
    over: wgpu::RenderPipeline,
    clear: wgpu::RenderPipeline,
    format: wgpu::TextureFormat,
    layer: Option<Layer>,
}

/// The layer texture and what is drawn in it.
struct Layer {
    size: [u32; 2],
    pixels_per_point: f32,
    view: wgpu::TextureView,
    bind: wgpu::BindGroup,
    /// Each primitive drawn there, in egui's order: its rectangle and its key.
    held: Vec<(PixelRect, u64)>,
}

impl Overlay {
    /// For frames of `format` (the window surface's).
    pub fn new(device: &wgpu::Device, format: wgpu::TextureFormat) -> Overlay {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("overlay"),
            source: wgpu::ShaderSource::Wgsl(shader::OVERLAY.into()),
        });
        let pipeline = |entry: &str, blend: Option<wgpu::BlendState>| {
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(entry),
                layout: None,
                vertex: wgpu::VertexState {
                    module: &module,
                    entry_point: Some("vs_main"),
                    buffers: &[],
                    compilation_options: Default::default(),
                },
                primitive: Default::default(),
                depth_stencil: None,
                multisample: Default::default(),
                fragment: Some(wgpu::FragmentState {
                    module: &module,
                    entry_point: Some(entry),
                    targets: &[Some(wgpu::ColorTargetState {
                        format,
                        blend,
                        write_mask: wgpu::ColorWrites::ALL,
                    })],
                    compilation_options: Default::default(),
                }),
                multiview_mask: None,
                cache: None,
            })
        };
        Overlay {
            egui: egui_wgpu::Renderer::new(device, format, Default::default()),
            over: pipeline(
                "fs_over",
                Some(wgpu::BlendState::PREMULTIPLIED_ALPHA_BLENDING),
            ),
            clear: pipeline("fs_clear", None),
            format,
            layer: None,
        }
    }

    /// Bring the layer up to egui's output and lay it over `target` (`size` pixels). Returns
    /// egui's own command buffers (its uploads), to be submitted before `enc`'s, and what was
    /// redrawn.
    #[allow(clippy::too_many_arguments)]
    pub fn draw(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        enc: &mut wgpu::CommandEncoder,
        target: &wgpu::TextureView,
        size: [u32; 2],
        ctx: &egui::Context,
        out: egui::FullOutput,
    ) -> (Vec<wgpu::CommandBuffer>, Drawn) {
        let ppp = out.pixels_per_point;
        let prims = ctx.tessellate(out.shapes, ppp);
        // A texture egui replaced whole may be read by any primitive; a patch (the font atlas
        // gaining a glyph) leaves what others read as it was, and those that read the patch
        // have changed meshes anyway.
        let mut whole = false;
        for (id, deltas) in &out.textures_delta.set {
            for delta in deltas {
                whole |= delta.pos.is_none();
                self.egui.update_texture(device, queue, *id, delta);
            }
        }
        let fresh: Vec<(PixelRect, u64)> = prims.iter().map(|p| held(p, ppp, size)).collect();
        let layer = match self.layer.take() {
            Some(l) if l.size == size && l.pixels_per_point == ppp => l,
            _ => {
                whole = true;
                Layer::new(device, &self.over, self.format, size, ppp)
            }
        };
        let redraw = if whole {
            None
        } else {
            changed(&layer.held, &fresh)
        };
        let screen = egui_wgpu::ScreenDescriptor {
            size_in_pixels: size,
            pixels_per_point: ppp,
        };
        // The primitives to draw, and the rectangles to empty first (all of it: the whole layer).
        let (jobs, empty): (Vec<ClippedPrimitive>, Vec<PixelRect>) = match redraw {
            None => (prims, vec![[0, 0, size[0], size[1]]]),
            Some(idx) => (
                idx.iter().map(|&(i, _)| prims[i].clone()).collect(),
                idx.iter().map(|&(_, r)| r).collect(),
            ),
        };
        let extra = self.egui.update_buffers(device, queue, enc, &jobs, &screen);
        if !empty.is_empty() {
            let pass = pipeline::over_pass(enc, "overlay layer", &layer.view);
            let mut pass = pass.forget_lifetime();
            pass.set_pipeline(&self.clear);
            for r in &empty {
                if scissor(&mut pass, *r) {
                    pass.draw(0..3, 0..1);
                }
            }
            self.egui.render(&mut pass, &jobs, &screen);
        }
        for id in &out.textures_delta.free {
            self.egui.free_texture(id);
        }
        {
            let mut pass = pipeline::over_pass(enc, "overlay", target);
            pass.set_pipeline(&self.over);
            pass.set_bind_group(0, &layer.bind, &[]);
            for r in disjoint(fresh.iter().map(|h| h.0).collect()) {
                if scissor(&mut pass, r) {
                    pass.draw(0..3, 0..1);
                }
            }
        }
        let drawn = Drawn {
            redrawn: jobs.len(),
            total: fresh.len(),
        };
        self.layer = Some(Layer {
            held: fresh,
            ..layer
        });
        (extra, drawn)
    }
}

impl Layer {
    fn new(
        device: &wgpu::Device,
        over: &wgpu::RenderPipeline,
        format: wgpu::TextureFormat,
        size: [u32; 2],
        pixels_per_point: f32,
    ) -> Layer {
        let tex = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("overlay layer"),
            size: wgpu::Extent3d {
                width: size[0].max(1),
                height: size[1].max(1),
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        });
        let view = tex.create_view(&Default::default());
        let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("overlay layer"),
            layout: &over.get_bind_group_layout(0),
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::TextureView(&view),
            }],
        });
        Layer {
            size,
            pixels_per_point,
            view,
            bind,
            held: Vec::new(),
        }
    }
}

/// Restrict the pass to `r`; false when it is empty (nothing to draw).
fn scissor(pass: &mut wgpu::RenderPass<'_>, r: PixelRect) -> bool {
    if r[2] <= r[0] || r[3] <= r[1] {
        return false;
    }
    pass.set_scissor_rect(r[0], r[1], r[2] - r[0], r[3] - r[1]);
    true
}

/// A primitive's rectangle in pixels: its mesh's bounds within its clip rectangle (rounded as
/// egui's renderer rounds its scissor), every pixel it can draw; and a key that changes when
/// what it draws does. Vertex positions enter the key to 1/8 px: a slider's handle creeping by
/// a thousandth of a pixel a frame (time running) would otherwise redraw the panel every frame,
/// for a picture that differs by less than the rounding shows.
fn held(p: &ClippedPrimitive, ppp: f32, size: [u32; 2]) -> (PixelRect, u64) {
    let px = |v: f32, max: u32| ((v * ppp).round().max(0.0) as u32).min(max);
    let clip = [
        px(p.clip_rect.min.x, size[0]),
        px(p.clip_rect.min.y, size[1]),
        px(p.clip_rect.max.x, size[0]),
        px(p.clip_rect.max.y, size[1]),
    ];
    let mut h = DefaultHasher::new();
    let rect = match &p.primitive {
        Primitive::Mesh(m) => {
            m.texture_id.hash(&mut h);
            m.indices.hash(&mut h);
            let (mut lo, mut hi) = ([f32::MAX; 2], [f32::MIN; 2]);
            for v in &m.vertices {
                let (x, y) = (v.pos.x * ppp, v.pos.y * ppp);
                lo = [lo[0].min(x), lo[1].min(y)];
                hi = [hi[0].max(x), hi[1].max(y)];
                ((x * 8.0).round() as i32).hash(&mut h);
                ((y * 8.0).round() as i32).hash(&mut h);
                v.uv.x.to_bits().hash(&mut h);
                v.uv.y.to_bits().hash(&mut h);
                v.color.to_array().hash(&mut h);
            }
            let at = |v: f32, max: u32| (v.max(0.0) as u32).min(max);
            let x0 = clip[0].max(at(lo[0].floor(), size[0]));
            let y0 = clip[1].max(at(lo[1].floor(), size[1]));
            let x1 = clip[2].min(at(hi[0].ceil(), size[0])).max(x0);
            let y1 = clip[3].min(at(hi[1].ceil(), size[1])).max(y0);
            [x0, y0, x1, y1]
        }
        // A callback draws what it likes in its clip rectangle: never taken as unchanged
        // (Stratus paints none).
        Primitive::Callback(_) => {
            std::time::Instant::now().hash(&mut h);
            clip
        }
    };
    rect.hash(&mut h);
    (rect, h.finish())
}

/// Which primitives to redraw, and the rectangle to empty for each first (where it stood and
/// where it will stand), when the layer can be mended in place: the same number of primitives,
/// and no rectangle to empty touching a primitive that stays (emptying it would erase that
/// one's pixels). `None` when the whole layer must be redrawn.
fn changed(old: &[(PixelRect, u64)], new: &[(PixelRect, u64)]) -> Option<Vec<(usize, PixelRect)>> {
    if old.len() != new.len() {
        return None;
    }
    let redo: Vec<(usize, PixelRect)> = (0..new.len())
        .filter(|&i| old[i].1 != new[i].1)
        .map(|i| (i, bounds(old[i].0, new[i].0)))
        .collect();
    let alone = redo.iter().all(|&(_, r)| {
        (0..new.len())
            .filter(|j| !redo.iter().any(|&(i, _)| i == *j))
            .all(|j| !overlap(r, new[j].0))
    });
    alone.then_some(redo)
}

/// The smallest rectangle holding both (an empty one holds nothing).
fn bounds(a: PixelRect, b: PixelRect) -> PixelRect {
    let empty = |r: PixelRect| r[2] <= r[0] || r[3] <= r[1];
    match (empty(a), empty(b)) {
        (true, _) => b,
        (_, true) => a,
        _ => [
            a[0].min(b[0]),
            a[1].min(b[1]),
            a[2].max(b[2]),
            a[3].max(b[3]),
        ],
    }
}

fn overlap(a: PixelRect, b: PixelRect) -> bool {
    a[0] < b[2] && b[0] < a[2] && a[1] < b[3] && b[1] < a[3]
}

/// The rectangles merged until none overlaps another: laying the layer over the frame once
/// in each covers every primitive and blends no pixel twice.
fn disjoint(mut rects: Vec<PixelRect>) -> Vec<PixelRect> {
    rects.retain(|r| r[2] > r[0] && r[3] > r[1]);
    let mut i = 0;
    while i < rects.len() {
        let hit = (0..rects.len()).find(|&j| j != i && overlap(rects[i], rects[j]));
        match hit {
            Some(j) => {
                rects[i] = bounds(rects[i], rects[j]);
                rects.swap_remove(j);
                i = 0;
            }
            None => i += 1,
        }
    }
    rects
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn merged_rectangles_do_not_overlap_and_cover_all() {
        let rects = vec![
            [0, 0, 10, 10],
            [5, 5, 20, 8],
            [30, 0, 40, 40],
            [50, 50, 50, 60],
        ];
        let out = disjoint(rects.clone());
        assert_eq!(out.len(), 2, "{out:?}");
        for (i, a) in out.iter().enumerate() {
            for b in &out[i + 1..] {
                assert!(!overlap(*a, *b));
            }
        }
        for r in &rects[..3] {
            assert!(out
                .iter()
                .any(|o| o[0] <= r[0] && o[1] <= r[1] && o[2] >= r[2] && o[3] >= r[3]));
        }
    }

    #[test]
    fn a_changed_primitive_over_one_that_stays_redraws_the_whole_layer() {
        let old = [([0, 0, 10, 10], 1), ([20, 0, 30, 10], 2)];
        // The second grows within its own space: emptied where it was and will be.
        assert_eq!(
            changed(&old, &[([0, 0, 10, 10], 1), ([22, 0, 34, 10], 3)]),
            Some(vec![(1, [20, 0, 34, 10])])
        );
        assert_eq!(changed(&old, &old), Some(vec![]));
        // Now it reaches into the first, which stays: the whole layer.
        assert_eq!(
            changed(&old, &[([0, 0, 10, 10], 1), ([5, 0, 30, 10], 3)]),
            None
        );
        // Both change: both emptied, then both redrawn in egui's order.
        assert_eq!(
            changed(&old, &[([0, 0, 12, 10], 4), ([5, 0, 30, 10], 3)]).map(|v| v.len()),
            Some(2)
        );
        assert_eq!(changed(&old, &old[..1]), None);
    }
}
