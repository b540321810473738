//! `stratus probe`: what a map holds at one point — the ground (terrain height, surface, the
//! column's cloud water) and per layer coverage, cloud base and top, type and where the heights
//! came from. What a user checks a map against a sounding or a METAR with. From a Zarr store
//! only the chunks around the point are read, and how much that was is reported.

use std::path::PathBuf;
use std::process::ExitCode;

use stratus::scene::Scene;
use stratus_ingest::error::shown;
use stratus_ingest::ground::GroundSource;

use super::options::{parse_lat_lon, parse_time};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// CloudMap sidecar (MAP.json), series sidecar or Zarr store (STORE.zarr).
    #[arg(long)]
    pub map: PathBuf,
    /// With a series: the moment (ISO 8601 UTC), blended between the two steps around it;
    /// default: the first step.
    #[arg(long)]
    pub time: Option<String>,
    /// The point, LAT,LON in degrees.
    #[arg(long, allow_hyphen_values = true)]
    pub at: String,
    /// Print JSON: {"lat", "lon", "ground_m", "ground_source", "land", "ice", "snow_kg_m2",
    /// "snow_cover", "albedo", "cwat_kg_m2", "ground_fields",
    /// "layers": [{"kind", "coverage", "base_m", "top_m", "type", "source"}]}; from a store also
    /// "store": {"chunks_read", "bytes_read", "store_bytes"}.
    #[arg(long)]
    pub json: bool,
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let (lat, lon) = parse_lat_lon(&a.at, "--at")?;
    let time = a.time.as_deref().map(parse_time).transpose()?;
    let scene = Scene::open(&a.map);
    let store = scene.store().cloned();
    let map = scene.map_near(time, lat, lon)?;
    let r = map.meta.region;
    let Some(p) = map.probe(lat, lon) else {
        anyhow::bail!(
            "{}: {lat},{lon} is outside the map's region ({}..{}°N, {}..{}°E)",
            shown(&a.map),
            r.south,
            r.north,
            r.west,
            r.east
        );
    };
    let read = store.map(|s| {
        let st = s.stats();
        serde_json::json!({"chunks_read": st.chunks_read, "bytes_read": st.bytes_read,
                           "store_bytes": s.size_on_disk()})
    });
    if a.json {
        let mut v = serde_json::to_value(&p)?;
        if let (Some(r), Some(o)) = (&read, v.as_object_mut()) {
            o.insert("store".into(), r.clone());
        }
        out!("{}", serde_json::to_string_pretty(&v)?)?;
        return Ok(ExitCode::SUCCESS);
    }
    out!("{lat:.4}, {lon:.4} in {}", shown(&a.map))?;
    let g = &p.ground;
    match g.ground_source {
        GroundSource::Orography => {
            let f = |v: Option<f64>, d: usize| v.map_or("-".to_string(), |v| format!("{v:.d$}"));
            out!(
                "ground  {:.0} m (orography)  land {}  ice {}  snow {} kg/m² (cover {})  albedo {}",
                g.ground_m.round() + 0.0,
                f(g.land, 2),
                f(g.ice, 2),
                f(g.snow_kg_m2, 1),
                f(g.snow_cover, 2),
                f(g.albedo, 2)
            )?;
        }
        GroundSource::None => out!("ground  0 m (sea level: the map has no ground grid here)")?,
    }
    match g.cwat_kg_m2 {
        Some(c) => out!("column cloud water {c:.3} kg/m²")?,
        None => out!("column cloud water - (not in the forecast)")?,
    }
    out!(
        "{:<7} {:>8} {:>8} {:>8}  {:<14} source",
        "layer",
        "coverage",
        "base m",
        "top m",
        "type"
    )?;
    let m = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.0}"));
    for l in &p.layers {
        out!(
            "{:<7} {:>8.3} {:>8} {:>8}  {:<14} {}",
            l.kind.name(),
            l.coverage,
            m(l.base_m),
            m(l.top_m),
            l.cloud_type.map_or("-", |t| t.name()),
            l.source.name()
        )?;
    }
    if let Some(r) = read {
        out!(
            "read {} chunk(s), {} of the store's {} bytes",
            r["chunks_read"],
            r["bytes_read"],
            r["store_bytes"]
        )?;
    }
    Ok(ExitCode::SUCCESS)
}
