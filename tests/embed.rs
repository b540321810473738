//! The embedding API (render::embed, issue 33) on a real adapter (lavapipe in CI): a host draws
//! quads at known heights under a camera looking straight down through a 2 km cloud deck, and
//! the clouds are drawn over them through the API. Depth must be honoured: a quad in front
//! hides the cloud completely, one behind shows through by the deck's transmittance computed
//! from the march's own extinction (`Renderer::section`), one inside is partly veiled; with
//! standard and reversed-Z depth. Nothing is made on the frame path; misuse is a typed error.

#[path = "../examples/embed/host.rs"]
mod host;

use chrono::{DateTime, Utc};
use glam::Vec3;
use host::Host;
use stratus::render::camera::ecef;
use stratus::render::embed::{
    CloudExposure, DepthConvention, EmbedError, EmbedOptions, EmbeddedClouds, GeoAnchor,
    HostCamera, HostFormats, HostFrame,
};
use stratus::render::{Gpu, Renderer, Settings};
use stratus_ingest::cloudmap::CloudMap;
use stratus_ingest::meta::LayerKind;
use stratus_ingest::region::Region;

const SIZE: u32 = 33;
const CAM_ALT: f32 = 7000.0;
const ANCHOR: GeoAnchor = GeoAnchor {
    lat_deg: 47.0,
    lon_deg: 8.0,
    alt_m: 0.0,
};
const HDR: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;
const DEPTH: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

fn noon() -> DateTime<Utc> {
    DateTime::parse_from_rfc3339("2024-06-21T11:30:00Z")
        .expect("a valid time")
        .with_timezone(&Utc)
}

/// An overcast middle deck 3–5 km over the anchor.
fn deck() -> CloudMap {
    let r = Region {
        south: 46.0,
        north: 48.0,
        west: 7.0,
        east: 9.0,
    };
    CloudMap::from_fn(
        r,
        64,
        64,
        &[(LayerKind::Middle, 3000.0, 5000.0)],
        noon(),
        |_, _| [0.0, 1.0, 0.0],
    )
}

/// Straight down from 7 km over the anchor, north up.
fn camera(depth: DepthConvention) -> HostCamera {
    let far = match depth {
        DepthConvention::Standard => 20_000.0,
        DepthConvention::ReversedZ => f32::INFINITY,
    };
    let eye = Vec3::new(0.0, CAM_ALT, 0.0);
    HostCamera::look_at(
        ANCHOR,
        eye,
        eye - Vec3::Y,
        Vec3::NEG_Z,
        40.0,
        1.0,
        (10.0, far),
        depth,
    )
}

fn frame<'a>(host: &'a Host, camera: &'a HostCamera) -> HostFrame<'a> {
    HostFrame {
        camera,
        color: &host.color_view,
        depth: &host.depth_view,
        time: noon(),
    }
}

/// The host's frame (a quad covering the view at `quad_alt`, or none) with the clouds over it;
/// the centre pixel's colour for a white and a black host: their difference is the cloud's
/// transmittance there, the black one the cloud's own light.
fn centre_transmittance(
    host: &Host,
    clouds: &mut EmbeddedClouds,
    depth: DepthConvention,
    quad_alt: Option<f32>,
) -> (f32, f32) {
    let cam = camera(depth);
    let mut centre = [0.0f32; 2];
    for (k, grey) in [1.0f32, 0.0].into_iter().enumerate() {
        let meshes: Vec<host::Mesh> = quad_alt
            .map(|y| host.mesh(&host::quad(Vec3::new(0.0, y, 0.0), 20_000.0, [grey; 3])))
            .into_iter()
            .collect();
        let refs: Vec<&host::Mesh> = meshes.iter().collect();
        let sky = [grey as f64; 3];
        let mut enc = host.device.create_command_encoder(&Default::default());
        host.draw(&mut enc, cam.view_projection(), depth, &refs, sky);
        clouds
            .encode(&mut enc, &frame(host, &cam))
            .expect("an embedded frame");
        host.queue.submit([enc.finish()]);
        let px = host.read_color();
        let c = px[(SIZE / 2 * SIZE + SIZE / 2) as usize];
        centre[k] = c[1];
    }
    (centre[0] - centre[1], centre[1])
}

/// The deck's transmittance from the camera down to `alt`, from the march's own extinction on
/// the vertical under the camera (5 m rows).
fn expected_transmittance(section: &[f32], alt: f32) -> f32 {
    let rows = section.len() as f32;
    let dz = CAM_ALT / rows;
    let tau: f32 = section
        .iter()
        .enumerate()
        .filter(|(i, _)| CAM_ALT * (1.0 - (*i as f32 + 0.5) / rows) >= alt)
        .map(|(_, s)| s * dz)
        .sum();
    (-tau).exp()
}

fn embedded(host: &Host) -> EmbeddedClouds {
    let mut clouds = EmbeddedClouds::new(
        &host.device,
        &host.queue,
        &deck(),
        HostFormats {
            color: HDR,
            depth: DEPTH,
        },
        EmbedOptions {
            exposure: CloudExposure::Scale(1.0),
            ..Default::default()
        },
    )
    .expect("the embedding on the host's device");
    // One ray per pixel, no jitter to resolve: the centre pixel is the vertical ray itself.
    clouds.settings.march.shortcuts.jitter = false;
    clouds
}

fn host() -> Host {
    let (device, queue) = host::open_device().expect("a wgpu adapter (mesa-vulkan-drivers)");
    Host::new(device, queue, (SIZE, SIZE), HDR, DEPTH)
}

#[test]
fn depth_is_honoured_in_both_conventions() {
    let host = host();
    let mut clouds = embedded(&host);
    // The reference: the march's own extinction under the camera, at the embedding's settings.
    let mut reference = Renderer::new(Gpu::new(None).expect("a wgpu adapter"), &deck());
    let column = [ecef(ANCHOR.lat_deg, ANCHOR.lon_deg, 0.0).normalize()];
    let mut settings: Settings = clouds.settings.clone();
    settings.time = noon();
    let section = reference
        .section(&column, 1400, CAM_ALT, &settings)
        .expect("a section");
    // A thin deck, so that its transmittance is measurable: optical depth about 1.2.
    let tau_full = -expected_transmittance(&section, 0.0).ln();
    assert!(tau_full > 0.05, "the deck has cloud: τ {tau_full}");
    settings.extinction *= 1.2 / tau_full;
    clouds.settings.extinction = settings.extinction;
    let section = reference
        .section(&column, 1400, CAM_ALT, &settings)
        .expect("a section");
    let (t_behind_want, t_inside_want) = (
        expected_transmittance(&section, 1000.0),
        expected_transmittance(&section, 4000.0),
    );
    eprintln!("expected: behind {t_behind_want:.4}, inside {t_inside_want:.4}");
    for depth in [DepthConvention::Standard, DepthConvention::ReversedZ] {
        let (t_front, light_front) = centre_transmittance(&host, &mut clouds, depth, Some(6000.0));
        let (t_inside, light_inside) =
            centre_transmittance(&host, &mut clouds, depth, Some(4000.0));
        let (t_behind, _) = centre_transmittance(&host, &mut clouds, depth, Some(1000.0));
        let (t_none, _) = centre_transmittance(&host, &mut clouds, depth, None);
        eprintln!(
            "{depth:?}: front {t_front:.4} (light {light_front:.4}), inside {t_inside:.4} (light {light_inside:.4}), behind {t_behind:.4}, no host geometry {t_none:.4}"
        );
        // In front: the cloud is hidden completely (transmittance 1, no light of its own).
        assert!(
            (t_front - 1.0).abs() < 2e-3 && light_front.abs() < 1e-4,
            "{depth:?}"
        );
        // Behind: the whole deck's transmittance, from the march's own extinction.
        assert!(
            (t_behind - t_behind_want).abs() < 0.02,
            "{depth:?}: behind {t_behind} vs {t_behind_want}"
        );
        assert!(t_behind_want > 0.15 && t_behind_want < 0.6);
        // Inside: partly veiled, by the upper part of the deck.
        assert!(
            (t_inside - t_inside_want).abs() < 0.02,
            "{depth:?}: inside {t_inside} vs {t_inside_want}"
        );
        assert!(t_inside > t_behind + 0.05 && t_inside < 0.95 && light_inside > 0.0);
        // With no host geometry the ray goes on to the sea: the whole deck again.
        assert!((t_none - t_behind).abs() < 0.01, "{depth:?}");
    }
}

#[test]
fn nothing_is_made_on_the_frame_path() {
    let host = host();
    let mut clouds = embedded(&host);
    let cam = camera(DepthConvention::ReversedZ);
    let quad = host.mesh(&host::quad(Vec3::new(0.0, 4000.0, 0.0), 20_000.0, [0.5; 3]));
    let run = |clouds: &mut EmbeddedClouds, host: &Host, n: u32| {
        for _ in 0..n {
            let mut enc = host.device.create_command_encoder(&Default::default());
            host.draw(
                &mut enc,
                cam.view_projection(),
                DepthConvention::ReversedZ,
                &[&quad],
                [0.2; 3],
            );
            clouds
                .encode(&mut enc, &frame(host, &cam))
                .expect("a frame");
            host.queue.submit([enc.finish()]);
        }
    };
    let at_start = clouds.creations();
    run(&mut clouds, &host, 1);
    let after_first = clouds.creations();
    assert!(
        after_first.textures > at_start.textures,
        "the first frame sizes the targets"
    );
    run(&mut clouds, &host, 4);
    assert_eq!(clouds.creations(), after_first, "frames 2–5 made nothing");
    assert_eq!(clouds.renderer().made().targets, 1);
    // A new target size makes one set again, then nothing.
    let (device, queue) = (host.device.clone(), host.queue.clone());
    let bigger = Host::new(device, queue, (SIZE + 8, SIZE + 8), HDR, DEPTH);
    let cam2 = HostCamera::look_at(
        ANCHOR,
        Vec3::new(0.0, CAM_ALT, 0.0),
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::NEG_Z,
        40.0,
        1.0,
        (10.0, f32::INFINITY),
        DepthConvention::ReversedZ,
    );
    for _ in 0..3 {
        let mut enc = bigger.device.create_command_encoder(&Default::default());
        clouds
            .encode(&mut enc, &frame(&bigger, &cam2))
            .expect("a frame at the new size");
        bigger.queue.submit([enc.finish()]);
    }
    assert_eq!(clouds.renderer().made().targets, 2);
    let resized = clouds.creations();
    assert_eq!(resized.textures, after_first.textures + 2);
    // Stratus' own sky where the host drew nothing (its depth buffer left clear): every pixel
    // is written, opaque, and the frame made nothing either.
    clouds.sky = true;
    let mut enc = bigger.device.create_command_encoder(&Default::default());
    clouds
        .encode(&mut enc, &frame(&bigger, &cam2))
        .expect("a frame with Stratus' sky");
    bigger.queue.submit([enc.finish()]);
    let px = bigger.read_color();
    assert!(
        px.iter().all(|p| p[3] == 1.0 && p[2] > 0.0),
        "the sky everywhere"
    );
    assert_eq!(clouds.creations(), resized);
    // The embedding reads nothing back: its source never maps a buffer.
    let src = include_str!("../src/render/embed/mod.rs").to_string()
        + include_str!("../src/render/embed/stage.rs");
    assert!(!src.contains("map_async") && !src.contains("readback"));
}

#[test]
fn misuse_is_a_typed_error() {
    // Two devices of one adapter: the host's, and another one a depth buffer comes from.
    let mut devices = host::open_devices(2).expect("two devices on one adapter");
    let (other, _other_queue) = devices.pop().expect("the second device");
    let (device, queue) = devices.pop().expect("the first device");
    let host = Host::new(device, queue, (SIZE, SIZE), HDR, DEPTH);
    let mut clouds = embedded(&host);
    let cam = camera(DepthConvention::ReversedZ);
    let dev = &host.device;
    let tex = |size: u32, format, usage| {
        dev.create_texture(&wgpu::TextureDescriptor {
            label: None,
            size: wgpu::Extent3d {
                width: size,
                height: size,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage,
            view_formats: &[],
        })
        .create_view(&Default::default())
    };
    use wgpu::TextureUsages as U;
    let try_frame = |clouds: &mut EmbeddedClouds,
                     color: &wgpu::TextureView,
                     depth: &wgpu::TextureView,
                     camera: &HostCamera| {
        let mut enc = dev.create_command_encoder(&Default::default());
        let r = clouds.encode(
            &mut enc,
            &HostFrame {
                camera,
                color,
                depth,
                time: noon(),
            },
        );
        host.queue.submit([enc.finish()]);
        r
    };
    // A depth target of another size.
    let small_depth = tex(SIZE - 1, DEPTH, U::RENDER_ATTACHMENT | U::TEXTURE_BINDING);
    let e = try_frame(&mut clouds, &host.color_view, &small_depth, &cam);
    assert!(matches!(e, Err(EmbedError::SizeMismatch { .. })), "{e:?}");
    // A colour format the composite does not take, and a colour texture as the depth.
    let unorm = tex(SIZE, wgpu::TextureFormat::Rgba8Unorm, U::RENDER_ATTACHMENT);
    let e = try_frame(&mut clouds, &unorm, &host.depth_view, &cam);
    assert!(
        matches!(e, Err(EmbedError::UnsupportedFormat { .. })),
        "{e:?}"
    );
    let not_depth = tex(SIZE, wgpu::TextureFormat::R32Float, U::TEXTURE_BINDING);
    let e = try_frame(&mut clouds, &host.color_view, &not_depth, &cam);
    assert!(
        matches!(e, Err(EmbedError::UnsupportedFormat { .. })),
        "{e:?}"
    );
    // A depth buffer the embedding may not read.
    let unreadable = tex(SIZE, DEPTH, U::RENDER_ATTACHMENT);
    let e = try_frame(&mut clouds, &host.color_view, &unreadable, &cam);
    assert!(matches!(e, Err(EmbedError::Usage { .. })), "{e:?}");
    // A multisampled depth buffer (to be resolved first).
    let msaa = dev
        .create_texture(&wgpu::TextureDescriptor {
            label: None,
            size: wgpu::Extent3d {
                width: SIZE,
                height: SIZE,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 4,
            dimension: wgpu::TextureDimension::D2,
            format: DEPTH,
            usage: U::RENDER_ATTACHMENT | U::TEXTURE_BINDING,
            view_formats: &[],
        })
        .create_view(&Default::default());
    let e = try_frame(&mut clouds, &host.color_view, &msaa, &cam);
    assert!(matches!(e, Err(EmbedError::Multisampled { .. })), "{e:?}");
    // A camera with NaN in it, and a projection of another aspect.
    let mut nan = cam;
    nan.view.w_axis.y = f32::NAN;
    let e = try_frame(&mut clouds, &host.color_view, &host.depth_view, &nan);
    assert!(matches!(e, Err(EmbedError::BadCamera(_))), "{e:?}");
    let mut wide = cam;
    wide.projection.x_axis.x *= 0.5;
    let e = try_frame(&mut clouds, &host.color_view, &host.depth_view, &wide);
    assert!(matches!(e, Err(EmbedError::Projection(_))), "{e:?}");
    // A depth buffer of another device (refused when first seen: see docs/embedding.md).
    let foreign = other
        .create_texture(&wgpu::TextureDescriptor {
            label: None,
            size: wgpu::Extent3d {
                width: SIZE,
                height: SIZE,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: DEPTH,
            usage: U::RENDER_ATTACHMENT | U::TEXTURE_BINDING,
            view_formats: &[],
        })
        .create_view(&Default::default());
    let e = try_frame(&mut clouds, &host.color_view, &foreign, &cam);
    assert!(matches!(e, Err(EmbedError::Gpu(_))), "{e:?}");
    // Formats refused at creation too.
    let e = EmbeddedClouds::new(
        &host.device,
        &host.queue,
        &deck(),
        HostFormats {
            color: wgpu::TextureFormat::R8Unorm,
            depth: DEPTH,
        },
        EmbedOptions::default(),
    );
    assert!(matches!(e, Err(EmbedError::UnsupportedFormat { .. })));
    // After all that, a good frame still draws (no lost device).
    let mut enc = dev.create_command_encoder(&Default::default());
    host.draw(
        &mut enc,
        cam.view_projection(),
        DepthConvention::ReversedZ,
        &[],
        [0.0; 3],
    );
    clouds
        .encode(&mut enc, &frame(&host, &cam))
        .expect("a good frame");
    host.queue.submit([enc.finish()]);
    let px = host.read_color();
    assert!(px.iter().all(|p| p.iter().all(|v| v.is_finite())));
    assert!(px.iter().any(|p| p[3] > 0.0));
}

/// A host that asked for WebGPU's default limits (not its adapter's) gets the clouds too.
#[test]
fn a_device_with_default_limits_takes_the_clouds() {
    let (device, queue) = host::open_devices_with(1, Some(wgpu::Limits::default()))
        .expect("a device with the default limits")
        .remove(0);
    let host = Host::new(device, queue, (SIZE, SIZE), HDR, DEPTH);
    let mut clouds = embedded(&host);
    let cam = camera(DepthConvention::Standard);
    let mut enc = host.device.create_command_encoder(&Default::default());
    host.draw(&mut enc, cam.view_projection(), cam.depth, &[], [0.0; 3]);
    clouds
        .encode(&mut enc, &frame(&host, &cam))
        .expect("a frame");
    host.queue.submit([enc.finish()]);
    let px = host.read_color();
    assert!(px.iter().any(|p| p[3] > 0.0 && p[1] > 0.0), "cloud drawn");
}
