//! Numerical stability at the extremes (the stability matrix): every case must give finite
//! output — the cloud layer, the background it is laid over, the exposure and their composite —
//! and its documented behaviour. Radiance is checked against the most light can bring in:
//! Sun (≤ 1 per channel) × SUN_I 20 × (1 + ½ + ¼ octaves) × peak phase (< 1) × powder (≤ 2) + sky (< 1).

use std::sync::{Mutex, MutexGuard, OnceLock};

use chrono::{DateTime, Utc};
use glam::DVec3;
use stratus::render::{Camera, Gpu, Output, Preset, Renderer, Settings, View};
use stratus_ingest::cloudmap::CloudMap;
use stratus_ingest::meta::LayerKind;
use stratus_ingest::pipeline::{coverage, validate_rh_cr};
use stratus_ingest::region::Region;

const T: &str = "2024-03-20T12:00:00Z";
const MAX_RADIANCE: f32 = 20.0 * 1.75 * 1.0 * 2.0 + 1.0;

fn world(cover: f64) -> CloudMap {
    let r = Region {
        south: -90.0,
        north: 90.0,
        west: -180.0,
        east: 180.0,
    };
    CloudMap::from_fn(
        r,
        128,
        64,
        &[
            (LayerKind::Low, 1000.0, 3000.0),
            (LayerKind::High, 7000.0, 9000.0),
        ],
        t(),
        |_, _| [cover, 0.0, cover],
    )
}

fn t() -> DateTime<Utc> {
    DateTime::parse_from_rfc3339(T)
        .expect("a valid time")
        .with_timezone(&Utc)
}

fn renderer() -> MutexGuard<'static, Renderer> {
    static R: OnceLock<Mutex<Renderer>> = OnceLock::new();
    R.get_or_init(|| Mutex::new(Renderer::new(Gpu::new(None).expect("adapter"), &world(0.0))))
        .lock()
        .unwrap_or_else(|e| e.into_inner())
}

fn settings() -> Settings {
    Settings::new(
        Preset::Fast,
        DateTime::parse_from_rfc3339(T).unwrap().with_timezone(&Utc),
    )
}

fn check(o: &Output, case: &str) {
    for c in &o.cloud {
        assert!(c.iter().all(|v| v.is_finite()), "{case}: non-finite {c:?}");
        assert!((0.0..=1.0).contains(&c[3]), "{case}: alpha {}", c[3]);
        assert!(
            c[..3].iter().all(|&v| (0.0..=MAX_RADIANCE).contains(&v)),
            "{case}: radiance {c:?}"
        );
    }
}

/// The most the background may bring: the Sun's disc (SUN_I 20 × its limb-darkened peak)
/// seen through clear air, with margin.
const MAX_BACKGROUND: f32 = 1.0e4;

/// The final composite, made of what the present stage makes it of: the background (sky,
/// ground, haze) under the cloud layer, times the frame's exposure. Every part and the sum
/// must be finite: an Inf or NaN there would be a black or white pixel after the tone curve.
fn check_composite(o: &Output, scene: &[[f32; 4]], exposure: f32, case: &str) {
    assert!(
        exposure.is_finite() && exposure > 0.0,
        "{case}: exposure {exposure}"
    );
    assert_eq!(
        scene.len(),
        o.cloud.len(),
        "{case}: one background per pixel"
    );
    for (b, c) in scene.iter().zip(&o.cloud) {
        assert!(
            b.iter().all(|v| v.is_finite()) && b.iter().all(|&v| v >= 0.0),
            "{case}: background {b:?}"
        );
        assert!(
            b[..3].iter().all(|&v| v <= MAX_BACKGROUND),
            "{case}: background radiance {b:?}"
        );
        for k in 0..3 {
            let lin = (b[k] * (1.0 - c[3]) + c[k]) * exposure;
            assert!(lin.is_finite() && lin >= 0.0, "{case}: composite {lin}");
        }
    }
}

fn go(map: &CloudMap, view: View, s: &Settings, case: &str) -> Output {
    let mut r = renderer();
    r.set_map(map);
    let o = r
        .render(&view, 32, 24, s)
        .unwrap_or_else(|e| panic!("{case}: {e}"));
    check(&o, case);
    let scene = r.read_scene().unwrap_or_else(|e| panic!("{case}: {e}"));
    let e = r.read_exposure().unwrap_or_else(|e| panic!("{case}: {e}"));
    check_composite(&o, &scene, e.value, case);
    o
}

fn cam(lat: f64, lon: f64, alt: f64, heading: f64, pitch: f64) -> View {
    View::Perspective(Camera::new(lat, lon, alt, heading, pitch))
}

#[test]
fn humidity_extremes() {
    for rc in [0.0, 0.65, 0.9999] {
        assert_eq!(coverage(0.0, rc), 0.0);
        assert_eq!(coverage(rc, rc), 0.0);
        assert_eq!(coverage(1.0, rc), 1.0);
        assert_eq!(
            coverage(1.07, rc),
            1.0,
            "RH above 100 % is full cover, not more"
        );
        assert!(validate_rh_cr(rc).is_ok());
    }
    assert!(validate_rh_cr(1.0).is_err());
    assert!(validate_rh_cr(1.5).is_err());
    assert!(validate_rh_cr(f64::NAN).is_err());
}

#[test]
fn cameras_anywhere() {
    let map = world(0.8);
    let s = settings();
    let cases = [
        ("sea level", cam(10.0, 20.0, 0.0, 0.0, 5.0)),
        ("inside a layer", cam(10.0, 20.0, 2000.0, 90.0, 0.0)),
        ("on the low base", cam(10.0, 20.0, 1000.0, 0.0, 0.0)),
        ("on the high top", cam(10.0, 20.0, 9000.0, 0.0, -10.0)),
        ("1000 km up", cam(10.0, 20.0, 1.0e6, 0.0, -90.0)),
        ("north pole", cam(90.0, 0.0, 5000.0, 0.0, -20.0)),
        ("south pole", cam(-90.0, 0.0, 5000.0, 0.0, -20.0)),
        ("date line", cam(0.0, 180.0, 5000.0, 90.0, -5.0)),
        ("straight up", cam(10.0, 20.0, 500.0, 0.0, 90.0)),
        ("straight down", cam(10.0, 20.0, 12_000.0, 0.0, -90.0)),
    ];
    for (case, view) in cases {
        let o = go(&map, view, &s, case);
        if case == "straight down" || case == "1000 km up" {
            assert!(
                o.alpha().iter().all(|&a| a > 0.9),
                "{case}: cover 0.8 from above is opaque"
            );
        }
    }
}

#[test]
fn suns_anywhere() {
    let map = world(0.8);
    for (case, enu) in [
        ("zenith", DVec3::Z),
        ("horizon", DVec3::X),
        ("below", DVec3::new(0.0, 1.0, -0.5)),
    ] {
        let mut s = settings();
        s.sun_override = Some(enu);
        go(&map, cam(10.0, 20.0, 12_000.0, 0.0, -30.0), &s, case);
    }
}

#[test]
fn multipliers_at_their_limits() {
    let map = world(0.7);
    let above = cam(10.0, 20.0, 12_000.0, 0.0, -90.0);
    for (cm, dm) in [
        (0.0, 1.0),
        (1000.0, 1.0),
        (1.0, 0.0),
        (1.0, 1000.0),
        (1000.0, 1000.0),
    ] {
        let mut s = settings();
        s.coverage_mul = cm;
        s.density_mul = dm;
        let o = go(&map, above, &s, &format!("coverage ×{cm}, density ×{dm}"));
        if cm == 0.0 || dm == 0.0 {
            assert!(o.alpha().iter().all(|&a| a == 0.0), "×0 draws nothing");
        }
        if cm >= 1000.0 && dm >= 1.0 {
            assert!(
                o.alpha().iter().all(|&a| a > 0.99),
                "coverage ×1000 is full cover: opaque"
            );
        }
    }
}

#[test]
fn steps_at_their_limits() {
    let map = world(0.9);
    let v = cam(10.0, 20.0, 4000.0, 0.0, -3.0);
    let mut tiny = settings();
    tiny.march.step_min_m = 1.0;
    tiny.march.step_max_m = 1.0;
    tiny.march.max_steps = 1;
    go(&map, v, &tiny, "one 1 m step");
    let mut huge = settings();
    huge.march.step_min_m = 1.0e5;
    huge.march.step_max_m = 1.0e5;
    go(&map, v, &huge, "100 km steps");
    let mut bad = settings();
    bad.march.step_min_m = 0.0;
    assert!(
        renderer().render(&v, 8, 8, &bad).is_err(),
        "a zero step is refused"
    );
}

#[test]
fn maps_tiny_and_too_large() {
    let s = settings();
    let r = Region {
        south: 0.0,
        north: 10.0,
        west: 0.0,
        east: 10.0,
    };
    let one = CloudMap::from_fn(
        r,
        1,
        1,
        &[(LayerKind::Middle, 3000.0, 5000.0)],
        t(),
        |_, _| [0.0, 1.0, 0.0],
    );
    let o = go(&one, View::TopDown, &s, "1×1 map");
    assert!(
        o.alpha().iter().all(|&a| a > 0.99),
        "a 1×1 full map covers its region"
    );
    // Wider than any adapter's 2D texture limit here: rendered downscaled, with a warning.
    let max = renderer().gpu.device.limits().max_texture_dimension_2d;
    let wide = CloudMap::from_fn(
        r,
        max + 2,
        2,
        &[(LayerKind::Middle, 3000.0, 5000.0)],
        t(),
        |_, lo| [0.0, (lo < 5.0) as u8 as f64, 0.0],
    );
    let o = go(&wide, View::TopDown, &s, "map over the texture limit");
    let a = o.alpha();
    // West half cloud, east half clear.
    assert!(a[0] > 0.9 && a[31] == 0.0, "{} {}", a[0], a[31]);
}

/// The light and the scene at their extremes (issue 14): the real East Asia map with its
/// terrain, every Sun (high, on the horizon, below it) from every camera (on the Tibetan
/// terrain, at 80 km, straight up, straight down). The cloud layer is finite and bounded, and
/// the exposure the frame was shown with is a finite positive number.
#[path = "common/mod.rs"]
mod common;

#[test]
fn light_and_terrain_at_the_extremes() {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let sidecar = common::real_map(dir.path(), "ea", "0,55,39,105", "260x220");
    let map = CloudMap::load(&sidecar).expect("the map");
    let (ground, _) = map.ground_height_m(33.0, 85.0);
    assert!(ground > 4000.0, "Tibet's ground is {ground} m");
    // The footprints at their extremes too (issue 30): a pixel tens of metres wide near the
    // ground, and kilometres wide from 80 km straight down or along rays grazing the Earth's
    // limb (the horizon's dip from 80 km is 9.0°), where every pattern has faded to its mean.
    let cameras = [
        ("on the terrain", cam(33.0, 85.0, ground + 2.0, 0.0, 10.0)),
        ("80 km up", cam(30.0, 80.0, 80_000.0, 0.0, -60.0)),
        (
            "80 km up, straight down",
            cam(30.0, 80.0, 80_000.0, 0.0, -90.0),
        ),
        (
            "80 km up, grazing the horizon",
            cam(30.0, 80.0, 80_000.0, 70.0, -8.9),
        ),
        (
            "on the terrain, grazing the horizon",
            cam(33.0, 85.0, ground + 2.0, 270.0, 0.0),
        ),
        ("straight up", cam(33.0, 85.0, ground + 2.0, 0.0, 90.0)),
        ("straight down", cam(33.0, 85.0, 12_000.0, 0.0, -90.0)),
    ];
    for (sun, enu) in [
        ("high Sun", DVec3::new(0.3, 0.2, 1.0)),
        ("Sun on the horizon", DVec3::X),
        ("Sun below it", DVec3::new(0.0, 1.0, -0.3)),
    ] {
        let mut s = settings();
        s.sun_override = Some(enu);
        for (where_, view) in cameras {
            let case = format!("{sun}, {where_}");
            let o = go(&map, view, &s, &case);
            let e = renderer().read_exposure().expect("the exposure");
            assert!(
                e.value.is_finite() && e.value > 0.0 && e.metered.is_finite(),
                "{case}: exposure {e:?}"
            );
            assert!(o.pixels.len() == o.cloud.len() * 4, "{case}");
        }
    }
}
