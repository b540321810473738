//! Pipelines and bind groups, the plumbing every stage shares: compute pipelines built from a
//! stage's module, a cloud stage's feature variants ([`Variant`], compiled per frame's features
//! as pipeline-overridable constants, [`StagePipelines`]), the pipeline layout of a stage that
//! evaluates the cloud as the march does ([`cloud_stage`]), and bind groups numbered in order
//! ([`bind`], [`bind_frame_textures`]), and the full-screen draw ([`fullscreen`], [`over_pass`]). The layouts themselves come from each stage's binding
//! table (render::contract).

use std::collections::{HashMap, HashSet};
use std::sync::{Arc, Mutex};

use super::contract::{self, Binding};
use super::frame::flags;
use super::gpu::Gpu;
use super::shader;

/// Which of the cloud stages' optional code a frame compiles in: its flags ([`FEATURE_BITS`] of
/// them) as the WGSL constant `FEATURES`. A CPU driver runs both sides of every branch, so a frame
/// would otherwise pay for every feature it does not use (the two-step blend, the bands' carve,
/// the towers, the cells, the streaks, the detail noise, the top-down view's lighting, the
/// grazing pixels' extra rays).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Variant(u32);

/// The flags that select a variant: those that add or remove code on the per-sample path.
pub const FEATURE_BITS: u32 = flags::STRUCTURE
    | flags::TOWERS
    | flags::STREAKS
    | flags::CELLS
    | flags::BLEND
    | flags::DETAIL
    | flags::NO_SKY
    | flags::GRAZE
    | flags::ENVELOPE;

impl Variant {
    /// The variant a frame's flags (`frame::flags`) need.
    pub fn of(flags: u32) -> Variant {
        Variant(flags & FEATURE_BITS)
    }

    /// Whether it compiles in the cumulonimbus towers.
    pub fn towers(self) -> bool {
        self.0 & flags::TOWERS != 0
    }

    /// Whether it compiles in the cumulus cells.
    pub fn cells(self) -> bool {
        self.0 & flags::CELLS != 0
    }

    /// Whether it compiles in the cirrus streaks.
    pub fn streaks(self) -> bool {
        self.0 & flags::STREAKS != 0
    }

    /// Which genera's code it holds, for `render --timings`: "cells, towers, streaks", or
    /// "none" (a map without them, or a view that reaches none: render::reach).
    pub fn describe_genera(self) -> String {
        let held: Vec<&str> = [
            (self.cells(), "cells"),
            (self.towers(), "towers"),
            (self.streaks(), "streaks"),
        ]
        .into_iter()
        .filter_map(|(on, name)| on.then_some(name))
        .collect();
        if held.is_empty() {
            "none".into()
        } else {
            held.join(", ")
        }
    }

    /// Whether it is the top-down view's (no sky, limb or terrain behind the cloud).
    pub fn no_sky(self) -> bool {
        self.0 & flags::NO_SKY != 0
    }
}

/// One cloud-evaluating stage's pipelines (march, shadow, section), one per [`Variant`], each
/// compiled the first time a frame needs it. A clone shares the variants compiled (the thread
/// of [`StagePipelines::prepare`] adds to them).
#[derive(Clone)]
pub struct StagePipelines {
    label: String,
    layout: wgpu::PipelineLayout,
    module: wgpu::ShaderModule,
    /// The stage's own constants, besides the variant's.
    constants: Vec<(&'static str, f64)>,
    /// The feature flags the stage's code does not read: left out of its variants.
    unread: u32,
    /// The module's entry point (`main` unless [`StagePipelines::entry`] names another).
    entry: &'static str,
    compiled: Arc<Mutex<Compiled>>,
}

/// The variants compiled, and those compiling on a thread ([`StagePipelines::prepare`]).
#[derive(Default)]
struct Compiled {
    ready: HashMap<Variant, wgpu::ComputePipeline>,
    pending: HashSet<Variant>,
}

impl StagePipelines {
    pub fn new(
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
            entry: "main",
            compiled: Arc::default(),
        }
    }

    /// The same stage's pipelines of another entry point of its module.
    pub fn entry(&self, label: &str, entry: &'static str) -> StagePipelines {
        StagePipelines {
            label: label.to_string(),
            entry,
            compiled: Arc::default(),
            ..StagePipelines::new(
                label,
                self.layout.clone(),
                self.module.clone(),
                &self.constants,
                self.unread,
            )
        }
    }

    /// The pipeline for a frame's variant (compiled on first use).
    pub fn get(&self, gpu: &Gpu, v: Variant) -> wgpu::ComputePipeline {
        let v = self.key(v);
        if let Some(p) = self.lock().ready.get(&v) {
            return p.clone();
        }
        let p = self.compile(&gpu.device, v);
        self.lock().ready.entry(v).or_insert(p).clone()
    }

    /// Whether `v`'s pipeline is compiled.
    pub fn is_ready(&self, v: Variant) -> bool {
        self.lock().ready.contains_key(&self.key(v))
    }

    /// Starts compiling `v` on a thread, unless it is compiled or compiling: a frame that must
    /// not wait (the window's) goes on with a variant it has and takes `v` once it is ready.
    pub fn prepare(&self, gpu: &Gpu, v: Variant) {
        let v = self.key(v);
        {
            let mut c = self.lock();
            if c.ready.contains_key(&v) || !c.pending.insert(v) {
                return;
            }
        }
        let stage = self.clone();
        let device = gpu.device.clone();
        std::thread::spawn(move || {
            let p = stage.compile(&device, v);
            let mut c = stage.lock();
            c.pending.remove(&v);
            c.ready.insert(v, p);
        });
    }

    /// The variants compiled so far.
    pub fn compiled(&self) -> Vec<Variant> {
        self.lock().ready.keys().copied().collect()
    }

    /// The variant as this stage compiles it: without the flags its code does not read.
    fn key(&self, v: Variant) -> Variant {
        Variant(v.0 & !self.unread)
    }

    fn compile(&self, device: &wgpu::Device, v: Variant) -> wgpu::ComputePipeline {
        let label = format!("{} (features {:#x})", self.label, v.0);
        let mut constants = self.constants.clone();
        constants.extend([("FIXED_FEATURES", 1.0), ("FEATURES", f64::from(v.0))]);
        let (layout, module) = (&self.layout, &self.module);
        entry_pipeline(device, &label, layout, module, self.entry, &constants)
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Compiled> {
        // A poisoned lock only means a thread panicked while compiling: the map is intact.
        self.compiled.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// A compute stage that evaluates the cloud as the march does: the march's device and map
/// groups (`shared`), then its own bindings as group `own_group`; entry point `main`, with
/// these pipeline-overridable constants besides the variant's; `unread`: the feature flags its
/// code does not read (frames differing only in them share a pipeline). Returns its pipelines
/// and its own group's layout.
pub fn cloud_stage(
    gpu: &Gpu,
    label: &str,
    shared: [&wgpu::BindGroupLayout; 2],
    (own, own_group, source): (&[Binding], u32, &str),
    constants: &[(&'static str, f64)],
    unread: u32,
) -> (StagePipelines, wgpu::BindGroupLayout) {
    let dev = &gpu.device;
    let stage = wgpu::ShaderStages::COMPUTE;
    let own_layout = contract::layout(dev, label, own, own_group, stage);
    let [device_layout, map_layout] = shared;
    let pipeline_layout = dev.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: &[Some(device_layout), Some(map_layout), Some(&own_layout)],
        immediate_size: 0,
    });
    let module = shader::module(dev, label, source);
    let pipelines = StagePipelines::new(label, pipeline_layout, module, constants, unread);
    (pipelines, own_layout)
}

/// A compute pipeline of `module`'s entry point `main` with these overridable constants.
pub fn compute_pipeline(
    gpu: &Gpu,
    label: &str,
    layout: &wgpu::PipelineLayout,
    module: &wgpu::ShaderModule,
    constants: &[(&str, f64)],
) -> wgpu::ComputePipeline {
    entry_pipeline(&gpu.device, label, layout, module, "main", constants)
}

/// A compute pipeline of one entry point of `module`, with these overridable constants.
pub fn entry_pipeline(
    dev: &wgpu::Device,
    label: &str,
    layout: &wgpu::PipelineLayout,
    module: &wgpu::ShaderModule,
    entry: &str,
    constants: &[(&str, f64)],
) -> wgpu::ComputePipeline {
    dev.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(label),
        layout: Some(layout),
        module,
        entry_point: Some(entry),
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

/// A render pipeline drawing fullscreen.wgsl's one triangle over a target with `module`'s
/// `fs_main` (the present stage, embed's composite).
pub fn fullscreen(
    dev: &wgpu::Device,
    label: &str,
    layout: &wgpu::PipelineLayout,
    module: &wgpu::ShaderModule,
    constants: &[(&str, f64)],
    target: wgpu::ColorTargetState,
) -> wgpu::RenderPipeline {
    dev.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(label),
        layout: Some(layout),
        vertex: wgpu::VertexState {
            module,
            entry_point: Some("vs_main"),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive: Default::default(),
        depth_stencil: None,
        multisample: Default::default(),
        fragment: Some(wgpu::FragmentState {
            module,
            entry_point: Some("fs_main"),
            compilation_options: wgpu::PipelineCompilationOptions {
                constants,
                ..Default::default()
            },
            targets: &[Some(target)],
        }),
        multiview_mask: None,
        cache: None,
    })
}

/// A render pass drawing over what `target` holds (loaded, then stored): the embed composite
/// over the host's picture, the window's interface over the clouds.
pub fn over_pass<'e>(
    enc: &'e mut wgpu::CommandEncoder,
    label: &str,
    target: &wgpu::TextureView,
) -> wgpu::RenderPass<'e> {
    enc.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some(label),
        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
            view: target,
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations {
                load: wgpu::LoadOp::Load,
                store: wgpu::StoreOp::Store,
            },
        })],
        depth_stencil_attachment: None,
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    })
}
