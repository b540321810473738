//! Present stage: a full-screen triangle (shaders/present.wgsl) that composites the cloud
//! texture over the background the march found (sky, Sun, Moon, stars, ground), enlarging
//! bilinearly where the march was smaller (one read of the picture render::resolve resolved and
//! composited at the march's size), and tone-maps into the target format.

use super::contract::{self, Binding, Resource};
use super::gpu::Gpu;
use super::pipeline::bind;
use super::scene::{SCENE_BINDINGS, SCENE_GROUP};
use super::shader;

/// present.wgsl's own bindings: the frame uniforms (the device's lifetime), the march's cloud
/// texture (the output size's) and the exposure stage's result (the device's).
pub const BINDINGS: &[Binding] = &[
    contract::frame(0, 0),
    contract::texture(1, 0),
    // The background behind the cloud and each pixel's distance (the march's scene texture).
    contract::texture(1, 1),
    Binding {
        group: 2,
        binding: 0,
        resource: Resource::StorageRead,
    },
];

/// Every binding of present.wgsl, with the scene's group (render::shadow).
pub fn bindings() -> Vec<Binding> {
    BINDINGS.iter().chain(SCENE_BINDINGS).copied().collect()
}

/// How the present stage reads the march: at the target's own size (the march's jitter
/// resolved over 3×3 march pixels), or enlarged from a smaller march (the window's render
/// scale): one bilinear read of that march resolved and laid over its background at its own
/// size (render::resolve).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Resample {
    Same,
    Enlarged,
}

impl Resample {
    /// For a march of `march_scale` pixels a target pixel (frame.wgsl `march_scale`).
    pub fn of(march_scale: f32) -> Resample {
        if march_scale < super::frame::ENLARGED_BELOW {
            Resample::Enlarged
        } else {
            Resample::Same
        }
    }
}

/// A present pipeline made by [`PresentPass::prepare`]; only it makes them, so one always
/// names a pipeline that exists.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PipelineId(usize);

/// The present pipelines (one per target format and [`Resample`], sharing one layout) and the
/// uniforms' bind group.
pub struct PresentPass {
    layouts: [wgpu::BindGroupLayout; 2],
    layout: wgpu::PipelineLayout,
    device_bind: wgpu::BindGroup,
    exposure_bind: wgpu::BindGroup,
    pipelines: Vec<((wgpu::TextureFormat, Resample), wgpu::RenderPipeline)>,
}

impl PresentPass {
    pub fn new(
        gpu: &Gpu,
        uniforms: &wgpu::Buffer,
        exposure: &wgpu::Buffer,
        scene_layout: &wgpu::BindGroupLayout,
    ) -> PresentPass {
        let dev = &gpu.device;
        let stage = wgpu::ShaderStages::FRAGMENT | wgpu::ShaderStages::VERTEX;
        let layouts = [
            contract::layout(dev, "present: device", BINDINGS, 0, stage),
            contract::layout(dev, "present: target", BINDINGS, 1, stage),
        ];
        // Read in the fragment stage only: a vertex stage may not see a storage buffer here.
        let exposure_layout = contract::layout(
            dev,
            "present: exposure",
            BINDINGS,
            2,
            wgpu::ShaderStages::FRAGMENT,
        );
        let layout = dev.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("present"),
            bind_group_layouts: &[
                Some(&layouts[0]),
                Some(&layouts[1]),
                Some(&exposure_layout),
                Some(scene_layout),
            ],
            immediate_size: 0,
        });
        let exposure_bind = bind(
            dev,
            "present: exposure",
            &exposure_layout,
            [wgpu::BindingResource::Buffer(
                exposure.as_entire_buffer_binding(),
            )],
        );
        let device_bind = bind(
            dev,
            "present: device",
            &layouts[0],
            [wgpu::BindingResource::Buffer(
                uniforms.as_entire_buffer_binding(),
            )],
        );
        PresentPass {
            layouts,
            layout,
            device_bind,
            exposure_bind,
            pipelines: Vec::new(),
        }
    }

    /// The pipeline for a target format and a way of reading the march, made on first use.
    /// Both are pipeline constants, not uniform branches: a CPU driver runs every side of a
    /// branch for every pixel, taken or not, so a window that enlarges its march paid for the
    /// full-size resolve as well (about 20 ms of a 1280×720 frame on lavapipe).
    pub fn prepare(
        &mut self,
        gpu: &Gpu,
        format: wgpu::TextureFormat,
        resample: Resample,
    ) -> PipelineId {
        let key = (format, resample);
        if let Some(i) = self.pipelines.iter().position(|(k, _)| *k == key) {
            return PipelineId(i);
        }
        let dev = &gpu.device;
        let module = shader::module(dev, "present", shader::PRESENT);
        let encode = [
            ("ENCODE_SRGB", if format.is_srgb() { 0.0 } else { 1.0 }),
            (
                "UPSAMPLE",
                if resample == Resample::Same { 0.0 } else { 1.0 },
            ),
        ];
        let pipeline = super::pipeline::fullscreen(
            dev,
            "present",
            &self.layout,
            &module,
            &encode,
            format.into(),
        );
        self.pipelines.push((key, pipeline));
        PipelineId(self.pipelines.len() - 1)
    }

    /// The frame's bind group (cloud and scene textures): made again only when the output
    /// size changes.
    pub fn bind_target(
        &self,
        gpu: &Gpu,
        cloud: &wgpu::TextureView,
        scene: &wgpu::TextureView,
    ) -> wgpu::BindGroup {
        super::pipeline::bind_frame_textures(
            &gpu.device,
            "present: target",
            &self.layouts[1],
            cloud,
            scene,
        )
    }

    /// Record the pass with a pipeline from [`PresentPass::prepare`].
    pub fn encode(
        &self,
        enc: &mut wgpu::CommandEncoder,
        pipeline: PipelineId,
        target_bind: &wgpu::BindGroup,
        scene_bind: &wgpu::BindGroup,
        (target, size): (&wgpu::TextureView, (u32, u32)),
        timestamps: Option<wgpu::RenderPassTimestampWrites<'_>>,
    ) {
        let pipeline = &self.pipelines[pipeline.0].1;
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("present"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: target,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: timestamps,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        // Only the picture's part of the target: the window's panel covers the rest.
        pass.set_viewport(0.0, 0.0, size.0 as f32, size.1 as f32, 0.0, 1.0);
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &self.device_bind, &[]);
        pass.set_bind_group(1, target_bind, &[]);
        pass.set_bind_group(2, &self.exposure_bind, &[]);
        pass.set_bind_group(SCENE_GROUP, scene_bind, &[]);
        pass.draw(0..3, 0..1);
    }
}

#[cfg(test)]
mod tests {
    use super::Resample;

    #[test]
    fn a_march_at_the_targets_size_is_resolved_and_a_smaller_one_enlarged() {
        // The window's CPU default (¼ of 1280) and a march a pixel short of the target's size
        // enlarge; the target's own size, or a rounding over it, resolves in place.
        assert_eq!(Resample::of(320.0 / 1280.0), Resample::Enlarged);
        assert_eq!(Resample::of(1266.0 / 1280.0), Resample::Enlarged);
        assert_eq!(Resample::of(1.0), Resample::Same);
        assert_eq!(Resample::of(1279.0 / 1280.0), Resample::Same);
    }
}
