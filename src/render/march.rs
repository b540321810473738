//! March stage: dispatches shaders/march.wgsl, one invocation per pixel, into the cloud texture
//! (premultiplied linear radiance + opacity), counting the work it does.

use super::gpu::Gpu;
use super::noise::NoiseTextures;
use super::shader;
use super::weather::WeatherMap;

/// Work counters, in the order march.wgsl writes them.
pub const COUNTERS: usize = 9;
pub const CLOUD_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;

/// The per-pixel mask of rays cut short (1 bit a pixel) for a `width`×`height` march.
pub fn cut_mask_buffer(gpu: &Gpu, width: u32, height: u32) -> wgpu::Buffer {
    let words = (width as u64 * height as u64).div_ceil(32).max(1);
    gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("cut rays"),
        size: words * 4,
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_DST
            | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    })
}

pub struct MarchPass {
    pipeline: wgpu::ComputePipeline,
    pub uniforms: wgpu::Buffer,
    pub counters: wgpu::Buffer,
    clamp_lin: wgpu::Sampler,
    repeat_lin: wgpu::Sampler,
}

impl MarchPass {
    pub fn new(gpu: &Gpu) -> MarchPass {
        let dev = &gpu.device;
        let module = shader::module(dev, "march", shader::MARCH);
        let pipeline = dev.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("march"),
            layout: None,
            module: &module,
            entry_point: Some("main"),
            compilation_options: Default::default(),
            cache: None,
        });
        let uniforms = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("frame uniforms"),
            size: std::mem::size_of::<super::frame::FrameUniforms>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let counters = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("work counters"),
            size: (COUNTERS * 4) as u64,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_DST
                | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let sampler = |mode: wgpu::AddressMode, label: &str| {
            dev.create_sampler(&wgpu::SamplerDescriptor {
                label: Some(label),
                address_mode_u: mode,
                address_mode_v: mode,
                address_mode_w: mode,
                mag_filter: wgpu::FilterMode::Linear,
                min_filter: wgpu::FilterMode::Linear,
                ..Default::default()
            })
        };
        MarchPass {
            pipeline,
            uniforms,
            counters,
            clamp_lin: sampler(wgpu::AddressMode::ClampToEdge, "clamp"),
            repeat_lin: sampler(wgpu::AddressMode::Repeat, "repeat"),
        }
    }

    pub fn bind(
        &self,
        gpu: &Gpu,
        weather: &WeatherMap,
        noise: &NoiseTextures,
        cloud: &wgpu::TextureView,
        cut_mask: &wgpu::Buffer,
    ) -> wgpu::BindGroup {
        let view = |t: &wgpu::Texture| t.create_view(&Default::default());
        let (w, c, s, d) = (
            view(&weather.texture),
            view(&weather.coarse),
            view(&noise.shape),
            view(&noise.detail),
        );
        use wgpu::BindingResource as R;
        let entries = [
            R::Buffer(self.uniforms.as_entire_buffer_binding()),
            R::TextureView(&w),
            R::TextureView(&c),
            R::TextureView(&s),
            R::TextureView(&d),
            R::Sampler(&self.clamp_lin),
            R::Sampler(&self.repeat_lin),
            R::TextureView(cloud),
            R::Buffer(self.counters.as_entire_buffer_binding()),
            R::Buffer(cut_mask.as_entire_buffer_binding()),
        ];
        let entries: Vec<wgpu::BindGroupEntry> = entries
            .into_iter()
            .enumerate()
            .map(|(i, resource)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource,
            })
            .collect();
        gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("march"),
            layout: &self.pipeline.get_bind_group_layout(0),
            entries: &entries,
        })
    }

    pub fn encode(
        &self,
        enc: &mut wgpu::CommandEncoder,
        bind: &wgpu::BindGroup,
        width: u32,
        height: u32,
        timestamps: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("march"),
            timestamp_writes: timestamps,
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, bind, &[]);
        pass.dispatch_workgroups(width.div_ceil(8), height.div_ceil(8), 1);
    }
}
