//! March stage: dispatches shaders/march.wgsl, one invocation per pixel, into the cloud texture
//! (premultiplied linear radiance + opacity) and the background behind it into the scene
//! texture (radiance + distance), counting the work it does. A reprojected frame marches one
//! pixel of each subset cell (render::reproject).
//!
//! Its bindings come in three groups by lifetime: the device's (uniforms, noise, samplers,
//! counters), the map's (weather and coarse textures) and the output size's (cloud texture,
//! cut-ray mask), so a new map or size rebinds only its own group.

use super::contract::{self, Binding, Resource};
use super::frame::FrameUniforms;
use super::gpu::Gpu;
use super::noise::NoiseTextures;
pub use super::pipeline::Variant;
use super::pipeline::{bind, StagePipelines};
use super::scene::{SCENE_BINDINGS, SCENE_GROUP};
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
        pub reworked: u32,
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
    // Two steps blended (render::blend): the later step's coverage, the motion between them.
    b(GROUP_MAP, 6, Resource::Texture2d { filterable: true }),
    b(GROUP_MAP, 7, Resource::Texture2d { filterable: true }),
    b(GROUP_TARGET, 0, Resource::StorageTexture(CLOUD_FORMAT, 2)),
    b(GROUP_TARGET, 1, Resource::StorageRw),
    // The background behind the cloud and the pixel's distance (km).
    b(GROUP_TARGET, 2, Resource::StorageTexture(CLOUD_FORMAT, 2)),
    // The farthest each pixel's ray may go (m): a host's depth (render::embed), else one huge
    // value ([`MarchPass::unlimited`]).
    b(GROUP_TARGET, 3, Resource::StorageRead),
    // The exposure the present stage last showed (render::exposure): the limb's rays are
    // averaged as they will be seen.
    b(GROUP_TARGET, 4, Resource::StorageRead),
    // The pixels left for the second dispatch ([`rework_buffer`]).
    b(GROUP_TARGET, 5, Resource::StorageRw),
];

/// Every binding of march.wgsl with the scene's group (render::scene) that it shares.
pub fn bindings() -> Vec<Binding> {
    BINDINGS.iter().chain(SCENE_BINDINGS).copied().collect()
}

const fn b(group: u32, binding: u32, resource: Resource) -> Binding {
    Binding {
        group,
        binding,
        resource,
    }
}

/// `ray_far`'s value where nothing stops a ray (m): the march's own ends decide.
pub const UNLIMITED_M: f32 = 3.0e38;

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

/// The rework list's header (march.wgsl `ReworkList`: the workgroups, the count, padding to its
/// entries' alignment) and one entry's size (`ReworkEntry`): checked by render::contract.
pub(crate) const REWORK_HEADER: u64 = 16;
pub(crate) const REWORK_ENTRY: u64 = 64;
/// `rework`'s workgroup (march.wgsl `REWORK_GROUP` invocations) and its invocations a pixel
/// (`GRAZE_EXTRA`, one extra ray each).
pub(crate) const REWORK_GROUP: u32 = 64;
pub(crate) const GRAZE_EXTRA: u32 = 4;
/// The rework list's grazing entries one workgroup of its dispatch takes (its split entries take
/// `REWORK_GROUP`).
const REWORK_PER_GROUP: u64 = (REWORK_GROUP / GRAZE_EXTRA) as u64;

/// The list of pixels a `width`×`height` march leaves for its second dispatch (march.wgsl
/// `ReworkList`): those the limb or a silhouette splits, and the grazing pixels that take more
/// rays. Room for a quarter of the pixels (at least 4096, at most what one dispatch's
/// workgroups and one binding hold: the grazing and the split entries' last workgroups may each
/// be part-filled, one more than the entries fill); a pixel past it keeps its first ray.
pub fn rework_buffer(gpu: &Gpu, width: u32, height: u32) -> wgpu::Buffer {
    let most = (65_534 * REWORK_PER_GROUP).min((128 << 20) / REWORK_ENTRY - 1);
    let entries = (width as u64 * height as u64).div_ceil(4).clamp(4096, most);
    gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("rework list"),
        size: REWORK_HEADER + entries * REWORK_ENTRY,
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_DST
            | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    })
}

/// A march's output buffers besides its textures: the cut-ray mask and the rework list.
#[derive(Clone, Copy)]
pub struct RayBuffers<'a> {
    pub cut_mask: &'a wgpu::Buffer,
    pub rework: &'a wgpu::Buffer,
}

pub struct MarchPass {
    pipelines: StagePipelines,
    /// The second dispatch (march.wgsl `rework`), over the pixels the first left.
    rework: StagePipelines,
    /// Its indirect arguments: the first's workgroup count, copied from the rework list.
    rework_args: wgpu::Buffer,
    layouts: [wgpu::BindGroupLayout; 3],
    pub uniforms: wgpu::Buffer,
    pub counters: wgpu::Buffer,
    /// One [`UNLIMITED_M`]: the rays' farthest reach when no host depth limits them.
    pub unlimited: wgpu::Buffer,
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
        let unlimited = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("unlimited rays"),
            size: 4,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        gpu.queue
            .write_buffer(&unlimited, 0, &UNLIMITED_M.to_le_bytes());
        let sampler = |mode: wgpu::AddressMode, label: &str| {
            dev.create_sampler(&wgpu::SamplerDescriptor {
                label: Some(label),
                address_mode_u: mode,
                address_mode_v: mode,
                address_mode_w: mode,
                mag_filter: wgpu::FilterMode::Linear,
                min_filter: wgpu::FilterMode::Linear,
                // The noise statistics are read at the one level nearest a sample's
                // footprint (cloud.wgsl `footprint_lod`).
                mipmap_filter: wgpu::MipmapFilterMode::Nearest,
                ..Default::default()
            })
        };
        let clamp_lin = sampler(wgpu::AddressMode::ClampToEdge, "clamp");
        let repeat_lin = sampler(wgpu::AddressMode::Repeat, "repeat");
        let (shape, detail) = (
            noise.shape_stats.create_view(&Default::default()),
            noise.detail_stats.create_view(&Default::default()),
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
        let pipelines = StagePipelines::new("march", layout, module, &[], 0);
        MarchPass {
            rework: pipelines.entry("march: rework", "rework"),
            rework_args: rework_args(gpu),
            pipelines,
            layouts,
            uniforms,
            counters,
            unlimited,
            device_bind,
        }
    }

    /// The variants compiled so far (tests: a map selects its variant).
    pub fn compiled(&self) -> Vec<Variant> {
        self.pipelines.compiled()
    }

    /// Whether both dispatches' pipelines of `v` are compiled.
    pub fn is_ready(&self, v: Variant) -> bool {
        self.pipelines.is_ready(v) && (v.no_sky() || self.rework.is_ready(v))
    }

    /// Starts compiling `v`'s pipelines on threads (`StagePipelines::prepare`).
    pub fn prepare(&self, gpu: &Gpu, v: Variant) {
        self.pipelines.prepare(gpu, v);
        if !v.no_sky() {
            self.rework.prepare(gpu, v);
        }
    }

    /// The layouts of the device's and the map's groups, which the shadow and section stages
    /// share (`pipeline::cloud_stage`).
    pub fn shared_layouts(&self) -> [&wgpu::BindGroupLayout; 2] {
        [&self.layouts[0], &self.layouts[1]]
    }

    pub fn device_bind(&self) -> &wgpu::BindGroup {
        &self.device_bind
    }

    /// The map's bind group: made again only when the map's textures are.
    pub fn bind_map(&self, gpu: &Gpu, weather: &WeatherMap) -> wgpu::BindGroup {
        let view = |t: &wgpu::Texture| t.create_view(&Default::default());
        let (w, c) = (view(&weather.texture), view(&weather.coarse));
        let st = weather.structure.textures.each_ref().map(view);
        let (next, motion) = (view(&weather.blend.next), view(&weather.blend.motion));
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
                R::TextureView(&motion),
            ],
        )
    }

    /// The output's bind group: made again only when the output size changes. `far`: each
    /// pixel's farthest reach (m), or [`MarchPass::unlimited`]; `exposure`: the exposure
    /// stage's state (render::exposure::ExposurePass::state).
    pub fn bind_target(
        &self,
        gpu: &Gpu,
        (cloud, scene): (&wgpu::TextureView, &wgpu::TextureView),
        rays: RayBuffers<'_>,
        far: &wgpu::Buffer,
        exposure: &wgpu::Buffer,
    ) -> wgpu::BindGroup {
        bind(
            &gpu.device,
            "march: target",
            &self.layouts[2],
            [
                wgpu::BindingResource::TextureView(cloud),
                wgpu::BindingResource::Buffer(rays.cut_mask.as_entire_buffer_binding()),
                wgpu::BindingResource::TextureView(scene),
                wgpu::BindingResource::Buffer(far.as_entire_buffer_binding()),
                wgpu::BindingResource::Buffer(exposure.as_entire_buffer_binding()),
                wgpu::BindingResource::Buffer(rays.rework.as_entire_buffer_binding()),
            ],
        )
    }

    /// `variant`: the genera's code the frame's map needs ([`Variant::of`] its flags). Two
    /// dispatches: every pixel's first ray, then (indirect, sized by their count) the pixels that
    /// take more, from `rework`, the list the target's bind group holds.
    #[allow(clippy::too_many_arguments)]
    pub fn encode(
        &self,
        gpu: &Gpu,
        variant: Variant,
        enc: &mut wgpu::CommandEncoder,
        (map_bind, target_bind, scene_bind): (&wgpu::BindGroup, &wgpu::BindGroup, &wgpu::BindGroup),
        rework: &wgpu::Buffer,
        (width, height): (u32, u32),
        timestamps: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        enc.clear_buffer(rework, 0, Some(REWORK_HEADER));
        // A top-down view has no limb, silhouette or grazing pixel: nothing is left.
        let second = !variant.no_sky();
        let (first_ts, second_ts) = match timestamps {
            Some(t) if second => split_writes(t),
            t => (t, None),
        };
        let groups = [map_bind, target_bind, scene_bind];
        // `width`×`height` invocations: the pixels, or the subset cells of a reprojected frame.
        {
            let stage = ("march", &self.pipelines);
            let mut pass = self.begin(enc, gpu, stage, variant, groups, first_ts);
            pass.dispatch_workgroups(width.div_ceil(8), height.div_ceil(8), 1);
        }
        if second {
            enc.copy_buffer_to_buffer(rework, 0, &self.rework_args, 0, Some(4));
            let stage = ("march: rework", &self.rework);
            let mut pass = self.begin(enc, gpu, stage, variant, groups, second_ts);
            pass.dispatch_workgroups_indirect(&self.rework_args, 0);
        }
    }

    /// A compute pass (`label`) with one of the stage's pipelines and its bind groups set.
    fn begin<'e>(
        &self,
        enc: &'e mut wgpu::CommandEncoder,
        gpu: &Gpu,
        (label, pipelines): (&str, &StagePipelines),
        variant: Variant,
        [map_bind, target_bind, scene_bind]: [&wgpu::BindGroup; 3],
        timestamps: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) -> wgpu::ComputePass<'e> {
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some(label),
            timestamp_writes: timestamps,
        });
        pass.set_pipeline(&pipelines.get(gpu, variant));
        pass.set_bind_group(GROUP_DEVICE, &self.device_bind, &[]);
        pass.set_bind_group(GROUP_MAP, map_bind, &[]);
        pass.set_bind_group(GROUP_TARGET, target_bind, &[]);
        pass.set_bind_group(SCENE_GROUP, scene_bind, &[]);
        pass
    }
}

/// The second dispatch's indirect arguments: x copied from the rework list before each
/// dispatch, y and z one.
fn rework_args(gpu: &Gpu) -> wgpu::Buffer {
    let args = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("rework dispatch"),
        size: 12,
        usage: wgpu::BufferUsages::INDIRECT | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let xyz: Vec<u8> = [0u32, 1, 1].iter().flat_map(|v| v.to_le_bytes()).collect();
    gpu.queue.write_buffer(&args, 0, &xyz);
    args
}

/// One pass's timestamp writes split over two passes: the first's start, the second's end.
fn split_writes(
    t: wgpu::ComputePassTimestampWrites<'_>,
) -> (
    Option<wgpu::ComputePassTimestampWrites<'_>>,
    Option<wgpu::ComputePassTimestampWrites<'_>>,
) {
    let part = |begin: Option<u32>, end: Option<u32>| {
        (begin.is_some() || end.is_some()).then_some(wgpu::ComputePassTimestampWrites {
            query_set: t.query_set,
            beginning_of_pass_write_index: begin,
            end_of_pass_write_index: end,
        })
    };
    (
        part(t.beginning_of_pass_write_index, None),
        part(None, t.end_of_pass_write_index),
    )
}
