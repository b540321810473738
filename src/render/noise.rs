//! Noise stage: generates the tileable shape (128³ RGBA) and detail (32³ RGB) noise textures
//! on the GPU once at start-up (shaders/noise.wgsl), from a fixed seed.

use wgpu::util::DeviceExt;

use super::contract::{self, Binding, Resource};
use super::gpu::Gpu;
use super::pipeline::bind;
use super::shader;
use super::texture::texture_3d;

pub const SHAPE_SIZE: u32 = 128;
pub const DETAIL_SIZE: u32 = 32;
/// The seed every Stratus noise texture is made from: the same clouds on every run.
pub const SEED: u32 = 0x5715_7a75;

crate::gpu_struct! {
    /// What one noise dispatch makes (`NoiseParams` in noise.wgsl).
    pub struct NoiseParams as "NoiseParams" {
        /// Texels per side.
        pub size: u32,
        /// 0 shape, 1 detail.
        pub kind: u32,
        pub seed: u32,
        /// u32s per texel row in the output buffer (rows padded to the copy alignment).
        pub row_words: u32,
    }
}

/// Every binding of noise.wgsl.
pub const BINDINGS: &[Binding] = &[
    contract::uniform::<NoiseParams>(0, 0),
    Binding {
        group: 0,
        binding: 1,
        resource: Resource::StorageRw,
    },
];

/// Bytes per texel row in the noise output buffer: 4 per texel, padded to what a buffer-to-
/// texture copy needs.
fn row_bytes(size: u32) -> u32 {
    (size * 4).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT)
}

pub struct NoiseTextures {
    pub shape: wgpu::Texture,
    pub detail: wgpu::Texture,
}

impl NoiseTextures {
    pub fn generate(gpu: &Gpu) -> NoiseTextures {
        let dev = &gpu.device;
        let module = shader::module(dev, "noise", shader::NOISE);
        let group = contract::layout(dev, "noise", BINDINGS, 0, wgpu::ShaderStages::COMPUTE);
        let layout = dev.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("noise"),
            bind_group_layouts: &[Some(&group)],
            immediate_size: 0,
        });
        let pipeline = dev.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("noise"),
            layout: Some(&layout),
            module: &module,
            entry_point: Some("main"),
            compilation_options: Default::default(),
            cache: None,
        });
        let make = |size: u32, kind: u32, label: &str| {
            let tex = texture_3d(
                dev,
                label,
                (size, size, size),
                wgpu::TextureFormat::Rgba8Unorm,
                wgpu::TextureUsages::TEXTURE_BINDING
                    | wgpu::TextureUsages::COPY_DST
                    | wgpu::TextureUsages::COPY_SRC,
            );
            let params = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("noise params"),
                contents: bytemuck::bytes_of(&NoiseParams {
                    size,
                    kind,
                    seed: SEED,
                    row_words: row_bytes(size) / 4,
                }),
                usage: wgpu::BufferUsages::UNIFORM,
            });
            let texels = dev.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: row_bytes(size) as u64 * size as u64 * size as u64,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            let bind = bind(
                dev,
                label,
                &group,
                [params.as_entire_binding(), texels.as_entire_binding()],
            );
            let mut enc = dev.create_command_encoder(&Default::default());
            {
                let mut pass = enc.begin_compute_pass(&Default::default());
                pass.set_pipeline(&pipeline);
                pass.set_bind_group(0, &bind, &[]);
                let g = size.div_ceil(4);
                pass.dispatch_workgroups(g, g, g);
            }
            enc.copy_buffer_to_texture(
                wgpu::TexelCopyBufferInfo {
                    buffer: &texels,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some(row_bytes(size)),
                        rows_per_image: Some(size),
                    },
                },
                tex.as_image_copy(),
                tex.size(),
            );
            gpu.queue.submit([enc.finish()]);
            tex
        };
        NoiseTextures {
            shape: make(SHAPE_SIZE, 0, "shape noise"),
            detail: make(DETAIL_SIZE, 1, "detail noise"),
        }
    }
}

impl NoiseTextures {
    /// The shape texture's bytes, slice by slice (RGBA8): for tests that check what the GPU made.
    pub fn read_shape(&self, gpu: &Gpu) -> Result<Vec<u8>, super::RenderError> {
        let size = self.shape.size();
        let bytes = row_bytes(size.width);
        let buffer = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("shape noise readback"),
            size: bytes as u64 * size.height as u64 * size.depth_or_array_layers as u64,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut enc = gpu.device.create_command_encoder(&Default::default());
        enc.copy_texture_to_buffer(
            self.shape.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &buffer,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(bytes),
                    rows_per_image: Some(size.height),
                },
            },
            size,
        );
        gpu.queue.submit([enc.finish()]);
        super::readback::Pending::whole(buffer).finish(gpu)
    }
}
