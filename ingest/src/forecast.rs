//! Loading what a CloudMap needs from one GRIB2 file: RH on isobaric levels (and gh on the
//! same levels for layer altitudes), decoding only those messages, and the fields beside RH
//! that give the map its structure, types and winds ([`WeatherInputs`], all optional).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use chrono::{DateTime, Utc};

use crate::error::{IngestError, Result};
use crate::grib::{self, Field, MessageInfo};
use crate::ground::GroundInputs;
use crate::region::Region;
pub use crate::weather::RhLevel;
use crate::weather::WeatherInputs;

/// Top of the troposphere the default all-layer ingest folds in, hPa: GFS also carries RH up
/// to 10 hPa, where no weather cloud forms and the altitude (~30 km) would put "cirrus" in space.
pub const DEFAULT_TOP_HPA: f64 = 100.0;

/// Which RH levels to load.
#[derive(Debug, Clone, Copy)]
pub enum LevelSelect {
    /// One level, hPa (the seed paper's case).
    One(f64),
    /// Every isobaric level with pressure ≥ this, hPa.
    AllBelow(f64),
}

/// The RH levels and geopotential heights of one forecast file.
#[derive(Debug, Clone)]
pub struct Forecast {
    pub path: PathBuf,
    /// Descending pressure (ascending altitude).
    pub levels: Vec<RhLevel>,
    /// Geopotential height fields by level (hPa × 1000, rounded, as key).
    gh: BTreeMap<i64, Field>,
    pub reference_time: Option<DateTime<Utc>>,
    pub step_hours: Option<f64>,
    /// What the file holds besides RH for the map's structure, types and winds (issue 13).
    pub weather: WeatherInputs,
    /// The ground's fields (issue 14) when the file has orography on the RH grid.
    pub ground: Option<GroundInputs>,
}

fn key(p: f64) -> i64 {
    (p * 1000.0).round() as i64
}

fn list_levels(ps: &[f64]) -> String {
    ps.iter()
        .map(|p| {
            if (p - p.round()).abs() < 1e-9 {
                format!("{}", p.round())
            } else {
                format!("{p}")
            }
        })
        .collect::<Vec<_>>()
        .join(", ")
        + " hPa"
}

impl Forecast {
    /// Read `path` (at most [`crate::input::MAX_GRIB_BYTES`]) and decode the RH (and gh) levels `select` asks for.
    pub fn open(path: &Path, select: LevelSelect) -> Result<Forecast> {
        let bytes = crate::input::read_grib(path)?;
        Self::from_bytes(path, &bytes, select)
    }

    pub fn from_bytes(path: &Path, bytes: &[u8], select: LevelSelect) -> Result<Forecast> {
        Self::from_bytes_at(path, bytes, select, None)
    }

    /// Read `path` like [`Forecast::open`], keeping only the messages of forecast step `step`
    /// (hours) when one is given: one step of a file that holds several.
    pub fn open_step(path: &Path, select: LevelSelect, step: Option<f64>) -> Result<Forecast> {
        let bytes = crate::input::read_grib(path)?;
        Self::from_bytes_at(path, &bytes, select, step)
    }

    /// [`Forecast::from_bytes`] of one step (all messages when `step` is `None`).
    pub fn from_bytes_at(
        path: &Path,
        bytes: &[u8],
        select: LevelSelect,
        step: Option<f64>,
    ) -> Result<Forecast> {
        let mut msgs = grib::scan(bytes).map_err(|e| grib_error(path, e))?;
        if let Some(h) = step {
            // Fields of other steps (and accumulations whose step reads differently) are left
            // out: the step's RH, gh, winds and instantaneous fields stay.
            msgs.retain(|m| m.step_hours.is_some_and(|s| (s - h).abs() < 1e-6));
        }
        let rh: Vec<&MessageInfo> = msgs
            .iter()
            .filter(|m| m.is_relative_humidity() && m.pressure_hpa().is_some())
            .collect();
        if rh.is_empty() {
            return Err(IngestError::NoRelativeHumidity {
                path: path.to_path_buf(),
                holds: holdings(&msgs),
            });
        }
        let mut present: Vec<f64> = rh.iter().filter_map(|m| m.pressure_hpa()).collect();
        present.sort_by(|a, b| b.total_cmp(a));
        present.dedup();
        let wanted = select_levels(path, &rh, &present, select)?;
        let first_grid = wanted[0].grid.clone();
        let levels = decode_levels(path, bytes, &wanted)?;
        // gh on the same grid and levels gives the layer altitudes; absent gh is not an error.
        let gh = decode_gh(bytes, &msgs, &first_grid, &present);
        let top = present
            .iter()
            .copied()
            .filter(|p| levels.iter().any(|l| (l.pressure_hpa - p).abs() < 1e-6))
            .fold(DEFAULT_TOP_HPA, f64::min);
        let weather = WeatherInputs::load(path, bytes, &msgs, &first_grid, top);
        let ground =
            GroundInputs::load(path, bytes, &msgs, &first_grid, weather.surface_gh.as_ref());
        Ok(Forecast {
            weather,
            ground,
            path: path.to_path_buf(),
            reference_time: wanted[0].reference_time,
            step_hours: wanted[0].step_hours,
            levels,
            gh,
        })
    }

    /// Region-mean geopotential height at `p` hPa, if the file has gh there.
    pub fn mean_gh(&self, p: f64, region: &Region) -> Option<f64> {
        let f = self.gh.get(&key(p))?;
        let g = &f.grid;
        let (mut sum, mut n) = (0.0, 0usize);
        for j in 0..g.nj {
            let lat = g.north() - j as f64 * g.dj;
            for i in 0..g.ni {
                let lon = g.west() + i as f64 * g.di;
                if region.to_pixel(lat, lon, 1, 1).is_some() {
                    sum += f.at(i, j);
                    n += 1;
                }
            }
        }
        if n == 0 {
            // Region smaller than a grid cell: use the whole field rather than nothing.
            n = f.values.len();
            sum = f.values.iter().sum();
        }
        Some(sum / n as f64)
    }

    /// reference_time + step: the time the clouds are valid for.
    pub fn valid_time(&self) -> Option<DateTime<Utc>> {
        Some(grib::info::after_step(
            self.reference_time?,
            self.step_hours?,
        ))
    }

    /// Pressures of all loaded RH levels, descending.
    pub fn pressures(&self) -> Vec<f64> {
        self.levels.iter().map(|l| l.pressure_hpa).collect()
    }
}

/// The RH messages `select` asks for, among `rh` (levels `present`, for the message when one
/// is absent).
fn select_levels<'m>(
    path: &Path,
    rh: &[&'m MessageInfo],
    present: &[f64],
    select: LevelSelect,
) -> Result<Vec<&'m MessageInfo>> {
    let wanted: Vec<&MessageInfo> = match select {
        LevelSelect::One(p) => {
            let m = rh
                .iter()
                .find(|m| m.pressure_hpa().is_some_and(|q| (q - p).abs() < 1e-6))
                .ok_or_else(|| IngestError::LevelAbsent {
                    path: path.to_path_buf(),
                    level: p,
                    present: list_levels(present),
                })?;
            vec![*m]
        }
        LevelSelect::AllBelow(top) => {
            let mut seen = std::collections::BTreeSet::new();
            let v: Vec<&MessageInfo> = rh
                .iter()
                .copied()
                .filter(|m| m.pressure_hpa().is_some_and(|q| q >= top))
                .filter(|m| seen.insert(key(m.pressure_hpa().unwrap_or(0.0))))
                .collect();
            if v.is_empty() {
                return Err(IngestError::LevelAbsent {
                    path: path.to_path_buf(),
                    level: top,
                    present: format!(
                        "{} (none at or below the {top} hPa top; pick one with --level)",
                        list_levels(present)
                    ),
                });
            }
            v
        }
    };
    Ok(wanted)
}

/// Decode the `wanted` RH messages (all on one grid), range-checked and gap-filled, in
/// descending pressure.
fn decode_levels(path: &Path, bytes: &[u8], wanted: &[&MessageInfo]) -> Result<Vec<RhLevel>> {
    let first_grid = &wanted[0].grid;
    let mut levels = Vec::with_capacity(wanted.len());
    for m in wanted {
        if &m.grid != first_grid {
            return Err(IngestError::Grib {
                path: path.to_path_buf(),
                msg: format!(
                    "RH levels are on different grids (message {} differs from message {})",
                    m.index + 1,
                    wanted[0].index + 1
                ),
            });
        }
        let mut field = grib::decode_values(bytes, m).map_err(|e| grib_error(path, e))?;
        check_rh_range(path, m, &field)?;
        fill_missing(&mut field).map_err(|msg| IngestError::Grib {
            path: path.to_path_buf(),
            msg: format!("message {}: {msg}", m.index + 1),
        })?;
        levels.push(RhLevel {
            pressure_hpa: m.pressure_hpa().unwrap_or(f64::NAN),
            field,
        });
    }
    levels.sort_by(|a, b| b.pressure_hpa.total_cmp(&a.pressure_hpa));
    Ok(levels)
}

/// The file's gh on `grid` at the `present` RH levels, by level; a gh field that does not
/// decode or is not finite everywhere is left out.
fn decode_gh(
    bytes: &[u8],
    msgs: &[MessageInfo],
    grid: &Option<grib::LatLonGrid>,
    present: &[f64],
) -> BTreeMap<i64, Field> {
    let mut gh = BTreeMap::new();
    for m in msgs.iter().filter(|m| {
        m.is_geopotential_height()
            && &m.grid == grid
            && m.pressure_hpa()
                .is_some_and(|p| present.iter().any(|q| (q - p).abs() < 1e-6))
    }) {
        if let (Some(p), Ok(f)) = (m.pressure_hpa(), grib::decode_values(bytes, m)) {
            if f.values.iter().all(|v| v.is_finite()) {
                gh.insert(key(p), f);
            }
        }
    }
    gh
}

/// A GRIB error of the file at `path`.
fn grib_error(path: &Path, e: grib::GribError) -> IngestError {
    IngestError::Grib {
        path: path.to_path_buf(),
        msg: e.to_string(),
    }
}

/// RH is a percentage; values far outside [0, 100] mean corrupt data, not weather. (GFS RH can
/// slightly exceed 100 % over ice; the clamp after interpolation handles that.)
fn check_rh_range(path: &Path, m: &MessageInfo, f: &Field) -> Result<()> {
    let (lo, hi) = f
        .values
        .iter()
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    if lo < -5.0 || hi > 200.0 {
        return Err(IngestError::Grib {
            path: path.to_path_buf(),
            msg: format!(
                "message {} decodes to relative humidity {lo:.3e}..{hi:.3e} %, which is not humidity (corrupt data section?)",
                m.index + 1
            ),
        });
    }
    Ok(())
}

/// Replace missing (NaN) points by the mean of their valid 4-neighbours, sweeping until none is
/// left, so the spline never sees NaN.
pub fn fill_missing(f: &mut Field) -> std::result::Result<(), String> {
    let (ni, nj) = (f.grid.ni, f.grid.nj);
    let wrap = f.grid.is_global();
    if f.values.iter().all(|v| v.is_nan()) {
        return Err("every grid point is missing".into());
    }
    while f.values.iter().any(|v| v.is_nan()) {
        let prev = f.values.clone();
        for j in 0..nj {
            for i in 0..ni {
                if !prev[j * ni + i].is_nan() {
                    continue;
                }
                let mut nb = Vec::with_capacity(4);
                if j > 0 {
                    nb.push(prev[(j - 1) * ni + i]);
                }
                if j + 1 < nj {
                    nb.push(prev[(j + 1) * ni + i]);
                }
                if i > 0 {
                    nb.push(prev[j * ni + i - 1]);
                } else if wrap {
                    nb.push(prev[j * ni + ni - 1]);
                }
                if i + 1 < ni {
                    nb.push(prev[j * ni + i + 1]);
                } else if wrap {
                    nb.push(prev[j * ni]);
                }
                let valid: Vec<f64> = nb.into_iter().filter(|v| !v.is_nan()).collect();
                if !valid.is_empty() {
                    f.values[j * ni + i] = valid.iter().sum::<f64>() / valid.len() as f64;
                }
            }
        }
    }
    Ok(())
}

/// "r at 25 levels; t …" style summary of what a file holds, for the no-RH error.
fn holdings(msgs: &[MessageInfo]) -> String {
    let mut by: BTreeMap<String, Vec<String>> = BTreeMap::new();
    for m in msgs {
        by.entry(m.short_name()).or_default().push(m.level_text());
    }
    by.into_iter()
        .map(|(name, levels)| {
            if levels.len() == 1 {
                format!("{name} on {}", levels[0])
            } else {
                format!("{name} on {} levels", levels.len())
            }
        })
        .collect::<Vec<_>>()
        .join("; ")
}
