//! Noise stage: generates the tileable shape (128³ RGBA) and detail (32³ RGB) noise textures
//! on the GPU once at start-up (shaders/noise.wgsl), from a fixed seed, and from each the mip
//! chain of its carved value's mean and variance that the cloud stages sample by footprint
//! (shaders/noise_stats.wgsl; issue 30).

use wgpu::util::DeviceExt;

use super::contract::{self, Binding, Resource};
use super::gpu::Gpu;
use super::pipeline::bind;
use super::shader;
use super::texture::{texture_3d, texture_3d_mipped};

pub const SHAPE_SIZE: u32 = 128;
pub const DETAIL_SIZE: u32 = 32;
/// The detail FBM's mean over its whole tile (its statistics' last level; checked in
/// tests/render.rs). A march without detail erodes edges by this mean (cloud.wgsl `carve`).
pub const DETAIL_MEAN: f32 = 0.486;
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

crate::gpu_struct! {
    /// One level of a statistics texture (`StatsParams` in noise_stats.wgsl).
    pub struct StatsParams as "StatsParams" {
        /// Texels per side of the level written.
        pub size: u32,
        /// 0: level 0 from the RGBA8 noise; 1: the next level from the previous one.
        pub mode: u32,
        /// 0 shape, 1 detail.
        pub kind: u32,
        /// u32s per texel row of the level written, and of the one read.
        pub row_words: u32,
        pub src_row_words: u32,
        pub pad0: u32,
        pub pad1: u32,
        pub pad2: u32,
    }
}

/// Every binding of noise_stats.wgsl.
pub const STATS_BINDINGS: &[Binding] = &[
    contract::uniform::<StatsParams>(0, 0),
    Binding {
        group: 0,
        binding: 1,
        resource: Resource::StorageRead,
    },
    Binding {
        group: 0,
        binding: 2,
        resource: Resource::StorageRw,
    },
];

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

/// Bytes per texel row of a statistics level: four half floats a texel, padded.
fn stats_row_bytes(size: u32) -> u32 {
    (size * 8).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT)
}

pub struct NoiseTextures {
    pub shape: wgpu::Texture,
    pub detail: wgpu::Texture,
    /// Per level: the shape's carved value (the Perlin-Worley remapped by the Worley FBM, as
    /// cloud.wgsl carves it), mean and variance over the texels the level's texel covers
    /// (Rgba16Float: mean, variance, least, greatest; every level down to 1³).
    pub shape_stats: wgpu::Texture,
    /// The same of the detail noise's FBM.
    pub detail_stats: wgpu::Texture,
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
            (tex, texels)
        };
        let (shape, shape_texels) = make(SHAPE_SIZE, 0, "shape noise");
        let (detail, detail_texels) = make(DETAIL_SIZE, 1, "detail noise");
        let stats = Stats::new(gpu);
        NoiseTextures {
            shape_stats: stats.make(gpu, &shape_texels, SHAPE_SIZE, 0, "shape noise stats"),
            detail_stats: stats.make(gpu, &detail_texels, DETAIL_SIZE, 1, "detail noise stats"),
            shape,
            detail,
        }
    }
}

/// The statistics stage's pipeline (noise_stats.wgsl).
struct Stats {
    group: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
}

impl Stats {
    fn new(gpu: &Gpu) -> Stats {
        let dev = &gpu.device;
        let module = shader::module(dev, "noise stats", shader::NOISE_STATS);
        let group = contract::layout(
            dev,
            "noise stats",
            STATS_BINDINGS,
            0,
            wgpu::ShaderStages::COMPUTE,
        );
        let layout = dev.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("noise stats"),
            bind_group_layouts: &[Some(&group)],
            immediate_size: 0,
        });
        let pipeline = dev.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("noise stats"),
            layout: Some(&layout),
            module: &module,
            entry_point: Some("main"),
            compilation_options: Default::default(),
            cache: None,
        });
        Stats { group, pipeline }
    }

    /// The statistics texture of one noise texture (`size`³, its packed RGBA8 `texels`): level
    /// 0 from the texels, each next level from the one before, all in one submission.
    fn make(
        &self,
        gpu: &Gpu,
        texels: &wgpu::Buffer,
        size: u32,
        kind: u32,
        label: &str,
    ) -> wgpu::Texture {
        let dev = &gpu.device;
        let levels = size.ilog2() + 1;
        let tex = texture_3d_mipped(
            dev,
            label,
            (size, size, size),
            levels,
            wgpu::TextureFormat::Rgba16Float,
            wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_DST
                | wgpu::TextureUsages::COPY_SRC,
        );
        let mut enc = dev.create_command_encoder(&Default::default());
        // Each level's buffer is the next one's source; the first reads the noise's texels.
        let mut src: Option<wgpu::Buffer> = None;
        for level in 0..levels {
            let n = size >> level;
            let params = StatsParams {
                size: n,
                mode: u32::from(level > 0),
                kind,
                row_words: stats_row_bytes(n) / 4,
                src_row_words: if level == 0 {
                    row_bytes(n) / 4
                } else {
                    stats_row_bytes(2 * n) / 4
                },
                ..Default::default()
            };
            let uniform = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("noise stats params"),
                contents: bytemuck::bytes_of(&params),
                usage: wgpu::BufferUsages::UNIFORM,
            });
            let dst = dev.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: stats_row_bytes(n) as u64 * n as u64 * n as u64,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            let read = src.as_ref().unwrap_or(texels);
            let bind = bind(
                dev,
                label,
                &self.group,
                [
                    uniform.as_entire_binding(),
                    read.as_entire_binding(),
                    dst.as_entire_binding(),
                ],
            );
            {
                let mut pass = enc.begin_compute_pass(&Default::default());
                pass.set_pipeline(&self.pipeline);
                pass.set_bind_group(0, &bind, &[]);
                let g = n.div_ceil(4);
                pass.dispatch_workgroups(g, g, g);
            }
            enc.copy_buffer_to_texture(
                wgpu::TexelCopyBufferInfo {
                    buffer: &dst,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some(stats_row_bytes(n)),
                        rows_per_image: Some(n),
                    },
                },
                wgpu::TexelCopyTextureInfo {
                    texture: &tex,
                    mip_level: level,
                    origin: wgpu::Origin3d::ZERO,
                    aspect: wgpu::TextureAspect::All,
                },
                wgpu::Extent3d {
                    width: n,
                    height: n,
                    depth_or_array_layers: n,
                },
            );
            src = Some(dst);
        }
        gpu.queue.submit([enc.finish()]);
        tex
    }
}

impl NoiseTextures {
    /// One level of the shape statistics, texel by texel (x fastest, then y, then z): (mean,
    /// variance, least, greatest). For tests that check what the GPU made.
    pub fn read_shape_stats(
        &self,
        gpu: &Gpu,
        level: u32,
    ) -> Result<Vec<[f32; 4]>, super::RenderError> {
        read_stats(gpu, &self.shape_stats, SHAPE_SIZE >> level, level)
    }

    /// One level of the detail FBM's statistics, as [`NoiseTextures::read_shape_stats`].
    pub fn read_detail_stats(
        &self,
        gpu: &Gpu,
        level: u32,
    ) -> Result<Vec<[f32; 4]>, super::RenderError> {
        read_stats(gpu, &self.detail_stats, DETAIL_SIZE >> level, level)
    }

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

/// Level `level` (`n` texels a side) of a statistics texture, texel by texel.
fn read_stats(
    gpu: &Gpu,
    stats: &wgpu::Texture,
    n: u32,
    level: u32,
) -> Result<Vec<[f32; 4]>, super::RenderError> {
    let row = stats_row_bytes(n);
    let buffer = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("noise stats readback"),
        size: row as u64 * n as u64 * n as u64,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut enc = gpu.device.create_command_encoder(&Default::default());
    enc.copy_texture_to_buffer(
        wgpu::TexelCopyTextureInfo {
            texture: stats,
            mip_level: level,
            origin: wgpu::Origin3d::ZERO,
            aspect: wgpu::TextureAspect::All,
        },
        wgpu::TexelCopyBufferInfo {
            buffer: &buffer,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(row),
                rows_per_image: Some(n),
            },
        },
        wgpu::Extent3d {
            width: n,
            height: n,
            depth_or_array_layers: n,
        },
    );
    gpu.queue.submit([enc.finish()]);
    let raw = super::readback::Pending::whole(buffer).finish(gpu)?;
    let mut out = Vec::with_capacity((n * n * n) as usize);
    for r in raw.chunks_exact(row as usize) {
        for t in r[..(n * 8) as usize].chunks_exact(8) {
            let h = |i: usize| half::f16::from_le_bytes([t[2 * i], t[2 * i + 1]]).to_f32();
            out.push([h(0), h(1), h(2), h(3)]);
        }
    }
    Ok(out)
}
