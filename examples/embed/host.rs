//! A minimal wgpu "host": its own device, colour and depth targets, and a pipeline drawing
//! coloured triangles with a depth test, in either depth convention. It stands for a simulator
//! or engine around Stratus' clouds (examples/embed/main.rs) and for the host the tests draw
//! with (tests/embed.rs includes this file).

#![allow(dead_code)]

use bytemuck::{Pod, Zeroable};
use glam::{Mat4, Vec3};
use stratus::render::embed::DepthConvention;

/// One vertex: host-world position (m) and linear colour.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct Vertex {
    pub pos: [f32; 3],
    pub color: [f32; 3],
}

pub struct Mesh {
    buffer: wgpu::Buffer,
    count: u32,
}

pub struct Host {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub color: wgpu::Texture,
    pub depth: wgpu::Texture,
    pub color_view: wgpu::TextureView,
    pub depth_view: wgpu::TextureView,
    uniforms: wgpu::Buffer,
    bind: wgpu::BindGroup,
    /// Standard (Less, cleared to 1) and reversed-Z (Greater, cleared to 0).
    pipelines: [wgpu::RenderPipeline; 2],
}

const SHADER: &str = "
struct U { vp: mat4x4<f32> };
@group(0) @binding(0) var<uniform> u: U;
struct V { @builtin(position) p: vec4<f32>, @location(0) c: vec3<f32> };
@vertex fn vs(@location(0) pos: vec3<f32>, @location(1) col: vec3<f32>) -> V {
    var o: V;
    o.p = u.vp * vec4<f32>(pos, 1.0);
    o.c = col;
    return o;
}
@fragment fn fs(i: V) -> @location(0) vec4<f32> { return vec4<f32>(i.c, 1.0); }
";

/// A headless device as a host would open it: the first adapter, the adapter's limits. The
/// primary backends only (as `stratus::render::Gpu`): GL's EGL probes a display otherwise.
pub fn open_device() -> Result<(wgpu::Device, wgpu::Queue), String> {
    open_devices(1).map(|mut d| d.remove(0))
}

/// `n` devices on one adapter of one instance (tests: a texture of another device).
pub fn open_devices(n: usize) -> Result<Vec<(wgpu::Device, wgpu::Queue)>, String> {
    open_devices_with(n, None)
}

/// Like [`open_devices`] with the given limits (`None`: the adapter's).
pub fn open_devices_with(
    n: usize,
    limits: Option<wgpu::Limits>,
) -> Result<Vec<(wgpu::Device, wgpu::Queue)>, String> {
    let mut desc = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
    if std::env::var_os("WGPU_BACKEND").is_none() {
        desc.backends = wgpu::Backends::PRIMARY;
    }
    let instance = wgpu::Instance::new(desc);
    let adapter =
        pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions::default()))
            .map_err(|e| format!("no adapter: {e}"))?;
    let desc = wgpu::DeviceDescriptor {
        label: Some("host"),
        required_limits: limits.unwrap_or_else(|| adapter.limits()),
        ..Default::default()
    };
    (0..n)
        .map(|_| {
            pollster::block_on(adapter.request_device(&desc)).map_err(|e| format!("no device: {e}"))
        })
        .collect()
}

impl Host {
    pub fn new(
        device: wgpu::Device,
        queue: wgpu::Queue,
        (width, height): (u32, u32),
        color_format: wgpu::TextureFormat,
        depth_format: wgpu::TextureFormat,
    ) -> Host {
        let tex = |label, format, usage| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: wgpu::Extent3d {
                    width,
                    height,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
        };
        use wgpu::TextureUsages as U;
        let color = tex(
            "host colour",
            color_format,
            U::RENDER_ATTACHMENT | U::COPY_SRC,
        );
        // The embedding reads the depth buffer: TEXTURE_BINDING.
        let depth = tex(
            "host depth",
            depth_format,
            U::RENDER_ATTACHMENT | U::TEXTURE_BINDING,
        );
        let uniforms = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("host vp"),
            size: 64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: None,
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::VERTEX,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            }],
        });
        let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: uniforms.as_entire_binding(),
            }],
        });
        let pl = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: None,
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("host"),
            source: wgpu::ShaderSource::Wgsl(SHADER.into()),
        });
        let pipeline = |compare| {
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some("host"),
                layout: Some(&pl),
                vertex: wgpu::VertexState {
                    module: &module,
                    entry_point: Some("vs"),
                    compilation_options: Default::default(),
                    buffers: &[Some(wgpu::VertexBufferLayout {
                        array_stride: 24,
                        step_mode: wgpu::VertexStepMode::Vertex,
                        attributes: &wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3],
                    })],
                },
                primitive: Default::default(),
                depth_stencil: Some(wgpu::DepthStencilState {
                    format: depth_format,
                    depth_write_enabled: Some(true),
                    depth_compare: Some(compare),
                    stencil: Default::default(),
                    bias: Default::default(),
                }),
                multisample: Default::default(),
                fragment: Some(wgpu::FragmentState {
                    module: &module,
                    entry_point: Some("fs"),
                    compilation_options: Default::default(),
                    targets: &[Some(color_format.into())],
                }),
                multiview_mask: None,
                cache: None,
            })
        };
        let pipelines = [
            pipeline(wgpu::CompareFunction::Less),
            pipeline(wgpu::CompareFunction::Greater),
        ];
        Host {
            color_view: color.create_view(&Default::default()),
            depth_view: depth.create_view(&Default::default()),
            device,
            queue,
            color,
            depth,
            uniforms,
            bind,
            pipelines,
        }
    }

    pub fn mesh(&self, vertices: &[Vertex]) -> Mesh {
        let buffer = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("host mesh"),
            size: (std::mem::size_of_val(vertices) as u64).max(24),
            usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        self.queue
            .write_buffer(&buffer, 0, bytemuck::cast_slice(vertices));
        Mesh {
            buffer,
            count: vertices.len() as u32,
        }
    }

    /// Replace a mesh's vertices (as many as it was made with, or fewer): the host moving an
    /// object, without a new buffer.
    pub fn update_mesh(&self, mesh: &Mesh, vertices: &[Vertex]) {
        let n = vertices.len().min(mesh.count as usize);
        self.queue
            .write_buffer(&mesh.buffer, 0, bytemuck::cast_slice(&vertices[..n]));
    }

    /// The host's own frame: clear to `sky`, draw the meshes with `view_projection`.
    pub fn draw(
        &self,
        enc: &mut wgpu::CommandEncoder,
        view_projection: Mat4,
        depth: DepthConvention,
        meshes: &[&Mesh],
        sky: [f64; 3],
    ) {
        self.queue.write_buffer(
            &self.uniforms,
            0,
            bytemuck::bytes_of(&view_projection.to_cols_array()),
        );
        let (clear, i) = match depth {
            DepthConvention::Standard => (1.0, 0),
            DepthConvention::ReversedZ => (0.0, 1),
        };
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("host"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &self.color_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color {
                        r: sky[0],
                        g: sky[1],
                        b: sky[2],
                        a: 1.0,
                    }),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &self.depth_view,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(clear),
                    store: wgpu::StoreOp::Store,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&self.pipelines[i]);
        pass.set_bind_group(0, &self.bind, &[]);
        for m in meshes {
            pass.set_vertex_buffer(0, m.buffer.slice(..));
            pass.draw(0..m.count, 0..1);
        }
    }

    /// The colour target's texels, back on the CPU (test and PNG only: never on the frame path
    /// of a real host), as RGBA f32 for a Rgba16Float target or RGBA8 bytes widened otherwise.
    pub fn read_color(&self) -> Vec<[f32; 4]> {
        let gpu = stratus::render::Gpu::host(&self.device, &self.queue);
        let mut enc = self.device.create_command_encoder(&Default::default());
        let float = self.color.format() == wgpu::TextureFormat::Rgba16Float;
        let bpp = if float { 8 } else { 4 };
        let rb = stratus::render::readback::Pending::texture(&gpu, &mut enc, &self.color, bpp);
        self.queue.submit([enc.finish()]);
        let raw = rb.finish(&gpu).expect("the host's colour read back");
        if float {
            stratus::render::readback::rgba16f(&raw)
        } else {
            raw.chunks_exact(4)
                .map(|p| [p[0], p[1], p[2], p[3]].map(|v| v as f32 / 255.0))
                .collect()
        }
    }
}

/// A horizontal square at `center` (host world), `half` metres from its centre to each side.
pub fn quad(center: Vec3, half: f32, color: [f32; 3]) -> Vec<Vertex> {
    let c = center;
    let p = |dx: f32, dz: f32| Vertex {
        pos: [c.x + dx, c.y, c.z + dz],
        color,
    };
    vec![
        p(-half, -half),
        p(half, -half),
        p(half, half),
        p(-half, -half),
        p(half, half),
        p(-half, half),
    ]
}

/// A box (an aircraft's size, say), its faces shaded by a light from `sun` (host world).
pub fn cuboid(center: Vec3, half: Vec3, color: [f32; 3], sun: Vec3) -> Vec<Vertex> {
    let mut v = Vec::with_capacity(36);
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            let mut n = Vec3::ZERO;
            n[axis] = sign;
            let (u, w) = (Vec3::new(n.y, n.z, n.x), Vec3::new(n.z, n.x, n.y));
            let shade = 0.25 + 0.75 * n.dot(sun.normalize()).max(0.0);
            let col = color.map(|c| c * shade);
            let corner = |a: f32, b: f32| Vertex {
                pos: (center + (n + u * a + w * b) * half).to_array(),
                color: col,
            };
            v.extend([
                corner(-1.0, -1.0),
                corner(1.0, -1.0),
                corner(1.0, 1.0),
                corner(-1.0, -1.0),
                corner(1.0, 1.0),
                corner(-1.0, 1.0),
            ]);
        }
    }
    v
}

/// A terrain mesh of `n`×`n` cells over ±`half` metres around the origin: rolling hills from a
/// sum of sines, green low, brown and grey high, lit from `sun`.
pub fn terrain(n: u32, half: f32, sun: Vec3) -> Vec<Vertex> {
    let height = |x: f32, z: f32| {
        let h = 300.0 * ((x * 0.00021).sin() * (z * 0.00017).cos())
            + 160.0 * ((x * 0.00053 + 1.3).sin() * (z * 0.00047 + 0.4).sin())
            + 50.0 * ((x * 0.0013).cos() * (z * 0.0011 + 2.0).sin());
        h + 350.0
    };
    let step = 2.0 * half / n as f32;
    let at = |i: u32, j: u32| {
        let (x, z) = (-half + i as f32 * step, -half + j as f32 * step);
        Vec3::new(x, height(x, z), z)
    };
    let sun = sun.normalize();
    let mut v = Vec::with_capacity((n * n * 6) as usize);
    for j in 0..n {
        for i in 0..n {
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            for tri in [[a, c, b], [a, d, c]] {
                let normal = (tri[1] - tri[0]).cross(tri[2] - tri[0]).normalize();
                let normal = if normal.y < 0.0 { -normal } else { normal };
                let shade = 0.2 + 0.8 * normal.dot(sun).max(0.0);
                let hgt = (tri[0].y + tri[1].y + tri[2].y) / 3.0;
                // Green low, brown, grey high: blended, so colour does not step along edges.
                let mix = |a: [f32; 3], b: [f32; 3], t: f32| {
                    let t = t.clamp(0.0, 1.0);
                    [0, 1, 2].map(|k| a[k] + (b[k] - a[k]) * t)
                };
                let (green, brown, grey) =
                    ([0.10, 0.22, 0.07], [0.22, 0.19, 0.10], [0.35, 0.34, 0.32]);
                let base = if hgt < 600.0 {
                    mix(green, brown, (hgt - 350.0) / 250.0)
                } else {
                    mix(brown, grey, (hgt - 600.0) / 250.0)
                };
                for p in tri {
                    v.push(Vertex {
                        pos: p.to_array(),
                        color: base.map(|c| c * shade),
                    });
                }
            }
        }
    }
    v
}
