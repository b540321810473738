//! A small wgpu host with Stratus' clouds inside it (render::embed, issue 33): the host opens
//! its own device, draws its own terrain mesh and an aircraft-sized box near the camera with a
//! reversed-Z depth buffer, then hands Stratus its device, camera, colour and depth, and the
//! clouds are marched up to the host's depth and blended over its colour.
//!
//! `cargo run --release --example embed -- [--window | --out embed.png] [--size 640x360]
//!  [--map m.json] [--frames N] [--compare] [--sky]`
//!
//! With no `--out`, `--frames` or `--compare` it opens a window and flies north over the deck
//! (Esc closes it); `--window --frames N` closes it after N frames.
//! Without `--map`, a made-up broken low deck (1.4–2.2 km) over the host's hills near 47°N 8°E.
//! `--frames N` times N embedded frames; `--compare` also times Stratus' own frame
//! (`Renderer::encode`, what `stratus render` records, without its read-back) at the same view
//! and size on the same kind of device. `--sky`: Stratus' own sky where the host drew nothing
//! (beyond its 30 km of terrain), instead of the host's flat blue.

mod host;
mod window;

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{anyhow, Context};
use chrono::{DateTime, Utc};
use glam::Vec3;
use host::Host;
use stratus::render::embed::{
    CloudExposure, DepthConvention, EmbedOptions, EmbeddedClouds, GeoAnchor, HostCamera,
    HostFormats, HostFrame,
};
use stratus::render::{Gpu, Renderer, View};
use stratus_ingest::cloudmap::CloudMap;
use stratus_ingest::meta::LayerKind;
use stratus_ingest::region::Region;

const COLOR: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;
const DEPTH: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
const ANCHOR: GeoAnchor = GeoAnchor {
    lat_deg: 47.0,
    lon_deg: 8.0,
    alt_m: 0.0,
};

struct Args {
    out: Option<PathBuf>,
    size: (u32, u32),
    map: Option<PathBuf>,
    /// `--frames N`: timed frames headless, or the window's frame count before it closes.
    frames: Option<u32>,
    compare: bool,
    sky: bool,
    window: bool,
}

fn args() -> anyhow::Result<Args> {
    let mut a = Args {
        out: None,
        size: (640, 360),
        map: None,
        frames: None,
        compare: false,
        sky: false,
        window: false,
    };
    let mut headless = false;
    let mut it = std::env::args().skip(1);
    while let Some(k) = it.next() {
        let mut value = || it.next().ok_or_else(|| anyhow!("{k} needs a value"));
        match k.as_str() {
            "--out" => {
                a.out = Some(value()?.into());
                headless = true;
            }
            "--window" => a.window = true,
            "--map" => a.map = Some(value()?.into()),
            "--frames" => {
                a.frames = Some(value()?.parse().context("--frames")?);
                headless = !a.window;
            }
            "--compare" => {
                a.compare = true;
                headless = true;
            }
            "--sky" => a.sky = true,
            "--size" => {
                let v = value()?;
                let (w, h) = v.split_once('x').ok_or_else(|| anyhow!("--size WxH"))?;
                a.size = (w.parse()?, h.parse()?);
            }
            other => return Err(anyhow!("unknown argument {other}")),
        }
    }
    // No output asked for: the window. `--window --frames N` closes it after N frames.
    a.window |= !headless;
    if a.window && (a.out.is_some() || a.compare) {
        return Err(anyhow!(
            "--window draws to the screen: not with --out or --compare"
        ));
    }
    Ok(a)
}

fn time() -> DateTime<Utc> {
    DateTime::parse_from_rfc3339("2024-06-21T09:30:00Z")
        .map(|t| t.with_timezone(&Utc))
        .unwrap_or_default()
}

/// A broken low deck over the host's hills: coverage from a few smooth waves.
fn made_up_map() -> CloudMap {
    let r = Region {
        south: 46.0,
        north: 48.0,
        west: 7.0,
        east: 9.0,
    };
    CloudMap::from_fn(
        r,
        256,
        256,
        &[(LayerKind::Low, 1400.0, 2200.0)],
        time(),
        |lat, lon| {
            // Cells a few km across (1° of latitude is 111 km).
            let w = (lat * 70.0).sin() * (lon * 50.0 + 1.0).cos()
                + 0.5 * (lat * 150.0 + lon * 110.0).sin();
            [(0.42 + 0.3 * w).clamp(0.0, 1.0), 0.0, 0.0]
        },
    )
}

/// Where the host's camera starts: 2.6 km up over the origin.
const EYE: Vec3 = Vec3::new(0.0, 2600.0, 0.0);

/// The host's camera at `eye`, looking north and a little down over the deck.
fn camera(eye: Vec3, size: (u32, u32)) -> HostCamera {
    HostCamera::look_at(
        ANCHOR,
        eye,
        eye + Vec3::new(0.15, -0.35, -1.0),
        Vec3::Y,
        55.0,
        size.0 as f32 / size.1 as f32,
        (0.5, f32::INFINITY),
        DepthConvention::ReversedZ,
    )
}

/// What the host owns: its device and targets, its terrain and aircraft, and Stratus' clouds on
/// its device.
struct World {
    host: Host,
    terrain: host::Mesh,
    aircraft: host::Mesh,
    clouds: EmbeddedClouds,
}

const SUN: Vec3 = Vec3::new(0.5, 0.6, 0.3);

/// An aircraft-sized box (36 m span, 6 m high, 38 m long) 160 m ahead of `eye`, a little below.
fn aircraft(eye: Vec3) -> Vec<host::Vertex> {
    host::cuboid(
        eye + Vec3::new(30.0, -40.0, -160.0),
        Vec3::new(18.0, 3.0, 19.0),
        [0.75, 0.12, 0.08],
        SUN,
    )
}

impl World {
    /// The host's scene and Stratus on its device, drawing into `color` targets of `size`.
    fn new(
        device: wgpu::Device,
        queue: wgpu::Queue,
        size: (u32, u32),
        color: wgpu::TextureFormat,
        map: &CloudMap,
        options: EmbedOptions,
    ) -> anyhow::Result<World> {
        let host = Host::new(device, queue, size, color, DEPTH);
        let terrain = host.mesh(&host::terrain(160, 30_000.0, SUN));
        let aircraft = host.mesh(&aircraft(EYE));
        let clouds = EmbeddedClouds::new(
            &host.device,
            &host.queue,
            map,
            HostFormats {
                color,
                depth: DEPTH,
            },
            options,
        )?;
        Ok(World {
            host,
            terrain,
            aircraft,
            clouds,
        })
    }

    /// One frame: the host's terrain and box, then the clouds up to its depth, over its colour.
    fn encode(
        &mut self,
        enc: &mut wgpu::CommandEncoder,
        cam: &HostCamera,
        time: DateTime<Utc>,
    ) -> anyhow::Result<()> {
        self.host.draw(
            enc,
            cam.view_projection(),
            cam.depth,
            &[&self.terrain, &self.aircraft],
            [0.30, 0.48, 0.80],
        );
        self.clouds.encode(
            enc,
            &HostFrame {
                camera: cam,
                color: &self.host.color_view,
                depth: &self.host.depth_view,
                time,
            },
        )?;
        Ok(())
    }
}

fn main() -> anyhow::Result<()> {
    let a = args()?;
    let map = match &a.map {
        Some(p) => CloudMap::load(p).with_context(|| format!("reading {}", p.display()))?,
        None => made_up_map(),
    };
    let options = EmbedOptions {
        exposure: CloudExposure::Stratus,
        sky: a.sky,
        ..Default::default()
    };
    if a.window {
        return window::run(a.size, a.frames, map, options);
    }
    // The host: its own device, targets and scene.
    let (device, queue) = host::open_device().map_err(|e| anyhow!(e))?;
    let mut world = World::new(device, queue, a.size, COLOR, &map, options)?;
    let cam = camera(EYE, a.size);
    let mut ms = Vec::new();
    for _ in 0..a.frames.unwrap_or(1).max(1) {
        let start = Instant::now();
        let mut enc = world
            .host
            .device
            .create_command_encoder(&Default::default());
        world.encode(&mut enc, &cam, time())?;
        world.host.queue.submit([enc.finish()]);
        world
            .host
            .device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| anyhow!("{e}"))?;
        ms.push(start.elapsed().as_secs_f64() * 1e3);
    }
    report("embedded frame (host + clouds)", &ms);
    if let Some(out) = &a.out {
        let px = world.host.read_color();
        let bytes: Vec<u8> = px
            .iter()
            .flat_map(|p| p.map(|v| (v * 255.0).round().clamp(0.0, 255.0) as u8))
            .collect();
        let img = image::RgbaImage::from_raw(a.size.0, a.size.1, bytes)
            .ok_or_else(|| anyhow!("picture size"))?;
        img.save(out)
            .with_context(|| format!("writing {}", out.display()))?;
        eprintln!("wrote {}", out.display());
    }
    if a.compare {
        compare(&map, &cam, &a, &world.clouds)?;
    }
    Ok(())
}

/// Stratus' own frame at the same view and size: `Renderer::encode` into a target of the same
/// format, submitted and waited for, as many frames.
fn compare(
    map: &CloudMap,
    cam: &HostCamera,
    a: &Args,
    clouds: &EmbeddedClouds,
) -> anyhow::Result<()> {
    let mut r = Renderer::new(Gpu::new(None)?, map);
    let view = View::Perspective(cam.to_stratus(a.size.0, a.size.1)?);
    let mut settings = clouds.settings.clone();
    settings.time = time();
    let target = r.gpu.device.create_texture(&wgpu::TextureDescriptor {
        label: Some("own frame"),
        size: wgpu::Extent3d {
            width: a.size.0,
            height: a.size.1,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: COLOR,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
        view_formats: &[],
    });
    let tv = target.create_view(&Default::default());
    let mut ms = Vec::new();
    for _ in 0..a.frames.unwrap_or(1).max(1) {
        let start = Instant::now();
        let mut enc = r.gpu.device.create_command_encoder(&Default::default());
        r.encode(
            &mut enc, &view, a.size.0, a.size.1, &settings, &tv, COLOR, a.size,
        )?;
        r.gpu.queue.submit([enc.finish()]);
        r.gpu.wait()?;
        ms.push(start.elapsed().as_secs_f64() * 1e3);
    }
    report("Stratus' own frame (Renderer::encode)", &ms);
    Ok(())
}

/// Print the frames' times; the first (pipelines compiled, light volume made) apart.
fn report(what: &str, ms: &[f64]) {
    let first = ms.first().copied().unwrap_or(0.0);
    let rest = &ms[1.min(ms.len())..];
    if rest.is_empty() {
        println!("{what}: first {first:.0} ms");
        return;
    }
    let mut sorted = rest.to_vec();
    sorted.sort_by(f64::total_cmp);
    println!(
        "{what}: first {first:.0} ms, then median {:.0} ms (min {:.0}, max {:.0}, {} frames)",
        sorted[sorted.len() / 2],
        sorted[0],
        sorted[sorted.len() - 1],
        rest.len()
    );
}
