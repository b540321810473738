//! `stratus section` on the real sample: the curtain's cloud stands where the map's base and
//! top say, clear air above it, and bad paths or heights are refused with exit 2.

mod common;

use common::{real_map, stratus};

/// The North Atlantic from the real sample; the map's sidecar path.
fn natl(dir: &std::path::Path) -> String {
    let map = real_map(dir, "natl", "30,70,-60,30", "360x160");
    map.to_str().unwrap().to_string()
}

/// Whether a pixel is cloud drawn by the section (bright grey), not an overlay line.
fn is_cloud(p: &image::Rgba<u8>) -> bool {
    let [r, g, b, _] = p.0;
    r > 150 && g > 150 && b > 150 && r.abs_diff(g) < 20 && g.abs_diff(b) < 30
}

#[test]
fn the_curtain_shows_the_cloud_between_the_maps_base_and_top() {
    let dir = tempfile::tempdir().unwrap();
    let map = natl(dir.path());
    // Along 52.5°N, from 40°W to 10°W: the overcast at 25°W is the middle column.
    let out = dir.path().join("s.png");
    let (w, h, top) = (61u32, 200u32, 12_000.0f64);
    let o = stratus(&[
        "section",
        "--map",
        &map,
        "--from",
        "52.5,-40",
        "--to",
        "52.5,-10",
        "--size",
        &format!("{w}x{h}"),
        "--top-m",
        &top.to_string(),
        "--preset",
        "fast",
        "--layers",
        "middle",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let img = image::open(&out).unwrap().to_rgba8();
    assert_eq!(img.dimensions(), (w, h));
    let probe = stratus(&["probe", "--map", &map, "--at", "52.5,-25", "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&probe.stdout).unwrap();
    let middle = &v["layers"][1];
    let (base, topm) = (
        middle["base_m"].as_f64().unwrap(),
        middle["top_m"].as_f64().unwrap(),
    );
    // The middle column is at 25°W (the great circle bows north, so a few columns either side
    // are close to it).
    let alt = |y: u32| top * (1.0 - (y as f64 + 0.5) / h as f64);
    let rows: Vec<u32> = (0..h)
        .filter(|&y| (w / 2 - 1..=w / 2 + 1).any(|x| is_cloud(img.get_pixel(x, y))))
        .collect();
    assert!(
        rows.len() > 20,
        "no cloud in the overcast's column: {rows:?}"
    );
    // The renderer widens columns thinner than 1 200 m and filters between structure texels.
    for &y in &rows {
        assert!(
            alt(y) > base - 600.0 && alt(y) < topm + 600.0,
            "cloud at {:.0} m outside the map's {base:.0}–{topm:.0} m",
            alt(y)
        );
    }
    // Clear air over everything above the highest top.
    for y in 0..(h as f64 * (1.0 - (topm + 1500.0) / top)) as u32 {
        for x in 0..w {
            assert!(
                !is_cloud(img.get_pixel(x, y)),
                "cloud at {x},{y} ({:.0} m)",
                alt(y)
            );
        }
    }
}

#[test]
fn bad_paths_and_heights_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let map = natl(dir.path());
    let out = dir.path().join("s.png");
    for (from, to, extra) in [
        ("50,-20", "50,-20", None),
        ("50,-20", "-50,160", None),
        ("50,-20", "60,0", Some("--top-m=-5")),
        ("50,x", "60,0", None),
    ] {
        let mut args = vec![
            "section",
            "--map",
            &map,
            "--from",
            from,
            "--to",
            to,
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend(extra);
        let o = stratus(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{from} {to}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{err}");
        assert!(!out.exists(), "{from} {to}: a picture was written");
    }
}

/// Issue 28 #7: a point is LAT,LON with the latitude within ±90 and the longitude within ±360
/// (one parser for every command); anything else is one line naming the flag.
#[test]
fn points_off_the_globe_are_refused_naming_the_flag() {
    let dir = tempfile::tempdir().unwrap();
    let map = natl(dir.path());
    let out = dir.path().join("s.png");
    for (from, to, flag, what) in [
        (
            "1000,0",
            "50,-20",
            "--from",
            "latitude 1000 is outside -90..90",
        ),
        ("91,0", "50,-20", "--from", "latitude 91 is outside"),
        ("50,-20", "180,0", "--to", "latitude 180 is outside"),
        ("50,-20", "-90.5,0", "--to", "latitude -90.5 is outside"),
        (
            "50,400",
            "50,-20",
            "--from",
            "longitude 400 is outside -360..360",
        ),
        ("50,-20", "50,-1e308", "--to", "longitude -1e308 is outside"),
        ("nan,0", "50,-20", "--from", "LAT,LON"),
        ("50,-20", "50,inf", "--to", "LAT,LON"),
    ] {
        let o = stratus(&[
            "section",
            "--map",
            &map,
            "--from",
            from,
            "--to",
            to,
            "--size",
            "64x32",
            "--out",
            out.to_str().unwrap(),
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{from} {to}: {err}");
        let line = err.trim();
        assert_eq!(line.lines().count(), 1, "{err}");
        assert!(
            line.contains(flag) && line.contains(what),
            "{from} {to}: wanted {flag} and {what:?} in {err}"
        );
        assert!(!out.exists(), "{from} {to}: a picture was written");
    }
}

/// Issue 28 #8: a section larger than the device can hold is refused before anything is
/// allocated, one line naming --size and the limit (not a wgpu validation error after seconds).
/// Where the adapter does hold it (a GPU whose storage buffers bind 256 MiB), it is drawn.
#[test]
fn a_section_larger_than_the_device_allows_is_one_line_naming_size() {
    let dir = tempfile::tempdir().unwrap();
    let map = natl(dir.path());
    let out = dir.path().join("s.png");
    let o = stratus(&[
        "section",
        "--map",
        &map,
        "--from",
        "50,-20",
        "--to",
        "60,0",
        "--size",
        "8192x8192",
        "--preset",
        "fast",
        "--out",
        out.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    if o.status.success() {
        assert!(out.exists());
        return;
    }
    assert_eq!(o.status.code(), Some(2), "{err}");
    // Mesa's Wayland probe may print a line of its own on machines without a display session.
    let lines: Vec<&str> = err
        .lines()
        .filter(|l| !l.contains("XDG_RUNTIME_DIR") && !l.starts_with("stratus: adapter"))
        .collect();
    assert_eq!(lines.len(), 1, "{err}");
    assert!(
        lines[0].contains("--size 8192x8192") && lines[0].contains("max_"),
        "{err}"
    );
    assert!(!out.exists());
}
