//! Noise stage: generates the tileable shape (128³ RGBA) and detail (32³ RGB) noise textures
//! on the GPU once at start-up (shaders/noise.wgsl), from a fixed seed.

use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt;

use super::gpu::Gpu;
use super::shader;

pub const SHAPE_SIZE: u32 = 128;
pub const DETAIL_SIZE: u32 = 32;
/// The seed every Stratus noise texture is made from: the same clouds on every run.
pub const SEED: u32 = 0x5715_7a75;

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct NoiseParams {
    size: u32,
    kind: u32,
    seed: u32,
    _pad: u32,
}

pub struct NoiseTextures {
    pub shape: wgpu::Texture,
    pub detail: wgpu::Texture,
}

impl NoiseTextures {
    pub fn generate(gpu: &Gpu) -> NoiseTextures {
        let dev = &gpu.device;
        let module = shader::module(dev, "noise", shader::NOISE);
        let pipeline = dev.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("noise"),
            layout: None,
            module: &module,
            entry_point: Some("main"),
            compilation_options: Default::default(),
            cache: None,
        });
        let make = |size: u32, kind: u32, label: &str| {
            let tex = dev.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: wgpu::Extent3d {
                    width: size,
                    height: size,
                    depth_or_array_layers: size,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D3,
                format: wgpu::TextureFormat::Rgba8Unorm,
                usage: wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::TEXTURE_BINDING,
                view_formats: &[],
            });
            let params = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("noise params"),
                contents: bytemuck::bytes_of(&NoiseParams {
                    size,
                    kind,
                    seed: SEED,
                    _pad: 0,
                }),
                usage: wgpu::BufferUsages::UNIFORM,
            });
            let view = tex.create_view(&Default::default());
            let bind = dev.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some(label),
                layout: &pipeline.get_bind_group_layout(0),
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: params.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: wgpu::BindingResource::TextureView(&view),
                    },
                ],
            });
            let mut enc = dev.create_command_encoder(&Default::default());
            {
                let mut pass = enc.begin_compute_pass(&Default::default());
                pass.set_pipeline(&pipeline);
                pass.set_bind_group(0, &bind, &[]);
                let g = size.div_ceil(4);
                pass.dispatch_workgroups(g, g, g);
            }
            gpu.queue.submit([enc.finish()]);
            tex
        };
        NoiseTextures {
            shape: make(SHAPE_SIZE, 0, "shape noise"),
            detail: make(DETAIL_SIZE, 1, "detail noise"),
        }
    }
}
