//! WGSL sources: each stage's file from `shaders/` with the shared `common.wgsl` in front, the
//! stages that evaluate the cloud (march, section, shadow) with `cloud.wgsl` too, and those that
//! light or show the scene (march, present, exposure) with `scene.wgsl`.

pub const NOISE: &str = concat!(
    include_str!("../../shaders/common.wgsl"),
    include_str!("../../shaders/noise.wgsl")
);
pub const NOISE_STATS: &str = concat!(
    include_str!("../../shaders/common.wgsl"),
    include_str!("../../shaders/noise_stats.wgsl")
);
pub const MARCH: &str = concat!(
    include_str!("../../shaders/common.wgsl"),
    include_str!("../../shaders/frame.wgsl"),
    include_str!("../../shaders/cloud.wgsl"),
    include_str!("../../shaders/scene.wgsl"),
    include_str!("../../shaders/march.wgsl")
);
pub const SHADOW: &str = concat!(
    include_str!("../../shaders/common.wgsl"),
    include_str!("../../shaders/frame.wgsl"),
    include_str!("../../shaders/cloud.wgsl"),
    include_str!("../../shaders/shadow.wgsl")
);
pub const ATMOSPHERE: &str = concat!(
    include_str!("../../shaders/common.wgsl"),
    include_str!("../../shaders/frame.wgsl"),
    include_str!("../../shaders/atmosphere.wgsl")
);
pub const EXPOSURE: &str = concat!(
    include_str!("../../shaders/common.wgsl"),
    include_str!("../../shaders/frame.wgsl"),
    include_str!("../../shaders/scene.wgsl"),
    include_str!("../../shaders/exposure.wgsl")
);
pub const SECTION: &str = concat!(
    include_str!("../../shaders/common.wgsl"),
    include_str!("../../shaders/frame.wgsl"),
    include_str!("../../shaders/cloud.wgsl"),
    include_str!("../../shaders/section.wgsl")
);
pub const REPROJECT: &str = concat!(
    include_str!("../../shaders/common.wgsl"),
    include_str!("../../shaders/frame.wgsl"),
    include_str!("../../shaders/reproject.wgsl")
);
pub const PRESENT: &str = concat!(
    include_str!("../../shaders/common.wgsl"),
    include_str!("../../shaders/frame.wgsl"),
    include_str!("../../shaders/scene.wgsl"),
    include_str!("../../shaders/fullscreen.wgsl"),
    include_str!("../../shaders/present.wgsl")
);
pub const EMBED: &str = concat!(
    include_str!("../../shaders/common.wgsl"),
    include_str!("../../shaders/fullscreen.wgsl"),
    include_str!("../../shaders/embed.wgsl")
);

pub fn module(device: &wgpu::Device, label: &str, source: &str) -> wgpu::ShaderModule {
    device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every stage parses and validates with naga, without a GPU.
    #[test]
    fn shaders_validate() {
        for (name, src) in [
            ("noise", NOISE),
            ("noise stats", NOISE_STATS),
            ("march", MARCH),
            ("section", SECTION),
            ("present", PRESENT),
            ("shadow", SHADOW),
            ("exposure", EXPOSURE),
            ("reproject", REPROJECT),
            ("atmosphere", ATMOSPHERE),
            ("embed", EMBED),
        ] {
            let module = naga::front::wgsl::parse_str(src)
                .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(src)));
            naga::valid::Validator::new(
                naga::valid::ValidationFlags::all(),
                naga::valid::Capabilities::default(),
            )
            .validate(&module)
            .unwrap_or_else(|e| panic!("{name}: {e:?}"));
        }
    }
}
