//! The motion between a store's steps (issue 31's stored motion; docs/zarr.md, "Motion"):
//! `motion_u` and `motion_v` (interval × layer × motion_y × motion_x, uint16) hold exactly the
//! samples of a series' `NAME-fHHH.motion-u/v.png` images ([`MotionSamples`]), one chunk per
//! interval and layer (the working grid is at most 256 px a side); `motion_scale` (interval,
//! float64) their scale, so that (sample − 32768) × scale is map pixels per interval. Interval
//! `k` is the motion from step `k` to step `k + 1`; the series in the group's attributes
//! names the arrays in each step's motion entry, and the reader hands them to the series
//! ([`Store::read_motion`]) instead of estimating the motion.

use std::collections::BTreeMap;
use std::path::Path;

use serde_json::{json, Map, Value};

use crate::error::Result;
use crate::series::meta::StepMotion;
use crate::series::motion::{work_size, Motion};
use crate::series::stored::{from_samples, MotionSamples, ZERO};
use crate::series::SeriesMeta;

use super::array::{encode_chunk, ArrayMeta, Dtype};
use super::read::read_json;
use super::write::Put;
use super::{fault, Store};

/// The east component's array (map pixels per interval, east positive).
pub const MOTION_U: &str = "motion_u";
/// The south component's array (map pixels per interval, south positive).
pub const MOTION_V: &str = "motion_v";
/// Each interval's scale (map pixels per interval per unit of the samples).
pub const MOTION_SCALE: &str = "motion_scale";

/// The motion arrays of a store of maps `map_w` × `map_h` with `intervals` intervals.
pub fn array_metas((map_w, map_h): (u32, u32), intervals: u64) -> Vec<(String, ArrayMeta)> {
    let (w, h) = work_size(map_w as usize, map_h as usize);
    let attrs = |what: &str| -> Map<String, Value> {
        let v = json!({
            "long_name": format!("guarded cloud motion from the step to the next, {what}"),
            "units": "1",
            "comment": "map pixels per interval = (value - 32768) * motion_scale[interval]; \
                        on the motion's working grid over the region (docs/time.md); \
                        interval k runs from time k to time k + 1",
        });
        v.as_object().cloned().unwrap_or_default()
    };
    let field = |name: &str, what: &str| {
        (
            name.to_string(),
            ArrayMeta {
                shape: vec![intervals, 3, h as u64, w as u64],
                chunks: vec![1, 1, h as u64, w as u64],
                dtype: Dtype::U16,
                dims: ["interval", "layer", "motion_y", "motion_x"]
                    .map(String::from)
                    .to_vec(),
                attributes: attrs(what),
            },
        )
    };
    let scale_attrs = json!({
        "long_name": "scale of motion_u and motion_v: map pixels per interval per unit",
    });
    vec![
        field(MOTION_U, "eastward"),
        field(MOTION_V, "southward"),
        (
            MOTION_SCALE.to_string(),
            ArrayMeta {
                shape: vec![intervals],
                chunks: vec![1],
                dtype: Dtype::F64,
                dims: vec!["interval".into()],
                attributes: scale_attrs.as_object().cloned().unwrap_or_default(),
            },
        ),
    ]
}

/// The series' motion entry for samples stored in the arrays.
pub fn entry(s: &MotionSamples) -> StepMotion {
    StepMotion {
        u: MOTION_U.into(),
        v: MOTION_V.into(),
        width: s.width as u32,
        height: s.height as u32,
        scale: s.scale,
    }
}

/// Interval `k`'s chunks: the six layer planes and the scale.
pub fn write_interval(store: &Path, k: usize, s: &MotionSamples, put: Put) -> Result<()> {
    for (name, texels) in [(MOTION_U, &s.u), (MOTION_V, &s.v)] {
        for l in 0..3 {
            let vals: Vec<u64> = texels.iter().map(|t| u64::from(t[l])).collect();
            let p = ArrayMeta::chunk_path(&store.join(name), &[k as u64, l as u64, 0, 0]);
            put(&p, &encode_chunk(&vals, Dtype::U16))?;
        }
    }
    put(
        &ArrayMeta::chunk_path(&store.join(MOTION_SCALE), &[k as u64]),
        &encode_chunk(&[s.scale.to_bits()], Dtype::F64),
    )
}

/// The motion arrays' metadata when `series` names stored motion, checked against it: the
/// working grid, and an interval axis at least as long as the steps' (an append cut short
/// may have left it longer).
pub(crate) fn open_arrays(path: &Path, series: &SeriesMeta) -> Result<BTreeMap<String, ArrayMeta>> {
    let mut out = BTreeMap::new();
    if series.steps.iter().all(|s| s.motion.is_none()) {
        return Ok(out);
    }
    let intervals = series.steps.len() as u64 - 1;
    for (name, want) in array_metas((series.width, series.height), intervals) {
        let p = path.join(&name).join("zarr.json");
        let a = ArrayMeta::from_json(&read_json(&p)?).map_err(|e| fault(&p, e))?;
        let agrees = a.dtype == want.dtype
            && a.chunks == want.chunks
            && a.shape.len() == want.shape.len()
            && a.shape[0] >= intervals
            && a.shape[1..] == want.shape[1..];
        if !agrees {
            return Err(fault(
                &p,
                format!(
                    "shape {:?} or chunks {:?} are not the motion's {:?} in {:?}",
                    a.shape, a.chunks, want.shape, want.chunks
                ),
            ));
        }
        out.insert(name, a);
    }
    Ok(out)
}

impl Store {
    /// The stored motion from step `k` to step `k + 1` (the samples its motion images
    /// would hold), decoded for the series; a missing or damaged chunk names its file.
    pub fn read_motion(&self, k: usize) -> Result<Motion> {
        let m = self
            .series
            .steps
            .get(k)
            .and_then(|s| s.motion.as_ref())
            .ok_or_else(|| fault(&self.path, format!("no stored motion after step {k}")))?;
        let n = m.width as usize * m.height as usize;
        let mut planes = Vec::with_capacity(2);
        for name in [MOTION_U, MOTION_V] {
            let a = self
                .arrays
                .get(name)
                .ok_or_else(|| fault(&self.path.join(name), "missing: the store is not whole"))?;
            let mut texels = vec![[ZERO; 3]; n];
            for l in 0..3 {
                let p = ArrayMeta::chunk_path(&self.path.join(name), &[k as u64, l as u64, 0, 0]);
                let vals = self.read_chunk(&p, a)?;
                for (t, v) in texels.iter_mut().zip(vals) {
                    t[l] = v as u16;
                }
            }
            planes.push(texels);
        }
        let v = planes.pop().unwrap_or_default();
        let u = planes.pop().unwrap_or_default();
        let s = MotionSamples {
            width: m.width as usize,
            height: m.height as usize,
            scale: m.scale,
            u,
            v,
        };
        Ok(from_samples(&s, &self.series))
    }
}
