//! The contract's check: the tables of what both sides share (constants, structs, every
//! stage's bindings) and the naga parse that compares each stage's WGSL with them. Only the
//! test imports the stages.

use super::*;
use crate::render::frame::{self, flags, FrameUniforms, SUN_INTENSITY};
use crate::render::march::Counters;
use naga::{ImageClass, ImageDimension, ScalarKind, TypeInner};

fn parse(name: &str, src: &str) -> naga::Module {
    naga::front::wgsl::parse_str(src)
        .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(src)))
}

fn type_name(module: &naga::Module, ty: naga::Handle<naga::Type>) -> String {
    let scalar = |s: naga::Scalar| match (s.kind, s.width) {
        (ScalarKind::Float, 4) => "f32".to_string(),
        (ScalarKind::Uint, 4) => "u32".to_string(),
        (ScalarKind::Sint, 4) => "i32".to_string(),
        other => format!("{other:?}"),
    };
    match &module.types[ty].inner {
        TypeInner::Scalar(s) => scalar(*s),
        TypeInner::Vector { size, scalar: s } => format!("vec{}<{}>", *size as u8, scalar(*s)),
        other => format!("{other:?}"),
    }
}

/// Differences between a WGSL struct and the Rust struct it must match.
fn struct_diffs(
    module: &naga::Module,
    stage: &str,
    name: &str,
    fields: &[Field],
    size: usize,
) -> Vec<String> {
    let Some((_, ty)) = module
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some(name))
    else {
        return vec![];
    };
    let TypeInner::Struct { members, span } = &ty.inner else {
        return vec![format!("{stage}: {name} is not a struct")];
    };
    let mut d = Vec::new();
    // A uniform struct's size is rounded up to its 16-byte alignment.
    if *span as usize != size {
        d.push(format!(
            "{stage}: {name} is {span} bytes in WGSL, {size} in Rust"
        ));
    }
    if members.len() != fields.len() {
        d.push(format!(
            "{stage}: {name} has {} fields in WGSL, {} in Rust",
            members.len(),
            fields.len()
        ));
    }
    for (m, f) in members.iter().zip(fields) {
        let mname = m.name.as_deref().unwrap_or("?");
        let wgsl_ty = type_name(module, m.ty);
        let wsize = module.types[m.ty].inner.size(module.to_ctx()) as usize;
        if mname != f.name || m.offset as usize != f.offset || wsize != f.size || wgsl_ty != f.wgsl
        {
            d.push(format!(
                "{stage}: {name}.{mname}: {wgsl_ty} at {} ({wsize} B) in WGSL, but Rust has {}: {} at {} ({} B)",
                m.offset, f.name, f.wgsl, f.offset, f.size
            ));
        }
    }
    d
}

fn constant_diffs(module: &naga::Module, stage: &str) -> Vec<String> {
    let mut d = Vec::new();
    for (name, want) in shared_constants() {
        let Some((_, c)) = module
            .constants
            .iter()
            .find(|(_, c)| c.name.as_deref() == Some(name))
        else {
            continue;
        };
        let got = &module.global_expressions[c.init];
        let f32_at = |h: &naga::Handle<naga::Expression>| match module.global_expressions[*h] {
            naga::Expression::Literal(naga::Literal::F32(v)) => Some(v),
            _ => None,
        };
        let ok = match (got, want) {
            (naga::Expression::Literal(naga::Literal::F32(v)), Shared::F32(w)) => *v == w,
            (naga::Expression::Literal(naga::Literal::U32(v)), Shared::U32(w)) => *v == w,
            (naga::Expression::Compose { components, .. }, Shared::Vec3F32(w)) => {
                components.iter().map(f32_at).eq(w.map(Some))
            }
            _ => false,
        };
        if !ok {
            d.push(format!(
                "{stage}: const {name} is {got:?}, Rust has {want:?}"
            ));
        }
    }
    d
}

/// A WGSL resource binding reduced to a [`Resource`].
fn resource_of(module: &naga::Module, var: &naga::GlobalVariable) -> Option<Resource> {
    let inner = &module.types[var.ty].inner;
    Some(match (var.space, inner) {
        (naga::AddressSpace::Uniform, _) => {
            // The shared struct of that name (its `&'static str`), "?" for any other.
            let name = module.types[var.ty].name.as_deref();
            let shared = shared_structs().into_iter().map(|s| s.0);
            let known = shared.into_iter().find(|n| Some(*n) == name);
            Resource::Uniform(known.unwrap_or("?"), inner.size(module.to_ctx()) as u64)
        }
        (naga::AddressSpace::Storage { access }, _)
            if access.contains(naga::StorageAccess::STORE) =>
        {
            Resource::StorageRw
        }
        (naga::AddressSpace::Storage { .. }, _) => Resource::StorageRead,
        (
            naga::AddressSpace::Handle,
            TypeInner::Image {
                dim,
                arrayed: false,
                class,
            },
        ) => match (dim, class) {
            (ImageDimension::D2, ImageClass::Sampled { multi: false, .. }) => {
                Resource::Texture2d { filterable: true }
            }
            (ImageDimension::D3, ImageClass::Sampled { multi: false, .. }) => Resource::Texture3d,
            (d, ImageClass::Storage { format, .. }) => {
                let f = match format {
                    naga::StorageFormat::Rgba16Float => wgpu::TextureFormat::Rgba16Float,
                    naga::StorageFormat::Rgba8Unorm => wgpu::TextureFormat::Rgba8Unorm,
                    _ => return None,
                };
                Resource::StorageTexture(f, if *d == ImageDimension::D3 { 3 } else { 2 })
            }
            _ => return None,
        },
        (naga::AddressSpace::Handle, TypeInner::Sampler { comparison: false }) => Resource::Sampler,
        _ => return None,
    })
}

/// What WGSL can tell of a resource: not whether a texture is filterable.
fn comparable(r: Resource) -> Resource {
    match r {
        Resource::Texture2d { .. } => Resource::Texture2d { filterable: true },
        other => other,
    }
}

fn binding_diffs(module: &naga::Module, stage: &str, table: &[Binding]) -> Vec<String> {
    let mut d = Vec::new();
    let mut seen = Vec::new();
    for (_, var) in module.global_variables.iter() {
        let Some(rb) = &var.binding else { continue };
        let name = var.name.as_deref().unwrap_or("?");
        let got = resource_of(module, var);
        seen.push((rb.group, rb.binding));
        match table
            .iter()
            .find(|b| b.group == rb.group && b.binding == rb.binding)
        {
            None => d.push(format!(
                "{stage}: `{name}` at group {} binding {} has no Rust layout entry",
                rb.group, rb.binding
            )),
            Some(b) if Some(comparable(b.resource)) != got => d.push(format!(
                "{stage}: `{name}` at group {} binding {} is {got:?} in WGSL, {:?} in Rust",
                rb.group, rb.binding, b.resource
            )),
            Some(_) => {}
        }
    }
    for b in table {
        if !seen.contains(&(b.group, b.binding)) {
            d.push(format!(
                "{stage}: Rust lays out group {} binding {} ({:?}), WGSL declares none",
                b.group, b.binding, b.resource
            ));
        }
    }
    d
}

fn all_diffs(stage: &str, src: &str, table: &[Binding]) -> Vec<String> {
    let module = parse(stage, src);
    let mut d = Vec::new();
    for (name, fields, size) in shared_structs() {
        d.extend(struct_diffs(&module, stage, name, &fields, size));
    }
    d.extend(constant_diffs(&module, stage));
    d.extend(binding_diffs(&module, stage, table));
    d
}

fn stages() -> Vec<(&'static str, &'static str, &'static [Binding])> {
    use crate::render::{
        atmosphere, exposure, march, noise, present, reproject, resolve, section, shader, shadow,
    };
    // The section's table is the march's groups 0 and 1 and its own: made once, kept (the
    // same for the stages that add the scene's group).
    static SECTION: std::sync::OnceLock<Vec<Binding>> = std::sync::OnceLock::new();
    static SHADOW: std::sync::OnceLock<Vec<Binding>> = std::sync::OnceLock::new();
    static MARCH: std::sync::OnceLock<Vec<Binding>> = std::sync::OnceLock::new();
    static PRESENT: std::sync::OnceLock<Vec<Binding>> = std::sync::OnceLock::new();
    static EXPOSURE: std::sync::OnceLock<Vec<Binding>> = std::sync::OnceLock::new();
    vec![
        ("noise", shader::NOISE, noise::BINDINGS),
        ("noise stats", shader::NOISE_STATS, noise::STATS_BINDINGS),
        ("atmosphere", shader::ATMOSPHERE, atmosphere::BINDINGS),
        ("reproject", shader::REPROJECT, reproject::BINDINGS),
        ("resolve", shader::RESOLVE, resolve::BINDINGS),
        (
            "march",
            shader::MARCH,
            MARCH.get_or_init(march::bindings).as_slice(),
        ),
        (
            "present",
            shader::PRESENT,
            PRESENT.get_or_init(present::bindings).as_slice(),
        ),
        (
            "shadow",
            shader::SHADOW,
            SHADOW.get_or_init(shadow::bindings).as_slice(),
        ),
        (
            "exposure",
            shader::EXPOSURE,
            EXPOSURE.get_or_init(exposure::bindings).as_slice(),
        ),
        (
            "section",
            shader::SECTION,
            SECTION.get_or_init(section::bindings).as_slice(),
        ),
    ]
}

#[test]
fn wgsl_matches_rust() {
    let mut d = Vec::new();
    for (stage, src, table) in stages() {
        d.extend(all_diffs(stage, src, table));
    }
    assert!(
        d.is_empty(),
        "the WGSL and Rust sides disagree:\n{}",
        d.join("\n")
    );
}

/// Every shared constant is declared by at least one stage, and `Frame` by every stage
/// that reads the frame: a renamed constant cannot slip out of the check.
#[test]
fn every_shared_item_is_checked_somewhere() {
    let modules: Vec<naga::Module> = stages().iter().map(|(n, s, _)| parse(n, s)).collect();
    for (name, _) in shared_constants() {
        let found = modules.iter().any(|m| {
            m.constants
                .iter()
                .any(|(_, c)| c.name.as_deref() == Some(name))
        });
        assert!(found, "no stage declares the shared constant {name}");
    }
    for m in &modules[1..] {
        assert!(m
            .types
            .iter()
            .any(|(_, t)| t.name.as_deref() == Some(FrameUniforms::WGSL_NAME)));
    }
}

/// The check itself can fail: each kind of slip is caught.
#[test]
fn the_check_catches_each_kind_of_slip() {
    let (stage, src, table) = stages()
        .into_iter()
        .find(|s| s.0 == "march")
        .expect("the march stage");
    assert!(all_diffs(stage, src, table).is_empty());
    let slips = [
        // A renamed field (one the march does not read, so its source still parses).
        ("    march_scale: f32,", "    march_ratio: f32,"),
        // Two fields swapped (same types: only the names betray it).
        (
            "    step_min_m: f32,\n    step_growth: f32,",
            "    step_growth: f32,\n    step_min_m: f32,",
        ),
        // A type changed (u32 flags read as f32).
        ("    flags: u32,", "    flags: f32,"),
        // A shared constant changed.
        ("const SUN_I: f32 = 20.0;", "const SUN_I: f32 = 21.0;"),
        (
            "const FLAG_STRIDE: u32 = 64u;",
            "const FLAG_STRIDE: u32 = 128u;",
        ),
        ("const C_CUT: u32 = 8u;", "const C_CUT: u32 = 7u;"),
        // A shared vector constant's component changed.
        (
            "DEFAULT_ALBEDO: vec3<f32> = vec3<f32>(0.08, 0.10, 0.07)",
            "DEFAULT_ALBEDO: vec3<f32> = vec3<f32>(0.08, 0.10, 0.08)",
        ),
        // A binding moved.
        (
            "@group(1) @binding(1) var coarse",
            "@group(1) @binding(2) var coarse",
        ),
    ];
    for (from, to) in slips {
        assert!(
            src.contains(from),
            "the slip test's pattern is gone: {from}"
        );
        let changed = src.replacen(from, to, 1);
        assert!(
            !all_diffs(stage, &changed, table).is_empty(),
            "changing `{from}` to `{to}` went unnoticed"
        );
    }
}

/// A constant both sides use, by its WGSL name.
#[derive(Clone, Copy, Debug)]
enum Shared {
    F32(f32),
    U32(u32),
    Vec3F32([f32; 3]),
}

/// Every constant the WGSL side must declare with this value wherever it declares it.
fn shared_constants() -> Vec<(&'static str, Shared)> {
    use stratus_ingest::weather::CloudType;
    use Shared::*;
    let mut v = vec![
        ("EARTH_R", F32(crate::render::camera::EARTH_R as f32)),
        ("SUN_I", F32(SUN_INTENSITY as f32)),
        // The clear air the haze leaves out (frame::CLEAR_AIR_EXTINCTION), atmosphere.wgsl's.
        ("RAYLEIGH_GREEN", F32(frame::RAYLEIGH_GREEN as f32)),
        ("MIE_EXTINCT", F32(frame::MIE_EXTINCTION as f32)),
        // The edge erosion a march without detail applies (cloud.wgsl `carve`).
        ("DETAIL_MEAN", F32(crate::render::noise::DETAIL_MEAN)),
        // The ground where a map has none (render::ground's stand-in, scene.wgsl's).
        (
            "DEFAULT_ALBEDO",
            Vec3F32(crate::render::ground::DEFAULT_ALBEDO),
        ),
        ("FLAG_SKIP", U32(flags::SKIP)),
        ("FLAG_CULL", U32(flags::CULL)),
        ("FLAG_DETAIL", U32(flags::DETAIL)),
        ("FLAG_JITTER", U32(flags::JITTER)),
        ("FLAG_NO_SKY", U32(flags::NO_SKY)),
        ("FLAG_LIGHT_LOD", U32(flags::LIGHT_LOD)),
        ("FLAG_STRIDE", U32(flags::STRIDE)),
        ("FLAG_STRUCTURE", U32(flags::STRUCTURE)),
        ("FLAG_TOWERS", U32(flags::TOWERS)),
        ("FLAG_STREAKS", U32(flags::STREAKS)),
        ("FLAG_BLEND", U32(flags::BLEND)),
        ("FLAG_CELLS", U32(flags::CELLS)),
        ("FLAG_GRAZE", U32(flags::GRAZE)),
        ("FLAG_ENVELOPE", U32(flags::ENVELOPE)),
        ("CELL_PERIOD_M", F32(crate::render::cells::PERIOD_M)),
        (
            "REFERENCE_THICKNESS_M",
            F32(crate::render::frame::REFERENCE_THICKNESS_M),
        ),
        ("PROFILE_ROWS", F32(crate::render::profile::LUT_ROWS as f32)),
        (
            "PROFILE_WIDTH",
            F32(crate::render::profile::LUT_WIDTH as f32),
        ),
        ("T_CIRRUS", F32(CloudType::Cirrus.code() as f32)),
        ("T_CIRROSTRATUS", F32(CloudType::Cirrostratus.code() as f32)),
        ("T_CUMULONIMBUS", F32(CloudType::Cumulonimbus.code() as f32)),
        ("T_CUMULUS", F32(CloudType::Cumulus.code() as f32)),
        (
            "N_COUNTERS",
            U32((std::mem::size_of::<Counters>() / 4) as u32),
        ),
        // The rework list's dispatch (render::march sizes the list and its workgroups).
        ("REWORK_GROUP", U32(crate::render::march::REWORK_GROUP)),
        ("GRAZE_EXTRA", U32(crate::render::march::GRAZE_EXTRA)),
    ];
    // One index constant per counter, named after its field: `C_RAYS` is `Counters::rays`.
    for f in Counters::fields() {
        v.push((counter_const(f.name), U32((f.offset / 4) as u32)));
    }
    v
}

/// The rework list render::march sizes and clears (its entries' size, its header's) is laid out
/// so in march.wgsl.
#[test]
fn the_rework_list_is_laid_out_as_the_host_sizes_it() {
    use crate::render::march::{REWORK_ENTRY, REWORK_HEADER};
    let m = parse("march", crate::render::shader::MARCH);
    let find = |name: &str| {
        m.types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some(name))
            .map(|(_, t)| t.inner.clone())
    };
    let Some(TypeInner::Struct { span, .. }) = find("ReworkEntry") else {
        panic!("march.wgsl declares no struct ReworkEntry");
    };
    assert_eq!(u64::from(span), REWORK_ENTRY, "ReworkEntry's size");
    let Some(TypeInner::Struct { members, .. }) = find("ReworkList") else {
        panic!("march.wgsl declares no struct ReworkList");
    };
    let entries = members
        .iter()
        .find(|m| m.name.as_deref() == Some("entries"))
        .expect("ReworkList has its entries");
    assert_eq!(
        u64::from(entries.offset),
        REWORK_HEADER,
        "ReworkList's header"
    );
}

fn counter_const(field: &str) -> &'static str {
    match field {
        "rays" => "C_RAYS",
        "steps" => "C_STEPS",
        "density_samples" => "C_DENSITY",
        "detail_samples" => "C_DETAIL",
        "light_samples" => "C_LIGHT",
        "outside_samples" => "C_OUTSIDE",
        "skipped_steps" => "C_SKIPPED",
        "early_exits" => "C_EARLY",
        "cut_rays" => "C_CUT",
        "reworked" => "C_REWORK",
        _ => "C_UNKNOWN",
    }
}

/// The structs shared by every stage that declares them.
fn shared_structs() -> Vec<(&'static str, Vec<Field>, usize)> {
    use crate::render::exposure::{ExposureParams, ExposureState};
    use crate::render::noise::{NoiseParams, StatsParams};
    use crate::render::reproject::ReprojectParams;
    use crate::render::scene::ShadowParams;
    use crate::render::section::SectionParams;
    vec![
        (
            ShadowParams::WGSL_NAME,
            ShadowParams::fields(),
            std::mem::size_of::<ShadowParams>(),
        ),
        (
            ExposureParams::WGSL_NAME,
            ExposureParams::fields(),
            std::mem::size_of::<ExposureParams>(),
        ),
        (
            ExposureState::WGSL_NAME,
            ExposureState::fields(),
            std::mem::size_of::<ExposureState>(),
        ),
        (
            SectionParams::WGSL_NAME,
            SectionParams::fields(),
            std::mem::size_of::<SectionParams>(),
        ),
        (
            FrameUniforms::WGSL_NAME,
            FrameUniforms::fields(),
            std::mem::size_of::<FrameUniforms>(),
        ),
        (
            NoiseParams::WGSL_NAME,
            NoiseParams::fields(),
            std::mem::size_of::<NoiseParams>(),
        ),
        (
            StatsParams::WGSL_NAME,
            StatsParams::fields(),
            std::mem::size_of::<StatsParams>(),
        ),
        (
            ReprojectParams::WGSL_NAME,
            ReprojectParams::fields(),
            std::mem::size_of::<ReprojectParams>(),
        ),
    ]
}
