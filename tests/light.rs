//! The full-column light (DESIGN §8) on the real GFS sample and on a made-up cloud, asserted
//! on the renderer's linear output: how dark an overcast's base is against its top, how dark
//! the ground is under it, and where a cloud's shadow falls.

mod common;

use chrono::{DateTime, Utc};
use glam::DVec3;
use stratus::render::{Camera, Gpu, Output, Preset, Renderer, Settings, View};
use stratus_ingest::cloudmap::CloudMap;
use stratus_ingest::meta::LayerKind;
use stratus_ingest::region::Region;

fn time(s: &str) -> DateTime<Utc> {
    DateTime::parse_from_rfc3339(s)
        .expect("a valid time")
        .with_timezone(&Utc)
}

/// Local noon near 25°W on the sample's valid day: the Sun about 17° up at 52.5°N.
const NOON_25W: &str = "2011-01-15T13:40:00Z";

fn luminance(c: [f32; 4]) -> f64 {
    0.2126 * c[0] as f64 + 0.7152 * c[1] as f64 + 0.0722 * c[2] as f64
}

/// Mean linear luminance of the nearly opaque (cloud) pixels, and how many there are.
fn cloud_luminance(o: &Output) -> (f64, usize) {
    let lum: Vec<f64> = o
        .cloud
        .iter()
        .filter(|c| c[3] > 0.95)
        .map(|&c| luminance(c) / c[3] as f64)
        .collect();
    (lum.iter().sum::<f64>() / lum.len().max(1) as f64, lum.len())
}

/// The column's cloud water (kg m⁻²) at a point on the 2.5° grid, decoded from the file.
fn cwat_at(lat: f64, lon_east: f64) -> f64 {
    let bytes = std::fs::read(common::sample("gfs/gfs.t12z.pgrbf120.2p5deg.grib2"))
        .expect("the real GFS sample");
    let msgs = stratus_ingest::grib::scan(&bytes).expect("scan");
    let m = msgs
        .iter()
        .find(|m| m.parameter() == (0, 6, 6))
        .expect("cwat (0.6.6) in the sample");
    let f = stratus_ingest::grib::decode_values(&bytes, m).expect("decode cwat");
    // 144×73, 90°N → 90°S, 0 → 357.5°E.
    let (i, j) = (
        (lon_east / 2.5).round() as usize,
        ((90.0 - lat) / 2.5).round() as usize,
    );
    f.values[j * 144 + i]
}

#[test]
fn an_overcast_base_is_as_dark_as_its_cloud_water_says() {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let map = common::real_map(dir.path(), "natl", "30,65,-60,10", "512x256");
    let map = CloudMap::load(&map).expect("the map");
    let mut r = Renderer::new(Gpu::new(None).expect("a wgpu adapter"), &map);
    let mut s = Settings::new(Preset::Balanced, time(NOON_25W));
    // A fixed exposure (it does not touch the linear cloud layer measured here anyway).
    s.exposure_auto = false;
    let (w, h) = (192, 108);
    let mut above = Camera::new(52.5, -25.0, 12_000.0, 180.0, -60.0);
    above.fov_deg = 30.0;
    let mut below = Camera::new(52.5, -25.0, 50.0, 180.0, 60.0);
    below.fov_deg = 30.0;
    let top = r
        .render(&View::Perspective(above), w, h, &s)
        .expect("the top");
    let base = r
        .render(&View::Perspective(below), w, h, &s)
        .expect("the base");
    let (l_top, n_top) = cloud_luminance(&top);
    let (l_base, n_base) = cloud_luminance(&base);
    // The same without the clear air in front (the aerial-perspective switch), for the record:
    // the air adds its blue light to the dark base and takes a little from the top.
    let mut bare = s.clone();
    bare.march.aerial = false;
    let top_bare = cloud_luminance(
        &r.render(&View::Perspective(above), w, h, &bare)
            .expect("top"),
    )
    .0;
    let base_bare = cloud_luminance(
        &r.render(&View::Perspective(below), w, h, &bare)
            .expect("base"),
    )
    .0;
    eprintln!(
        "without the air in front: top {top_bare:.4}, base {base_bare:.4}: base/top {:.4}",
        base_bare / top_bare
    );
    assert!(n_top > (w * h) as usize / 2 && n_base > (w * h) as usize / 2);
    let ratio = l_base / l_top;
    // The two-stream estimate (DESIGN §8): τ ≈ 1.5·LWP/(ρ_w·r_e), diffuse transmittance
    // T = 1/(1 + ¾(1 − g)τ), reflectance 1 − T; base over top ≈ T/(1 − T). Its range over
    // droplet radii 5–20 µm and g 0.8–0.9.
    let cwat = cwat_at(52.5, 335.0);
    let two_stream = |r_e_um: f64, g: f64| {
        let tau = 1.5 * cwat / (1000.0 * r_e_um * 1e-6);
        let t = 1.0 / (1.0 + 0.75 * (1.0 - g) * tau);
        t / (1.0 - t)
    };
    let (lo, hi) = (two_stream(5.0, 0.8), two_stream(20.0, 0.9));
    eprintln!(
        "cwat {cwat:.3} kg/m²; top {l_top:.4}, base {l_base:.4}: base/top {ratio:.4}; two-stream range {lo:.4}..{hi:.4}"
    );
    assert!((0.7..1.0).contains(&cwat), "cwat {cwat}");
    assert!(ratio <= 0.5, "the base is {ratio:.3} of the top");
    assert!(
        (lo..=hi).contains(&ratio),
        "base/top {ratio:.4} outside the two-stream range {lo:.4}..{hi:.4}"
    );
}

/// Linear radiance × exposure of a tone-mapped sRGB byte: the present stage's curves undone
/// (sRGB, then Narkowicz's ACES fit, which is a ratio of quadratics).
fn untone(byte: u8) -> f64 {
    let c = byte as f64 / 255.0;
    let y = if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    };
    let (a, b, k) = (2.51 - 2.43 * y, 0.03 - 0.59 * y, -0.14 * y);
    (-b + (b * b - 4.0 * a * k).sqrt()) / (2.0 * a)
}

fn pixel_luminance(o: &Output, i: usize) -> f64 {
    let p = &o.pixels[i * 4..i * 4 + 3];
    0.2126 * untone(p[0]) + 0.7152 * untone(p[1]) + 0.0722 * untone(p[2])
}

fn region(s: f64, n: f64, w: f64, e: f64) -> Region {
    Region {
        south: s,
        north: n,
        west: w,
        east: e,
    }
}

/// A middle layer 4.0–4.6 km over a 3° square at 45°N 10°E, coverage from `f(lat, lon)`.
fn made_up(f: impl Fn(f64, f64) -> f64 + Sync) -> CloudMap {
    CloudMap::from_fn(
        region(43.5, 46.5, 8.5, 11.5),
        240,
        240,
        &[(LayerKind::Middle, 4000.0, 4600.0)],
        time("2024-06-21T12:00:00Z"),
        |la, lo| [0.0, f(la, lo), 0.0],
    )
}

/// Sun 45° up in the east, a fixed exposure 2 stops over daylight.
fn sun_east_settings() -> Settings {
    let mut s = Settings::new(Preset::Balanced, time("2024-06-21T12:00:00Z"));
    let el = 45f64.to_radians();
    s.sun_override = Some(DVec3::new(el.cos(), 0.0, el.sin()));
    s.exposure_auto = false;
    s.exposure_ev = 2.0;
    s
}

#[test]
fn the_ground_under_an_overcast_is_darker_than_clear_ground_nearby() {
    // Overcast west of 10°E, clear east of it; two cameras 500 m up looking down at the ground,
    // 40 km inside each side.
    let map = made_up(|_, lo| if lo < 10.0 { 1.0 } else { 0.0 });
    let mut r = Renderer::new(Gpu::new(None).expect("a wgpu adapter"), &map);
    let s = sun_east_settings();
    let mean_ground = |lon: f64, r: &mut Renderer| {
        let mut cam = Camera::new(45.0, lon, 500.0, 0.0, -40.0);
        cam.fov_deg = 20.0;
        let o = r
            .render(&View::Perspective(cam), 96, 64, &s)
            .expect("a frame");
        let ground: Vec<f64> = (0..o.cloud.len())
            .filter(|&i| o.cloud[i][3] < 0.01)
            .map(|i| pixel_luminance(&o, i))
            .collect();
        assert!(ground.len() > o.cloud.len() / 2, "the ground is hidden");
        ground.iter().sum::<f64>() / ground.len() as f64
    };
    let under = mean_ground(9.5, &mut r);
    let clear = mean_ground(10.5, &mut r);
    eprintln!(
        "ground under the overcast {under:.5}, clear {clear:.5}: {:.1}×",
        clear / under
    );
    assert!(clear >= 2.0 * under, "clear {clear} vs under {under}");
}

#[test]
fn a_cloud_shadow_falls_where_geometry_puts_it() {
    // One round cloud 15 km across at 45°N 10°E, 4.0–4.6 km up; the Sun 45° up in the east, so
    // the shadow lies height × cot(45°) ≈ 4.3 km west of it. Seen straight down from 120 km.
    let (lat0, lon0): (f64, f64) = (45.0, 10.0);
    let map = made_up(|la, lo| {
        let dx = (lo - lon0) * lat0.to_radians().cos();
        let d = ((la - lat0).powi(2) + dx * dx).sqrt();
        if d < 0.07 {
            1.0
        } else {
            0.0
        }
    });
    let mut r = Renderer::new(Gpu::new(None).expect("a wgpu adapter"), &map);
    // The geometry of the shadow on the ground, without the air in front of it: seen through
    // the whole atmosphere the clear air's own light (the aerial-perspective table) in front of
    // dark ground (albedo 0.08) lowers the shadow's contrast.
    let mut s = sun_east_settings();
    s.march.aerial = false;
    let mut cam = Camera::new(lat0, lon0, 120_000.0, 0.0, -90.0);
    cam.fov_deg = 30.0;
    let (w, h) = (240u32, 240u32);
    let o = r
        .render(&View::Perspective(cam), w, h, &s)
        .expect("a frame");
    let centroid = |pick: &dyn Fn(usize) -> bool| {
        let (mut sx, mut sy, mut n) = (0.0, 0.0, 0.0);
        for i in (0..o.cloud.len()).filter(|&i| pick(i)) {
            sx += (i % w as usize) as f64 + 0.5;
            sy += (i / w as usize) as f64 + 0.5;
            n += 1.0;
        }
        assert!(n > 20.0, "too few pixels ({n})");
        (sx / n, sy / n)
    };
    if let Ok(p) = std::env::var("STRATUS_TEST_PNG") {
        o.to_image().save(p).expect("save");
    }
    // The shadow's far (west) edge against the cloud's: the cloud hides the rest of its
    // shadow from above. Edges at half-way (alpha 0.5; ground half-way between the shadow's
    // darkest and clear ground), over the rows through the cloud's middle.
    let cloud = centroid(&|i| o.cloud[i][3] > 0.5);
    let mut ground: Vec<f64> = (0..o.cloud.len())
        .filter(|&i| o.cloud[i][3] < 0.01)
        .map(|i| pixel_luminance(&o, i))
        .collect();
    ground.sort_by(f64::total_cmp);
    let (darkest, clear) = (ground[0], ground[ground.len() / 2]);
    assert!(darkest < 0.5 * clear, "no shadow: {darkest} vs {clear}");
    let half = 0.5 * (darkest + clear);
    let (mut sum, mut n) = (0.0, 0.0);
    let row0 = cloud.1 as usize;
    for y in row0 - 8..=row0 + 8 {
        let at = |x: usize| y * w as usize + x;
        let Some(cx) = (0..w as usize).find(|&x| o.cloud[at(x)][3] > 0.5) else {
            continue;
        };
        let Some(sx) = (0..cx).find(|&x| pixel_luminance(&o, at(x)) < half) else {
            continue;
        };
        sum += sx as f64 - cx as f64;
        n += 1.0;
    }
    assert!(n >= 8.0, "the shadow's edge was found on {n} rows");
    let got = (sum / n, 0.0);
    // Where geometry puts them: the cloud's middle and its shadow, projected by the camera.
    let el = 45f64.to_radians();
    let mid_h = 4300.0;
    let offset_m = mid_h / el.tan();
    let dlon = -offset_m / (6_371_000.0 * lat0.to_radians().cos()) * 180.0 / std::f64::consts::PI;
    let at = |lat: f64, lon: f64, alt: f64| {
        cam.project(stratus::render::camera::ecef(lat, lon, alt), w, h)
            .expect("in view")
    };
    let want_cloud = at(lat0, lon0, mid_h);
    let want_shadow = at(lat0, lon0 + dlon, 0.0);
    let want = (want_shadow.0 - want_cloud.0, want_shadow.1 - want_cloud.1);
    assert!(
        want.1.abs() < 0.5,
        "the Sun is east: the shadow moves along a row"
    );
    let err = (got.0 - want.0).abs();
    eprintln!(
        "shadow offset {got:.1?} px, geometry {want:.1?} px: off by {err:.2} px ({:.2} % of the width)",
        100.0 * err / w as f64
    );
    assert!(want.0.abs() > 5.0, "the test's offset is too small to see");
    assert!(err <= 0.02 * w as f64);
}

/// `stratus bench`'s "Sun moving" row times the window's frames: each a slice of the new
/// volume, not a whole one (which a single picture makes, and which the row timed from
/// def727e until the twenty-fifth session of issue 30: 300–400 ms a frame more).
#[test]
fn the_benchs_moving_sun_frames_make_the_light_a_slice_a_frame() {
    let map = made_up(|la, lo| {
        if (la - 45.0).abs() < 0.1 && (lo - 10.0).abs() < 0.1 {
            1.0
        } else {
            0.0
        }
    });
    let view = View::Perspective(Camera::new(45.0, 10.0, 120_000.0, 0.0, -90.0));
    // The row's own settings, a single picture's, as `bench::run` passes them: the row's
    // timing function must make its frames as the window does (lost once, in a5fc7b3).
    let mut s = sun_east_settings();
    s.sun_override = None;
    let mut r = Renderer::new(Gpu::new(None).expect("a wgpu adapter"), &map);
    let slices = stratus::render::shadow::SLICES;
    stratus::bench::timed_moving(&mut r, &view, 64, 64, &s, slices as usize - 1)
        .expect("the row's frames");
    assert_eq!(
        r.light_builds().0,
        1,
        "only the first of {slices} frames made a whole volume"
    );
}

#[test]
fn a_moving_sun_remakes_the_light_over_frames_and_shows_it_whole() {
    // The round cloud of the shadow test, seen from 120 km; the Sun then sinks from 45° to 30°.
    // Frames of a sequence, as the window's and `flight`'s (an exposure that adapts over
    // frames, though fixed here): a single picture makes its light whole at once
    // (tests/render.rs `a_picture_is_lit_by_its_own_sun_after_another`), and so does a
    // single picture after this sequence, below.
    let map = made_up(|la, lo| {
        let d = ((la - 45.0).powi(2) + ((lo - 10.0) * 0.707).powi(2)).sqrt();
        if d < 0.07 {
            1.0
        } else {
            0.0
        }
    });
    let mut cam = Camera::new(45.0, 10.0, 120_000.0, 0.0, -90.0);
    cam.fov_deg = 30.0;
    let view = View::Perspective(cam);
    let mut s = sun_east_settings();
    s.exposure_rate = 0.5;
    let mut r = Renderer::new(Gpu::new(None).expect("a wgpu adapter"), &map);
    r.render(&view, 96, 96, &s).expect("a frame");
    let (made, _) = r.light_builds();
    let el = 30f64.to_radians();
    s.sun_override = Some(DVec3::new(el.cos(), 0.0, el.sin()));
    let slices = stratus::render::shadow::SLICES;
    for k in 1..slices {
        r.render(&view, 96, 96, &s).expect("a frame");
        assert_eq!(
            r.light_builds().0,
            made,
            "frame {k}: the new volume is shown before it is whole"
        );
    }
    let sliced = r.render(&view, 96, 96, &s).expect("a frame");
    assert_eq!(r.light_builds().0, made + 1, "made in {slices} frames");
    // Made a slice a frame, it is the volume made whole at once.
    let mut fresh = Renderer::new(Gpu::new(None).expect("a wgpu adapter"), &map);
    let whole = fresh.render(&view, 96, 96, &s).expect("a frame");
    assert!(
        sliced.cloud == whole.cloud && sliced.pixels == whole.pixels,
        "the sliced volume differs from the whole one"
    );
    // And the shadow moved with the Sun: the frame differs from the first Sun's.
    let mut before = sun_east_settings();
    before.sun_override = Some(DVec3::new(1.0, 0.0, 1.0).normalize());
    let built = fresh.light_builds().0;
    let old = fresh.render(&view, 96, 96, &before).expect("a frame");
    assert!(old.pixels != whole.pixels);
    // A single picture (`before`'s exposure rate is 1) made its light whole at once.
    assert_eq!(
        fresh.light_builds().0,
        built + 1,
        "a single picture's light"
    );
}
