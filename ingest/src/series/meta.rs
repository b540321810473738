//! The series sidecar (`NAME.json`, format [`SERIES_FORMAT`]): the run, the region and size
//! every step shares, the layers, and per step its forecast hour, valid time, the step map's
//! own sidecar, its layer-wind images and (issue 31) its motion images to the next step. Read
//! with a cap and checked field by field.

use std::path::Path;

use chrono::{DateTime, Utc};
use serde::{Deserialize, Serialize};

use crate::layer::LayerKind;
use crate::region::{check_side, Region};

/// Format tag of a series sidecar.
pub const SERIES_FORMAT: &str = "stratus-cloudmap-series/1";

/// Most steps a series may list (a 16-day GFS run hourly is 385).
pub const MAX_STEPS: usize = 1000;

/// The series sidecar.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SeriesMeta {
    pub format: String,
    /// The run: analysis time shared by every step.
    #[serde(with = "time_text")]
    pub reference_time: DateTime<Utc>,
    pub region: Region,
    pub width: u32,
    pub height: u32,
    pub layers: Vec<SeriesLayer>,
    /// In increasing forecast hour.
    pub steps: Vec<SeriesStep>,
}

/// A layer every step map holds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SeriesLayer {
    pub kind: LayerKind,
    pub channel: usize,
    pub levels_hpa: Vec<f64>,
}

impl From<&crate::meta::LayerMeta> for SeriesLayer {
    /// A map's layer as the series names it (every step's map has the same layers).
    fn from(l: &crate::meta::LayerMeta) -> SeriesLayer {
        SeriesLayer {
            kind: l.kind,
            channel: l.channel,
            levels_hpa: l.levels_hpa.clone(),
        }
    }
}

/// One forecast step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SeriesStep {
    pub forecast_hour: f64,
    #[serde(with = "time_text")]
    pub valid_time: DateTime<Utc>,
    /// The step map's sidecar, a file name in the series sidecar's folder.
    pub map: String,
    /// The step's per-pixel layer winds (its `wind-u`/`wind-v` structure images, m/s east and
    /// north); `None` for a map without structure images.
    #[serde(default)]
    pub winds: Option<StepWinds>,
    /// Per layer (low, middle, high) the mean of those images over the region, (east, north)
    /// m/s ([`super::winds`]): the renderer's noise drift. Absent in older sidecars (the
    /// renderer then decodes the step map for it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mean_wind: Option<super::winds::LayerWinds>,
    /// The guarded motion from this step to the next ([`super::stored`]); `None` on the last
    /// step, and on every step of a sidecar written before issue 31 (the motion is then
    /// estimated from the steps when an interval is needed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub motion: Option<StepMotion>,
}

/// A step's motion images (16-bit RGBA PNG, R/G/B = low/middle/high, A unused): the guarded
/// motion to the next step on the motion's working grid, east (`u`) and south (`v`) in map
/// pixels per interval, as (sample − 32768) × `scale`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StepMotion {
    pub u: String,
    pub v: String,
    /// The working grid ([`super::motion::work_size`] of the series' size).
    pub width: u32,
    pub height: u32,
    /// Map pixels per interval per unit of the samples.
    pub scale: f64,
}

/// File names of a step map's layer-wind images (R/G/B = low/middle/high; docs/ingest.md).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StepWinds {
    pub u: String,
    pub v: String,
}

/// Steps are whole minutes after the run, so two steps are at least a minute apart. GRIB
/// can state steps in seconds, but forecasts are written hours apart (GFS: 1 h to 120 h, then
/// 3 h) and the finest sub-hourly ones in minutes (HRRR: 15 min); a step a fraction of a
/// second after another is a damaged file, and an interval that short has nothing to blend
/// and valid times (whole seconds) that may round together.
pub const STEP_UNIT_MINUTES: f64 = 1.0;

/// Whether `hour` is a whole number of minutes (to a few milliseconds).
pub fn is_whole_minutes(hour: f64) -> bool {
    let m = hour * 60.0 / STEP_UNIT_MINUTES;
    (m - m.round()).abs() < 1e-4
}

/// Why `hour` is not a step a series may hold, if it is not one (a phrase after its name).
pub fn step_hour_fault(hour: f64) -> Option<String> {
    (!is_whole_minutes(hour)).then(|| {
        format!(
            "{} ({} s after the run) is not a whole number of minutes; steps are whole minutes after the run, at least a minute apart",
            show_hour(hour),
            crate::meta::show_num((hour * 3600.0 * 1000.0).round() / 1000.0)
        )
    })
}

/// A name that stays in the sidecar's folder.
pub(crate) fn is_plain_name(name: &str) -> bool {
    let p = Path::new(name);
    !name.is_empty()
        && p.file_name() == Some(p.as_os_str())
        && !name.contains(['/', '\\'])
        && name != ".."
}

impl SeriesMeta {
    /// Check every field a reader will trust; the error names the field.
    pub fn validate(&self) -> Result<(), String> {
        if self.format != SERIES_FORMAT {
            return Err(format!(
                "format: {:?} is not {SERIES_FORMAT:?}",
                self.format
            ));
        }
        self.region.validate().map_err(|e| format!("region: {e}"))?;
        check_side("width", self.width)?;
        check_side("height", self.height)?;
        if self.layers.is_empty() {
            return Err("layers: none".into());
        }
        for (i, l) in self.layers.iter().enumerate() {
            if l.channel != l.kind.channel() {
                return Err(format!(
                    "layers[{i}]: channel {} is not the {} layer's ({})",
                    l.channel,
                    l.kind.name(),
                    l.kind.channel()
                ));
            }
            if self.layers[..i].iter().any(|o| o.kind == l.kind) {
                return Err(format!("layers[{i}]: a second {} layer", l.kind.name()));
            }
        }
        if self.steps.is_empty() || self.steps.len() > MAX_STEPS {
            return Err(format!(
                "steps: {} listed; a series has 1..={MAX_STEPS}",
                self.steps.len()
            ));
        }
        for (i, s) in self.steps.iter().enumerate() {
            let at = format!("steps[{i}]");
            if !(s.forecast_hour.is_finite() && (0.0..=100_000.0).contains(&s.forecast_hour)) {
                return Err(format!(
                    "{at}.forecast_hour: {} is not a forecast hour",
                    crate::meta::show_num(s.forecast_hour)
                ));
            }
            if let Some(fault) = step_hour_fault(s.forecast_hour) {
                return Err(format!("{at}.forecast_hour: {fault}"));
            }
            if i > 0 && s.forecast_hour <= self.steps[i - 1].forecast_hour {
                return Err(format!(
                    "{at}.forecast_hour: {} does not follow {} (steps go in increasing hour, each once)",
                    show_hour(s.forecast_hour),
                    show_hour(self.steps[i - 1].forecast_hour)
                ));
            }
            let expected = crate::grib::info::after_step(self.reference_time, s.forecast_hour);
            if (s.valid_time - expected).num_seconds().abs() > 1 {
                return Err(format!(
                    "{at}.valid_time: {} is not the run's {} {}",
                    crate::meta::format_time(&s.valid_time),
                    crate::meta::format_time(&self.reference_time),
                    show_hour(s.forecast_hour)
                ));
            }
            if !is_plain_name(&s.map) {
                return Err(format!(
                    "{at}.map: {:?} is not a file name in the sidecar's folder",
                    s.map
                ));
            }
            if s.mean_wind.is_some_and(|w| !super::winds::is_plausible(&w)) {
                return Err(format!(
                    "{at}.mean_wind: not finite, or beyond ±{} m/s",
                    super::winds::MAX_MEAN_WIND
                ));
            }
            if let Some(w) = &s.winds {
                for (k, n) in [("u", &w.u), ("v", &w.v)] {
                    if !is_plain_name(n) {
                        return Err(format!(
                            "{at}.winds.{k}: {n:?} is not a file name in the sidecar's folder"
                        ));
                    }
                }
            }
            if let Some(m) = &s.motion {
                let last = i + 1 == self.steps.len();
                self.motion_fault(m, last)
                    .map_or(Ok(()), |f| Err(format!("{at}.motion{f}")))?;
            }
        }
        Ok(())
    }

    /// What is wrong with a step's motion entry (a phrase after `steps[i].motion`), if
    /// anything: names, the working grid's size, the scale (finite, positive, and no motion
    /// it can encode beyond the map's size per interval), and no motion after the last step.
    fn motion_fault(&self, m: &StepMotion, last: bool) -> Option<String> {
        if last {
            return Some(": the last step has no next step to move to".into());
        }
        for (k, n) in [("u", &m.u), ("v", &m.v)] {
            if !is_plain_name(n) {
                return Some(format!(
                    ".{k}: {n:?} is not a file name in the sidecar's folder"
                ));
            }
        }
        let (w, h) = super::motion::work_size(self.width as usize, self.height as usize);
        if (m.width as usize, m.height as usize) != (w, h) {
            return Some(format!(
                ": {}x{} is not the motion grid of a {}x{} map ({w}x{h})",
                m.width, m.height, self.width, self.height
            ));
        }
        let most = f64::from(self.width.max(self.height));
        if !(m.scale.is_finite() && m.scale > 0.0 && m.scale * 32768.0 <= most) {
            return Some(format!(
                ".scale: {} is not finite and positive, or encodes motion beyond the map's {most} px per interval",
                crate::meta::show_num(m.scale)
            ));
        }
        None
    }
}

/// Times as the map sidecars store them (RFC 3339, UTC, whole seconds).
pub(crate) mod time_text {
    use crate::meta::{format_time, parse_time};
    use chrono::{DateTime, Utc};
    use serde::{de::Error, Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(t: &DateTime<Utc>, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&format_time(t))
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<DateTime<Utc>, D::Error> {
        let s = String::deserialize(d)?;
        parse_time(&s).map_err(D::Error::custom)
    }
}

/// `forecast hour` as a file-name tag: `f006` for whole hours, `f001p50` otherwise.
pub fn hour_tag(hour: f64) -> String {
    if (hour - hour.round()).abs() < 1e-9 {
        format!("f{:03}", hour.round() as i64)
    } else {
        let whole = hour.trunc() as i64;
        let frac = ((hour - hour.trunc()) * 100.0).round() as i64;
        format!("f{whole:03}p{frac:02}")
    }
}

/// A forecast hour as people write it: `+6 h`, `+1.5 h`, `+0.000278 h`.
pub fn show_hour(hour: f64) -> String {
    let sign = if hour < 0.0 { "-" } else { "+" };
    let h = hour.abs();
    if !(h.is_finite() && h < 1e7) {
        format!("{sign}{} h", crate::meta::show_num(h))
    } else if (h - h.round()).abs() < 1e-9 {
        format!("{sign}{} h", h.round() as i64)
    } else {
        let t = format!("{h:.6}");
        format!("{sign}{} h", t.trim_end_matches('0').trim_end_matches('.'))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn meta() -> SeriesMeta {
        let t0 = crate::meta::parse_time("2015-09-12T18:00:00Z").unwrap();
        let step = |h: f64, name: &str| SeriesStep {
            forecast_hour: h,
            valid_time: crate::grib::info::after_step(t0, h),
            map: format!("{name}.json"),
            winds: Some(StepWinds {
                u: format!("{name}.wind-u.png"),
                v: format!("{name}.wind-v.png"),
            }),
            mean_wind: Some([[1.5, -0.5], [6.0, 0.25], [12.0, 3.0]]),
            motion: None,
        };
        SeriesMeta {
            format: SERIES_FORMAT.into(),
            reference_time: t0,
            region: Region::parse("30,70,-60,40").unwrap(),
            width: 64,
            height: 32,
            layers: vec![SeriesLayer {
                kind: LayerKind::High,
                channel: 2,
                levels_hpa: vec![300.0],
            }],
            steps: vec![step(0.0, "m-f000"), step(6.0, "m-f006")],
        }
    }

    #[test]
    fn a_sidecar_round_trips_and_its_faults_are_named() {
        let m = meta();
        m.validate().unwrap();
        let text = serde_json::to_string(&m).unwrap();
        assert!(
            text.contains("\"reference_time\":\"2015-09-12T18:00:00Z\""),
            "{text}"
        );
        let back: SeriesMeta = serde_json::from_str(&text).unwrap();
        assert_eq!(back, m);

        let mut bad = m.clone();
        bad.steps.swap(0, 1);
        assert!(bad
            .validate()
            .unwrap_err()
            .contains("steps[1].forecast_hour"));
        let mut bad = m.clone();
        bad.steps[1].forecast_hour = 0.0;
        assert!(bad.validate().unwrap_err().contains("does not follow"));
        let mut bad = m.clone();
        bad.steps[1].forecast_hour = 0.0002;
        bad.steps[1].valid_time = crate::grib::info::after_step(bad.reference_time, 0.0002);
        assert!(bad
            .validate()
            .unwrap_err()
            .contains("steps[1].forecast_hour: +0.0002 h (0.72 s after the run) is not a whole number of minutes"));
        let mut bad = m.clone();
        bad.steps[1].map = "../x.json".into();
        assert!(bad.validate().unwrap_err().contains("steps[1].map"));
        let mut bad = m.clone();
        bad.steps[0].valid_time = bad.steps[1].valid_time;
        assert!(bad.validate().unwrap_err().contains("steps[0].valid_time"));
        let mut bad = m.clone();
        bad.format = "stratus-cloudmap/3".into();
        assert!(bad.validate().unwrap_err().contains("format"));
        let mut bad = m.clone();
        bad.steps[1].mean_wind = Some([[f64::NAN, 0.0], [0.0; 2], [0.0; 2]]);
        assert!(bad.validate().unwrap_err().contains("steps[1].mean_wind"));
        bad.steps[1].mean_wind = Some([[0.0; 2], [0.0, -400.0], [0.0; 2]]);
        assert!(bad.validate().unwrap_err().contains("steps[1].mean_wind"));
        // An older sidecar, without the means, still reads.
        let mut old = m.clone();
        old.steps.iter_mut().for_each(|s| s.mean_wind = None);
        let text = serde_json::to_string(&old).unwrap();
        assert!(!text.contains("mean_wind"), "{text}");
        assert_eq!(serde_json::from_str::<SeriesMeta>(&text).unwrap(), old);
        old.validate().unwrap();
        // The motion entry: on a step with a next one, on the working grid, a sane scale.
        let motion = |scale: f64, w: u32| StepMotion {
            u: "m-f000.motion-u.png".into(),
            v: "m-f000.motion-v.png".into(),
            width: w,
            height: 32,
            scale,
        };
        let mut ok = m.clone();
        ok.steps[0].motion = Some(motion(0.001, 64));
        ok.validate().unwrap();
        let back: SeriesMeta = serde_json::from_str(&serde_json::to_string(&ok).unwrap()).unwrap();
        assert_eq!(back, ok);
        for (k, mo, says) in [
            (1, motion(0.001, 64), "steps[1].motion: the last step"),
            (
                0,
                motion(0.001, 32),
                "steps[0].motion: 32x32 is not the motion grid",
            ),
            (0, motion(0.0, 64), "steps[0].motion.scale"),
            (0, motion(f64::NAN, 64), "steps[0].motion.scale"),
            (0, motion(1.0, 64), "steps[0].motion.scale"),
        ] {
            let mut bad = m.clone();
            bad.steps[k].motion = Some(mo);
            let e = bad.validate().unwrap_err();
            assert!(e.contains(says), "{e}");
        }
        let mut bad = m;
        bad.steps.clear();
        assert!(bad.validate().unwrap_err().contains("steps"));
    }

    #[test]
    fn hour_tags_sort_and_read_back() {
        assert_eq!(hour_tag(0.0), "f000");
        assert_eq!(hour_tag(6.0), "f006");
        assert_eq!(hour_tag(120.0), "f120");
        assert_eq!(hour_tag(1.5), "f001p50");
        assert_eq!(show_hour(6.0), "+6 h");
        assert_eq!(show_hour(1.5), "+1.5 h");
        assert_eq!(show_hour(1.0 / 3600.0), "+0.000278 h");
        assert!(is_whole_minutes(0.25) && is_whole_minutes(1.0 / 60.0));
        assert!(!is_whole_minutes(0.0002));
    }
}
