//! Which forecast files make one series, from their headers only: every file's relative
//! humidity on one grid and of one run, each step once, given in increasing forecast hour.
//! Anything else is one error naming the file and the fault, found before anything is
//! decoded or written.

use std::path::{Path, PathBuf};

use chrono::{DateTime, Utc};

use crate::error::{IngestError, Result};
use crate::grib::{self, LatLonGrid};
use crate::meta::format_time;

use super::meta::{show_hour, step_hour_fault};

/// What one input file holds, from its headers.
#[derive(Debug, Clone)]
pub struct InputFile {
    pub path: PathBuf,
    /// The grid of its RH.
    pub grid: LatLonGrid,
    pub reference_time: DateTime<Utc>,
    /// Forecast hours of its RH, ascending, each once.
    pub steps: Vec<f64>,
}

/// One step of a series and where it comes from.
#[derive(Debug, Clone, PartialEq)]
pub struct StepSource {
    pub path: PathBuf,
    pub hour: f64,
    /// The file holds other steps too (so its messages are filtered to this one's).
    pub shared_file: bool,
}

/// Read `path`'s headers: the grid, run and steps of its isobaric relative humidity.
pub fn survey(path: &Path) -> Result<InputFile> {
    let bytes = crate::input::read_grib(path)?;
    let msgs = grib::scan(&bytes).map_err(|e| IngestError::Grib {
        path: path.to_path_buf(),
        msg: e.to_string(),
    })?;
    let rh: Vec<_> = msgs
        .iter()
        .filter(|m| m.is_relative_humidity() && m.pressure_hpa().is_some())
        .collect();
    let first = rh.first().ok_or_else(|| {
        IngestError::series(path, "holds no relative humidity on isobaric levels")
    })?;
    let grid = first.grid.clone().ok_or_else(|| {
        IngestError::series(
            path,
            "its relative humidity is not on a regular lat/lon grid",
        )
    })?;
    if let Some(m) = rh.iter().find(|m| m.grid.as_ref() != Some(&grid)) {
        return Err(IngestError::series(
            path,
            format!(
                "relative humidity on two grids (message {} differs from message {})",
                m.index + 1,
                first.index + 1
            ),
        ));
    }
    let reference_time = first
        .reference_time
        .ok_or_else(|| IngestError::series(path, "has no readable reference time (run)"))?;
    if let Some(m) = rh.iter().find(|m| m.reference_time != Some(reference_time)) {
        return Err(IngestError::series(
            path,
            format!(
                "holds two runs (message {} is not of the {} run)",
                m.index + 1,
                format_time(&reference_time)
            ),
        ));
    }
    let mut steps = Vec::new();
    for m in &rh {
        let h = m.step_hours.ok_or_else(|| {
            IngestError::series(
                path,
                format!("message {} has no readable forecast step", m.index + 1),
            )
        })?;
        if !steps.iter().any(|s: &f64| (s - h).abs() < 1e-6) {
            steps.push(h);
        }
    }
    steps.sort_by(f64::total_cmp);
    Ok(InputFile {
        path: path.to_path_buf(),
        grid,
        reference_time,
        steps,
    })
}

fn describe_grid(g: &LatLonGrid) -> String {
    format!(
        "{}x{} points at {}x{} degrees from {}N {}E",
        g.ni,
        g.nj,
        g.di,
        g.dj,
        g.north(),
        g.west()
    )
}

/// The steps `files` (in the order given) make, or the first reason they do not make one
/// series: a grid or run other than the first file's, a step that is not whole minutes after
/// the run ([`step_hour_fault`]), a step twice, steps out of order.
pub fn series_steps(files: &[InputFile]) -> Result<Vec<StepSource>> {
    let Some(first) = files.first() else {
        return Err(IngestError::BadMap("no forecast files given".into()));
    };
    for f in &files[1..] {
        if f.grid != first.grid {
            return Err(IngestError::series(
                &f.path,
                format!(
                    "its grid ({}) is not the grid of {} ({}); a series is one grid",
                    describe_grid(&f.grid),
                    crate::error::shown(&first.path),
                    describe_grid(&first.grid)
                ),
            ));
        }
        if f.reference_time != first.reference_time {
            return Err(IngestError::series(
                &f.path,
                format!(
                    "it is of the {} run, {} is of the {} run; a series is one run",
                    format_time(&f.reference_time),
                    crate::error::shown(&first.path),
                    format_time(&first.reference_time)
                ),
            ));
        }
    }
    let steps: Vec<StepSource> = files
        .iter()
        .flat_map(|f| {
            f.steps.iter().map(|&hour| StepSource {
                path: f.path.clone(),
                hour,
                shared_file: f.steps.len() > 1,
            })
        })
        .collect();
    if let Some((s, fault)) = steps
        .iter()
        .find_map(|s| Some((s, step_hour_fault(s.hour)?)))
    {
        return Err(IngestError::series(&s.path, format!("step {fault}")));
    }
    for (k, s) in steps.iter().enumerate() {
        if let Some(o) = steps[..k].iter().find(|o| (o.hour - s.hour).abs() < 1e-6) {
            let also = if o.path == s.path {
                "given twice".to_string()
            } else {
                format!("also in {}", crate::error::shown(&o.path))
            };
            return Err(IngestError::series(
                &s.path,
                format!("step {} is duplicated ({also})", show_hour(s.hour)),
            ));
        }
    }
    for (k, s) in steps.iter().enumerate().skip(1) {
        let prev = &steps[k - 1];
        if s.hour < prev.hour {
            let mut sorted: Vec<&StepSource> = steps.iter().collect();
            sorted.sort_by(|a, b| a.hour.total_cmp(&b.hour));
            let mut order: Vec<String> = Vec::new();
            for x in sorted {
                let name = crate::error::shown(&x.path).to_string();
                if order.last() != Some(&name) {
                    order.push(name);
                }
            }
            return Err(IngestError::series(
                &s.path,
                format!(
                    "step {} comes after {} of {}: steps out of order; give the files in increasing forecast hour: {}",
                    show_hour(s.hour),
                    show_hour(prev.hour),
                    crate::error::shown(&prev.path),
                    order.join(" ")
                ),
            ));
        }
    }
    Ok(steps)
}
