//! March stage: dispatches shaders/march.wgsl, one invocation per pixel, into the cloud texture
//! (premultiplied linear radiance + opacity) and the background behind it into the scene
//! texture (radiance + distance), counting the work it does. A reprojected frame marches one
//! pixel of each subset cell (render::reproject).
//!
//! Its bindings come in three groups by lifetime: the device's (uniforms, noise, samplers,
//! counters), the map's (weather and coarse textures) and the output size's (cloud texture,
//! cut-ray mask), so a new map or size rebinds only its own group.

use std::collections::HashMap;
use std::sync::Mutex;

use super::contract::{self, Binding, Resource};
use super::frame::FrameUniforms;
use super::gpu::Gpu;
use super::noise::NoiseTextures;
use super::shader;
use super::weather::WeatherMap;

pub const CLOUD_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;

crate::gpu_struct! {
    /// The march's work counters, as the GPU accumulates them (`counters` in march.wgsl, whose
    /// `C_*` index constants follow these fields in order: checked by render::contract).
    pub struct Counters as "Counters" {
        pub rays: u32,
        pub steps: u32,
        pub density_samples: u32,
        pub detail_samples: u32,
        pub light_samples: u32,
        pub outside_samples: u32,
        pub skipped_steps: u32,
        pub early_exits: u32,
        pub cut_rays: u32,
    }
}

/// Bind group numbers, by lifetime.
pub const GROUP_DEVICE: u32 = 0;
pub const GROUP_MAP: u32 = 1;
pub const GROUP_TARGET: u32 = 2;

/// Every binding of march.wgsl.
pub const BINDINGS: &[Binding] = &[
    contract::frame(GROUP_DEVICE, 0),
    b(GROUP_DEVICE, 1, Resource::Texture3d),
    b(GROUP_DEVICE, 2, Resource::Texture3d),
    b(GROUP_DEVICE, 3, Resource::Sampler),
    b(GROUP_DEVICE, 4, Resource::Sampler),
    b(GROUP_DEVICE, 5, Resource::StorageRw),
    // The genus profiles (render::profile).
    b(GROUP_DEVICE, 6, Resource::Texture2d { filterable: true }),
    // The cumulus cells (render::cells).
    b(GROUP_DEVICE, 7, Resource::Texture2d { filterable: true }),
    b(GROUP_MAP, 0, Resource::Texture2d { filterable: true }),
    // The coarse map is R32Float: loaded, never filtered.
    b(GROUP_MAP, 1, Resource::Texture2d { filterable: false }),
    // The structure (render::structure): base, top, genus (loaded), wind.
    b(GROUP_MAP, 2, Resource::Texture2d { filterable: true }),
    b(GROUP_MAP, 3, Resource::Texture2d { filterable: true }),
    b(GROUP_MAP, 4, Resource::Texture2d { filterable: false }),
    b(GROUP_MAP, 5, Resource::Texture2d { filterable: true }),
    // Two steps blended (render::blend): the later step's coverage, both steps' winds.
    b(GROUP_MAP, 6, Resource::Texture2d { filterable: true }),
    b(GROUP_MAP, 7, Resource::Texture2d { filterable: true }),
    b(GROUP_TARGET, 0, Resource::StorageTexture(CLOUD_FORMAT, 2)),
    b(GROUP_TARGET, 1, Resource::StorageRw),
    // The background behind the cloud and the pixel's distance (km).
    b(GROUP_TARGET, 2, Resource::StorageTexture(CLOUD_FORMAT, 2)),
];

/// Every binding of march.wgsl with the scene's group (render::shadow) that it shares.
pub fn bindings() -> Vec<Binding> {
    BINDINGS
        .iter()
        .chain(super::shadow::SCENE_BINDINGS)
        .copied()
        .collect()
}

const fn b(group: u32, binding: u32, resource: Resource) -> Binding {
    Binding {
        group,
        binding,
        resource,
    }
}

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

/// Which of the cloud stages' optional code a frame compiles in: its flags ([`FEATURE_BITS`] of
/// them) as the WGSL constant `FEATURES`. A CPU driver runs both sides of every branch, so a frame
/// would otherwise pay for every feature it does not use (the two-step blend, the bands' carve,
/// the towers, the cells, the streaks, the detail noise, the top-down view's lighting).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Variant(u32);

/// The flags that select a variant: those that add or remove code on the per-sample path.
pub const FEATURE_BITS: u32 = {
    use super::frame::flags as fl;
    fl::STRUCTURE | fl::TOWERS | fl::STREAKS | fl::CELLS | fl::BLEND | fl::DETAIL | fl::NO_SKY
};

impl Variant {
    /// The variant a frame's flags (`frame::flags`) need.
    pub fn of(flags: u32) -> Variant {
        Variant(flags & FEATURE_BITS)
    }

    /// Whether it compiles in the cumulonimbus towers.
    pub fn towers(self) -> bool {
        self.0 & super::frame::flags::TOWERS != 0
    }

    /// Whether it compiles in the cumulus cells.
    pub fn cells(self) -> bool {
        self.0 & super::frame::flags::CELLS != 0
    }
}

pub struct MarchPass {
    pipelines: StagePipelines,
    layouts: [wgpu::BindGroupLayout; 3],
    pub uniforms: wgpu::Buffer,
    pub counters: wgpu::Buffer,
    /// The device-lifetime bind group (uniforms, noise, samplers, counters, genus profiles,
    /// cumulus cells).
    device_bind: wgpu::BindGroup,
}

impl MarchPass {
    pub fn new(
        gpu: &Gpu,
        noise: &NoiseTextures,
        scene_layout: &wgpu::BindGroupLayout,
    ) -> MarchPass {
        let dev = &gpu.device;
        let stage = wgpu::ShaderStages::COMPUTE;
        let layouts = [
            contract::layout(dev, "march: device", BINDINGS, GROUP_DEVICE, stage),
            contract::layout(dev, "march: map", BINDINGS, GROUP_MAP, stage),
            contract::layout(dev, "march: target", BINDINGS, GROUP_TARGET, stage),
        ];
        let layout = dev.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("march"),
            bind_group_layouts: &[
                Some(&layouts[0]),
                Some(&layouts[1]),
                Some(&layouts[2]),
                Some(scene_layout),
            ],
            immediate_size: 0,
        });
        let module = shader::module(dev, "march", shader::MARCH);
        let uniforms = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("frame uniforms"),
            size: std::mem::size_of::<FrameUniforms>() as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let counters = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("work counters"),
            size: std::mem::size_of::<Counters>() as u64,
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
        let clamp_lin = sampler(wgpu::AddressMode::ClampToEdge, "clamp");
        let repeat_lin = sampler(wgpu::AddressMode::Repeat, "repeat");
        let (shape, detail) = (
            noise.shape.create_view(&Default::default()),
            noise.detail.create_view(&Default::default()),
        );
        let profiles = super::profile::texture(gpu).create_view(&Default::default());
        let cells = super::cells::texture(gpu).create_view(&Default::default());
        use wgpu::BindingResource as R;
        let device_bind = bind(
            dev,
            "march: device",
            &layouts[0],
            [
                R::Buffer(uniforms.as_entire_buffer_binding()),
                R::TextureView(&shape),
                R::TextureView(&detail),
                R::Sampler(&clamp_lin),
                R::Sampler(&repeat_lin),
                R::Buffer(counters.as_entire_buffer_binding()),
                R::TextureView(&profiles),
                R::TextureView(&cells),
            ],
        );
        MarchPass {
            pipelines: StagePipelines::new("march", layout, module, &[], 0),
            layouts,
            uniforms,
            counters,
            device_bind,
        }
    }

    /// The variants compiled so far (tests: a map selects its variant).
    pub fn compiled(&self) -> Vec<Variant> {
        self.pipelines.compiled()
    }

    /// The layouts of the device's and the map's groups, which the section stage shares.
    pub fn shared_layouts(&self) -> [&wgpu::BindGroupLayout; 2] {
        [&self.layouts[0], &self.layouts[1]]
    }

    /// A compute stage that evaluates the cloud as the march does: the march's device and map
    /// groups, then its own bindings as group `GROUP_TARGET`; entry point `main`, with these
    /// pipeline-overridable constants besides the variant's; `unread`: the feature flags its
    /// code does not read (frames differing only in them share a pipeline). Returns its
    /// pipelines and its own group's layout.
    pub fn cloud_stage(
        &self,
        gpu: &Gpu,
        label: &str,
        (own, source): (&[Binding], &str),
        constants: &[(&'static str, f64)],
        unread: u32,
    ) -> (StagePipelines, wgpu::BindGroupLayout) {
        let dev = &gpu.device;
        let stage = wgpu::ShaderStages::COMPUTE;
        let own_layout = contract::layout(dev, label, own, GROUP_TARGET, stage);
        let [device_layout, map_layout] = self.shared_layouts();
        let pipeline_layout = dev.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(label),
            bind_group_layouts: &[Some(device_layout), Some(map_layout), Some(&own_layout)],
            immediate_size: 0,
        });
        let module = shader::module(dev, label, source);
        let pipelines = StagePipelines::new(label, pipeline_layout, module, constants, unread);
        (pipelines, own_layout)
    }

    pub fn device_bind(&self) -> &wgpu::BindGroup {
        &self.device_bind
    }

    /// The map's bind group: made again only when the map's textures are.
    pub fn bind_map(&self, gpu: &Gpu, weather: &WeatherMap) -> wgpu::BindGroup {
        let view = |t: &wgpu::Texture| t.create_view(&Default::default());
        let (w, c) = (view(&weather.texture), view(&weather.coarse));
        let st = weather.structure.textures.each_ref().map(view);
        let (next, wind) = (view(&weather.blend.next), view(&weather.blend.wind));
        use wgpu::BindingResource as R;
        bind(
            &gpu.device,
            "march: map",
            &self.layouts[1],
            [
                R::TextureView(&w),
                R::TextureView(&c),
                R::TextureView(&st[0]),
                R::TextureView(&st[1]),
                R::TextureView(&st[2]),
                R::TextureView(&st[3]),
                R::TextureView(&next),
                R::TextureView(&wind),
            ],
        )
    }

    /// The output's bind group: made again only when the output size changes.
    pub fn bind_target(
        &self,
        gpu: &Gpu,
        cloud: &wgpu::TextureView,
        scene: &wgpu::TextureView,
        cut_mask: &wgpu::Buffer,
    ) -> wgpu::BindGroup {
        bind(
            &gpu.device,
            "march: target",
            &self.layouts[2],
            [
                wgpu::BindingResource::TextureView(cloud),
                wgpu::BindingResource::Buffer(cut_mask.as_entire_buffer_binding()),
                wgpu::BindingResource::TextureView(scene),
            ],
        )
    }

    /// `variant`: the genera's code the frame's map needs ([`Variant::of`] its flags).
    #[allow(clippy::too_many_arguments)]
    pub fn encode(
        &self,
        gpu: &Gpu,
        variant: Variant,
        enc: &mut wgpu::CommandEncoder,
        map_bind: &wgpu::BindGroup,
        target_bind: &wgpu::BindGroup,
        scene_bind: &wgpu::BindGroup,
        (width, height): (u32, u32),
        timestamps: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        // `width`×`height` invocations: the pixels, or the subset cells of a reprojected frame.
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("march"),
            timestamp_writes: timestamps,
        });
        pass.set_pipeline(&self.pipelines.get(gpu, variant));
        pass.set_bind_group(GROUP_DEVICE, &self.device_bind, &[]);
        pass.set_bind_group(GROUP_MAP, map_bind, &[]);
        pass.set_bind_group(GROUP_TARGET, target_bind, &[]);
        pass.set_bind_group(super::shadow::SCENE_GROUP, scene_bind, &[]);
        pass.dispatch_workgroups(width.div_ceil(8), height.div_ceil(8), 1);
    }
}

/// One cloud-evaluating stage's pipelines (march, shadow, section), one per [`Variant`], each
/// compiled the first time a frame needs it.
pub struct StagePipelines {
    label: String,
    layout: wgpu::PipelineLayout,
    module: wgpu::ShaderModule,
    /// The stage's own constants, besides the variant's.
    constants: Vec<(&'static str, f64)>,
    /// The feature flags the stage's code does not read: left out of its variants.
    unread: u32,
    compiled: Mutex<HashMap<Variant, wgpu::ComputePipeline>>,
}

impl StagePipelines {
    fn new(
        label: &str,
        layout: wgpu::PipelineLayout,
        module: wgpu::ShaderModule,
        constants: &[(&'static str, f64)],
        unread: u32,
    ) -> StagePipelines {
        StagePipelines {
            label: label.to_string(),
            layout,
            module,
            constants: constants.to_vec(),
            unread,
            compiled: Mutex::default(),
        }
    }

    /// The pipeline for a frame's variant (compiled on first use).
    pub fn get(&self, gpu: &Gpu, v: Variant) -> wgpu::ComputePipeline {
        let v = Variant(v.0 & !self.unread);
        self.lock()
            .entry(v)
            .or_insert_with(|| {
                let label = format!("{} (features {:#x})", self.label, v.0);
                let mut constants = self.constants.clone();
                constants.extend([("FIXED_FEATURES", 1.0), ("FEATURES", f64::from(v.0))]);
                compute_pipeline(gpu, &label, &self.layout, &self.module, &constants)
            })
            .clone()
    }

    /// The variants compiled so far.
    pub fn compiled(&self) -> Vec<Variant> {
        self.lock().keys().copied().collect()
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, HashMap<Variant, wgpu::ComputePipeline>> {
        // A poisoned lock only means a thread panicked while compiling: the map is intact.
        self.compiled.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// A compute pipeline of `module`'s entry point `main` with these overridable constants.
fn compute_pipeline(
    gpu: &Gpu,
    label: &str,
    layout: &wgpu::PipelineLayout,
    module: &wgpu::ShaderModule,
    constants: &[(&str, f64)],
) -> wgpu::ComputePipeline {
    gpu.device
        .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(label),
            layout: Some(layout),
            module,
            entry_point: Some("main"),
            compilation_options: wgpu::PipelineCompilationOptions {
                constants,
                ..Default::default()
            },
            cache: None,
        })
}

/// A frame's cloud and scene textures bound as group 1 bindings 0 and 1, what the exposure
/// and present stages read (each with its own layout).
pub fn bind_frame_textures(
    dev: &wgpu::Device,
    label: &str,
    layout: &wgpu::BindGroupLayout,
    cloud: &wgpu::TextureView,
    scene: &wgpu::TextureView,
) -> wgpu::BindGroup {
    bind(
        dev,
        label,
        layout,
        [
            wgpu::BindingResource::TextureView(cloud),
            wgpu::BindingResource::TextureView(scene),
        ],
    )
}

/// A bind group whose entries are numbered in order from 0.
pub fn bind<const N: usize>(
    dev: &wgpu::Device,
    label: &str,
    layout: &wgpu::BindGroupLayout,
    resources: [wgpu::BindingResource<'_>; N],
) -> wgpu::BindGroup {
    let entries: Vec<wgpu::BindGroupEntry> = resources
        .into_iter()
        .enumerate()
        .map(|(i, resource)| wgpu::BindGroupEntry {
            binding: i as u32,
            resource,
        })
        .collect();
    dev.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(label),
        layout,
        entries: &entries,
    })
}
