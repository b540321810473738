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
