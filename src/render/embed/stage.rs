//! The embedding's own GPU work (shaders/embed.wgsl): the depth stage that turns the host's
//! depth buffer into each pixel's farthest ray reach, and the composite that blends the cloud
//! over the host's colour. Its resources by lifetime: pipelines and the parameters buffer once,
//! the reach buffer and the composite's bind group per target size, the depth stage's bind
//! group per host depth texture. Every creation is counted ([`Creations`]).

use super::camera::DepthModel;
use crate::render::pipeline::bind;
use crate::render::{shader, Gpu};

crate::gpu_struct! {
    /// The stages' parameters for a frame (`EmbedParams` in shaders/embed.wgsl).
    pub struct EmbedParams as "EmbedParams" {
        pub width: u32,
        pub height: u32,
        /// `1/z = inv_a + inv_b·depth` (camera::DepthModel).
        pub inv_a: f32,
        pub inv_b: f32,
        pub none_depth: f32,
        pub fx: f32,
        pub fy: f32,
        pub cx: f32,
        pub cy: f32,
        pub exposure_mul: f32,
        pub stratus_exposure: u32,
        pub tone: u32,
        pub resolve: u32,
        pub sky: u32,
        /// The march's step growth per metre: the jitter resolve's weights.
        pub step_growth: f32,
        pub _pad2: u32,
    }
}

/// GPU objects the embedding has made (the renderer's own and the embedding's), counted where
/// they are made: after the first frame at a size, a frame makes none.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Creations {
    pub buffers: u32,
    pub textures: u32,
    pub texture_views: u32,
    pub bind_groups: u32,
    pub pipelines: u32,
}

/// How the composite shows the cloud (render::embed::EmbeddedClouds' choices for a frame).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Look {
    pub exposure_mul: f32,
    pub stratus_exposure: bool,
    pub tone: bool,
    pub resolve: bool,
    /// The march's step growth per metre (the resolve's weights follow the step's grain).
    pub step_growth: f32,
    pub sky: bool,
}

/// What lives as long as the target size.
struct Sized {
    width: u32,
    height: u32,
    /// Each pixel's reach (m), written by the depth stage, read by the march and the composite.
    far: wgpu::Buffer,
    composite_bind: Option<wgpu::BindGroup>,
    /// The host depth texture the depth stage's group reads, and that group.
    depth: Option<(wgpu::Texture, wgpu::BindGroup)>,
}

pub(super) struct EmbedStage {
    params: wgpu::Buffer,
    params_bind: wgpu::BindGroup,
    depth_layout: wgpu::BindGroupLayout,
    composite_layout: wgpu::BindGroupLayout,
    far_pipeline: wgpu::ComputePipeline,
    composite_pipeline_layout: wgpu::PipelineLayout,
    module: wgpu::ShaderModule,
    composites: Vec<(wgpu::TextureFormat, wgpu::RenderPipeline)>,
    sized: Option<Sized>,
    pub(super) made: Creations,
}

fn entry(
    binding: u32,
    vis: wgpu::ShaderStages,
    ty: wgpu::BindingType,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: vis,
        ty,
        count: None,
    }
}

fn storage(read_only: bool) -> wgpu::BindingType {
    wgpu::BindingType::Buffer {
        ty: wgpu::BufferBindingType::Storage { read_only },
        has_dynamic_offset: false,
        min_binding_size: None,
    }
}

fn layout(
    dev: &wgpu::Device,
    label: &str,
    entries: &[wgpu::BindGroupLayoutEntry],
) -> wgpu::BindGroupLayout {
    dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(label),
        entries,
    })
}

impl EmbedStage {
    pub(super) fn new(gpu: &Gpu) -> EmbedStage {
        let dev = &gpu.device;
        let (cs, fs) = (wgpu::ShaderStages::COMPUTE, wgpu::ShaderStages::FRAGMENT);
        let params_layout = layout(dev, "embed: params", &[entry(0, cs | fs, storage(true))]);
        let depth_layout = layout(
            dev,
            "embed: depth",
            &[
                entry(
                    0,
                    cs,
                    wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Depth,
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                ),
                entry(1, cs, storage(false)),
            ],
        );
        let composite_layout = layout(
            dev,
            "embed: composite",
            &[
                entry(
                    0,
                    fs,
                    wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: false },
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                ),
                entry(1, fs, storage(true)),
                entry(2, fs, storage(true)),
                entry(
                    3,
                    fs,
                    wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: false },
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                ),
            ],
        );
        let params = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("embed: params"),
            size: std::mem::size_of::<EmbedParams>() as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let params_bind = bind(
            dev,
            "embed: params",
            &params_layout,
            [wgpu::BindingResource::Buffer(
                params.as_entire_buffer_binding(),
            )],
        );
        let module = shader::module(dev, "embed", shader::EMBED);
        let pipeline_layout = |label, groups: &[Option<&wgpu::BindGroupLayout>]| {
            dev.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some(label),
                bind_group_layouts: groups,
                immediate_size: 0,
            })
        };
        let far_layout =
            pipeline_layout("embed: far", &[Some(&params_layout), Some(&depth_layout)]);
        let far_pipeline = dev.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("embed: far"),
            layout: Some(&far_layout),
            module: &module,
            entry_point: Some("far_main"),
            compilation_options: Default::default(),
            cache: None,
        });
        let composite_pipeline_layout = pipeline_layout(
            "embed: composite",
            &[Some(&params_layout), None, Some(&composite_layout)],
        );
        EmbedStage {
            params,
            params_bind,
            depth_layout,
            composite_layout,
            far_pipeline,
            composite_pipeline_layout,
            module,
            composites: Vec::new(),
            sized: None,
            made: Creations {
                buffers: 1,
                pipelines: 1,
                bind_groups: 1,
                ..Default::default()
            },
        }
    }

    /// The composite's pipeline for a colour format, made on first use: blend One,
    /// OneMinusSrcAlpha (out = cloud + T·host).
    pub(super) fn prepare(&mut self, gpu: &Gpu, format: wgpu::TextureFormat) -> usize {
        if let Some(i) = self.composites.iter().position(|(f, _)| *f == format) {
            return i;
        }
        let blend = wgpu::BlendComponent {
            src_factor: wgpu::BlendFactor::One,
            dst_factor: wgpu::BlendFactor::OneMinusSrcAlpha,
            operation: wgpu::BlendOperation::Add,
        };
        let target = wgpu::ColorTargetState {
            format,
            blend: Some(wgpu::BlendState {
                color: blend,
                alpha: blend,
            }),
            write_mask: wgpu::ColorWrites::ALL,
        };
        let pipeline = crate::render::pipeline::fullscreen(
            &gpu.device,
            "embed: composite",
            &self.composite_pipeline_layout,
            &self.module,
            &[],
            target,
        );
        self.made.pipelines += 1;
        self.composites.push((format, pipeline));
        self.composites.len() - 1
    }

    /// The reach buffer for a `width`×`height` target: made again (and the groups that hold
    /// it dropped) when the size changes. True when it was made.
    pub(super) fn resize(&mut self, gpu: &Gpu, width: u32, height: u32) -> bool {
        if self
            .sized
            .as_ref()
            .is_some_and(|s| s.width == width && s.height == height)
        {
            return false;
        }
        let far = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("embed: ray reach"),
            size: width as u64 * height as u64 * 4,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        self.made.buffers += 1;
        self.sized = Some(Sized {
            width,
            height,
            far,
            composite_bind: None,
            depth: None,
        });
        true
    }

    /// The reach buffer (after [`EmbedStage::resize`]).
    pub(super) fn far(&self) -> Option<&wgpu::Buffer> {
        self.sized.as_ref().map(|s| &s.far)
    }

    /// The composite's group over the march's cloud and scene textures and the exposure
    /// stage's state: made with the size's targets.
    pub(super) fn bind_composite(
        &mut self,
        gpu: &Gpu,
        (cloud, scene): (&wgpu::Texture, &wgpu::Texture),
        exposure: &wgpu::Buffer,
    ) {
        let Some(s) = self.sized.as_mut() else {
            return;
        };
        let (cv, sv) = (
            cloud.create_view(&Default::default()),
            scene.create_view(&Default::default()),
        );
        use wgpu::BindingResource as R;
        s.composite_bind = Some(bind(
            &gpu.device,
            "embed: composite",
            &self.composite_layout,
            [
                R::TextureView(&cv),
                R::Buffer(s.far.as_entire_buffer_binding()),
                R::Buffer(exposure.as_entire_buffer_binding()),
                R::TextureView(&sv),
            ],
        ));
        self.made.texture_views += 2;
        self.made.bind_groups += 1;
    }

    /// The depth stage's group for the host's depth texture: kept while the host draws into
    /// the same texture, made again when it is another one. A texture the device refuses
    /// (another device's) is a GPU error, caught here.
    pub(super) fn bind_depth(&mut self, gpu: &Gpu, depth: &wgpu::Texture) -> Result<(), String> {
        let Some(s) = self.sized.as_mut() else {
            return Err("no target size yet".into());
        };
        if s.depth.as_ref().is_some_and(|(t, _)| t == depth) {
            return Ok(());
        }
        let scope = gpu.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let view = depth.create_view(&wgpu::TextureViewDescriptor {
            label: Some("embed: host depth"),
            aspect: wgpu::TextureAspect::DepthOnly,
            base_mip_level: 0,
            mip_level_count: Some(1),
            base_array_layer: 0,
            array_layer_count: Some(1),
            dimension: Some(wgpu::TextureViewDimension::D2),
            ..Default::default()
        });
        use wgpu::BindingResource as R;
        let group = bind(
            &gpu.device,
            "embed: depth",
            &self.depth_layout,
            [
                R::TextureView(&view),
                R::Buffer(s.far.as_entire_buffer_binding()),
            ],
        );
        self.made.texture_views += 1;
        self.made.bind_groups += 1;
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(e.to_string());
        }
        s.depth = Some((depth.clone(), group));
        Ok(())
    }

    /// Write the frame's parameters and record the depth stage.
    pub(super) fn encode_far(
        &self,
        gpu: &Gpu,
        enc: &mut wgpu::CommandEncoder,
        depth: &DepthModel,
        look: Look,
    ) {
        let Some(s) = self.sized.as_ref() else {
            return;
        };
        let Some((_, depth_bind)) = s.depth.as_ref() else {
            return;
        };
        let params = EmbedParams {
            width: s.width,
            height: s.height,
            inv_a: depth.inv_a,
            inv_b: depth.inv_b,
            none_depth: depth.none_depth,
            fx: depth.fx,
            fy: depth.fy,
            cx: 0.0,
            cy: 0.0,
            exposure_mul: look.exposure_mul,
            stratus_exposure: u32::from(look.stratus_exposure),
            tone: u32::from(look.tone),
            resolve: u32::from(look.resolve),
            sky: u32::from(look.sky),
            step_growth: look.step_growth,
            ..Default::default()
        };
        gpu.queue
            .write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("embed: far"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.far_pipeline);
        pass.set_bind_group(0, &self.params_bind, &[]);
        pass.set_bind_group(1, depth_bind, &[]);
        pass.dispatch_workgroups(s.width.div_ceil(8), s.height.div_ceil(8), 1);
    }

    /// Record the composite into the host's colour target (its contents kept: blended over).
    pub(super) fn encode_composite(
        &self,
        enc: &mut wgpu::CommandEncoder,
        pipeline: usize,
        target: &wgpu::TextureView,
    ) {
        let Some(bind) = self.sized.as_ref().and_then(|s| s.composite_bind.as_ref()) else {
            return;
        };
        let mut pass = crate::render::pipeline::over_pass(enc, "embed: composite", target);
        pass.set_pipeline(&self.composites[pipeline].1);
        pass.set_bind_group(0, &self.params_bind, &[]);
        pass.set_bind_group(2, bind, &[]);
        pass.draw(0..3, 0..1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::contract::GpuStruct;

    /// `EmbedParams` is laid out alike in Rust and in embed.wgsl: each field's name and offset,
    /// and the struct's size (as render::contract checks the stages' shared structs).
    #[test]
    fn params_match_the_wgsl() {
        let module = naga::front::wgsl::parse_str(shader::EMBED).expect("embed.wgsl parses");
        let (members, span) = module
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some(EmbedParams::WGSL_NAME))
            .and_then(|(_, t)| match &t.inner {
                naga::TypeInner::Struct { members, span } => Some((members.clone(), *span)),
                _ => None,
            })
            .expect("struct EmbedParams in embed.wgsl");
        let wgsl: Vec<(String, u32)> = members
            .iter()
            .map(|m| (m.name.clone().unwrap_or_default(), m.offset))
            .collect();
        let rust: Vec<(String, u32)> = EmbedParams::fields()
            .iter()
            .map(|f| (f.name.to_string(), f.offset as u32))
            .collect();
        assert_eq!(wgsl, rust);
        assert_eq!(span as usize, std::mem::size_of::<EmbedParams>());
    }
}
