//! Temporal reprojection's trade, measured the way the bench measures the others: along a
//! scripted flight, each reprojected frame (render::reproject, the window's policy) against a
//! frame that marches every pixel at the same camera, time and jitter: alpha MAE and linear-RGB
//! RMSE per frame, and after a teleport the frames until the error is back under `balanced`'s
//! goal.

use chrono::{DateTime, Utc};
use serde::Serialize;
use stratus_ingest::cloudmap::CloudMap;

use crate::flight::FlightPath;
use crate::render::{Camera, Gpu, RenderError, Renderer, Reprojection, Settings, View};

/// `balanced`'s accuracy goal (alpha MAE against the full march), which the frames after a
/// teleport are counted against.
pub const GOAL_ALPHA_MAE: f64 = 0.01;

/// One frame of one flight.
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    pub flight: String,
    pub frame: usize,
    pub alpha_mae: f64,
    pub rgb_rmse: f64,
    /// Why the reprojected frame did not use its history (a teleport, the first frame).
    pub reset: Option<&'static str>,
    /// Wall time of the reprojected frame and of the full march (ms).
    pub reprojected_ms: f64,
    pub full_ms: f64,
}

/// A flight: its name and one camera per frame.
pub struct Flight {
    pub name: String,
    pub cameras: Vec<Camera>,
}

/// Cameras along `path` from `t0` for `frames` frames at `fps`.
pub fn along(path: &FlightPath, t0: f64, frames: usize, fps: f64) -> Vec<Camera> {
    (0..frames)
        .map(|i| path.at(t0 + i as f64 / fps).0)
        .collect()
}

/// Fly each flight with a reprojecting renderer and a full-marching one, frame by frame.
pub fn measure(
    gpu: [Gpu; 2],
    map: &CloudMap,
    settings: &Settings,
    flights: &[Flight],
    (width, height): (u32, u32),
    progress: &dyn Fn(&str),
) -> Result<Vec<Row>, RenderError> {
    let [ga, gb] = gpu;
    let mut rep = Renderer::new(ga, map);
    let mut full = Renderer::new(gb, map);
    let mut rows = Vec::new();
    for f in flights {
        let mut s = settings.clone();
        for (i, cam) in f.cameras.iter().enumerate() {
            progress(&f.name);
            s.frame_index = i as u32;
            s.reprojection = Reprojection::On { full_reset: false };
            let view = View::Perspective(*cam);
            let a = rep.render(&view, width, height, &s)?;
            let reset = rep.last_reset();
            s.reprojection = Reprojection::Off;
            let b = full.render(&view, width, height, &s)?;
            let (mae, rmse, _) = crate::bench::errors(&a, &b);
            rows.push(Row {
                flight: f.name.clone(),
                frame: i,
                alpha_mae: mae,
                rgb_rmse: rmse,
                reset,
                reprojected_ms: a.timings.wall_ms,
                full_ms: b.timings.wall_ms,
            });
        }
    }
    Ok(rows)
}

/// Frames after the last reset of `flight` until its alpha MAE is at or under the goal (0: the
/// reset frame itself meets it); `None` when it never does.
pub fn frames_to_recover(rows: &[Row], flight: &str) -> Option<usize> {
    let f: Vec<&Row> = rows.iter().filter(|r| r.flight == flight).collect();
    let last_reset = f.iter().rposition(|r| r.reset.is_some())?;
    f[last_reset..]
        .iter()
        .position(|r| r.alpha_mae <= GOAL_ALPHA_MAE)
}

/// Per flight: mean and largest alpha MAE and RGB RMSE over the frames after the first (the
/// first has no history), and the frames to recover after its last reset.
pub fn table(rows: &[Row]) -> String {
    let mut names: Vec<&str> = rows.iter().map(|r| r.flight.as_str()).collect();
    names.dedup();
    let mut s = String::from(
        "| flight | frames | alpha MAE mean | alpha MAE max | RGB RMSE mean | RGB RMSE max | reprojected ms (median) | full ms (median) | frames to goal after the last reset |\n| --- | --- | --- | --- | --- | --- | --- | --- | --- |\n",
    );
    for n in names {
        let f: Vec<&Row> = rows.iter().filter(|r| r.flight == n).skip(1).collect();
        let mean =
            |v: &dyn Fn(&Row) -> f64| f.iter().map(|r| v(r)).sum::<f64>() / f.len().max(1) as f64;
        let max = |v: &dyn Fn(&Row) -> f64| f.iter().map(|r| v(r)).fold(0.0, f64::max);
        let median = |v: &dyn Fn(&Row) -> f64| {
            let mut x: Vec<f64> = f.iter().map(|r| v(r)).collect();
            x.sort_by(f64::total_cmp);
            x.get(x.len() / 2).copied().unwrap_or(0.0)
        };
        let recover = if rows
            .iter()
            .filter(|r| r.flight == n)
            .skip(1)
            .any(|r| r.reset.is_some())
        {
            frames_to_recover(rows, n).map_or("never".into(), |k| k.to_string())
        } else {
            "no reset".to_string()
        };
        s += &format!(
            "| {n} | {} | {:.4} | {:.4} | {:.4} | {:.4} | {:.0} | {:.0} | {recover} |\n",
            f.len() + 1,
            mean(&|r| r.alpha_mae),
            max(&|r| r.alpha_mae),
            mean(&|r| r.rgb_rmse),
            max(&|r| r.rgb_rmse),
            median(&|r| r.reprojected_ms),
            median(&|r| r.full_ms),
        );
    }
    s
}

/// A line chart (PNG): alpha MAE against frame number, one colour per flight, the goal as a
/// grey line; the y axis runs from 0 to `y_max`.
pub fn chart(rows: &[Row], y_max: f64) -> image::RgbImage {
    let palette = [[66, 133, 244], [234, 67, 53], [52, 168, 83], [251, 188, 5]];
    let (w, h) = (900u32, 320u32);
    let mut img = image::RgbImage::from_pixel(w, h, image::Rgb([255, 255, 255]));
    let frames = rows.iter().map(|r| r.frame).max().unwrap_or(1).max(1) as f64;
    let (left, right, top, bottom) = (10.0, w as f64 - 10.0, 10.0, h as f64 - 10.0);
    let x_of = |f: f64| left + f / frames * (right - left);
    let y_of = |v: f64| bottom - (v / y_max).clamp(0.0, 1.0) * (bottom - top);
    let mut put = |x: f64, y: f64, c: [u8; 3]| {
        let (x, y) = (x.round() as i64, y.round() as i64);
        for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            let (px, py) = (x + dx, y + dy);
            if px >= 0 && py >= 0 && (px as u32) < w && (py as u32) < h {
                img.put_pixel(px as u32, py as u32, image::Rgb(c));
            }
        }
    };
    let goal = y_of(GOAL_ALPHA_MAE);
    for x in 0..w {
        put(x as f64, goal, [190, 190, 190]);
    }
    let mut names: Vec<&str> = rows.iter().map(|r| r.flight.as_str()).collect();
    names.dedup();
    for (k, n) in names.iter().enumerate() {
        let c = palette[k % palette.len()];
        let f: Vec<&Row> = rows.iter().filter(|r| r.flight == *n).collect();
        for pair in f.windows(2) {
            let (a, b) = (pair[0], pair[1]);
            let steps = 40;
            for s in 0..=steps {
                let t = s as f64 / steps as f64;
                let x = x_of(a.frame as f64 + t * (b.frame - a.frame) as f64);
                let y = y_of(a.alpha_mae + t * (b.alpha_mae - a.alpha_mae));
                put(x, y, c);
            }
        }
    }
    img
}

/// The scene time the path keys at its start (every flight is flown at it).
pub fn path_time(path: &FlightPath) -> Option<DateTime<Utc>> {
    path.at(0.0).1
}
