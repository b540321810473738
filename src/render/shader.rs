//! WGSL sources: each stage's file from `shaders/` with the shared `common.wgsl` in front, the
//! stages that evaluate the cloud (march, section, shadow) with `cloud.wgsl` too, and those that
//! light or show the scene (march, present, exposure) with `scene.wgsl`, and those that resolve
//! the march's jitter (present, resolve) with `jitter.wgsl`.

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
    include_str!("../../shaders/jitter.wgsl"),
    include_str!("../../shaders/present.wgsl")
);
pub const RESOLVE: &str = concat!(
    include_str!("../../shaders/common.wgsl"),
    include_str!("../../shaders/frame.wgsl"),
    include_str!("../../shaders/jitter.wgsl"),
    include_str!("../../shaders/resolve.wgsl")
);
pub const EMBED: &str = concat!(
    include_str!("../../shaders/common.wgsl"),
    include_str!("../../shaders/fullscreen.wgsl"),
    include_str!("../../shaders/embed.wgsl")
);
/// The window's panel-and-HUD layer laid over a frame (app::overlay).
pub const OVERLAY: &str = concat!(
    include_str!("../../shaders/fullscreen.wgsl"),
    include_str!("../../shaders/overlay.wgsl")
);

pub fn module(device: &wgpu::Device, label: &str, source: &str) -> wgpu::ShaderModule {
    let source = if device.adapter_info().device_type == wgpu::DeviceType::Cpu {
        private_frame(source)
    } else {
        source.to_string()
    };
    device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    })
}

/// frame.wgsl's binding of the frame, and its `load_frame`, as written (for a GPU).
const FRAME_BINDING: &str = "@group(0) @binding(0) var<storage, read> f: Frame;";
const FRAME_LOAD: &str = "fn load_frame() {}";

/// A stage's source for a CPU adapter: the frame read once an invocation into a private copy
/// `f` (frame.wgsl `load_frame`), so the stage's many reads of it are not storage loads, which
/// lavapipe bounds-checks and cannot keep across the stage's own stores. A source without
/// frame.wgsl is returned as it is.
pub fn private_frame(source: &str) -> String {
    if !source.contains(FRAME_BINDING) {
        return source.to_string();
    }
    source
        .replacen(
            FRAME_BINDING,
            "@group(0) @binding(0) var<storage, read> frame_in: Frame;\nvar<private> f: Frame;",
            1,
        )
        .replacen(FRAME_LOAD, "fn load_frame() { f = frame_in; }", 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every stage's source, and whether it binds the frame (has frame.wgsl).
    const STAGES: [(&str, &str, bool); 12] = [
        ("noise", NOISE, false),
        ("noise stats", NOISE_STATS, false),
        ("march", MARCH, true),
        ("section", SECTION, true),
        ("present", PRESENT, true),
        ("resolve", RESOLVE, true),
        ("shadow", SHADOW, true),
        ("exposure", EXPOSURE, true),
        ("reproject", REPROJECT, true),
        ("atmosphere", ATMOSPHERE, true),
        ("embed", EMBED, false),
        ("overlay", OVERLAY, false),
    ];

    /// Every stage parses and validates with naga, without a GPU.
    #[test]
    fn shaders_validate() {
        for (name, src, _) in STAGES {
            // As a GPU gets it, and as a CPU adapter does (private_frame).
            for src in [src.to_string(), private_frame(src)] {
                let module = naga::front::wgsl::parse_str(&src)
                    .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(&src)));
                naga::valid::Validator::new(
                    naga::valid::ValidationFlags::all(),
                    naga::valid::Capabilities::default(),
                )
                .validate(&module)
                .unwrap_or_else(|e| panic!("{name}: {e:?}"));
            }
        }
    }

    /// On a CPU adapter the frame is a private copy that each entry point fills first
    /// (frame.wgsl `load_frame`): a stage with the frame is rewritten, and every compute and
    /// fragment entry point of it calls `load_frame` (one that did not would read zeros). The
    /// vertex stage (fullscreen.wgsl) does not read the frame.
    #[test]
    fn a_cpu_adapter_reads_the_frame_once_an_invocation() {
        for (name, src, _) in STAGES.into_iter().filter(|s| s.2) {
            let cpu = private_frame(src);
            assert!(
                cpu.contains("var<private> f: Frame;") && cpu.contains("f = frame_in;"),
                "{name} is not rewritten"
            );
            let entries = src.matches("@compute").count() + src.matches("@fragment").count();
            assert_eq!(
                src.matches("load_frame();").count(),
                entries,
                "{name}: an entry point does not call load_frame"
            );
        }
        for (_, src, _) in STAGES.into_iter().filter(|s| !s.2) {
            assert_eq!(private_frame(src), src);
        }
    }
}
