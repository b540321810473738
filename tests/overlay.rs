//! The window's panel and HUD laid over a frame from their own layer (app::overlay) show what
//! egui drawing straight onto the frame shows, frame after frame, while only what changed is
//! redrawn: the real panel and HUD, egui's own wgpu renderer as the yardstick, on a real wgpu
//! adapter (lavapipe in CI).

use chrono::{TimeZone, Utc};
use stratus::app::overlay::{Drawn, Overlay};
use stratus::app::panel::{self, Controls, Hud};
use stratus::render::readback::Pending;
use stratus::render::{Gpu, Preset};

const W: u32 = 800;
const H: u32 = 450;
const FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;

fn target(gpu: &Gpu) -> wgpu::Texture {
    gpu.device.create_texture(&wgpu::TextureDescriptor {
        label: Some("frame"),
        size: wgpu::Extent3d {
            width: W,
            height: H,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: FORMAT,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT
            | wgpu::TextureUsages::COPY_SRC
            | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    })
}

/// A sky-like gradient with a bright band, so a blend error anywhere shows.
fn clouds(gpu: &Gpu, tex: &wgpu::Texture, shift: u32) {
    let mut px = Vec::with_capacity((W * H * 4) as usize);
    for y in 0..H {
        for x in 0..W {
            let band = ((x + y + shift) / 40).is_multiple_of(2);
            px.extend_from_slice(&[
                (40 + y * 180 / H) as u8,
                if band { 230 } else { 90 },
                (255 - x * 120 / W) as u8,
                255,
            ]);
        }
    }
    gpu.queue.write_texture(
        tex.as_image_copy(),
        &px,
        wgpu::TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some(W * 4),
            rows_per_image: Some(H),
        },
        tex.size(),
    );
}

fn read(gpu: &Gpu, tex: &wgpu::Texture) -> Vec<u8> {
    let mut enc = gpu.device.create_command_encoder(&Default::default());
    let pending = Pending::texture(gpu, &mut enc, tex, 4);
    gpu.queue.submit([enc.finish()]);
    pending.finish(gpu).expect("read back")
}

fn hud(lat: f64, daylight: Option<&str>) -> Hud {
    Hud {
        lat,
        lon: 83.781,
        alt_m: 19_539.0,
        heading: 67.9,
        speed: 230.0,
        utc: Utc.with_ymd_and_hms(2011, 1, 15, 6, 24, 53).unwrap(),
        fps: 14.2,
        gpu_ms: None,
        frame_ms: 70.0,
        adapter: "test adapter".into(),
        march_size: (320, 180),
        follow: None,
        weather: None,
        daylight: daylight.map(str::to_string),
    }
}

/// One egui frame of the real panel and HUD.
fn ui(ctx: &egui::Context, controls: &mut Controls, h: &Hud) -> egui::FullOutput {
    let input = egui::RawInput {
        screen_rect: Some(egui::Rect::from_min_size(
            egui::Pos2::ZERO,
            egui::vec2(W as f32, H as f32),
        )),
        ..Default::default()
    };
    ctx.run_ui(input, |ui| {
        panel::panel(ui, controls);
        panel::hud(ui, h);
    })
}

/// egui straight onto the frame, as the window drew before the overlay.
fn direct(
    gpu: &Gpu,
    egui_r: &mut egui_wgpu::Renderer,
    ctx: &egui::Context,
    out: egui::FullOutput,
    view: &wgpu::TextureView,
) {
    let screen = egui_wgpu::ScreenDescriptor {
        size_in_pixels: [W, H],
        pixels_per_point: out.pixels_per_point,
    };
    for (id, deltas) in &out.textures_delta.set {
        for d in deltas {
            egui_r.update_texture(&gpu.device, &gpu.queue, *id, d);
        }
    }
    let prims = ctx.tessellate(out.shapes, out.pixels_per_point);
    let mut enc = gpu.device.create_command_encoder(&Default::default());
    let extra = egui_r.update_buffers(&gpu.device, &gpu.queue, &mut enc, &prims, &screen);
    {
        let mut pass =
            stratus::render::pipeline::over_pass(&mut enc, "egui", view).forget_lifetime();
        egui_r.render(&mut pass, &prims, &screen);
    }
    gpu.queue.submit(extra.into_iter().chain([enc.finish()]));
}

/// The largest per-channel difference and how many channels differ by more than 2/255.
fn diff(a: &[u8], b: &[u8]) -> (u8, usize) {
    let d = a.iter().zip(b).map(|(x, y)| x.abs_diff(*y));
    (d.clone().max().unwrap_or(0), d.filter(|&v| v > 2).count())
}

#[test]
fn the_layer_shows_what_egui_draws_and_redraws_only_what_changed() {
    let gpu = Gpu::new(None).expect("a wgpu adapter (install mesa-vulkan-drivers)");
    let (a, b) = (target(&gpu), target(&gpu));
    let (va, vb) = (
        a.create_view(&Default::default()),
        b.create_view(&Default::default()),
    );
    let mut overlay = Overlay::new(&gpu.device, FORMAT);
    let mut egui_r = egui_wgpu::Renderer::new(&gpu.device, FORMAT, Default::default());
    let ctx = egui::Context::default();
    let mut controls = Controls::new(Preset::Fast, [0.8, 0.65, 0.8], false, true);
    let dusk: Option<&str> = Some("Sun 3.7° below the horizon here: local solar 17:35");
    // What each frame changes: the first draws everything, and egui settles over the next
    // (the HUD fades in over a few frames, a window's first tenth of a second); then the HUD's latitude (the HUD
    // alone redrawn); nothing; a longer HUD; a shorter one again (its old lines must go from
    // the layer, or the next long one is drawn over them); the panel's coverage slider; the
    // clouds under an unchanged panel and HUD.
    let mut frames = vec![("first", 30.72, None, 1.0, 0)];
    frames.extend([("settling", 30.72, None, 1.0, 0); 11]);
    frames.extend([
        ("hud moved", 30.73, None, 1.0, 0),
        ("still", 30.73, None, 1.0, 0),
        ("still again", 30.73, None, 1.0, 0),
        ("hud grew", 30.74, dusk, 1.0, 0),
        ("hud shrank", 30.75, None, 1.0, 0),
        ("hud grew again", 30.75, dusk, 1.0, 0),
        ("panel changed", 30.75, None, 1.6, 0),
        ("clouds moved", 30.75, None, 1.6, 17),
    ]);
    let mut drawn: Vec<Drawn> = Vec::new();
    for (name, lat, day, coverage, shift) in frames {
        controls.coverage = coverage;
        let h = hud(lat, day);
        let oa = ui(&ctx, &mut controls, &h);
        let ob = oa.clone();
        clouds(&gpu, &a, shift);
        clouds(&gpu, &b, shift);
        let mut enc = gpu.device.create_command_encoder(&Default::default());
        let (extra, d) = overlay.draw(&gpu.device, &gpu.queue, &mut enc, &va, [W, H], &ctx, oa);
        gpu.queue.submit(extra.into_iter().chain([enc.finish()]));
        direct(&gpu, &mut egui_r, &ctx, ob, &vb);
        let (pa, pb) = (read(&gpu, &a), read(&gpu, &b));
        let (max, count) = diff(&pa, &pb);
        eprintln!("{name}: {d:?}, largest difference {max}/255, {count} channels over 2/255");
        assert!(
            max <= 3 && count == 0,
            "{name}: the layered frame differs from egui's own by up to {max}/255 ({count} channels over 2/255)"
        );
        drawn.push(d);
    }
    // Whether the layer was mended in place, not redrawn whole, where only the HUD changed.
    let drawn = &drawn[12..];
    let hud_only = drawn[0];
    assert!(
        hud_only.redrawn >= 1 && hud_only.redrawn < hud_only.total,
        "the HUD's change redrew {hud_only:?}"
    );
    assert_eq!(drawn[1].redrawn, 0, "nothing changed, yet {:?}", drawn[1]);
    assert_eq!(drawn[2].redrawn, 0, "nothing changed, yet {:?}", drawn[2]);
    assert_eq!(
        drawn[7].redrawn, 0,
        "only the clouds changed, yet {:?}",
        drawn[7]
    );
}
