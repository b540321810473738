//! `stratus render` (and `flight`) at the extremes issue 28 found, through the binary: the sky
//! before dawn under `--exposure auto` (it was drawn as saturated colour bands), and a series of
//! 1 000 steps (every step map was decoded to open it).

mod common;
use common::{sample, stratus};

use std::path::{Path, PathBuf};

/// The real 2015-09-12 18 UTC +0/+6 h series over the Southern Ocean south of New Zealand
/// (where 18 UTC is before dawn), `size` px, in `dir/NAME.json`.
fn southern_series(dir: &Path, name: &str, size: &str) -> PathBuf {
    let out = dir.join(format!("{name}.png"));
    let o = stratus(&[
        "ingest",
        sample("gfs-series/gfs.t18z.pgrb2.2p50.f000")
            .to_str()
            .unwrap(),
        sample("gfs-series/gfs.t18z.pgrb2.2p50.f006")
            .to_str()
            .unwrap(),
        "--region",
        "-70,-30,130,190",
        "--size",
        size,
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    dir.join(format!("{name}.json"))
}

fn run_ok(args: &[&str]) -> String {
    let o = stratus(args);
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// Render the issue's camera (50°S 160°E, 5 000 m, looking east 5° down) at `time`, `size`.
fn render_east(map: &Path, time: &str, size: &str, out: &Path, extra: &[&str]) -> String {
    let mut a = vec![
        "render",
        "--map",
        map.to_str().unwrap(),
        "--camera",
        "-50,160,5000",
        "--heading",
        "90",
        "--pitch",
        "-5",
        "--time",
        time,
        "--size",
        size,
        "--preset",
        "fast",
        "--out",
        out.to_str().unwrap(),
    ];
    a.extend_from_slice(extra);
    run_ok(&a)
}

fn rgb(path: &Path) -> image::RgbImage {
    image::open(path).unwrap().to_rgb8()
}

fn luma(p: &image::Rgb<u8>) -> f64 {
    0.2126 * p[0] as f64 + 0.7152 * p[1] as f64 + 0.0722 * p[2] as f64
}

/// Pixels with a channel at the top of its range: the tone curve clipped them, the way the
/// pre-dawn sky was drawn as flat blue, magenta, white and yellow bands.
fn clipped(img: &image::RgbImage) -> usize {
    img.pixels()
        .filter(|p| p.0.iter().any(|&c| c >= 250))
        .count()
}

/// Each row's mean luma, top to bottom.
fn row_luma(img: &image::RgbImage) -> Vec<f64> {
    (0..img.height())
        .map(|y| {
            (0..img.width())
                .map(|x| luma(img.get_pixel(x, y)))
                .sum::<f64>()
                / img.width() as f64
        })
        .collect()
}

/// Before dawn the sky is a dark gradient brightening down to a glow on the eastern horizon:
/// nothing clipped, the glow seen (not a black frame), and every row from the top down to the
/// glow's at least as bright as the one above it (the bands were bright, then dark, then bright
/// again).
fn assert_pre_dawn(img: &image::RgbImage, what: &str) {
    assert_eq!(clipped(img), 0, "{what}: clipped pixels");
    let rows = row_luma(img);
    let (glow_row, glow) = rows
        .iter()
        .copied()
        .enumerate()
        .fold((0, f64::MIN), |a, (i, l)| if l > a.1 { (i, l) } else { a });
    assert!(
        glow >= 8.0,
        "{what}: no glow on the horizon (rows {rows:.1?})"
    );
    assert!(
        glow <= 160.0,
        "{what}: the horizon glows like day (rows {rows:.1?})"
    );
    for y in 1..=glow_row {
        assert!(
            rows[y] + 1.0 >= rows[y - 1],
            "{what}: row {y} darker than the row above it on the way down to the glow (rows {rows:.1?})"
        );
    }
}

#[test]
fn the_sky_before_dawn_is_a_dark_gradient_not_saturated_bands() {
    let dir = tempfile::tempdir().unwrap();
    let series = southern_series(dir.path(), "south", "128x128");
    // The issue's picture (Sun 15° down), and where the old twilight ramp ended (12.5° down,
    // where the glow clipped most, with or without a Moon).
    for (time, what) in [
        ("2015-09-12T18:00:00Z", "Sun 15° down"),
        ("2015-09-12T18:18:00Z", "Sun 12.5° down"),
    ] {
        let out = dir.path().join(format!("{}.png", &time[11..13]));
        render_east(&series, time, "64x36", &out, &[]);
        assert_pre_dawn(&rgb(&out), what);
    }
    // Sun just under the horizon (2.8° down): twilight, nothing clipped.
    let out = dir.path().join("dawn.png");
    render_east(&series, "2015-09-12T19:20:00Z", "64x36", &out, &[]);
    assert_eq!(clipped(&rgb(&out)), 0, "Sun 2.8° down: clipped pixels");
    // Deep night (Sun 43° down, no Moon): dark, and nothing clipped. A plain step map, so the
    // time only moves the Sun.
    let out = dir.path().join("night.png");
    let step = dir.path().join("south-f000.json");
    render_east(&step, "2015-09-12T14:00:00Z", "64x36", &out, &[]);
    let night = rgb(&out);
    assert_eq!(clipped(&night), 0, "deep night: clipped pixels");
    let mean = night.pixels().map(luma).sum::<f64>() / night.pixels().len() as f64;
    assert!(mean < 10.0, "deep night is not dark: mean luma {mean}");
}

#[test]
fn a_flight_before_dawn_adapts_without_saturating() {
    // `flight` (as the window does) adapts its exposure over frames with the same stages.
    let dir = tempfile::tempdir().unwrap();
    let series = southern_series(dir.path(), "south", "128x128");
    let path = dir.path().join("path.json");
    let key = |t: f64, lon: f64| {
        format!(
            r#"{{"t": {t}, "lat": -50.0, "lon": {lon}, "alt_m": 5000.0, "heading": 90.0, "pitch": -5.0, "time": "2015-09-12T18:00:00Z"}}"#
        )
    };
    std::fs::write(
        &path,
        format!(
            r#"{{"fov_deg": 60.0, "keys": [{}, {}]}}"#,
            key(0.0, 160.0),
            key(1.0, 160.05)
        ),
    )
    .unwrap();
    let frames = dir.path().join("frames");
    run_ok(&[
        "flight",
        "--map",
        series.to_str().unwrap(),
        "--path",
        path.to_str().unwrap(),
        "--out",
        frames.to_str().unwrap(),
        "--size",
        "48x27",
        "--fps",
        "3",
        "--preset",
        "fast",
    ]);
    let mut pngs: Vec<PathBuf> = std::fs::read_dir(&frames)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "png"))
        .collect();
    pngs.sort();
    assert!(pngs.len() >= 3, "{pngs:?}");
    for p in &pngs {
        assert_pre_dawn(&rgb(p), &p.display().to_string());
    }
}

/// The `render --timings` line "series: D of N step maps decoded": D.
fn decoded(stdout: &str) -> usize {
    let line = stdout
        .lines()
        .find(|l| l.starts_with("series: "))
        .unwrap_or_else(|| panic!("no series line in {stdout}"));
    line["series: ".len()..]
        .split(' ')
        .next()
        .and_then(|d| d.parse().ok())
        .unwrap_or_else(|| panic!("{line}"))
}

#[test]
fn a_long_series_costs_a_frame_the_two_steps_around_its_time() {
    let dir = tempfile::tempdir().unwrap();
    let real = southern_series(dir.path(), "south", "32x32");
    let long = common::series::repeated(&real, "long", 1000, 1.0, true);
    let out = |name: &str| dir.path().join(format!("{name}.png"));
    let timed = ["--timings"];

    // The 2-step series and the 1 000-step one, late in it (the drift integrates the winds of
    // the 900 steps before): two step maps decoded either way.
    let two = render_east(&real, "2015-09-12T21:00:00Z", "32x18", &out("two"), &timed);
    assert_eq!(decoded(&two), 2, "{two}");
    let late = "2015-10-20T06:30:00Z"; // +900.5 h
    let d = decoded(&render_east(&long, late, "32x18", &out("long"), &timed));
    assert_eq!(
        d, 2,
        "a 1000-step series decoded {d} step maps for one frame"
    );

    // A series sidecar written before the means were recorded still renders, the same picture:
    // the means of the steps up to the moment come from their maps (decoded for it).
    let old = common::series::repeated(&real, "old", 1000, 1.0, false);
    let early = "2015-09-12T20:30:00Z"; // +2.5 h: steps 2 and 3 around it
    let with = render_east(&long, early, "32x18", &out("with"), &timed);
    let without = render_east(&old, early, "32x18", &out("without"), &timed);
    assert_eq!(decoded(&with), 2, "{with}");
    assert_eq!(decoded(&without), 4, "{without}");
    assert_eq!(
        rgb(&out("with")).into_raw(),
        rgb(&out("without")).into_raw(),
        "recorded and decoded mean winds drift the noise alike"
    );
}
