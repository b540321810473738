//! The contract between the Rust side and the WGSL side of the renderer: every struct both sides
//! read ([`gpu_struct!`]) and every binding ([`Binding`] tables, each stage declaring its own),
//! with the bind group layouts made from them ([`layout`]). The constants both sides use are
//! listed in the test (`tests::shared_constants`), beside the tables of every stage's structs
//! and bindings: this module imports no stage. The WGSL files stay plain, readable WGSL; the
//! test `tests::wgsl_matches_rust` parses each stage with naga and fails on any difference in a
//! struct's field names, offsets, sizes or types, a binding's number or type, or a constant's
//! value. Adding a uniform is one field here and one in the WGSL struct, and the test says
//! when the two disagree.

/// One field of a struct shared with WGSL, as the Rust compiler laid it out.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Field {
    pub name: &'static str,
    pub offset: usize,
    pub size: usize,
    /// The WGSL type it must have.
    pub wgsl: &'static str,
}

/// A `#[repr(C)]` struct the GPU reads with the same layout.
pub trait GpuStruct: bytemuck::Pod {
    /// Its name in WGSL.
    const WGSL_NAME: &'static str;
    fn fields() -> Vec<Field>;
}

/// Rust types that stand for one WGSL type.
pub trait WgslType {
    const WGSL: &'static str;
}
impl WgslType for f32 {
    const WGSL: &'static str = "f32";
}
impl WgslType for u32 {
    const WGSL: &'static str = "u32";
}
impl WgslType for [f32; 2] {
    const WGSL: &'static str = "vec2<f32>";
}
impl WgslType for [f32; 3] {
    const WGSL: &'static str = "vec3<f32>";
}
impl WgslType for [f32; 4] {
    const WGSL: &'static str = "vec4<f32>";
}

/// Defines a `#[repr(C)]`, `Pod` struct whose layout the WGSL struct `$wgsl` must match.
/// Field types must implement [`WgslType`]; WGSL's alignment rules (a `vec3` starts on 16
/// bytes) are the writer's to keep, and the test catches any slip.
#[macro_export]
macro_rules! gpu_struct {
    (
        $(#[$meta:meta])*
        pub struct $name:ident as $wgsl:literal {
            $( $(#[$fmeta:meta])* pub $field:ident : $ty:ty, )*
        }
    ) => {
        $(#[$meta])*
        #[repr(C)]
        #[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
        pub struct $name {
            $( $(#[$fmeta])* pub $field: $ty, )*
        }

        impl $crate::render::contract::GpuStruct for $name {
            const WGSL_NAME: &'static str = $wgsl;
            fn fields() -> Vec<$crate::render::contract::Field> {
                vec![$(
                    $crate::render::contract::Field {
                        name: stringify!($field),
                        offset: std::mem::offset_of!($name, $field),
                        size: std::mem::size_of::<$ty>(),
                        wgsl: <$ty as $crate::render::contract::WgslType>::WGSL,
                    },
                )*]
            }
        }
    };
}

/// What a binding holds, in the words both sides can be reduced to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Resource {
    /// A uniform buffer holding the named shared struct, of this size.
    Uniform(&'static str, u64),
    /// A read-write storage buffer.
    StorageRw,
    /// A read-only storage buffer (a stage that only reads what another wrote).
    StorageRead,
    /// A sampled float 2D texture; `filterable: false` for formats such as R32Float that are
    /// only loaded (WGSL does not say which, so the test compares the rest).
    Texture2d {
        filterable: bool,
    },
    Texture3d,
    /// A write-only storage texture of this format and dimension (2 or 3).
    StorageTexture(wgpu::TextureFormat, u8),
    Sampler,
}

/// One binding of a stage: group, number and what it holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Binding {
    pub group: u32,
    pub binding: u32,
    pub resource: Resource,
}

impl Binding {
    /// The wgpu layout entry for this binding, visible to `stages`.
    pub fn layout_entry(&self, stages: wgpu::ShaderStages) -> wgpu::BindGroupLayoutEntry {
        use wgpu::BindingType as T;
        let ty = match self.resource {
            Resource::Uniform(_, size) => T::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: false,
                min_binding_size: wgpu::BufferSize::new(size),
            },
            Resource::StorageRw => T::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only: false },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            Resource::StorageRead => T::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only: true },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            Resource::Texture2d { filterable } => T::Texture {
                sample_type: wgpu::TextureSampleType::Float { filterable },
                view_dimension: wgpu::TextureViewDimension::D2,
                multisampled: false,
            },
            Resource::Texture3d => T::Texture {
                sample_type: wgpu::TextureSampleType::Float { filterable: true },
                view_dimension: wgpu::TextureViewDimension::D3,
                multisampled: false,
            },
            Resource::StorageTexture(format, dim) => T::StorageTexture {
                access: wgpu::StorageTextureAccess::WriteOnly,
                format,
                view_dimension: if dim == 3 {
                    wgpu::TextureViewDimension::D3
                } else {
                    wgpu::TextureViewDimension::D2
                },
            },
            Resource::Sampler => T::Sampler(wgpu::SamplerBindingType::Filtering),
        };
        wgpu::BindGroupLayoutEntry {
            binding: self.binding,
            visibility: stages,
            ty,
            count: None,
        }
    }
}

/// A bind group layout for the bindings of `group` in `table`.
pub fn layout(
    device: &wgpu::Device,
    label: &str,
    table: &[Binding],
    group: u32,
    stages: wgpu::ShaderStages,
) -> wgpu::BindGroupLayout {
    let entries: Vec<wgpu::BindGroupLayoutEntry> = table
        .iter()
        .filter(|b| b.group == group)
        .map(|b| b.layout_entry(stages))
        .collect();
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(label),
        entries: &entries,
    })
}

/// The uniform binding of a shared struct.
pub const fn uniform<T: GpuStruct>(group: u32, binding: u32) -> Binding {
    Binding {
        group,
        binding,
        resource: Resource::Uniform(T::WGSL_NAME, std::mem::size_of::<T>() as u64),
    }
}

/// A filterable 2-D texture read by the stage (a frame's cloud or scene texture, a table).
pub const fn texture(group: u32, binding: u32) -> Binding {
    Binding {
        group,
        binding,
        resource: Resource::Texture2d { filterable: true },
    }
}

/// The frame's binding (`FrameUniforms`, `f: Frame` in WGSL): a read-only storage buffer, not a
/// uniform buffer. Mesa's lavapipe compiles a variant of a shader for each set of values of the
/// uniforms its branches depend on ("inlined uniforms"); the camera's up and the Sun's
/// direction are among them, so a camera that moved recompiled the march every frame (about
/// 0.8 s a frame in the window on 2 cores). Storage buffers are never inlined.
pub const fn frame(group: u32, binding: u32) -> Binding {
    Binding {
        group,
        binding,
        resource: Resource::StorageRead,
    }
}

/// A stage's own parameters that change from frame to frame (the reprojection's camera, the
/// light volume's key light and rows): a read-only storage buffer too, for the reason given at
/// [`frame`]: as a uniform buffer lavapipe recompiled the stage for each new value.
pub const fn params(group: u32, binding: u32) -> Binding {
    Binding {
        group,
        binding,
        resource: Resource::StorageRead,
    }
}

#[cfg(test)]
mod tests;
