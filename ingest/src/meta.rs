//! The CloudMap sidecar (`MAP.json`): what a CloudMap PNG covers and how it was made.
//!
//! The renderer and the scorer read only this and the PNG; nothing downstream re-reads GRIB.
//!
//! The schema alone: the vocabulary it names lives below it ([`LayerKind`] and
//! [`AltitudeSource`] in `layer`, [`StructureGrid`] in `lattice`, [`CloudType`] in `cloud`)
//! and stays reachable here.

use chrono::{DateTime, SecondsFormat, Utc};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use thiserror::Error;

use crate::cloud::CloudType;
pub use crate::error::show_num;
use crate::ground::{GroundField, GroundMeta};
pub use crate::lattice::StructureGrid;
pub use crate::layer::{AltitudeSource, LayerKind, ALTITUDE_RANGE_M, LOW_TOP_HPA, MIDDLE_TOP_HPA};
use crate::region::{check_side, Region};
use std::collections::BTreeMap;

/// Sidecar format tag written now; bumped when a field changes meaning or becomes required.
/// Version 2 adds `image_id`, which the PNG must carry (see [`crate::output::write_pair`]).
/// Version 3 adds the structure images (`extra_images`: base, top, type, winds; each carries
/// the same image id) and per-layer `structure` statistics (docs/ingest.md).
pub const FORMAT: &str = "stratus-cloudmap/3";

/// The second format, still read: an image id, no structure images.
pub const FORMAT_V2: &str = "stratus-cloudmap/2";

/// The first sidecar format, still read: no `image_id`, so the PNG is not checked against it.
pub const FORMAT_V1: &str = "stratus-cloudmap/1";

/// What an extra image of a version-3 map holds (encodings in [`crate::structure`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ExtraRole {
    /// 16-bit RGBA: cloud base of low, middle, high; A: convective cloud base.
    Base,
    /// 16-bit RGBA: cloud top of low, middle, high; A: convective cloud top.
    Top,
    /// 8-bit RGBA: cloud type code of low, middle, high; A: base/top source, 2 bits a layer.
    Type,
    /// 16-bit RGB: layer-mean eastward / northward wind of low, middle, high.
    WindU,
    WindV,
}

impl ExtraRole {
    pub const ALL: [ExtraRole; 5] = [
        ExtraRole::Base,
        ExtraRole::Top,
        ExtraRole::Type,
        ExtraRole::WindU,
        ExtraRole::WindV,
    ];

    /// `MAP.png` → `MAP.<suffix>.png`.
    pub const fn suffix(self) -> &'static str {
        match self {
            ExtraRole::Base => "base",
            ExtraRole::Top => "top",
            ExtraRole::Type => "type",
            ExtraRole::WindU => "wind-u",
            ExtraRole::WindV => "wind-v",
        }
    }
}

/// One extra image of the map, in the sidecar's folder.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ExtraImage {
    pub role: ExtraRole,
    pub image: String,
}

/// A layer's structure over the map (version 3): what the renderer needs before it reads the
/// images, and what a reader checks at a glance.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LayerStructure {
    /// Lowest base and highest top over the layer's cloudy pixels (coverage > 0), m above sea
    /// level: the renderer's march bounds. The band when no pixel is cloudy.
    pub base_min_m: f64,
    pub top_max_m: f64,
    /// Pixels with coverage > 0.
    pub cloudy_pixels: u64,
    /// Share of the cloudy pixels whose base/top came from each source (sums to 1 when any).
    pub sources: BTreeMap<AltitudeSource, f64>,
    /// Share of the cloudy pixels of each cloud type.
    pub types: BTreeMap<CloudType, f64>,
    /// Whether the file had winds on this layer's levels (else the wind images hold 0 here).
    pub wind: bool,
}

/// One cloud layer of the map.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LayerMeta {
    pub kind: LayerKind,
    /// PNG channel holding this layer's coverage (0 = R, 1 = G, 2 = B).
    pub channel: usize,
    /// Isobaric levels folded into this layer (max coverage over them), hPa, descending.
    pub levels_hpa: Vec<f64>,
    pub rh_cr: f64,
    /// Cloud base and top above mean sea level, metres.
    pub base_m: f64,
    pub top_m: f64,
    pub altitude_source: AltitudeSource,
    /// Mean and max coverage over the map (0..1), for quick inspection.
    pub mean_coverage: f64,
    pub max_coverage: f64,
    /// Per-pixel structure summary (version 3 maps with structure images).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub structure: Option<LayerStructure>,
}

/// Where the forecast came from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SourceMeta {
    pub file: String,
    /// Analysis (reference) time; `None` when the file's date is unreadable. Stored as RFC 3339
    /// UTC with whole seconds (`2011-01-10T12:00:00Z`), or `""` when `None`.
    #[serde(with = "sidecar_time")]
    pub reference_time: Option<DateTime<Utc>>,
    /// Forecast step, hours.
    pub forecast_step_h: f64,
    /// reference_time + step: the time the clouds are valid for. Stored like `reference_time`.
    #[serde(with = "sidecar_time")]
    pub valid_time: Option<DateTime<Utc>>,
    /// Grid of the source field: Ni × Nj and spacing in degrees.
    pub grid_ni: usize,
    pub grid_nj: usize,
    pub grid_di_deg: f64,
    pub grid_dj_deg: f64,
    /// Fields besides RH the structure was made from (version 3), e.g. `cloud-layer-pressures`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub fields: Vec<String>,
}

/// The sidecar written next to each CloudMap PNG.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CloudMapMeta {
    pub format: String,
    /// PNG file name, in the sidecar's directory (a plain name, no folders).
    pub image: String,
    /// Identifier the PNG carries in its `stratus-image-id` text chunk (format 2): a PNG that
    /// does not carry it is not this sidecar's. Absent in format 1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub image_id: Option<String>,
    /// The structure images (version 3), all carrying `image_id`; empty: no structure, and the
    /// loader gives each layer its band and default type.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub extra_images: Vec<ExtraImage>,
    /// Where the structure images' pixels lie; absent: the map's own pixels.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub structure_grid: Option<StructureGrid>,
    /// The ground images and their lattice ([`crate::ground`]); absent: no ground (sea level).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ground: Option<GroundMeta>,
    pub region: Region,
    pub width: u32,
    pub height: u32,
    pub layers: Vec<LayerMeta>,
    /// `spline`, `catmull-rom`, `bilinear` or `nearest`.
    pub interpolation: String,
    pub source: SourceMeta,
}

impl CloudMapMeta {
    /// Path of the PNG this sidecar describes.
    pub fn image_path(&self, sidecar: &Path) -> PathBuf {
        sidecar
            .parent()
            .unwrap_or_else(|| Path::new("."))
            .join(&self.image)
    }

    pub fn layer(&self, kind: LayerKind) -> Option<&LayerMeta> {
        self.layers.iter().find(|l| l.kind == kind)
    }

    /// Check everything the renderer and scorer will trust: the format, a plain image name,
    /// the region, the size (at most [`crate::region::MAX_SIDE`] a side), and each layer's
    /// physical ranges (band within [`ALTITUDE_RANGE_M`] with base below top, a critical
    /// humidity the formula accepts, the channel of its kind, coverage in 0..1), all finite.
    /// The error names the field and why, e.g. `layers[1] (middle).top_m: 1e12 m is outside
    /// -500..=100000 m`.
    pub fn validate(&self) -> Result<(), String> {
        self.validate_content()?;
        self.validate_image()
    }

    /// The parts of [`validate`](Self::validate) that do not concern the image file: what a
    /// map must satisfy before it is written at all.
    pub fn validate_content(&self) -> Result<(), String> {
        self.region.validate().map_err(|e| format!("region: {e}"))?;
        check_side("width", self.width)?;
        check_side("height", self.height)?;
        if self.layers.len() > 3 {
            return Err(format!(
                "layers: {} layers; a map has at most 3",
                self.layers.len()
            ));
        }
        for (i, l) in self.layers.iter().enumerate() {
            self.validate_layer(i, l)?;
        }
        if let Some(g) = &self.ground {
            self.validate_ground(g)?;
        }
        let s = &self.source;
        for (name, v) in [
            ("forecast_step_h", s.forecast_step_h),
            ("grid_di_deg", s.grid_di_deg),
            ("grid_dj_deg", s.grid_dj_deg),
        ] {
            if !v.is_finite() {
                return Err(format!("source.{name}: {} is not a number", show_num(v)));
            }
        }
        Ok(())
    }

    /// [`validate_content`](Self::validate_content) of layer `i`: one layer of each kind in
    /// its own channel, its band inside [`ALTITUDE_RANGE_M`] and ordered, its rh_cr, coverage,
    /// levels and structure summary.
    fn validate_layer(&self, i: usize, l: &LayerMeta) -> Result<(), String> {
        let at = format!("layers[{i}] ({})", l.kind.name());
        if self.layers[..i].iter().any(|o| o.kind == l.kind) {
            return Err(format!("{at}: a second {} layer", l.kind.name()));
        }
        if l.channel != l.kind.channel() {
            return Err(format!(
                "{at}.channel: {} but a {} layer is in channel {}",
                l.channel,
                l.kind.name(),
                l.kind.channel()
            ));
        }
        for (name, v) in [("base_m", l.base_m), ("top_m", l.top_m)] {
            if !ALTITUDE_RANGE_M.contains(&v) {
                return Err(format!(
                    "{at}.{name}: {} m is outside {}..={} m",
                    show_num(v),
                    ALTITUDE_RANGE_M.start(),
                    ALTITUDE_RANGE_M.end()
                ));
            }
        }
        if l.base_m >= l.top_m {
            return Err(format!(
                "{at}: base_m {} m is not below top_m {} m",
                show_num(l.base_m),
                show_num(l.top_m)
            ));
        }
        crate::layer::validate_rh_cr(l.rh_cr).map_err(|e| format!("{at}.rh_cr: {e}"))?;
        for (name, v) in [
            ("mean_coverage", l.mean_coverage),
            ("max_coverage", l.max_coverage),
        ] {
            if !(0.0..=1.0).contains(&v) {
                return Err(format!("{at}.{name}: {} is outside 0..=1", show_num(v)));
            }
        }
        if let Some(p) = l.levels_hpa.iter().find(|p| !(p.is_finite() && **p > 0.0)) {
            return Err(format!(
                "{at}.levels_hpa: {} hPa is not a pressure",
                show_num(*p)
            ));
        }
        if let Some(st) = &l.structure {
            for (name, v) in [("base_min_m", st.base_min_m), ("top_max_m", st.top_max_m)] {
                if !ALTITUDE_RANGE_M.contains(&v) {
                    return Err(format!(
                        "{at}.structure.{name}: {} m is outside {}..={} m",
                        show_num(v),
                        ALTITUDE_RANGE_M.start(),
                        ALTITUDE_RANGE_M.end()
                    ));
                }
            }
            let fractions = st.sources.values().chain(st.types.values());
            if let Some(v) = fractions.into_iter().find(|v| !(0.0..=1.0).contains(*v)) {
                return Err(format!(
                    "{at}.structure: share {} is outside 0..=1",
                    show_num(*v)
                ));
            }
        }
        Ok(())
    }

    /// [`validate_content`](Self::validate_content) of the ground: its lattice against the map,
    /// its heights, and its fields (orography among them, none twice).
    fn validate_ground(&self, g: &GroundMeta) -> Result<(), String> {
        g.grid
            .validate_as("ground.grid", &self.region, (self.width, self.height))?;
        for (name, v) in [
            ("height_min_m", g.height_min_m),
            ("height_max_m", g.height_max_m),
        ] {
            if !ALTITUDE_RANGE_M.contains(&v) {
                return Err(format!(
                    "ground.{name}: {} m is outside {}..={} m",
                    show_num(v),
                    ALTITUDE_RANGE_M.start(),
                    ALTITUDE_RANGE_M.end()
                ));
            }
        }
        if !g.fields.contains(&GroundField::Orography) {
            return Err("ground.fields: no orography (a ground is made from it)".into());
        }
        if let Some((k, f)) = g
            .fields
            .iter()
            .enumerate()
            .find(|(k, f)| g.fields[..*k].contains(f))
        {
            return Err(format!("ground.fields[{k}]: {} listed twice", f.name()));
        }
        Ok(())
    }

    fn validate_image(&self) -> Result<(), String> {
        let plain = |name: &str| {
            let p = Path::new(name);
            !name.is_empty() && p.file_name() == Some(p.as_os_str()) && !name.contains(['/', '\\'])
        };
        if !plain(&self.image) {
            return Err(format!(
                "image: {:?} is not a file name in the sidecar's folder",
                self.image
            ));
        }
        let id_format = matches!(self.format.as_str(), FORMAT | FORMAT_V2);
        match (self.format.as_str(), &self.image_id) {
            (FORMAT_V1, _) => {}
            (_, Some(id)) if id_format => {
                if !(id.len() == 32 && id.bytes().all(|b| b.is_ascii_hexdigit())) {
                    return Err(format!("image_id: {id:?} is not 32 hex digits"));
                }
            }
            (f, None) if id_format => return Err(format!("image_id: missing (required by {f})")),
            (f, _) => {
                return Err(format!(
                    "format: {f:?} is not {FORMAT:?}, {FORMAT_V2:?} or {FORMAT_V1:?}"
                ))
            }
        }
        if let Some(g) = &self.ground {
            if self.format != FORMAT {
                return Err(format!(
                    "ground: given in a {} sidecar; only {FORMAT} has it",
                    self.format
                ));
            }
            let taken: Vec<&str> = std::iter::once(self.image.as_str())
                .chain(self.extra_images.iter().map(|x| x.image.as_str()))
                .collect();
            for (name, v) in [("image", &g.image), ("water_image", &g.water_image)] {
                if !plain(v.as_str()) || taken.contains(&v.as_str()) {
                    return Err(format!(
                        "ground.{name}: {v:?} is not a file name in the sidecar's folder other than the map's other images"
                    ));
                }
            }
            if g.image == g.water_image {
                return Err("ground: image and water_image are the same file".into());
            }
        }
        if self.extra_images.is_empty() {
            if self.structure_grid.is_some() {
                return Err("structure_grid: given without extra_images".into());
            }
            return Ok(());
        }
        if self.format != FORMAT {
            return Err(format!(
                "extra_images: listed in a {} sidecar; only {FORMAT} has them",
                self.format
            ));
        }
        for (i, x) in self.extra_images.iter().enumerate() {
            let at = format!("extra_images[{i}] ({})", x.role.suffix());
            if !plain(&x.image) || x.image == self.image {
                return Err(format!(
                    "{at}.image: {:?} is not a file name in the sidecar's folder other than the map's",
                    x.image
                ));
            }
            if self.extra_images[..i]
                .iter()
                .any(|o| o.role == x.role || o.image == x.image)
            {
                return Err(format!("{at}: listed twice"));
            }
        }
        if let Some(r) = ExtraRole::ALL
            .iter()
            .find(|r| !self.extra_images.iter().any(|x| x.role == **r))
        {
            return Err(format!(
                "extra_images: no {} image (a map has all five or none)",
                r.suffix()
            ));
        }
        if let Some(g) = &self.structure_grid {
            g.validate(&self.region, (self.width, self.height))?;
        }
        Ok(())
    }

    /// The extra image of `role`, if the map has structure images.
    pub fn extra(&self, role: ExtraRole) -> Option<&ExtraImage> {
        self.extra_images.iter().find(|x| x.role == role)
    }

    /// Where the structure images' pixels lie: what the sidecar records, the map's own
    /// pixels where it records nothing (the first version-3 sidecars wrote them so).
    pub fn structure_pixels(&self) -> StructureGrid {
        self.structure_grid
            .unwrap_or_else(|| StructureGrid::of_map(&self.region, self.width, self.height))
    }
}

/// A time that is not ISO 8601 / RFC 3339.
#[derive(Debug, Clone, PartialEq, Error)]
#[error("time {0:?} is not ISO 8601 (e.g. 2011-01-15T06:00:00Z)")]
pub struct BadTime(pub String);

/// Parse a UTC time as stratus writes and accepts it: RFC 3339 with any offset (converted to
/// UTC), or a date and time without offset (`2011-01-15T06:00:00`, `2011-01-15T06:00`), read
/// as UTC. The one parser for sidecar times and `--time`.
pub fn parse_time(s: &str) -> Result<DateTime<Utc>, BadTime> {
    DateTime::parse_from_rfc3339(s)
        .map(|d| d.with_timezone(&Utc))
        .or_else(|_| {
            chrono::NaiveDateTime::parse_from_str(s, "%Y-%m-%dT%H:%M:%S").map(|n| n.and_utc())
        })
        .or_else(|_| {
            chrono::NaiveDateTime::parse_from_str(s, "%Y-%m-%dT%H:%M").map(|n| n.and_utc())
        })
        .map_err(|_| BadTime(s.to_string()))
}

/// A time as the sidecar stores it: RFC 3339, UTC, whole seconds, `Z` (`2011-01-15T12:00:00Z`).
pub fn format_time(t: &DateTime<Utc>) -> String {
    t.to_rfc3339_opts(SecondsFormat::Secs, true)
}

/// Serde for the sidecar's optional times: `""` is "unknown", so version-1 sidecars (which
/// wrote `""` when the GRIB date was unreadable) load and new ones are byte-identical.
mod sidecar_time {
    use super::{format_time, parse_time};
    use chrono::{DateTime, Utc};
    use serde::{de::Error, Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(t: &Option<DateTime<Utc>>, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&t.as_ref().map(format_time).unwrap_or_default())
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<DateTime<Utc>>, D::Error> {
        let s = String::deserialize(d)?;
        if s.is_empty() {
            return Ok(None);
        }
        parse_time(&s).map(Some).map_err(D::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sidecar as version 1 wrote it (what `ingest` of the 2.5° GFS file made), byte for byte.
    pub(crate) const V1_SIDECAR: &str = r#"{
  "format": "stratus-cloudmap/1",
  "image": "ea.png",
  "region": {
    "south": 0.0,
    "north": 55.0,
    "west": 39.0,
    "east": 105.0
  },
  "width": 260,
  "height": 220,
  "layers": [
    {
      "kind": "middle",
      "channel": 1,
      "levels_hpa": [
        600.0,
        500.0
      ],
      "rh_cr": 0.65,
      "base_m": 3147.5,
      "top_m": 6624.25,
      "altitude_source": "geopotential-height",
      "mean_coverage": 0.125,
      "max_coverage": 1.0
    }
  ],
  "interpolation": "spline",
  "source": {
    "file": "/data/gfs.t12z.pgrbf120.2p5deg.grib2",
    "reference_time": "2011-01-10T12:00:00Z",
    "forecast_step_h": 120.0,
    "valid_time": "2011-01-15T12:00:00Z",
    "grid_ni": 144,
    "grid_nj": 73,
    "grid_di_deg": 2.5,
    "grid_dj_deg": 2.5
  }
}"#;

    #[test]
    fn times_are_typed_and_round_trip_byte_identical() {
        let m: CloudMapMeta = serde_json::from_str(V1_SIDECAR).unwrap();
        assert_eq!(
            m.source.valid_time,
            Some(parse_time("2011-01-15T12:00:00Z").unwrap())
        );
        assert_eq!(serde_json::to_string_pretty(&m).unwrap(), V1_SIDECAR);
        // An unknown time is "" both ways.
        let blank = V1_SIDECAR.replace("2011-01-10T12:00:00Z", "");
        let m: CloudMapMeta = serde_json::from_str(&blank).unwrap();
        assert_eq!(m.source.reference_time, None);
        assert_eq!(serde_json::to_string_pretty(&m).unwrap(), blank);
        // A time that is not one is refused, and the error says which.
        let bad = V1_SIDECAR.replace("2011-01-15T12:00:00Z", "next tuesday");
        let e = serde_json::from_str::<CloudMapMeta>(&bad).unwrap_err();
        assert!(
            e.to_string().contains("\"next tuesday\" is not ISO 8601"),
            "{e}"
        );
    }

    #[test]
    fn one_parser_for_every_time_form() {
        let t = parse_time("2011-01-15T06:00:00Z").unwrap();
        assert_eq!(parse_time("2011-01-15T06:00:00").unwrap(), t);
        assert_eq!(parse_time("2011-01-15T06:00").unwrap(), t);
        assert_eq!(parse_time("2011-01-15T08:00:00+02:00").unwrap(), t);
        assert_eq!(format_time(&t), "2011-01-15T06:00:00Z");
        assert!(parse_time("2011-13-15T06:00").is_err());
    }

    #[test]
    fn rh_cr_defaults_are_defined_once() {
        let by_kind: Vec<f64> = LayerKind::ALL.iter().map(|k| k.default_rh_cr()).collect();
        assert_eq!(by_kind, LayerKind::DEFAULT_RH_CR);
        assert_eq!(LayerKind::DEFAULT_RH_CR, [0.80, 0.65, 0.80]);
    }
}
