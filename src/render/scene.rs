//! The scene's bind group (group 3, shaders/scene.wgsl): what the stages that light the cloud or
//! show the scene (march, present, exposure) share besides the frame: the shadow stage's
//! full-column light volume, its sampler and look-up parameters ([`ShadowParams`]), the
//! atmosphere's sky-view and aerial-perspective tables, and the map's ground (render::ground).
//! Its resources live here; the group is made once per light volume (render::shadow holds two
//! and shows one), so [`Scene::bind`] takes the volume.

use stratus_ingest::ground::Ground;

use super::contract::{self, Binding, Resource};
use super::gpu::Gpu;
use super::pipeline::bind;

crate::gpu_struct! {
    /// The light volume's parameters (`ShadowParams` in shaders/common.wgsl): what the scene's
    /// group looks the volume up with, and (with its key light and rows) what the shadow stage
    /// makes one with.
    pub struct ShadowParams as "ShadowParams" {
        /// Toward the key light the volume was made for (ECEF unit vector).
        pub key_dir: [f32; 3],
        /// Altitude of the volume's bottom face (m).
        pub bottom_m: f32,
        /// Altitude of its top face (m): the top of the highest drawn cloud.
        pub top_m: f32,
        /// 0 when the preset's switch is off: every look-up gives no cloud.
        pub enabled: u32,
        /// Samples per path.
        pub steps: u32,
        /// Longest path toward the key light (m).
        pub max_path_m: f32,
        /// Region uv → ground texture uv: uv · (x, y) + (z, w) (`Ground::texture_transform`).
        pub ground_uv: [f32; 4],
        /// Highest terrain in the map (m).
        pub ground_top_m: f32,
        /// 1 when the map has a ground (render::ground), else sea level and a plain albedo.
        pub ground_on: u32,
        /// 1 when the preset draws the terrain.
        pub terrain_on: u32,
        /// 1 when the preset draws the clear air in front of ground and cloud.
        pub aerial_on: u32,
        /// The rows of texels this dispatch makes, [row0, row_end) (the shadow stage only: a
        /// volume made over several frames, `ShadowPass::update`).
        pub row0: u32,
        pub row_end: u32,
        pub pad0: u32,
        pub pad1: u32,
    }
}

/// The scene's group, shared by march.wgsl, present.wgsl and exposure.wgsl (scene.wgsl).
pub const SCENE_GROUP: u32 = 3;
pub const SCENE_BINDINGS: &[Binding] = &[
    // The light volume (render::shadow).
    Binding {
        group: SCENE_GROUP,
        binding: 0,
        resource: Resource::Texture3d,
    },
    Binding {
        group: SCENE_GROUP,
        binding: 1,
        resource: Resource::Sampler,
    },
    contract::params(SCENE_GROUP, 2),
    // The atmosphere's sky-view table (render::atmosphere).
    contract::texture(SCENE_GROUP, 3),
    // The map's ground (render::ground).
    contract::texture(SCENE_GROUP, 4),
    // The atmosphere's aerial-perspective table.
    Binding {
        group: SCENE_GROUP,
        binding: 5,
        resource: Resource::Texture3d,
    },
];

/// The scene group's layout, visible to every stage that shares it.
pub fn scene_layout(dev: &wgpu::Device) -> wgpu::BindGroupLayout {
    contract::layout(
        dev,
        "scene",
        SCENE_BINDINGS,
        SCENE_GROUP,
        wgpu::ShaderStages::COMPUTE | wgpu::ShaderStages::FRAGMENT | wgpu::ShaderStages::VERTEX,
    )
}

/// The atmosphere's tables the scene's group shows (render::atmosphere).
pub struct SkyViews {
    pub sky_view: wgpu::TextureView,
    pub aerial: wgpu::TextureView,
}

/// Everything in the scene's group but the light volume: made with the device, the ground
/// replaced with each map.
pub struct Scene {
    layout: wgpu::BindGroupLayout,
    /// Samples the volume and the ground.
    sampler: wgpu::Sampler,
    /// The look-up parameters.
    params: wgpu::Buffer,
    sky: SkyViews,
    ground: wgpu::TextureView,
    /// The ground's uv transform and highest terrain; `None` without a ground.
    ground_fit: Option<([f32; 4], f32)>,
}

impl Scene {
    pub fn new(gpu: &Gpu, layout: wgpu::BindGroupLayout, sky: SkyViews) -> Scene {
        let dev = &gpu.device;
        let sampler = dev.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("shadow volume"),
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            ..Default::default()
        });
        let (ground_tex, _) = super::ground::upload(gpu, None);
        Scene {
            layout,
            sampler,
            params: params_buffer(gpu, "shadow params"),
            sky,
            ground: ground_tex.create_view(&Default::default()),
            ground_fit: None,
        }
    }

    /// A map's ground (or none: sea level and a plain albedo). The groups made before show the
    /// old one: make them again.
    pub fn set_ground(&mut self, gpu: &Gpu, ground: Option<&Ground>) {
        let (tex, uv) = super::ground::upload(gpu, ground);
        self.ground = tex.create_view(&Default::default());
        self.ground_fit = ground.map(|g| (uv, g.height_range().1.max(0.0) as f32));
    }

    /// The ground's uv transform and highest terrain; `None` without a ground.
    pub fn ground_fit(&self) -> Option<([f32; 4], f32)> {
        self.ground_fit
    }

    /// The look-up parameters every group reads.
    pub fn write_params(&self, gpu: &Gpu, params: &ShadowParams) {
        gpu.queue
            .write_buffer(&self.params, 0, bytemuck::bytes_of(params));
    }

    /// The scene's group showing this light volume.
    pub fn bind(&self, gpu: &Gpu, volume: &wgpu::TextureView) -> wgpu::BindGroup {
        use wgpu::BindingResource as R;
        bind(
            &gpu.device,
            "scene",
            &self.layout,
            [
                R::TextureView(volume),
                R::Sampler(&self.sampler),
                R::Buffer(self.params.as_entire_buffer_binding()),
                R::TextureView(&self.sky.sky_view),
                R::TextureView(&self.ground),
                R::TextureView(&self.sky.aerial),
            ],
        )
    }
}

/// A buffer of one [`ShadowParams`], read by the stages as a storage buffer.
pub fn params_buffer(gpu: &Gpu, label: &str) -> wgpu::Buffer {
    gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: std::mem::size_of::<ShadowParams>() as u64,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}
