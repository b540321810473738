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
        let r = Reader {
            path,
            bytes,
            msgs,
            grid,
        };
        let mut w = WeatherInputs::default();
        w.load_surface(&r);
        w.load_gh(&r, top_hpa);
        let n = grid.as_ref().map_or(0, |g| g.ni * g.nj);
        w.load_winds(&r, top_hpa, n);
        w.load_condensate(&r, top_hpa, n);
        w
    }

    /// The single-level fields: GFS's cloud layer and convective cloud pressures, convective
    /// precipitation, CAPE, lifted index and orography.
    fn load_surface(&mut self, r: &Reader) {
        use SurfaceType as S;
        self.cloud_hpa = [
            r.pair(S::LowCloudBottom, S::LowCloudTop),
            r.pair(S::MiddleCloudBottom, S::MiddleCloudTop),
            r.pair(S::HighCloudBottom, S::HighCloudTop),
        ];
        if self.cloud_hpa.iter().any(Option::is_some) {
            self.found.push("cloud-layer-pressures");
        }
        self.convective_hpa = r.pair(S::ConvectiveCloudBottom, S::ConvectiveCloudTop);
        if self.convective_hpa.is_some() {
            self.found.push("convective-cloud-pressures");
        }
        // WMO 0.1.37 or NCEP's local 0.1.196, kg m⁻² s⁻¹ → mm/h.
        self.conv_precip_mm_h = r
            .get(&[(0, 1, 37), (0, 1, 196)], S::Surface)
            .map(|g| g.into_iter().map(|v| v * 3600.0).collect());
        if self.conv_precip_mm_h.is_some() {
            self.found.push("convective-precipitation-rate");
        }
        self.cape = r.get(&[(0, 7, 6)], S::Surface);
        if self.cape.is_some() {
            self.found.push("cape");
        }
        // Surface lifted index (WMO 0.7.10, NCEP 0.7.192), else the best four-layer one.
        self.lifted_index = r
            .get(&[(0, 7, 10), (0, 7, 192)], S::Surface)
            .or_else(|| r.get(&[(0, 7, 11), (0, 7, 193)], S::Surface));
        if self.lifted_index.is_some() {
            self.found.push("lifted-index");
        }
        self.surface_gh = r.get(&[(0, 3, 5)], S::Surface);
        if self.surface_gh.is_some() {
            self.found.push("orography");
        }
    }

    /// Geopotential height on the isobaric levels.
    fn load_gh(&mut self, r: &Reader, top_hpa: f64) {
        // gh a little above the top too: GFS puts tropical high-cloud tops near 80 hPa.
        self.gh = r
            .iso_from((0, 3, 5), top_hpa.min(50.0))
            .into_iter()
            .filter_map(|(p, m)| Some((p, r.decode(m)?)))
            .filter(|(_, g)| g.iter().all(|v| v.is_finite()))
            .collect();
        if !self.gh.is_empty() {
            self.found.push("geopotential-height");
        }
    }

    /// Each layer's mass-weighted mean wind over `n` grid points.
    fn load_winds(&mut self, r: &Reader, top_hpa: f64, n: usize) {
        // Winds: Σ u·Δp / Σ Δp per layer.
        let us = r.iso_from((0, 2, 2), top_hpa);
        let vs = r.iso_from((0, 2, 3), top_hpa);
        let levels: Vec<f64> = us.iter().map(|x| x.0).collect();
        let weights = layer_weights(&levels);
        let mut acc: [Option<WindSum>; 3] = Default::default();
        for ((p, um), (kind, dp)) in us.iter().zip(&weights) {
            let Some(vm) = vs.iter().find(|(q, _)| (q - p).abs() < 1e-6).map(|x| x.1) else {
                continue;
            };
            let (Some(u), Some(v)) = (r.decode(um), r.decode(vm)) else {
                continue;
            };
            let a = acc[kind.channel()].get_or_insert_with(|| (vec![0.0; n], vec![0.0; n], 0.0));
            for k in 0..n.min(u.len()).min(v.len()) {
                a.0[k] += u[k] as f64 * dp;
                a.1[k] += v[k] as f64 * dp;
            }
            a.2 += dp;
        }
        self.wind = acc.map(|a| {
            a.filter(|a| a.2 > 0.0).map(|(u, v, sum)| {
                let f = |x: Vec<f64>| x.into_iter().map(|s| (s / sum) as f32).collect();
                (f(u), f(v))
            })
        });
        if self.wind.iter().any(Option::is_some) {
            self.found.push("winds");
        }
    }

    /// Each layer's optical thickness over `n` grid points.
    fn load_condensate(&mut self, r: &Reader, top_hpa: f64, n: usize) {
        // Condensate: τ = Σ optical thickness of clwmr·Δp/g, phase from t on the level.
        let cw = r.iso_from((0, 1, 22), top_hpa);
        let ts = r.iso_from((0, 0, 0), top_hpa);
        let levels: Vec<f64> = cw.iter().map(|x| x.0).collect();
        let weights = layer_weights(&levels);
        let mut tau: [Option<Vec<f64>>; 3] = Default::default();
        for ((p, cm), (kind, dp)) in cw.iter().zip(&weights) {
            let Some(q) = r.decode(cm) else { continue };
            let t = ts
                .iter()
                .find(|(tp, _)| (tp - p).abs() < 1e-6)
                .and_then(|x| r.decode(x.1));
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
        self.tau = tau.map(|t| t.map(|t| t.into_iter().map(|v| v as f32).collect()));
        if self.tau.iter().any(Option::is_some) {
            self.found.push("cloud-mixing-ratio");
        }
    }
}

/// The file a [`WeatherInputs`] is read from: its messages and the RH grid they must share.
struct Reader<'a> {
    path: &'a Path,
    bytes: &'a [u8],
    msgs: &'a [MessageInfo],
    grid: &'a Option<LatLonGrid>,
}

impl<'a> Reader<'a> {
    /// A message's values as f32, if it is on the RH grid and decodes (else skipped, logged).
    fn decode(&self, m: &MessageInfo) -> Option<Grid32> {
        if &m.grid != self.grid {
            return None;
        }
        match grib::decode_values(self.bytes, m) {
            Ok(f) => Some(f.values.iter().map(|&v| v as f32).collect()),
            Err(e) => {
                tracing::warn!("{}: {} skipped: {e}", self.path.display(), m.short_name());
                None
            }
        }
    }

    /// The first message of one of `param` on `level`, decoded.
    fn get(&self, param: &[(u8, u8, u8)], level: SurfaceType) -> Option<Grid32> {
        self.msgs
            .iter()
            .find(|m| param.contains(&m.parameter()) && m.level_type == Some(level))
            .and_then(|m| self.decode(m))
    }

    /// Bottom and top pressure (hPa; Pa in the file) of a cloud, when both are there.
    fn pair(&self, b: SurfaceType, t: SurfaceType) -> Option<(Grid32, Grid32)> {
        const PRES: &[(u8, u8, u8)] = &[(0, 3, 0)];
        let hpa = |g: Grid32| -> Grid32 { g.into_iter().map(|v| v / 100.0).collect() };
        match (self.get(PRES, b), self.get(PRES, t)) {
            (Some(b), Some(t)) => Some((hpa(b), hpa(t))),
            _ => None,
        }
    }

    /// Isobaric stack of `param` up to `top` hPa, one message a level, descending pressure.
    fn iso_from(&self, param: (u8, u8, u8), top: f64) -> Vec<(f64, &'a MessageInfo)> {
        let mut v: Vec<(f64, &MessageInfo)> = self
            .msgs
            .iter()
            .filter(|m| m.parameter() == param)
            .filter_map(|m| Some((m.pressure_hpa()?, m)))
            .filter(|(p, _)| *p >= top - 1e-6)
            .collect();
        v.sort_by(|a, b| b.0.total_cmp(&a.0));
        v.dedup_by(|a, b| (a.0 - b.0).abs() < 1e-6);
        v
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
