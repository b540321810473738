//! Atmosphere stage: dispatches shaders/atmosphere.wgsl, the precomputed sky (Hillaire 2020;
//! DESIGN §8). The transmittance and multiple-scattering tables are made once per device; the
//! sky-view and aerial-perspective tables around the camera when the Sun's elevation there or
//! the camera's altitude moves. The present and march stages read them (scene.wgsl) instead of
//! evaluating a sky, or the air in front of ground and cloud, per pixel.

use super::contract::{self, Binding, Resource};
use super::frame::FrameUniforms;
use super::gpu::Gpu;
use super::pipeline::{bind, entry_pipeline};
use super::shader;
use super::texture::{texture_2d, texture_3d};

pub const LUT_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;
pub const TRANSMITTANCE_SIZE: (u32, u32) = (256, 64);
pub const MULTISCATTER_SIZE: (u32, u32) = (32, 32);
pub const SKY_VIEW_SIZE: (u32, u32) = (192, 108);
/// Aerial perspective: azimuth × elevation (the sky-view table's mapping) × distance slices.
pub const AERIAL_SIZE: (u32, u32, u32) = (64, 36, 32);
/// The Sun's elevation may move this far (degrees) before the sky-view table is made again.
pub const REBUILD_SUN_DEG: f64 = 0.1;
/// The camera may climb or sink this far (m, or 2 % of its altitude) before it is made again.
pub const REBUILD_ALT_M: f32 = 100.0;

/// Every binding of atmosphere.wgsl.
pub const BINDINGS: &[Binding] = &[
    contract::frame(0, 0),
    Binding {
        group: 1,
        binding: 0,
        resource: Resource::StorageTexture(LUT_FORMAT, 2),
    },
    contract::texture(2, 0),
    contract::texture(2, 1),
    Binding {
        group: 2,
        binding: 2,
        resource: Resource::Sampler,
    },
    Binding {
        group: 3,
        binding: 0,
        resource: Resource::StorageTexture(LUT_FORMAT, 3),
    },
];

pub struct AtmospherePass {
    transmittance: wgpu::ComputePipeline,
    multiscatter: wgpu::ComputePipeline,
    sky_view: wgpu::ComputePipeline,
    aerial: wgpu::ComputePipeline,
    aerial_out: wgpu::BindGroup,
    aerial_table: wgpu::Texture,
    device_bind: wgpu::BindGroup,
    out_binds: [wgpu::BindGroup; 3],
    /// The tables the multiple-scattering pass reads (the transmittance and a stand-in for
    /// itself), and those the sky-view pass reads.
    read_for_ms: wgpu::BindGroup,
    read_for_sky: wgpu::BindGroup,
    sky: wgpu::Texture,
    tables_made: bool,
    last: Option<(f32, f32)>,
    /// Sky-view tables made so far.
    pub builds: u32,
}

/// The pipelines of the four entry points, each with the groups it reads (`layouts`' first
/// two, three or four): the transmittance, multiple-scattering, sky-view and aerial tables.
fn pipelines(
    dev: &wgpu::Device,
    layouts: &[wgpu::BindGroupLayout; 4],
) -> [wgpu::ComputePipeline; 4] {
    let module = shader::module(dev, "atmosphere", shader::ATMOSPHERE);
    let pipeline = |entry: &str, groups: usize| {
        let all = layouts.each_ref().map(Some);
        let layout = dev.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(entry),
            bind_group_layouts: &all[..groups],
            immediate_size: 0,
        });
        entry_pipeline(dev, entry, &layout, &module, entry, &[])
    };
    [
        pipeline("transmittance", 2),
        pipeline("multiscatter", 3),
        pipeline("sky_view", 3),
        pipeline("aerial", 4),
    ]
}

fn table(dev: &wgpu::Device, label: &str, size: (u32, u32)) -> wgpu::Texture {
    texture_2d(
        dev,
        label,
        size,
        LUT_FORMAT,
        wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::TEXTURE_BINDING,
    )
}

impl AtmospherePass {
    pub fn new(gpu: &Gpu, uniforms: &wgpu::Buffer) -> AtmospherePass {
        let dev = &gpu.device;
        let stage = wgpu::ShaderStages::COMPUTE;
        let layouts = [0, 1, 2, 3].map(|g| contract::layout(dev, "atmosphere", BINDINGS, g, stage));
        let [transmittance, multiscatter, sky_view, aerial] = pipelines(dev, &layouts);
        let trans = table(dev, "transmittance table", TRANSMITTANCE_SIZE);
        let ms = table(dev, "multiple-scattering table", MULTISCATTER_SIZE);
        let sky = table(dev, "sky-view table", SKY_VIEW_SIZE);
        let stand_in = table(dev, "multiple-scattering stand-in", (1, 1));
        let aerial_table = texture_3d(
            dev,
            "aerial-perspective table",
            AERIAL_SIZE,
            LUT_FORMAT,
            wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::TEXTURE_BINDING,
        );
        let view = |t: &wgpu::Texture| t.create_view(&Default::default());
        let sampler = dev.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("atmosphere tables"),
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            ..Default::default()
        });
        use wgpu::BindingResource as R;
        let device_bind = bind(
            dev,
            "atmosphere: device",
            &layouts[0],
            [R::Buffer(uniforms.as_entire_buffer_binding())],
        );
        let out = |t: &wgpu::Texture| {
            bind(
                dev,
                "atmosphere: out",
                &layouts[1],
                [R::TextureView(&view(t))],
            )
        };
        let out_binds = [out(&trans), out(&ms), out(&sky)];
        let aerial_out = bind(
            dev,
            "atmosphere: aerial out",
            &layouts[3],
            [R::TextureView(&view(&aerial_table))],
        );
        let read = |second: &wgpu::Texture| {
            bind(
                dev,
                "atmosphere: read",
                &layouts[2],
                [
                    R::TextureView(&view(&trans)),
                    R::TextureView(&view(second)),
                    R::Sampler(&sampler),
                ],
            )
        };
        let read_for_ms = read(&stand_in);
        let read_for_sky = read(&ms);
        AtmospherePass {
            transmittance,
            multiscatter,
            sky_view,
            aerial,
            aerial_out,
            aerial_table,
            device_bind,
            out_binds,
            read_for_ms,
            read_for_sky,
            sky,
            tables_made: false,
            last: None,
            builds: 0,
        }
    }

    /// Forget what the sky-view table was made for: the next update makes it again.
    pub fn invalidate(&mut self) {
        self.last = None;
    }

    /// Make the next update build the sky-view table for exactly this frame's Sun and altitude
    /// unless it was made for them: a single picture's sky is then its own, not one made within
    /// [`REBUILD_SUN_DEG`] of it for whatever the renderer drew before.
    pub fn require_exact(&mut self, u: &FrameUniforms) {
        if self.last != Some(Self::made_for(u)) {
            self.last = None;
        }
    }

    /// The Sun's elevation and the camera's altitude, what the sky-view table is made for.
    fn made_for(u: &FrameUniforms) -> (f32, f32) {
        let up = glam::Vec3::from(u.cam_up);
        let sun_el = up.dot(glam::Vec3::from(u.sun_dir)).clamp(-1.0, 1.0).asin();
        (sun_el, u.cam_alt_m)
    }

    /// The sky-view table, for the scene's group.
    pub fn sky_view(&self) -> &wgpu::Texture {
        &self.sky
    }

    /// The aerial-perspective table, for the scene's group.
    pub fn aerial(&self) -> &wgpu::Texture {
        &self.aerial_table
    }

    /// Make what this frame needs (its uniforms already written before `enc` runs): the fixed
    /// tables on the first frame, the sky-view table when the Sun's elevation at the camera or
    /// the camera's altitude moved. Returns whether the sky-view table was made.
    pub fn update(&mut self, enc: &mut wgpu::CommandEncoder, u: &FrameUniforms) -> bool {
        let now = Self::made_for(u);
        let sun_el = now.0;
        let stale = self.last.is_none_or(|(el, alt)| {
            (el - sun_el).abs() > REBUILD_SUN_DEG.to_radians() as f32
                || (alt - u.cam_alt_m).abs() > REBUILD_ALT_M.max(0.02 * alt.abs())
        });
        if self.tables_made && !stale {
            return false;
        }
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("atmosphere"),
            timestamp_writes: None,
        });
        pass.set_bind_group(0, &self.device_bind, &[]);
        let groups = |(w, h): (u32, u32)| (w.div_ceil(8), h.div_ceil(8));
        if !self.tables_made {
            pass.set_pipeline(&self.transmittance);
            pass.set_bind_group(1, &self.out_binds[0], &[]);
            let (x, y) = groups(TRANSMITTANCE_SIZE);
            pass.dispatch_workgroups(x, y, 1);
            pass.set_pipeline(&self.multiscatter);
            pass.set_bind_group(1, &self.out_binds[1], &[]);
            pass.set_bind_group(2, &self.read_for_ms, &[]);
            let (x, y) = groups(MULTISCATTER_SIZE);
            pass.dispatch_workgroups(x, y, 1);
            self.tables_made = true;
        }
        pass.set_pipeline(&self.sky_view);
        pass.set_bind_group(1, &self.out_binds[2], &[]);
        pass.set_bind_group(2, &self.read_for_sky, &[]);
        let (x, y) = groups(SKY_VIEW_SIZE);
        pass.dispatch_workgroups(x, y, 1);
        pass.set_pipeline(&self.aerial);
        pass.set_bind_group(3, &self.aerial_out, &[]);
        let (x, y) = groups((AERIAL_SIZE.0, AERIAL_SIZE.1));
        pass.dispatch_workgroups(x, y, 1);
        self.last = Some(now);
        self.builds += 1;
        true
    }
}
