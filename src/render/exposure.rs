//! Exposure stage: dispatches shaders/exposure.wgsl, which meters each frame as it will be shown
//! (cloud over background) and sets the exposure the present stage applies: adapted to the scene
//! from ½ EV under to 3 EV over the Sun's-height exposure (opening up only by day), or fixed (`render --exposure EV`). The result stays
//! on the GPU (a storage buffer the present stage reads): nothing waits for it.

use super::contract::{self, Binding, Resource};
use super::gpu::Gpu;
use super::pipeline::bind;
use super::scene::{SCENE_BINDINGS, SCENE_GROUP};
use super::shader;

crate::gpu_struct! {
    /// The stage's settings for a frame (`ExposureParams` in shaders/common.wgsl).
    pub struct ExposureParams as "ExposureParams" {
        /// 2^EV, the offset over the adapted exposure.
        pub ev_mul: f32,
        /// Share of the way (in stops) from the last exposure to the metered one this frame.
        pub rate: f32,
        /// 0: the frame's exposure is used as it is.
        pub auto_on: u32,
        pub _pad: u32,
    }
}

crate::gpu_struct! {
    /// What the stage leaves for the present stage (`ExposureState`).
    pub struct ExposureState as "ExposureState" {
        pub value: f32,
        pub adapted: f32,
        /// Natural log of the metered mean luminance.
        pub metered: f32,
        pub _pad: f32,
    }
}

/// Every binding of exposure.wgsl.
pub const OWN_BINDINGS: &[Binding] = &[
    contract::frame(0, 0),
    contract::texture(1, 0),
    // The background behind the cloud (the march's scene texture).
    contract::texture(1, 1),
    Binding {
        group: 2,
        binding: 0,
        resource: Resource::StorageRw,
    },
    contract::uniform::<ExposureParams>(2, 1),
];

pub fn bindings() -> Vec<Binding> {
    OWN_BINDINGS.iter().chain(SCENE_BINDINGS).copied().collect()
}

pub struct ExposurePass {
    pipeline: wgpu::ComputePipeline,
    target_layout: wgpu::BindGroupLayout,
    device_bind: wgpu::BindGroup,
    own_bind: wgpu::BindGroup,
    params: wgpu::Buffer,
    /// The result, read by the present stage.
    pub state: wgpu::Buffer,
}

impl ExposurePass {
    pub fn new(
        gpu: &Gpu,
        uniforms: &wgpu::Buffer,
        scene_layout: &wgpu::BindGroupLayout,
    ) -> ExposurePass {
        let dev = &gpu.device;
        let stage = wgpu::ShaderStages::COMPUTE;
        let layouts = [0, 1, 2].map(|g| contract::layout(dev, "exposure", OWN_BINDINGS, g, stage));
        let pipeline_layout = dev.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("exposure"),
            bind_group_layouts: &[
                Some(&layouts[0]),
                Some(&layouts[1]),
                Some(&layouts[2]),
                Some(scene_layout),
            ],
            immediate_size: 0,
        });
        debug_assert_eq!(SCENE_GROUP, 3);
        let module = shader::module(dev, "exposure", shader::EXPOSURE);
        let pipeline = dev.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("exposure"),
            layout: Some(&pipeline_layout),
            module: &module,
            entry_point: Some("main"),
            compilation_options: Default::default(),
            cache: None,
        });
        let buffer = |label, size: usize, usage| {
            dev.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: size as u64,
                usage,
                mapped_at_creation: false,
            })
        };
        use wgpu::BufferUsages as U;
        let params = buffer(
            "exposure params",
            std::mem::size_of::<ExposureParams>(),
            U::UNIFORM | U::COPY_DST,
        );
        let state = buffer(
            "exposure state",
            std::mem::size_of::<ExposureState>(),
            U::STORAGE | U::COPY_DST | U::COPY_SRC,
        );
        use wgpu::BindingResource as R;
        let device_bind = bind(
            dev,
            "exposure: device",
            &layouts[0],
            [R::Buffer(uniforms.as_entire_buffer_binding())],
        );
        let own_bind = bind(
            dev,
            "exposure: own",
            &layouts[2],
            [
                R::Buffer(state.as_entire_buffer_binding()),
                R::Buffer(params.as_entire_buffer_binding()),
            ],
        );
        let [_, target_layout, _] = layouts;
        ExposurePass {
            pipeline,
            target_layout,
            device_bind,
            own_bind,
            params,
            state,
        }
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
            "exposure: target",
            &self.target_layout,
            cloud,
            scene,
        )
    }

    pub fn encode(
        &self,
        gpu: &Gpu,
        enc: &mut wgpu::CommandEncoder,
        params: &ExposureParams,
        target_bind: &wgpu::BindGroup,
        scene_bind: &wgpu::BindGroup,
    ) {
        gpu.queue
            .write_buffer(&self.params, 0, bytemuck::bytes_of(params));
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("exposure"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.device_bind, &[]);
        pass.set_bind_group(1, target_bind, &[]);
        pass.set_bind_group(2, &self.own_bind, &[]);
        pass.set_bind_group(SCENE_GROUP, scene_bind, &[]);
        pass.dispatch_workgroups(1, 1, 1);
    }
}
