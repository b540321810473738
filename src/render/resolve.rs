//! Resolve stage: where a march smaller than its target is enlarged (the window's render scale,
//! `render --render-scale`), shaders/resolve.wgsl resolves the march's jitter at the march's
//! own size, as the present stage does for a march at the target's size (shaders/jitter.wgsl),
//! and lays it over its background; the present stage then enlarges that picture with one
//! bilinear read a target pixel. It owns its pipeline; the textures it reads
//! and writes are the frame set's (render::targets).

use super::contract::{self, Binding, Resource};
use super::gpu::Gpu;
use super::march::CLOUD_FORMAT;
use super::pipeline::{bind, bind_frame_textures, compute_pipeline};
use super::shader;

/// resolve.wgsl's bindings: the frame, the march's cloud and scene textures, the resolved cloud.
pub const BINDINGS: &[Binding] = &[
    contract::frame(0, 0),
    contract::texture(1, 0),
    contract::texture(1, 1),
    Binding {
        group: 2,
        binding: 0,
        resource: Resource::StorageTexture(CLOUD_FORMAT, 2),
    },
];

/// resolve.wgsl's workgroup side.
const GROUP: u32 = 8;

pub struct ResolvePass {
    pipeline: wgpu::ComputePipeline,
    layouts: [wgpu::BindGroupLayout; 2],
    device_bind: wgpu::BindGroup,
}

impl ResolvePass {
    pub fn new(gpu: &Gpu, uniforms: &wgpu::Buffer) -> ResolvePass {
        let dev = &gpu.device;
        let stage = wgpu::ShaderStages::COMPUTE;
        let [device, target, out] =
            [0, 1, 2].map(|g| contract::layout(dev, "resolve", BINDINGS, g, stage));
        let layout = dev.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("resolve"),
            bind_group_layouts: &[Some(&device), Some(&target), Some(&out)],
            immediate_size: 0,
        });
        let module = shader::module(dev, "resolve", shader::RESOLVE);
        let pipeline = compute_pipeline(gpu, "resolve", &layout, &module, &[]);
        let device_bind = bind(
            dev,
            "resolve: device",
            &device,
            [wgpu::BindingResource::Buffer(
                uniforms.as_entire_buffer_binding(),
            )],
        );
        ResolvePass {
            pipeline,
            layouts: [target, out],
            device_bind,
        }
    }

    /// The bind groups reading a frame set's march (`cloud`, `scene`) and writing `resolved`,
    /// a texture of the march's size in [`CLOUD_FORMAT`].
    pub fn bind_target(
        &self,
        gpu: &Gpu,
        cloud: &wgpu::TextureView,
        scene: &wgpu::TextureView,
        resolved: &wgpu::TextureView,
    ) -> [wgpu::BindGroup; 2] {
        [
            bind_frame_textures(
                &gpu.device,
                "resolve: march",
                &self.layouts[0],
                cloud,
                scene,
            ),
            bind(
                &gpu.device,
                "resolve: out",
                &self.layouts[1],
                [wgpu::BindingResource::TextureView(resolved)],
            ),
        ]
    }

    /// Record the pass over a `size` march.
    pub fn encode(
        &self,
        enc: &mut wgpu::CommandEncoder,
        binds: &[wgpu::BindGroup; 2],
        size: (u32, u32),
    ) {
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("resolve"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.device_bind, &[]);
        pass.set_bind_group(1, &binds[0], &[]);
        pass.set_bind_group(2, &binds[1], &[]);
        pass.dispatch_workgroups(size.0.div_ceil(GROUP), size.1.div_ceil(GROUP), 1);
    }
}
