//! Weather that moves, on the GPU (DESIGN §9), with the real +0/+6 h GFS steps over the North
//! Atlantic and Europe and the real +0/+6/+12 h Poland series: the renderer's blend of two
//! steps along their motion against the CPU's (`Series::at`, issue 31), no popping as time advances a minute at a time across a step boundary,
//! and a 24-step series flown with two steps' textures on the GPU.
//!
//! The 3- and 24-step series are synthetic (labelled so in their sidecars' step list): the two
//! real step maps repeated with new valid times every 6 h, so there are step boundaries to
//! cross; every map in them is a real GFS step.
//!
//! `cargo test --release --test time -- --nocapture` prints the figures docs/time.md quotes.

mod common;

use std::path::{Path, PathBuf};

use chrono::{DateTime, Duration, Utc};
use common::{poland, sample, stratus};
use stratus::render::{Gpu, Preset, Renderer, Settings, View};
use stratus::scene::Scene;
use stratus::score::{self, compare, mask};
use stratus::timeline::Timeline;
use stratus_ingest::series::Series;

/// Ingest the two real steps into `dir/na.json`.
fn real_series(dir: &Path, size: &str) -> Option<PathBuf> {
    let f0 = sample("gfs-series/gfs.t18z.pgrb2.2p50.f000");
    let f6 = sample("gfs-series/gfs.t18z.pgrb2.2p50.f006");
    if !(f0.is_file() && f6.is_file()) {
        panic!("data-samples/gfs-series not found");
    }
    let out = dir.join("na.png");
    let o = stratus(&[
        "ingest",
        f0.to_str().unwrap(),
        f6.to_str().unwrap(),
        "--region",
        "30,70,-60,40",
        "--size",
        size,
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    Some(dir.join("na.json"))
}

/// A synthetic series of `n` steps 6 h apart beside the real one: +0 h, +6 h, +0 h, … maps,
/// each step with its own step sidecar.
fn synthetic_series(real: &Path, n: usize) -> PathBuf {
    common::series::repeated(real, &format!("synthetic-{n}-steps"), n, 6.0, true)
}

fn settings(time: DateTime<Utc>) -> Settings {
    Settings::new(Preset::Balanced, time)
}

fn dsc(a: &[f32], b: &[f32]) -> f64 {
    compare(&mask(a, 0.5), &mask(b, 0.5)).dice
}

/// The tolerance of the GPU blend against the CPU's (`Series::at`), half-way: Dice of the
/// top-down opacity masks (> 0.5) of the two renders, per drawn layer set. The two differ by
/// the f16 motion texture, the GPU's bilinear lookups and the noise carving the coverage.
const GPU_CPU_DICE: f64 = 0.95;

/// `series` (its first interval) blended at w = 0.5 on the GPU, against its CPU blend uploaded
/// as one map and rendered the same way, and against the earlier step held (the control).
fn gpu_blend_against_cpu(name: &str, path: &Path, (w, h): (u32, u32)) {
    let series = Series::load(path).unwrap();
    let (a, b) = (series.step_map(0).unwrap(), series.step_map(1).unwrap());
    let t = series.steps()[0].valid_time
        + (series.steps()[1].valid_time - series.steps()[0].valid_time) / 2;
    let cpu = series.at(t).unwrap();
    let motion = series.motion(0, &a, &b).unwrap();
    let mut r = Renderer::new(Gpu::new(None).expect("a wgpu adapter"), &a);
    let alpha = |r: &mut Renderer, on: [bool; 3]| {
        let mut s = settings(t);
        s.layers_on = on;
        // One streak direction for the three renders: the comparison is of the coverage.
        s.streak_wind = Some(stratus_ingest::series::winds::map_mean_wind(&a));
        r.render(&View::TopDown, w, h, &s).unwrap().alpha()
    };
    for (layers, on) in [
        ("all", [true; 3]),
        ("low", [true, false, false]),
        ("middle", [false, true, false]),
        ("high", [false, false, true]),
    ] {
        r.set_pair(&a, &b, &motion).unwrap();
        let gpu = alpha(&mut r, on);
        r.set_map(&cpu);
        let reference = alpha(&mut r, on);
        r.set_map(&a);
        let held = alpha(&mut r, on);
        let (d, d_held) = (dsc(&gpu, &reference), dsc(&held, &reference));
        println!(
            "{name} {layers}: GPU blend vs CPU blend (Series::at) DSC {d:.4}; earlier step held vs CPU blend {d_held:.4}"
        );
        assert!(
            d >= GPU_CPU_DICE,
            "{name} {layers}: DSC {d:.4} < {GPU_CPU_DICE}"
        );
        assert!(
            d > d_held,
            "{name} {layers}: the blend ({d:.4}) is no closer than holding ({d_held:.4})"
        );
    }
}

#[test]
fn the_gpu_blend_matches_the_cpu_blend_half_way() {
    let dir = tempfile::tempdir().unwrap();
    let Some(na) = real_series(dir.path(), "512x256") else {
        return;
    };
    gpu_blend_against_cpu("North Atlantic +3 h", &na, (512, 256));
    let pl = poland(dir.path());
    gpu_blend_against_cpu("Poland +3 h", &pl, (480, 320));
}

/// `stratus render --time` on a series blends on the GPU (the timeline, as `flight`), not on the
/// CPU: its top-down picture is the GPU path's, and that agrees with the CPU blend's.
#[test]
fn render_time_half_way_blends_on_the_gpu() {
    let dir = tempfile::tempdir().unwrap();
    let Some(path) = real_series(dir.path(), "512x256") else {
        return;
    };
    let series = Series::load(&path).unwrap();
    let t = series.steps()[0].valid_time + Duration::hours(3);
    let iso = t.format("%Y-%m-%dT%H:%M:%SZ").to_string();
    let shot = dir.path().join("render-time.png");
    let (w, h) = (512, 256);
    let t0 = std::time::Instant::now();
    let o = stratus(&[
        "render",
        "--map",
        path.to_str().unwrap(),
        "--time",
        &iso,
        "--top-down",
        "--size",
        &format!("{w}x{h}"),
        "--out",
        shot.to_str().unwrap(),
    ]);
    let cli_s = t0.elapsed().as_secs_f64();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    // What the command does, in the library: the step nearer +3 h, the pair on the GPU.
    let (start, tl) = Scene::open(&path).for_renderer(Some(t)).unwrap();
    let mut tl = tl.expect("a series");
    let mut r = Renderer::new(Gpu::new(None).expect("a wgpu adapter"), &start);
    let mut s = settings(t);
    s.drift_m = tl.prepare(&mut r, t).unwrap();
    s.streak_wind = Some(tl.streak_wind());
    let gpu = r.render(&View::TopDown, w, h, &s).unwrap();
    let t1 = std::time::Instant::now();
    let cpu_map = series.at(t).unwrap();
    let cpu_blend_s = t1.elapsed().as_secs_f64();
    // The same settings, drifted noise included: the drift is the moment's, not the blend's.
    r.set_map(&cpu_map);
    let cpu = r.render(&View::TopDown, w, h, &s).unwrap();

    // The command's picture is the GPU path's (pixel for pixel, up to rounding).
    let png = image::open(&shot).unwrap().to_rgba8();
    let same = gpu.to_image();
    let diff = png
        .as_raw()
        .iter()
        .zip(same.as_raw())
        .map(|(a, b)| f64::from(a.abs_diff(*b)))
        .sum::<f64>()
        / png.as_raw().len() as f64;
    let d = dsc(&gpu.alpha(), &cpu.alpha());
    println!(
        "render --time +3 h: command {cli_s:.1} s (the CPU blend alone takes {cpu_blend_s:.1} s); \
         command vs GPU path mean |Δ| {diff:.3}/255; GPU vs CPU blend, top-down DSC {d:.4}"
    );
    assert!(
        diff < 0.5,
        "render --time is not the GPU blend: mean |Δ| {diff:.3}/255"
    );
    assert!(d >= 0.95, "GPU blend vs CPU blend DSC {d:.4} < 0.95");
}

/// Per-frame change of opacity: (max over pixels, mean).
fn change(a: &[f32], b: &[f32]) -> (f32, f32) {
    let d: Vec<f32> = a.iter().zip(b).map(|(x, y)| (x - y).abs()).collect();
    let max = d.iter().copied().fold(0.0, f32::max);
    (max, d.iter().sum::<f32>() / d.len() as f32)
}

/// Bound on the per-minute change of top-down cloud opacity, the mean over pixels of |Δα|
/// (measured in docs/time.md). The max over pixels reaches 1 every minute, boundary or not:
/// the noise is carved by a sharp threshold, so a pixel whose noise sits at it flips on the
/// smallest change of coverage or noise position; the bound is on how many do. With the noise
/// held it bounds each ray; with it drifting, the opacity of 4×4-pixel blocks (the score's
/// area fraction): kilometre cells drifting a kilometre a minute flip 40 km point samples as
/// they move, which is motion seen through aliasing, not popping (0.020 a ray, docs/time.md).
const POP_BOUND_MEAN: f32 = 0.02;

#[test]
fn time_advancing_by_the_minute_does_not_pop_at_a_step_boundary() {
    let dir = tempfile::tempdir().unwrap();
    let Some(real) = real_series(dir.path(), "512x256") else {
        return;
    };
    let path = synthetic_series(&real, 3);
    let mut tl = Timeline::open(&path).unwrap();
    let (t0, _) = tl.span();
    let first = tl.series.step_map(0).unwrap();
    let mut r = Renderer::new(Gpu::new(None).expect("a wgpu adapter"), &first);
    // The whole region from above (the score's view): fixed, every layer in sight.
    let mut frames = |from_min: i64, n: i64, drift: bool| -> Vec<Vec<f32>> {
        (0..n)
            .map(|i| {
                let t = t0 + Duration::minutes(from_min + i);
                let mut s = settings(t);
                let d = tl.prepare(&mut r, t).unwrap();
                s.streak_wind = Some(tl.streak_wind());
                if drift {
                    s.drift_m = d;
                }
                r.render(&View::TopDown, 256, 128, &s).unwrap().alpha()
            })
            .collect()
    };
    let report = |name: &str, f: &[Vec<f32>]| -> Vec<(f32, f32)> {
        let c: Vec<(f32, f32)> = f.windows(2).map(|p| change(&p[0], &p[1])).collect();
        let max = c.iter().map(|x| x.0).fold(0.0, f32::max);
        let mean = c.iter().map(|x| x.1).fold(0.0, f32::max);
        println!("{name}: per minute, largest max |Δα| {max:.4}, largest mean |Δα| {mean:.5}; per frame (max, mean): {c:?}");
        c
    };
    for drift in [false, true] {
        let what = if drift {
            "noise drifting"
        } else {
            "noise held"
        };
        // Ten minutes either side of the +6 h boundary, and of the interval's middle (where
        // the genus switches to the later step's).
        let (fb, fm) = (frames(350, 21, drift), frames(170, 21, drift));
        let b = report(&format!("{what}, across +6 h"), &fb);
        let m = report(&format!("{what}, around +3 h"), &fm);
        let blocks = |f: &[Vec<f32>]| -> Vec<Vec<f32>> {
            f.iter()
                .map(|a| score::block_mean(a, (256, 128), score::BLOCK).0)
                .collect()
        };
        let bb = report(&format!("{what}, across +6 h, in blocks"), &blocks(&fb));
        let mb = report(&format!("{what}, around +3 h, in blocks"), &blocks(&fm));
        // Pairs 9 and 10 straddle +6 h exactly (frame 10 is +6 h 00 min).
        let pick = |f: fn(&(f32, f32)) -> f32, at: bool| {
            b.iter()
                .enumerate()
                .filter(|(i, _)| (9..=10).contains(i) == at)
                .map(|(_, x)| f(x))
                .chain(m.iter().filter(|_| !at).map(f))
                .fold(0.0, f32::max)
        };
        for (name, f) in [
            ("max", (|x: &(f32, f32)| x.0) as fn(&(f32, f32)) -> f32),
            ("mean", |x| x.1),
        ] {
            let (at, within) = (pick(f, true), pick(f, false));
            println!("{what}: step boundary {name} |Δα| {at:.4}; within the steps {within:.4}");
            assert!(
                at <= within,
                "{what}: the step boundary jumps ({name} {at:.4}) more than time within the steps ({within:.4})"
            );
        }
        let bounded = if drift { [&bb, &mb] } else { [&b, &m] };
        for x in bounded.into_iter().flatten() {
            assert!(
                x.1 <= POP_BOUND_MEAN,
                "{what}: mean |Δα| {} > {POP_BOUND_MEAN}",
                x.1
            );
        }
    }
}

#[test]
fn a_24_step_series_flies_with_two_steps_on_the_gpu() {
    let dir = tempfile::tempdir().unwrap();
    let Some(real) = real_series(dir.path(), "1024x512") else {
        return;
    };
    let path = synthetic_series(&real, 24);
    // Every interval with a stored motion, as a series ingested since issue 31 has: else the
    // eleven +6 → +0 h intervals would each be estimated at load (about 2 s each here).
    common::series::motion_everywhere(&path);
    let mut tl = Timeline::open(&path).unwrap();
    let (t0, t_end) = tl.span();
    let first = tl.series.step_map(0).unwrap();
    let mut r = Renderer::new(Gpu::new(None).expect("a wgpu adapter"), &first);
    let one_map = r.map_gpu_bytes();
    let mut most = 0u64;
    // A frame in the middle of each interval, 3 h through 135 h.
    let mut t = t0 + Duration::hours(3);
    while t <= t_end {
        let mut s = settings(t);
        s.drift_m = tl.prepare(&mut r, t).unwrap();
        s.streak_wind = Some(tl.streak_wind());
        r.render(&View::TopDown, 64, 32, &s).unwrap();
        most = most.max(r.map_gpu_bytes());
        t += Duration::hours(6);
    }
    println!(
        "24 steps 1024x512: one map {one_map} B on the GPU; flying the series at most {most} B ({} uploads)",
        tl.uploads
    );
    assert_eq!(tl.uploads, 23);
    // Two steps' coverage, one coarse map, one structure set, two steps' winds: under 2.2×
    // one map, whatever the series' length.
    assert!(most <= one_map * 22 / 10, "{most} B > 2.2 × {one_map} B");
    assert!(most > one_map, "the later step is on the GPU too");
}
