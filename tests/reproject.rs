//! Temporal reprojection on a real adapter (lavapipe in CI): flying past a cloud's edge leaves
//! no ghost trail, the reprojected frames stay close to a full march at the same cameras, and
//! a teleport or a new map starts the history afresh. Two renderers: one reprojects, one
//! marches every pixel with the same settings and jitter.

mod common;

use common::deck::{fast_settings, gpu, middle_deck};
use stratus::render::camera::Camera;
use stratus::render::{Output, Renderer, Reprojection, View};
use stratus_ingest::cloudmap::CloudMap;

/// A middle deck 3–5 km west of 2°E, clear air east of it: one sharp edge.
fn edge_map() -> CloudMap {
    middle_deck(|_, lo| if lo < 2.0 { 1.0 } else { 0.0 })
}

fn renderers(map: &CloudMap) -> (Renderer, Renderer) {
    (Renderer::new(gpu(), map), Renderer::new(gpu(), map))
}

const SIZE: (u32, u32) = (160, 96);

/// The frame reprojected by `a` and marched whole by `b` at one camera.
fn pair(a: &mut Renderer, b: &mut Renderer, cam: Camera, frame: u32) -> (Output, Output) {
    let mut s = fast_settings();
    s.frame_index = frame;
    s.reprojection = Reprojection::On { full_reset: false };
    let view = View::Perspective(cam);
    let rep = a
        .render(&view, SIZE.0, SIZE.1, &s)
        .expect("reprojected frame");
    s.reprojection = Reprojection::Off;
    let full = b.render(&view, SIZE.0, SIZE.1, &s).expect("full frame");
    (rep, full)
}

fn alpha_mae(a: &Output, b: &Output) -> f64 {
    a.cloud
        .iter()
        .zip(&b.cloud)
        .map(|(x, y)| (x[3] - y[3]).abs() as f64)
        .sum::<f64>()
        / a.cloud.len() as f64
}

/// Flying east over the deck past its edge at 1.2 km a frame while turning 1° a frame: wherever
/// the full march says the air is clear around a pixel (over a subset cell either side, so no
/// fresh sample this frame can hold cloud for it), the reprojected frame may keep cloud there
/// from its history for at most a few frames.
#[test]
fn flying_past_an_edge_leaves_no_ghost_trail() {
    let map = edge_map();
    let (mut a, mut b) = renderers(&map);
    let n = (SIZE.0 * SIZE.1) as usize;
    let mut ghost_run = vec![0u32; n];
    let mut worst_run = 0;
    let mut cleared = 0usize;
    let mut was_cloud = vec![false; n];
    let mut maes = Vec::new();
    for i in 0..24u32 {
        // 1.2 km a frame east (0.0108° of longitude at 1°N).
        let lon = 1.55 + 0.0108 * i as f64;
        let cam = Camera::new(1.0, lon, 8000.0, 90.0 + i as f64, -35.0);
        let (rep, full) = pair(&mut a, &mut b, cam, i);
        if i == 0 {
            assert_eq!(a.last_reset(), Some("first frame"));
        } else {
            assert_eq!(a.last_reset(), None, "frame {i}: the history fits");
            maes.push(alpha_mae(&rep, &full));
        }
        let clear = clear_around(&full, 4);
        for p in 0..n {
            let (r, f) = (rep.cloud[p][3], full.cloud[p][3]);
            if f < 0.05 && was_cloud[p] {
                cleared += 1;
                was_cloud[p] = false;
            }
            if f > 0.5 {
                was_cloud[p] = true;
            }
            if clear[p] && r > 0.2 {
                ghost_run[p] += 1;
                worst_run = worst_run.max(ghost_run[p]);
            } else {
                ghost_run[p] = 0;
            }
        }
    }
    // The flight must really take pixels from cloud to clear air, or the check proves nothing.
    assert!(
        cleared > 200,
        "only {cleared} pixels went from cloud to clear"
    );
    assert!(
        worst_run <= 3,
        "a pixel kept history cloud over clear air for {worst_run} frames"
    );
    let mean = maes.iter().sum::<f64>() / maes.len() as f64;
    let max = maes.iter().copied().fold(0.0, f64::max);
    eprintln!("alpha MAE against the full march: mean {mean:.4}, max {max:.4}; cleared {cleared}, worst ghost run {worst_run}");
    assert!(
        max < 0.03,
        "reprojected frames drift from the full march: {maes:?}"
    );
}

/// A still camera while the scene's time jumps 10 min a frame (a time-lapse through `flight`,
/// which marches every pixel when the history does not fit): no pixel of the last frame shows
/// this one's weather, so each frame is a full march, not this frame's subset enlarged over a
/// lattice of other weather (the stair-stepped washboard the time-lapse once drew).
#[test]
fn a_time_lapse_from_a_still_camera_marches_every_frame_whole() {
    let map = edge_map();
    let (mut a, mut b) = renderers(&map);
    let cam = Camera::new(1.0, 1.7, 7000.0, 80.0, -25.0);
    let start = fast_settings().time;
    for i in 0..4u32 {
        let mut s = fast_settings();
        s.frame_index = i;
        s.time = start + chrono::Duration::minutes(10 * i64::from(i));
        s.reprojection = Reprojection::On { full_reset: true };
        let view = View::Perspective(cam);
        let rep = a
            .render(&view, SIZE.0, SIZE.1, &s)
            .expect("time-lapse frame");
        let reason = a.last_reset();
        s.reprojection = Reprojection::Off;
        let full = b.render(&view, SIZE.0, SIZE.1, &s).expect("full frame");
        let mae = alpha_mae(&rep, &full);
        let want = if i == 0 { "first frame" } else { "time" };
        assert_eq!(reason, Some(want), "frame {i}");
        assert!(
            mae < 1e-4,
            "frame {i}: alpha MAE {mae} against the full march"
        );
    }
}

/// Pixels whose every neighbour within `r` pixels is clear (opacity < 0.05) in `o`.
fn clear_around(o: &Output, r: i64) -> Vec<bool> {
    let (w, h) = (o.width as i64, o.height as i64);
    let mut out = vec![false; (w * h) as usize];
    for y in 0..h {
        for x in 0..w {
            out[(y * w + x) as usize] = (-r..=r).all(|dy| {
                (-r..=r).all(|dx| {
                    let (xx, yy) = ((x + dx).clamp(0, w - 1), (y + dy).clamp(0, h - 1));
                    o.cloud[(yy * w + xx) as usize][3] < 0.05
                })
            });
        }
    }
    out
}

/// A still camera: every pixel is marched once in 16 frames, and the history holds them, so
/// the reprojected frame comes to match the full march as closely as two full marches a frame
/// apart do (the jitter changes each frame); a teleport and a new map start afresh.
#[test]
fn history_fills_at_rest_and_restarts_after_a_jump() {
    let map = edge_map();
    let (mut a, mut b) = renderers(&map);
    let cam = Camera::new(1.0, 1.7, 7000.0, 80.0, -25.0);
    let (first, full0) = pair(&mut a, &mut b, cam, 0);
    let upsampled = alpha_mae(&first, &full0);
    let mut frames = vec![(first, full0)];
    for i in 1..17 {
        frames.push(pair(&mut a, &mut b, cam, i));
    }
    let settled = alpha_mae(&frames[16].0, &frames[16].1);
    let floor = alpha_mae(&frames[16].1, &frames[15].1);
    eprintln!(
        "still view: alpha MAE {upsampled:.4} on the first frame (the subset upsampled), {settled:.4} after 16; two full marches a frame apart differ by {floor:.4}"
    );
    assert!(
        settled <= 1.5 * floor + 0.002,
        "a still view did not converge: {settled} against a floor of {floor}"
    );
    assert!(
        settled < upsampled,
        "the history adds nothing: {settled} vs {upsampled}"
    );
    // The first frame is the fresh subset enlarged bilinearly: 0.0146 (lavapipe). Weighted by
    // opacity and distance against the nearest fresh sample it was 0.0192, n-pixel blocks
    // along every edge (docs/footprint.md, "The enlarged march, bilinear").
    assert!(
        upsampled < 0.017,
        "the fresh subset's fill errs by alpha MAE {upsampled:.4} on the first frame"
    );
    // 50 km away in one frame: a teleport.
    let far = Camera::new(1.45, 1.7, 7000.0, 80.0, -25.0);
    let _ = pair(&mut a, &mut b, far, 17);
    assert_eq!(a.last_reset(), Some("teleport"));
    let _ = pair(&mut a, &mut b, far, 18);
    assert_eq!(a.last_reset(), None);
    a.set_map(&map);
    let _ = pair(&mut a, &mut b, far, 19);
    assert_eq!(a.last_reset(), Some("map"));
}
