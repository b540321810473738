//! Section stage: dispatches shaders/section.wgsl, which evaluates the march's own cloud
//! (cloud.wgsl, the same bind groups for the device and the map) on a vertical curtain along a
//! path over the ground: the curtain view meteorologists know from Met.3D and lidar.

use glam::DVec3;

use super::contract::{self, Binding, Resource};
use super::gpu::Gpu;
use super::march::{MarchPass, GROUP_TARGET};
use super::pipeline::{bind, StagePipelines, Variant};
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

/// Bytes of one section sample (its extinction, f32) and of one column direction (vec4<f32>).
const SAMPLE_BYTES: u64 = 4;
const COLUMN_BYTES: u64 = 16;

/// Whether a `width`×`height` section fits the device's `limits`, checked before anything is
/// allocated: its samples are one storage buffer, bound whole and read back whole (so at most
/// the smaller of `max_storage_buffer_binding_size` and `max_buffer_size`), its column
/// directions another, and its dispatch `width/8`×`height/8` workgroups. The error names the
/// limit and the most rows that fit at this width.
pub fn check_fits(limits: &wgpu::Limits, width: u32, height: u32) -> Result<(), String> {
    let mib = |b: u64| format!("{:.0} MiB", b as f64 / (1u64 << 20) as f64);
    let (binding, buffer) = (
        limits.max_storage_buffer_binding_size,
        limits.max_buffer_size,
    );
    let (cap, name) = if binding <= buffer {
        (binding, "max_storage_buffer_binding_size")
    } else {
        (buffer, "max_buffer_size")
    };
    let samples = width as u64 * height as u64 * SAMPLE_BYTES;
    if samples > cap {
        let rows = cap / (width as u64 * SAMPLE_BYTES);
        return Err(format!(
            "the section's {width}×{height} samples take {} in one storage buffer; this adapter allows {} ({name}): at {width} columns at most {rows} rows",
            mib(samples),
            mib(cap)
        ));
    }
    if width as u64 * COLUMN_BYTES > cap {
        return Err(format!(
            "{width} columns take {} in one storage buffer; this adapter allows {} ({name})",
            mib(width as u64 * COLUMN_BYTES),
            mib(cap)
        ));
    }
    let groups = limits.max_compute_workgroups_per_dimension;
    if width.div_ceil(8) > groups || height.div_ceil(8) > groups {
        return Err(format!(
            "the section's {width}×{height} samples need more than this adapter's {groups} workgroups a dimension (max_compute_workgroups_per_dimension, 8 samples each)"
        ));
    }
    Ok(())
}

pub struct SectionPass {
    pipelines: StagePipelines,
    layout: wgpu::BindGroupLayout,
}

impl SectionPass {
    pub fn new(gpu: &Gpu, march: &MarchPass) -> SectionPass {
        // Its frame is a top-down one, whose view the section does not draw.
        let unread = super::frame::flags::NO_SKY
            | super::frame::flags::GRAZE
            | super::frame::flags::ENVELOPE;
        let (pipelines, layout) = super::pipeline::cloud_stage(
            gpu,
            "section",
            march.shared_layouts(),
            (OWN_BINDINGS, GROUP_TARGET, shader::SECTION),
            &[],
            unread,
        );
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
