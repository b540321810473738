//! The fields beside RH that give a map its vertical structure, cloud types and winds, read
//! from the same GRIB2 file on the same grid. Every one is optional: a file that lacks a field
//! (or whose field does not decode, or lies on another grid) gives the next source down, never
//! an error. Level stacks that only feed per-layer sums (winds, condensate) are folded into
//! those sums as they are decoded, so memory stays a few fields however many levels there are.

use std::path::Path;

use crate::grib::{self, Field, LatLonGrid, MessageInfo, SurfaceType};
use crate::layer::LayerKind;

use super::kind::{layer_span_hpa, optical_thickness, ICE_BELOW_K};

/// Gravity, m s⁻² (for the mass of air between two pressures: Δp / g).
const G: f64 = 9.80665;

/// A field on the RH grid, row-major north→south; NaN where missing (bit-map).
pub type Grid32 = Vec<f32>;

/// RH on one isobaric level, in percent, NaN-free, rows north→south.
#[derive(Debug, Clone)]
pub struct RhLevel {
    pub pressure_hpa: f64,
    pub field: Field,
}

/// What the file holds besides RH, on the RH grid.
#[derive(Debug, Clone, Default)]
pub struct WeatherInputs {
    /// Geopotential height (m) on isobaric levels, descending pressure (hPa).
    pub gh: Vec<(f64, Grid32)>,
    /// Surface geopotential height (orography), m.
    pub surface_gh: Option<Grid32>,
    /// GFS's cloud bottom and top pressure (hPa) per layer (low, middle, high); NaN where GFS
    /// has no cloud of that layer.
    pub cloud_hpa: [Option<(Grid32, Grid32)>; 3],
    /// GFS's convective cloud bottom and top pressure (hPa); NaN where none.
    pub convective_hpa: Option<(Grid32, Grid32)>,
    /// Convective precipitation rate, mm/h.
    pub conv_precip_mm_h: Option<Grid32>,
    /// Surface CAPE (J/kg) and lifted index (K).
    pub cape: Option<Grid32>,
    pub lifted_index: Option<Grid32>,
    /// Per layer: visible optical thickness from GFS's cloud mixing ratio.
    pub tau: [Option<Grid32>; 3],
    /// Per layer: mass-weighted mean wind (u, v), m/s.
    pub wind: [Option<(Grid32, Grid32)>; 3],
    /// Names of the fields found, for the sidecar ("cloud-layer pressures", "cape", …).
    pub found: Vec<&'static str>,
}

impl WeatherInputs {
    /// Read what there is from `msgs` of `bytes`, on `grid`, for levels up to `top_hpa`.
    pub fn load(
        path: &Path,
        bytes: &[u8],
        msgs: &[MessageInfo],
        grid: &Option<LatLonGrid>,
        top_hpa: f64,
    ) -> WeatherInputs {
        let mut w = WeatherInputs::default();
        let decode = |m: &MessageInfo| -> Option<Grid32> {
            if &m.grid != grid {
                return None;
            }
            match grib::decode_values(bytes, m) {
                Ok(f) => Some(f.values.iter().map(|&v| v as f32).collect()),
                Err(e) => {
                    tracing::warn!("{}: {} skipped: {e}", path.display(), m.short_name());
                    None
                }
            }
        };
        let find = |param: &[(u8, u8, u8)], level: SurfaceType| {
            msgs.iter()
                .find(|m| param.contains(&m.parameter()) && m.level_type == Some(level))
        };
        let get = |param: &[(u8, u8, u8)], level: SurfaceType| find(param, level).and_then(decode);
        const PRES: &[(u8, u8, u8)] = &[(0, 3, 0)];
        use SurfaceType as S;
        // Pressures are in Pa in the file.
        let hpa = |g: Grid32| -> Grid32 { g.into_iter().map(|v| v / 100.0).collect() };
        let pair = |b: SurfaceType, t: SurfaceType| match (get(PRES, b), get(PRES, t)) {
            (Some(b), Some(t)) => Some((hpa(b), hpa(t))),
            _ => None,
        };
        w.cloud_hpa = [
            pair(S::LowCloudBottom, S::LowCloudTop),
            pair(S::MiddleCloudBottom, S::MiddleCloudTop),
            pair(S::HighCloudBottom, S::HighCloudTop),
        ];
        if w.cloud_hpa.iter().any(Option::is_some) {
            w.found.push("cloud-layer-pressures");
        }
        w.convective_hpa = pair(S::ConvectiveCloudBottom, S::ConvectiveCloudTop);
        if w.convective_hpa.is_some() {
            w.found.push("convective-cloud-pressures");
        }
        // WMO 0.1.37 or NCEP's local 0.1.196, kg m⁻² s⁻¹ → mm/h.
        w.conv_precip_mm_h = get(&[(0, 1, 37), (0, 1, 196)], S::Surface)
            .map(|g| g.into_iter().map(|v| v * 3600.0).collect());
        if w.conv_precip_mm_h.is_some() {
            w.found.push("convective-precipitation-rate");
        }
        w.cape = get(&[(0, 7, 6)], S::Surface);
        if w.cape.is_some() {
            w.found.push("cape");
        }
        // Surface lifted index (WMO 0.7.10, NCEP 0.7.192), else the best four-layer one.
        w.lifted_index = get(&[(0, 7, 10), (0, 7, 192)], S::Surface)
            .or_else(|| get(&[(0, 7, 11), (0, 7, 193)], S::Surface));
        if w.lifted_index.is_some() {
            w.found.push("lifted-index");
        }
        w.surface_gh = get(&[(0, 3, 5)], S::Surface);
        if w.surface_gh.is_some() {
            w.found.push("orography");
        }

        // Isobaric stacks up to `top_hpa`, one level at a time.
        let iso_from = |param: (u8, u8, u8), top: f64| -> Vec<(f64, &MessageInfo)> {
            let mut v: Vec<(f64, &MessageInfo)> = msgs
                .iter()
                .filter(|m| m.parameter() == param)
                .filter_map(|m| Some((m.pressure_hpa()?, m)))
                .filter(|(p, _)| *p >= top - 1e-6)
                .collect();
            v.sort_by(|a, b| b.0.total_cmp(&a.0));
            v.dedup_by(|a, b| (a.0 - b.0).abs() < 1e-6);
            v
        };
        let iso = |param: (u8, u8, u8)| iso_from(param, top_hpa);
        // gh a little above the top too: GFS puts tropical high-cloud tops near 80 hPa.
        w.gh = iso_from((0, 3, 5), top_hpa.min(50.0))
            .into_iter()
            .filter_map(|(p, m)| Some((p, decode(m)?)))
            .filter(|(_, g)| g.iter().all(|v| v.is_finite()))
            .collect();
        if !w.gh.is_empty() {
            w.found.push("geopotential-height");
        }
        let n = grid.as_ref().map_or(0, |g| g.ni * g.nj);
        // Winds: Σ u·Δp / Σ Δp per layer.
        let us = iso((0, 2, 2));
        let vs = iso((0, 2, 3));
        let levels: Vec<f64> = us.iter().map(|x| x.0).collect();
        let weights = layer_weights(&levels);
        let mut acc: [Option<WindSum>; 3] = Default::default();
        for ((p, um), (kind, dp)) in us.iter().zip(&weights) {
            let Some(vm) = vs.iter().find(|(q, _)| (q - p).abs() < 1e-6).map(|x| x.1) else {
                continue;
            };
            let (Some(u), Some(v)) = (decode(um), decode(vm)) else {
                continue;
            };
            let a = acc[kind.channel()].get_or_insert_with(|| (vec![0.0; n], vec![0.0; n], 0.0));
            for k in 0..n.min(u.len()).min(v.len()) {
                a.0[k] += u[k] as f64 * dp;
                a.1[k] += v[k] as f64 * dp;
            }
            a.2 += dp;
        }
        w.wind = acc.map(|a| {
            a.filter(|a| a.2 > 0.0).map(|(u, v, sum)| {
                let f = |x: Vec<f64>| x.into_iter().map(|s| (s / sum) as f32).collect();
                (f(u), f(v))
            })
        });
        if w.wind.iter().any(Option::is_some) {
            w.found.push("winds");
        }
        // Condensate: τ = Σ optical thickness of clwmr·Δp/g, phase from t on the level.
        let cw = iso((0, 1, 22));
        let ts = iso((0, 0, 0));
        let levels: Vec<f64> = cw.iter().map(|x| x.0).collect();
        let weights = layer_weights(&levels);
        let mut tau: [Option<Vec<f64>>; 3] = Default::default();
        for ((p, cm), (kind, dp)) in cw.iter().zip(&weights) {
            let Some(q) = decode(cm) else { continue };
            let t = ts
                .iter()
                .find(|(tp, _)| (tp - p).abs() < 1e-6)
                .and_then(|x| decode(x.1));
            let a = tau[kind.channel()].get_or_insert_with(|| vec![0.0; n]);
            for k in 0..n.min(q.len()) {
                let path = (q[k] as f64).max(0.0) * dp * 100.0 / G;
                // Without t on the level, the upper troposphere is taken as ice.
                let ice = t
                    .as_ref()
                    .and_then(|t| t.get(k))
                    .map_or(*p < 500.0, |&t| (t as f64) < ICE_BELOW_K);
                if path.is_finite() {
                    a[k] += optical_thickness(path, ice);
                }
            }
        }
        w.tau = tau.map(|t| t.map(|t| t.into_iter().map(|v| v as f32).collect()));
        if w.tau.iter().any(Option::is_some) {
            w.found.push("cloud-mixing-ratio");
        }
        w
    }
}

/// Σ u·Δp, Σ v·Δp per point, and Σ Δp.
type WindSum = (Vec<f64>, Vec<f64>, f64);

/// For isobaric levels (descending hPa): each level's layer and the pressure thickness (hPa) it
/// stands for — half-way to its neighbours, cut at the layer's bounds, the end levels' outer
/// halves mirrored — so a layer's weights sum to the pressure depth its levels cover.
pub fn layer_weights(levels: &[f64]) -> Vec<(LayerKind, f64)> {
    let n = levels.len();
    if n == 1 {
        // One level stands for its layer alone.
        return vec![(LayerKind::of_pressure_hpa(levels[0]), 1.0)];
    }
    (0..n)
        .map(|k| {
            let p = levels[k];
            let kind = LayerKind::of_pressure_hpa(p);
            let (l_bottom, l_top) = layer_span_hpa(kind);
            // Half-way to a neighbour of the same layer; to the layer's bound when the
            // neighbour is in another layer; mirrored past the outermost levels.
            let edge = |nb: Option<f64>, mirror: f64, bound: f64| match nb {
                Some(q) if LayerKind::of_pressure_hpa(q) == kind => 0.5 * (p + q),
                Some(_) => bound,
                None => 0.5 * (p + mirror),
            };
            let lo = edge(
                k.checked_sub(1).map(|b| levels[b]),
                2.0 * p - levels[1],
                l_bottom,
            )
            .min(l_bottom);
            let hi = edge(levels.get(k + 1).copied(), 2.0 * p - levels[n - 2], l_top).max(l_top);
            (kind, (lo - hi).max(0.0))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layer_weights_cover_each_layer_once() {
        let levels = [1000.0, 900.0, 700.0, 500.0, 300.0, 200.0];
        let w = layer_weights(&levels);
        let sum = |k: LayerKind| -> f64 { w.iter().filter(|x| x.0 == k).map(|x| x.1).sum() };
        // Low: 1050 (mirrored) .. 680; middle 680..440; high 440..150 (mirrored).
        assert!((sum(LayerKind::Low) - 370.0).abs() < 1e-9, "{w:?}");
        assert!((sum(LayerKind::Middle) - 240.0).abs() < 1e-9, "{w:?}");
        assert!((sum(LayerKind::High) - 290.0).abs() < 1e-9, "{w:?}");
        assert_eq!(layer_weights(&[500.0]), vec![(LayerKind::Middle, 1.0)]);
    }
}
