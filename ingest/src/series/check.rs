//! What a step map's own sidecar must agree with: the series entry that names it (forecast
//! hour, valid time, wind images), the series (run, region, size, layers) and the first
//! step (critical humidities, interpolation, source grid). A step sidecar records when it is
//! valid, so a series whose `map` entries were swapped, or a step map taken from another run
//! or another ingest, is refused instead of shown at the wrong moment.

use crate::meta::{format_time, CloudMapMeta, ExtraRole};

use super::meta::{show_hour, SeriesMeta, SeriesStep};

/// Hours closer than this are the same step (a thousandth of a second).
const HOUR_SLACK: f64 = 1e-6;

/// The first way `m` (the sidecar of `step`) disagrees with the series `series`, or with
/// `first`, the sidecar of the series' first step: a phrase that follows the sidecar's name.
pub fn step_fault(
    series: &SeriesMeta,
    step: &SeriesStep,
    m: &CloudMapMeta,
    first: Option<&CloudMapMeta>,
) -> Option<String> {
    let src = &m.source;
    if (src.forecast_step_h - step.forecast_hour).abs() > HOUR_SLACK
        || src.valid_time != Some(step.valid_time)
    {
        return Some(format!(
            "it is the {} step (valid {}), not the series' {} (valid {}); the series' map entries do not match their files",
            show_hour(src.forecast_step_h),
            src.valid_time.as_ref().map_or("unknown".into(), format_time),
            show_hour(step.forecast_hour),
            format_time(&step.valid_time)
        ));
    }
    if src.reference_time != Some(series.reference_time) {
        return Some(format!(
            "it is of the {} run, the series of the {} run",
            src.reference_time
                .as_ref()
                .map_or("unknown".into(), format_time),
            format_time(&series.reference_time)
        ));
    }
    if m.region != series.region || (m.width, m.height) != (series.width, series.height) {
        return Some("its region or size is not the series'".into());
    }
    // Kinds only: a step's levels may differ (an analysis can hold fewer than a forecast).
    if !m
        .layers
        .iter()
        .map(|l| l.kind)
        .eq(series.layers.iter().map(|l| l.kind))
    {
        return Some("its layers are not the series'".into());
    }
    if let Some(w) = &step.winds {
        let own = |r| m.extra(r).map(|x| x.image.as_str());
        if (own(ExtraRole::WindU), own(ExtraRole::WindV)) != (Some(&*w.u), Some(&*w.v)) {
            return Some(format!(
                "its wind images are not the {} and {} the series names for the step",
                w.u, w.v
            ));
        }
    }
    let first = first?;
    let rh_cr = |x: &CloudMapMeta| x.layers.iter().map(|l| l.rh_cr).collect::<Vec<_>>();
    if rh_cr(m) != rh_cr(first) {
        return Some(format!(
            "its critical humidities {:?} are not the first step's {:?}; a series is one ingest",
            rh_cr(m),
            rh_cr(first)
        ));
    }
    if m.interpolation != first.interpolation {
        return Some(format!(
            "its interpolation {:?} is not the first step's {:?}; a series is one ingest",
            m.interpolation, first.interpolation
        ));
    }
    let grid = |x: &CloudMapMeta| {
        let s = &x.source;
        (s.grid_ni, s.grid_nj, s.grid_di_deg, s.grid_dj_deg)
    };
    if grid(m) != grid(first) {
        return Some("its source grid is not the first step's; a series is one grid".into());
    }
    None
}
