//! Speed against accuracy, measured (issue: presets and shortcuts). Fixed scenes over a map are
//! rendered at every preset and with each shortcut switched off alone; each is timed and compared
//! with the `reference` preset: alpha MAE, linear-RGB RMSE, and the Dice score of the cloud masks.

use chrono::{DateTime, Utc};
use serde::Serialize;
use stratus_ingest::cloudmap::CloudMap;

use crate::render::{Output, Preset, RenderError, Renderer, Settings, View};
use crate::scenes::Sample;
use crate::score;

/// The bench's scenes, by name, over the synthetic sample (`scenes::synthetic`).
pub const SCENES: [&str; 4] = ["above-noon", "inside-layer", "horizon-dusk", "top-down"];
/// Its scene with terrain, over the real sample (`scenes::terrain`): the synthetic sample has
/// no ground, so only this one measures what the terrain costs.
pub const TERRAIN_SCENES: [&str; 1] = ["over-terrain"];

/// A map and the bench's scenes over it.
pub struct Set<'a> {
    pub sample: &'a Sample,
    pub map: &'a CloudMap,
    pub scenes: &'a [&'a str],
}

impl Set<'_> {
    /// Progress steps: per scene, the reference, each configuration and the per-change tables.
    pub fn steps(&self) -> usize {
        self.scenes.len() * (configs().len() + 1)
    }
}

/// One measured configuration.
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    pub scene: String,
    pub config: String,
    pub width: u32,
    pub height: u32,
    /// Median frame time: GPU march + present where timestamps are meaningful, else wall.
    pub frame_ms: f64,
    pub timed_by: &'static str,
    pub steps_per_px: f64,
    pub density_per_px: f64,
    pub light_per_px: f64,
    pub speedup_vs_reference: Option<f64>,
    pub alpha_mae: Option<f64>,
    pub rgb_rmse: Option<f64>,
    pub mask_dice: Option<f64>,
    /// Percentage of the frame's rays cut short by the driver (at the error size); the errors
    /// leave those pixels out.
    pub cut_pct: f64,
}

fn srgb_to_linear(c: u8) -> f64 {
    let c = c as f64 / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// (alpha MAE, linear-RGB RMSE, DSC of alpha > 0.5 masks) of `a` against the reference `r`,
/// over the pixels whose rays both frames marched to the end (see `Stats::cut_rays`).
pub fn errors(a: &Output, r: &Output) -> (f64, f64, f64) {
    let whole = |i: usize| !a.is_cut(i) && !r.is_cut(i);
    let n = (0..a.cloud.len().min(r.cloud.len()))
        .filter(|&i| whole(i))
        .count()
        .max(1) as f64;
    let mut abs = 0.0;
    let mut se = 0.0;
    for (i, ((x, y), (p, q))) in a
        .cloud
        .iter()
        .zip(&r.cloud)
        .zip(a.pixels.chunks_exact(4).zip(r.pixels.chunks_exact(4)))
        .enumerate()
    {
        if !whole(i) {
            continue;
        }
        abs += (x[3] - y[3]).abs() as f64;
        for c in 0..3 {
            se += (srgb_to_linear(p[c]) - srgb_to_linear(q[c])).powi(2);
        }
    }
    let rmse = (se / (3.0 * n)).sqrt();
    let masked = |o: &Output| {
        let mut m = score::mask(&o.alpha(), score::RENDER_THRESHOLD);
        for (i, v) in m.iter_mut().enumerate() {
            *v &= whole(i);
        }
        m
    };
    let dice = score::compare(&masked(a), &masked(r)).dice;
    (abs / n, rmse, dice)
}

/// The configurations measured: presets, then `balanced` with each shortcut off alone.
pub fn configs() -> Vec<(String, crate::render::MarchParams)> {
    let mut v: Vec<(String, crate::render::MarchParams)> = Preset::ALL
        .iter()
        .map(|p| (p.name().to_string(), p.params()))
        .collect();
    let b = Preset::Balanced.params();
    let mut off = |name: &str, f: &dyn Fn(&mut crate::render::Shortcuts)| {
        let mut p = b;
        f(&mut p.shortcuts);
        v.push((format!("balanced − {name}"), p));
    };
    off("early exit", &|s| s.early_exit = false);
    off("variable step", &|s| s.variable_step = false);
    off("region culling", &|s| s.region_cull = false);
    off("empty-space skip", &|s| s.empty_skip = false);
    off("light LOD", &|s| s.light_lod = false);
    off("clear-air stride", &|s| s.clear_stride = false);
    off("features by reach", &|s| s.feature_reach = false);
    // The scene's additions (issue 14), each off alone.
    let mut p = b;
    p.column_light = false;
    v.push(("balanced − column light".into(), p));
    let mut p = b;
    p.terrain = false;
    v.push(("balanced − terrain".into(), p));
    let mut p = b;
    p.aerial = false;
    v.push(("balanced − aerial perspective".into(), p));
    // The per-change work as a moving Sun pays for it: the Sun moves 15 minutes a frame, so
    // every frame makes the sky-view table again and a slice of a new light volume
    // (`shadow::SLICES`) (wall time: they are outside the timed passes).
    v.push((SUN_MOVING.into(), b));
    v
}

/// Whether a row times a per-change table rather than frames.
pub fn is_per_change(r: &Row) -> bool {
    r.config.starts_with("per change")
}

/// The configuration whose frames each pay for the per-change tables.
pub const SUN_MOVING: &str = "balanced, Sun moving";

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The settings of frames in a sequence, as the window makes them: the exposure adapting over
/// frames. A single picture (exposure at once, no reprojection) makes its light whole for its
/// own Sun (render::shadow `require_exact`); a window's frame whose Sun moved makes a slice.
fn sequence_settings(s: &Settings) -> Settings {
    let mut s = s.clone();
    s.exposure_rate = crate::app::panel::WINDOW_ADAPTATION;
    s
}

/// Time frames of a sequence whose Sun moves 15 minutes each (wall time), so each makes the
/// sky-view table again and a slice of the light volume: the "Sun moving" row. `s` is the
/// row's single-picture settings; the frames are made with `sequence_settings`.
pub fn timed_moving(
    r: &mut Renderer,
    view: &View,
    w: u32,
    h: u32,
    s: &Settings,
    repeats: usize,
) -> Result<(Output, f64, &'static str), RenderError> {
    let mut s = sequence_settings(s);
    let mut out = r.render(view, w, h, &s)?;
    let mut times = Vec::new();
    for _ in 0..repeats {
        s.time += chrono::Duration::minutes(15);
        out = r.render(view, w, h, &s)?;
        times.push(out.timings.wall_ms);
    }
    Ok((out, median(times), "wall"))
}

/// Time one configuration: a warm-up frame, then the median of `repeats`.
fn timed(
    r: &mut Renderer,
    view: &View,
    w: u32,
    h: u32,
    s: &Settings,
    repeats: usize,
) -> Result<(Output, f64, &'static str), RenderError> {
    let mut out = r.render(view, w, h, s)?;
    let gpu_ok = r.gpu.timestamps;
    let mut times = Vec::new();
    for _ in 0..repeats {
        out = r.render(view, w, h, s)?;
        let t = out.timings;
        times.push(match (gpu_ok, t.march_ms, t.present_ms) {
            (true, Some(m), Some(p)) => m + p,
            _ => t.wall_ms,
        });
    }
    Ok((out, median(times), if gpu_ok { "gpu" } else { "wall" }))
}

/// Run the bench: timings at `size`, errors against `reference` at `error_size`.
pub fn run(
    r: &mut Renderer,
    sets: &[Set],
    size: (u32, u32),
    error_size: (u32, u32),
    repeats: usize,
    progress: &dyn Fn(&str),
) -> Result<Vec<Row>, RenderError> {
    let mut rows = Vec::new();
    for set in sets {
        r.set_map(set.map);
        rows.extend(run_set(r, set, size, error_size, repeats, progress)?);
    }
    Ok(rows)
}

/// The bench over one map (already the renderer's), at its valid time unless a scene has its own.
fn run_set(
    r: &mut Renderer,
    set: &Set,
    size: (u32, u32),
    error_size: (u32, u32),
    repeats: usize,
    progress: &dyn Fn(&str),
) -> Result<Vec<Row>, RenderError> {
    let time: DateTime<Utc> = set.map.meta.source.valid_time.unwrap_or_default();
    let mut rows = Vec::new();
    for sc in set.sample.scenes_named(set.scenes) {
        let mut base = Settings::new(Preset::Reference, time);
        base.time = sc.time.unwrap_or(time);
        progress(&format!("{} reference", sc.name));
        let reference = r.render(&sc.view, error_size.0, error_size.1, &base)?;
        let mut ref_ms = None;
        for (name, params) in configs() {
            progress(&format!("{} {name}", sc.name));
            let mut s = base.clone();
            s.march = params;
            let (out, ms, by) = if name == "reference" {
                // The reference is timed at the error size only (it is slow by design).
                timed(r, &sc.view, error_size.0, error_size.1, &s, 1)?
            } else if name == SUN_MOVING {
                timed_moving(r, &sc.view, size.0, size.1, &s, repeats)?
            } else {
                timed(r, &sc.view, size.0, size.1, &s, repeats)?
            };
            let small = if (out.width, out.height) == error_size {
                out
            } else {
                r.render(&sc.view, error_size.0, error_size.1, &s)?
            };
            let (mae, rmse, dice) = errors(&small, &reference);
            if name == "reference" {
                ref_ms = Some(ms * (size.0 * size.1) as f64 / (error_size.0 * error_size.1) as f64);
            }
            let px = small.stats.rays.max(1) as f64;
            rows.push(Row {
                scene: sc.name.into(),
                config: name.clone(),
                width: if name == "reference" {
                    error_size.0
                } else {
                    size.0
                },
                height: if name == "reference" {
                    error_size.1
                } else {
                    size.1
                },
                frame_ms: ms,
                timed_by: by,
                steps_per_px: small.stats.steps as f64 / px,
                density_per_px: small.stats.density_samples as f64 / px,
                light_per_px: small.stats.light_samples as f64 / px,
                speedup_vs_reference: None,
                alpha_mae: Some(mae),
                rgb_rmse: Some(rmse),
                mask_dice: Some(dice),
                cut_pct: 100.0 * small.stats.cut_rays as f64 / px,
            });
        }
        // The per-change tables alone (not per frame): wall time of each made again.
        let mut s = base.clone();
        s.march = Preset::Balanced.params();
        let (sky_ms, volume_ms) = r.time_per_change(&sc.view, size.0, size.1, &s)?;
        for (config, ms) in [
            ("per change: sky-view table", sky_ms),
            ("per change: light volume", volume_ms),
        ] {
            rows.push(Row {
                scene: sc.name.into(),
                config: config.into(),
                width: size.0,
                height: size.1,
                frame_ms: ms,
                timed_by: "wall",
                steps_per_px: 0.0,
                density_per_px: 0.0,
                light_per_px: 0.0,
                speedup_vs_reference: None,
                alpha_mae: None,
                rgb_rmse: None,
                mask_dice: None,
                cut_pct: 0.0,
            });
        }
        if let Some(rm) = ref_ms {
            for row in rows
                .iter_mut()
                .filter(|x| x.scene == sc.name && x.config != "reference" && !is_per_change(x))
            {
                row.speedup_vs_reference = Some(rm / row.frame_ms);
            }
        }
    }
    Ok(rows)
}

/// A markdown table of the rows.
pub fn table(rows: &[Row]) -> String {
    let mut s = String::from(
        "| scene | config | size | frame ms | timed by | steps/px | density/px | light/px | × reference | alpha MAE | RGB RMSE | mask DSC | cut % |\n|---|---|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    let f = |v: Option<f64>, d: usize| v.map_or("–".to_string(), |x| format!("{x:.d$}"));
    for r in rows {
        s += &format!(
            "| {} | {} | {}×{} | {:.1} | {} | {:.1} | {:.1} | {:.1} | {} | {} | {} | {} | {:.2} |\n",
            r.scene,
            r.config,
            r.width,
            r.height,
            r.frame_ms,
            r.timed_by,
            r.steps_per_px,
            r.density_per_px,
            r.light_per_px,
            f(r.speedup_vs_reference, 1),
            f(r.alpha_mae, 4),
            f(r.rgb_rmse, 4),
            f(r.mask_dice, 4),
            r.cut_pct
        );
    }
    s
}

/// A bar chart (PNG): per scene, one bar per configuration, height = log10 speed-up over
/// reference; a dot on each bar marks alpha MAE × 100 on the same axis (legend in the docs).
pub fn chart(rows: &[Row]) -> image::RgbImage {
    let palette = [
        [66, 133, 244],
        [52, 168, 83],
        [251, 188, 5],
        [234, 67, 53],
        [140, 140, 140],
        [171, 71, 188],
        [0, 172, 193],
        [255, 112, 67],
        [124, 179, 66],
    ];
    let scenes: Vec<String> = {
        let mut v: Vec<String> = rows.iter().map(|r| r.scene.clone()).collect();
        v.dedup();
        v
    };
    let configs: Vec<String> = rows
        .iter()
        .filter(|r| r.config != "reference" && !is_per_change(r))
        .map(|r| r.config.clone())
        .fold(Vec::new(), |mut v, c| {
            if !v.contains(&c) {
                v.push(c);
            }
            v
        });
    let (w, h) = (900u32, 360u32);
    let mut img = image::RgbImage::from_pixel(w, h, image::Rgb([255, 255, 255]));
    let (top, bottom) = (20.0, h as f64 - 20.0);
    let max_log = 2.5f64; // ×316 at the top
    let y_of = |v: f64| bottom - (v / max_log).clamp(0.0, 1.0) * (bottom - top);
    // Grid lines at ×1, ×10, ×100.
    for k in 0..=2 {
        let y = y_of(k as f64) as u32;
        for x in 0..w {
            img.put_pixel(x, y.min(h - 1), image::Rgb([200, 200, 200]));
        }
    }
    let group = w as f64 / scenes.len().max(1) as f64;
    let bar = group / (configs.len() as f64 + 1.0);
    for (si, sc) in scenes.iter().enumerate() {
        for (ci, cfg) in configs.iter().enumerate() {
            let Some(r) = rows.iter().find(|r| &r.scene == sc && &r.config == cfg) else {
                continue;
            };
            let x0 = (si as f64 * group + (ci as f64 + 0.5) * bar) as u32;
            let x1 = (x0 as f64 + bar * 0.85) as u32;
            let y = y_of(r.speedup_vs_reference.unwrap_or(1.0).max(1e-3).log10()) as u32;
            for x in x0..x1.min(w) {
                for yy in y..bottom as u32 {
                    img.put_pixel(x, yy, image::Rgb(palette[ci % palette.len()]));
                }
            }
            if let Some(m) = r.alpha_mae {
                let ym = y_of(m * 100.0) as u32;
                for x in x0..x1.min(w) {
                    for yy in ym.saturating_sub(2)..(ym + 2).min(h) {
                        img.put_pixel(x, yy, image::Rgb([0, 0, 0]));
                    }
                }
            }
        }
    }
    img
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::{Stats, Timings};

    fn frame(alpha: [f32; 4], grey: [u8; 4], cut: Vec<bool>) -> Output {
        Output {
            width: 2,
            height: 2,
            pixels: grey.iter().flat_map(|&g| [g, g, g, 255]).collect(),
            cloud: alpha.iter().map(|&a| [a, a, a, a]).collect(),
            cut,
            stats: Stats::default(),
            timings: Timings::default(),
        }
    }

    #[test]
    fn errors_leave_out_pixels_cut_short() {
        let r = frame([1.0, 1.0, 0.0, 0.0], [200, 200, 0, 0], Vec::new());
        // Pixel 3 differs from the reference in every measure.
        let a = frame([1.0, 1.0, 0.0, 1.0], [200, 200, 0, 200], Vec::new());
        let (mae, rmse, dice) = errors(&a, &r);
        assert!((mae - 0.25).abs() < 1e-9, "{mae}");
        assert!(rmse > 0.1 && dice < 0.9, "{rmse} {dice}");
        // The same difference where the reference's ray was cut short is not counted.
        let r_cut = frame(
            [1.0, 1.0, 0.0, 0.0],
            [200, 200, 0, 0],
            vec![false, false, false, true],
        );
        assert_eq!(errors(&a, &r_cut), (0.0, 0.0, 1.0));
    }
}
