//! Section stage: dispatches shaders/section.wgsl, which evaluates the march's own cloud
//! (cloud.wgsl, the same bind groups for the device and the map) on a vertical curtain along a
//! path over the ground: the curtain view meteorologists know from Met.3D and lidar.

use glam::DVec3;

use super::contract::{self, Binding, Resource};
use super::gpu::Gpu;
use super::march::{bind, MarchPass, StagePipelines, Variant, GROUP_TARGET};
use super::shader;

crate::gpu_struct! {
    /// One section's size and height (`SectionParams` in section.wgsl).
    pub struct SectionParams as "SectionParams" {
        pub width: u32,
        pub height: u32,
        /// Altitude of the image's top edge (m); its bottom edge is sea level.
        pub top_m: f32,
        pub _pad: f32,
    }
}

/// section.wgsl's own bindings (groups 0 and 1 are the march's: [`super::march::BINDINGS`]).
pub const OWN_BINDINGS: &[Binding] = &[
    contract::uniform::<SectionParams>(GROUP_TARGET, 0),
    Binding {
        group: GROUP_TARGET,
        binding: 1,
        resource: Resource::StorageRw,
    },
    Binding {
        group: GROUP_TARGET,
        binding: 2,
        resource: Resource::StorageRw,
    },
];

/// Every binding of section.wgsl: the march's device and map groups, then its own.
pub fn bindings() -> Vec<Binding> {
    super::march::BINDINGS
        .iter()
        .filter(|b| b.group != GROUP_TARGET)
        .chain(OWN_BINDINGS)
        .copied()
        .collect()
}

pub struct SectionPass {
    pipelines: StagePipelines,
    layout: wgpu::BindGroupLayout,
}

impl SectionPass {
    pub fn new(gpu: &Gpu, march: &MarchPass) -> SectionPass {
        // Its frame is a top-down one, whose view the section does not draw.
        let unread = super::frame::flags::NO_SKY;
        let (pipelines, layout) =
            march.cloud_stage(gpu, "section", (OWN_BINDINGS, shader::SECTION), &[], unread);
        SectionPass { pipelines, layout }
    }

    /// Encode the section over `columns` (unit ECEF ground directions, one per image column)
    /// into a new buffer of `columns.len() × height` extinctions (1/m), row 0 at `top_m`, with
    /// the cloud's code the frame's map needs (`variant`).
    #[allow(clippy::too_many_arguments)]
    pub fn encode(
        &self,
        gpu: &Gpu,
        variant: Variant,
        enc: &mut wgpu::CommandEncoder,
        (device_bind, map_bind): (&wgpu::BindGroup, &wgpu::BindGroup),
        columns: &[DVec3],
        height: u32,
        top_m: f32,
    ) -> wgpu::Buffer {
        use wgpu::util::DeviceExt;
        let dev = &gpu.device;
        let width = columns.len() as u32;
        let params = SectionParams {
            width,
            height,
            top_m,
            _pad: 0.0,
        };
        let params = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("section params"),
            contents: bytemuck::bytes_of(&params),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let dirs: Vec<[f32; 4]> = columns
            .iter()
            .map(|d| [d.x as f32, d.y as f32, d.z as f32, 0.0])
            .collect();
        let dirs = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("section columns"),
            contents: bytemuck::cast_slice(&dirs),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let out = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("section extinction"),
            size: (width as u64 * height as u64 * 4).max(4),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let own = bind(
            dev,
            "section: own",
            &self.layout,
            [
                wgpu::BindingResource::Buffer(params.as_entire_buffer_binding()),
                wgpu::BindingResource::Buffer(dirs.as_entire_buffer_binding()),
                wgpu::BindingResource::Buffer(out.as_entire_buffer_binding()),
            ],
        );
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("section"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.pipelines.get(gpu, variant));
        pass.set_bind_group(0, device_bind, &[]);
        pass.set_bind_group(1, map_bind, &[]);
        pass.set_bind_group(GROUP_TARGET, &own, &[]);
        pass.dispatch_workgroups(width.div_ceil(8), height.div_ceil(8), 1);
        drop(pass);
        out
    }
}
