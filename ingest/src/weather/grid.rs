//! Per grid point and layer: cloud base and top (m above sea level) with the source each came
//! from, the cloud type, and the convective cloud's extent (DESIGN §7). Sources, in order:
//! GFS's own cloud bottom/top pressure of the layer, the RH column (where RH crosses the
//! layer's rh_cr between levels), the layer's band. Pressures become altitudes through the
//! point's geopotential height profile, interpolated in log-pressure.

use crate::layer::{standard_altitude_m, LayerKind, PointSource, ALTITUDE_RANGE_M};

use super::inputs::{RhLevel, WeatherInputs};
use super::kind::{classify, layer_span_hpa, ColumnFacts};

/// Thinnest cloud a base/top pair may describe, m (one model level is thicker; this only
/// keeps base < top after clamping to the ground).
pub const MIN_DEPTH_M: f64 = 50.0;

/// A map layer as the structure needs it.
#[derive(Debug, Clone, Copy)]
pub struct LayerSpec {
    pub kind: LayerKind,
    pub rh_cr: f64,
    pub band_base_m: f64,
    pub band_top_m: f64,
}

/// One layer's per-point structure.
#[derive(Debug, Clone)]
pub struct GridLayer {
    pub kind: LayerKind,
    pub base_m: Vec<f32>,
    pub top_m: Vec<f32>,
    pub source: Vec<PointSource>,
    /// [`super::CloudType`] codes.
    pub cloud_type: Vec<u8>,
}

/// The structure of every present layer on the forecast grid.
#[derive(Debug, Clone)]
pub struct GridStructure {
    pub ni: usize,
    pub nj: usize,
    /// Indexed by layer channel (low, middle, high); `None` for a layer the map lacks.
    pub layers: [Option<GridLayer>; 3],
    /// GFS's convective cloud base and top, m; NaN where there is none.
    pub convective_m: (Vec<f32>, Vec<f32>),
}

/// Altitude (m) of pressure `p` (hPa) in a profile of (hPa, m), descending pressure: linear in
/// ln p between levels, the end segments extended beyond them; the standard atmosphere
/// (shifted onto the one level there is) with fewer than two levels.
pub fn altitude_at(profile: &[(f64, f64)], p: f64) -> f64 {
    match profile {
        [] => standard_altitude_m(p),
        [(p0, z0)] => z0 + standard_altitude_m(p) - standard_altitude_m(*p0),
        _ => {
            let k = profile
                .windows(2)
                .position(|w| p >= w[1].0)
                .unwrap_or(profile.len() - 2);
            let ((pa, za), (pb, zb)) = (profile[k], profile[k + 1]);
            let t = (p.ln() - pa.ln()) / (pb.ln() - pa.ln());
            za + t * (zb - za)
        }
    }
}

/// Where RH crosses `rh_cr` around the layer's wettest level, as (bottom, top) hPa, or `None`
/// when no level of the layer reaches rh_cr. `column` is (hPa, RH %) for every loaded level,
/// descending pressure. The cloud is the run of the layer's levels at or above rh_cr around its
/// wettest level; its bottom (top) is the log-p crossing with the level below (above) when that
/// level is drier, the layer's bound when the wet air goes on past it, and the outermost level
/// when there is none beyond.
pub fn rh_column(column: &[(f64, f64)], kind: LayerKind, rh_cr: f64) -> Option<(f64, f64)> {
    let (l_bottom, l_top) = layer_span_hpa(kind);
    let inside: Vec<usize> = (0..column.len())
        .filter(|&k| LayerKind::of_pressure_hpa(column[k].0) == kind)
        .collect();
    let wettest = *inside
        .iter()
        .max_by(|&&a, &&b| column[a].1.total_cmp(&column[b].1))?;
    let cr = rh_cr * 100.0;
    if column[wettest].1 <= cr {
        return None;
    }
    let wet = |k: usize| inside.contains(&k) && column[k].1 >= cr;
    let (mut lo, mut hi) = (wettest, wettest);
    while lo > 0 && wet(lo - 1) {
        lo -= 1;
    }
    while hi + 1 < column.len() && wet(hi + 1) {
        hi += 1;
    }
    // log-p crossing between a wet level `a` and its neighbour `b`.
    let cross = |a: usize, b: usize| {
        let ((pa, ra), (pb, rb)) = (column[a], column[b]);
        let t = ((ra - cr) / (ra - rb)).clamp(0.0, 1.0);
        (pa.ln() + t * (pb.ln() - pa.ln())).exp()
    };
    let bottom = match lo.checked_sub(1) {
        Some(b) if column[b].1 < cr => cross(lo, b).min(l_bottom),
        Some(_) => l_bottom.min(column[lo - 1].0),
        None => column[lo].0,
    };
    let top = match hi + 1 < column.len() {
        true if column[hi + 1].1 < cr => cross(hi, hi + 1).max(l_top),
        true => l_top.max(column[hi + 1].0),
        false => column[hi].0,
    };
    Some((bottom, top))
}

impl GridStructure {
    /// Compute the structure of `layers` from the RH levels and the other fields.
    pub fn compute(
        levels: &[RhLevel],
        inputs: &WeatherInputs,
        layers: &[LayerSpec],
        ni: usize,
        nj: usize,
    ) -> GridStructure {
        let n = ni * nj;
        let has_conv = inputs.convective_hpa.is_some();
        let at = |g: &Option<Vec<f32>>, k: usize| {
            g.as_ref()
                .and_then(|g| g.get(k))
                .map(|&v| v as f64)
                .filter(|v| v.is_finite())
        };
        let mut out: [Option<GridLayer>; 3] = Default::default();
        for spec in layers {
            out[spec.kind.channel()] = Some(GridLayer {
                kind: spec.kind,
                base_m: Vec::with_capacity(n),
                top_m: Vec::with_capacity(n),
                source: Vec::with_capacity(n),
                cloud_type: Vec::with_capacity(n),
            });
        }
        let mut conv = (Vec::with_capacity(n), Vec::with_capacity(n));
        let mut profile = Vec::with_capacity(inputs.gh.len());
        let mut column = Vec::with_capacity(levels.len());
        let (lo_alt, hi_alt) = (*ALTITUDE_RANGE_M.start(), *ALTITUDE_RANGE_M.end());
        for k in 0..n {
            profile.clear();
            profile.extend(
                inputs
                    .gh
                    .iter()
                    .filter_map(|(p, g)| Some((*p, *g.get(k)? as f64))),
            );
            let alt = |p: f64| altitude_at(&profile, p).clamp(lo_alt, hi_alt);
            column.clear();
            column.extend(
                levels
                    .iter()
                    .filter_map(|l| Some((l.pressure_hpa, *l.field.values.get(k)?))),
            );
            let ground = at(&inputs.surface_gh, k).unwrap_or(lo_alt);
            let pair = |g: &Option<(Vec<f32>, Vec<f32>)>| -> Option<(f64, f64)> {
                let (b, t) = g.as_ref()?;
                let (b, t) = (*b.get(k)? as f64, *t.get(k)? as f64);
                (b.is_finite() && t.is_finite() && b > t && t > 0.0).then_some((b, t))
            };
            let conv_hpa = pair(&inputs.convective_hpa);
            let facts = ColumnFacts {
                has_convective_fields: has_conv,
                convective_cloud_hpa: conv_hpa,
                conv_precip_mm_h: at(&inputs.conv_precip_mm_h, k),
                cape: at(&inputs.cape, k),
                lifted_index: at(&inputs.lifted_index, k),
            };
            match conv_hpa {
                Some((b, t)) => {
                    conv.0.push(alt(b).max(ground) as f32);
                    conv.1
                        .push(alt(t).max(alt(b).max(ground) + MIN_DEPTH_M) as f32);
                }
                None => {
                    conv.0.push(f32::NAN);
                    conv.1.push(f32::NAN);
                }
            }
            for spec in layers {
                let c = spec.kind.channel();
                let Some(gl) = out[c].as_mut() else { continue };
                let (source, base, top) = if let Some((b, t)) = pair(&inputs.cloud_hpa[c]) {
                    (PointSource::GfsLayer, alt(b), alt(t))
                } else if let Some((b, t)) = rh_column(&column, spec.kind, spec.rh_cr) {
                    (PointSource::RhColumn, alt(b), alt(t))
                } else {
                    (PointSource::Band, spec.band_base_m, spec.band_top_m)
                };
                let base = base.max(ground).min(hi_alt - MIN_DEPTH_M);
                let top = top.max(base + MIN_DEPTH_M);
                let tau = at(&inputs.tau[c], k);
                gl.base_m.push(base as f32);
                gl.top_m.push(top as f32);
                gl.source.push(source);
                gl.cloud_type.push(classify(spec.kind, &facts, tau).code());
            }
        }
        GridStructure {
            ni,
            nj,
            layers: out,
            convective_m: conv,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn altitude_is_log_pressure_linear_and_extends() {
        let prof = [(1000.0, 100.0), (500.0, 5600.0)];
        assert!((altitude_at(&prof, 1000.0) - 100.0).abs() < 1e-9);
        assert!((altitude_at(&prof, 500.0) - 5600.0).abs() < 1e-9);
        // Half-way in ln p, not in p.
        let mid = (1000.0f64 * 500.0).sqrt();
        assert!((altitude_at(&prof, mid) - 2850.0).abs() < 1e-6);
        assert!(altitude_at(&prof, 250.0) > 10_000.0);
        assert!(altitude_at(&prof, 1050.0) < 100.0);
        assert!((altitude_at(&[], 500.0) - standard_altitude_m(500.0)).abs() < 1e-9);
    }

    #[test]
    fn rh_column_finds_the_crossings() {
        // Wet between 850 and 700 hPa: RH crosses 80 % half-way (in RH, hence in ln p)
        // between 925 (60 %) and 850 (100 %), and between 700 (90 %) and 600 (70 %)…
        let col = [
            (1000.0, 50.0),
            (925.0, 60.0),
            (850.0, 100.0),
            (700.0, 90.0),
            (600.0, 70.0),
            (500.0, 20.0),
        ];
        let (b, t) = rh_column(&col, LayerKind::Low, 0.8).unwrap();
        assert!((b - (925.0f64 * 850.0).sqrt()).abs() < 1e-6, "{b}");
        // …but the low layer ends at 680 hPa, and its wet run (850, 700) stops at its last
        // level: the crossing with 600 is past the bound, so the top is the bound.
        assert!((t - 680.0).abs() < 1e-6, "{t}");
        // The middle layer is dry at its own levels with rh_cr 0.8 (600: 70 %, 500: 20 %).
        assert_eq!(rh_column(&col, LayerKind::Middle, 0.8), None);
        // With rh_cr 0.65, 600 hPa is wet; below it the low layer is wet too: bottom = bound.
        let (b, t) = rh_column(&col, LayerKind::Middle, 0.65).unwrap();
        assert!((b - 680.0).abs() < 1e-6, "{b}");
        let want = (600.0f64.ln() + (5.0 / 50.0) * (500.0f64.ln() - 600.0f64.ln())).exp();
        assert!((t - want).abs() < 1e-6, "{t} vs {want}");
        // A wet lowest level has no level below: the bottom is that level.
        let fog = [(1000.0, 100.0), (925.0, 50.0)];
        let (b, _) = rh_column(&fog, LayerKind::Low, 0.8).unwrap();
        assert_eq!(b, 1000.0);
    }
}
