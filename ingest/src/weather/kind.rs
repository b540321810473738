//! The documented rule that picks a cloud genus ([`CloudType`], in `cloud`) per grid point and
//! layer from the forecast's convective and stability fields (docs/ingest.md, "Cloud type
//! rule").

use crate::cloud::CloudType;
use crate::layer::{LayerKind, LOW_TOP_HPA, MIDDLE_TOP_HPA};

/// Thresholds of the rule, with their sources in docs/ingest.md.
pub mod thresholds {
    /// A convective cloud whose top is at or above this pressure (hPa) is deep (DESIGN §7,
    /// ~7 km in the standard atmosphere: the glaciated, anvil-forming range).
    pub const DEEP_TOP_HPA: f64 = 400.0;
    /// Convective precipitation rate that counts as rain from it, mm/h (AMS Glossary:
    /// "light rain" starts at a trace; 0.1 mm/h is the smallest rate gauges report).
    pub const CONV_RAIN_MM_H: f64 = 0.1;
    /// Without GFS's convective cloud: CAPE (J/kg) and lifted index (K) of a deep-convective
    /// environment (NWS/SPC: CAPE ≥ 1000 moderate instability; LI ≤ −3 moderately unstable)…
    pub const DEEP_CAPE: f64 = 1000.0;
    pub const DEEP_LI: f64 = -3.0;
    /// …and of shallow convection: a buoyant surface parcel (LI < 0) with some CAPE.
    pub const SHALLOW_CAPE: f64 = 100.0;
    /// ISCCP optical-thickness class boundaries (Rossow & Schiffer 1999).
    pub const TAU_THIN: f64 = 3.6;
    pub const TAU_THICK: f64 = 23.0;
}

/// What the file says at one grid point, as the rule reads it. `None`: the file lacks the
/// field (or it is missing there under a bit-map where that means "unknown").
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ColumnFacts {
    /// Whether the file has GFS's convective cloud bottom/top at all.
    pub has_convective_fields: bool,
    /// GFS's convective cloud at this point: (bottom, top) pressure, hPa.
    pub convective_cloud_hpa: Option<(f64, f64)>,
    /// Convective precipitation rate, mm/h.
    pub conv_precip_mm_h: Option<f64>,
    /// Surface CAPE, J/kg.
    pub cape: Option<f64>,
    /// Surface (or best four-layer) lifted index, K.
    pub lifted_index: Option<f64>,
}

/// Regime of the column as a whole.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Convection {
    None,
    /// Convective cloud that is not deep: cumulus where it spans.
    Shallow,
    /// Deep convection with rain: cumulonimbus where it spans.
    Deep,
}

impl ColumnFacts {
    /// The column's convective regime and the pressure span (bottom, top hPa) it occupies.
    pub fn convection(&self) -> (Convection, (f64, f64)) {
        use thresholds::*;
        if self.has_convective_fields {
            let Some((bottom, top)) = self.convective_cloud_hpa.filter(|(b, t)| b > t) else {
                return (Convection::None, (0.0, 0.0));
            };
            let rains = match self.conv_precip_mm_h {
                Some(r) => r >= CONV_RAIN_MM_H,
                None => self.cape.is_some_and(|c| c >= DEEP_CAPE),
            };
            let regime = if top <= DEEP_TOP_HPA && rains {
                Convection::Deep
            } else {
                Convection::Shallow
            };
            return (regime, (bottom, top));
        }
        // No convective cloud fields (analyses): the stability indices alone.
        match (self.cape, self.lifted_index) {
            (Some(c), Some(li)) if c >= DEEP_CAPE && li <= DEEP_LI => {
                (Convection::Deep, (f64::INFINITY, 0.0))
            }
            (Some(c), Some(li)) if c >= SHALLOW_CAPE && li < 0.0 => {
                (Convection::Shallow, (f64::INFINITY, LOW_TOP_HPA))
            }
            _ => (Convection::None, (0.0, 0.0)),
        }
    }
}

/// Pressure range (bottom, top) of a layer, hPa (ISCCP: low > 680, middle 680–440, high < 440).
pub fn layer_span_hpa(kind: LayerKind) -> (f64, f64) {
    match kind {
        LayerKind::Low => (f64::INFINITY, LOW_TOP_HPA),
        LayerKind::Middle => (LOW_TOP_HPA, MIDDLE_TOP_HPA),
        LayerKind::High => (MIDDLE_TOP_HPA, 0.0),
    }
}

/// The rule: the genus of `kind`'s cloud at a column with `facts`, where `tau` is the layer's
/// optical thickness estimated from GFS's cloud condensate (`None` when the file has none).
pub fn classify(kind: LayerKind, facts: &ColumnFacts, tau: Option<f64>) -> CloudType {
    use thresholds::*;
    let (regime, (c_bottom, c_top)) = facts.convection();
    let (l_bottom, l_top) = layer_span_hpa(kind);
    // The convective cloud spans this layer when their pressure ranges overlap.
    let spans = c_bottom > l_top && c_top < l_bottom;
    match regime {
        Convection::Deep if spans => return CloudType::Cumulonimbus,
        Convection::Shallow if spans => return CloudType::Cumulus,
        _ => {}
    }
    let Some(tau) = tau else {
        return CloudType::layer_default(kind);
    };
    match kind {
        LayerKind::Low if tau >= TAU_THICK => CloudType::Stratus,
        LayerKind::Low => CloudType::Stratocumulus,
        LayerKind::Middle if tau >= TAU_THICK => CloudType::Nimbostratus,
        LayerKind::Middle if tau >= TAU_THIN => CloudType::Altostratus,
        LayerKind::Middle => CloudType::Altocumulus,
        LayerKind::High if tau >= TAU_THIN => CloudType::Cirrostratus,
        LayerKind::High => CloudType::Cirrus,
    }
}

/// Visible optical thickness of a condensate path (kg/m²) of one phase, after Stephens (1978):
/// τ = 3·W / (2·ρ·r_e), with the effective radii ISCCP assumes (liquid 10 µm, ice 30 µm).
pub fn optical_thickness(path_kg_m2: f64, ice: bool) -> f64 {
    let (rho, r_e) = if ice { (917.0, 30e-6) } else { (1000.0, 10e-6) };
    1.5 * path_kg_m2 / (rho * r_e)
}

/// Cloud colder than this (K) is taken as ice, as ISCCP does for its phase.
pub const ICE_BELOW_K: f64 = 260.0;

#[cfg(test)]
mod tests {
    use super::*;
    use CloudType as T;
    use LayerKind::{High, Low, Middle};

    fn gfs(conv: Option<(f64, f64)>, rain: f64) -> ColumnFacts {
        ColumnFacts {
            has_convective_fields: true,
            convective_cloud_hpa: conv,
            conv_precip_mm_h: Some(rain),
            cape: Some(500.0),
            lifted_index: Some(-2.0),
        }
    }

    #[test]
    fn codes_are_stable_and_round_trip() {
        let codes: Vec<u8> = CloudType::ALL.iter().map(|t| t.code()).collect();
        assert_eq!(codes, (1..=10).collect::<Vec<u8>>());
        assert_eq!(CloudType::Cumulonimbus.code(), 10);
        assert_eq!(CloudType::Cirrus.code(), 1);
        for t in CloudType::ALL {
            assert_eq!(CloudType::from_code(t.code()), Some(t));
            assert_eq!(
                serde_json::to_string(&t).unwrap(),
                format!("\"{}\"", t.name())
            );
        }
        assert_eq!(CloudType::from_code(0), None);
        assert_eq!(CloudType::from_code(11), None);
    }

    #[test]
    fn deep_convection_with_rain_is_cumulonimbus_through_the_column() {
        let f = gfs(Some((900.0, 300.0)), 0.4);
        for k in [Low, Middle, High] {
            assert_eq!(classify(k, &f, Some(1.0)), T::Cumulonimbus, "{k:?}");
        }
        // The same tower without rain, or topping out below 400 hPa, is cumulus.
        assert_eq!(
            classify(Low, &gfs(Some((900.0, 300.0)), 0.05), None),
            T::Cumulus
        );
        let congestus = gfs(Some((900.0, 500.0)), 2.0);
        assert_eq!(classify(Low, &congestus, None), T::Cumulus);
        assert_eq!(classify(Middle, &congestus, None), T::Cumulus);
        // Above the convective top the layer is what its condensate says.
        assert_eq!(classify(High, &congestus, Some(1.0)), T::Cirrus);
    }

    #[test]
    fn shallow_convection_marks_only_the_layers_it_spans() {
        let f = gfs(Some((950.0, 800.0)), 0.0);
        assert_eq!(classify(Low, &f, Some(30.0)), T::Cumulus);
        assert_eq!(classify(Middle, &f, Some(30.0)), T::Nimbostratus);
    }

    #[test]
    fn stratiform_layers_follow_the_isccp_optical_thickness_classes() {
        let f = gfs(None, 0.0);
        assert_eq!(classify(Low, &f, Some(2.0)), T::Stratocumulus);
        assert_eq!(classify(Low, &f, Some(40.0)), T::Stratus);
        assert_eq!(classify(Middle, &f, Some(2.0)), T::Altocumulus);
        assert_eq!(classify(Middle, &f, Some(10.0)), T::Altostratus);
        assert_eq!(classify(Middle, &f, Some(23.0)), T::Nimbostratus);
        assert_eq!(classify(High, &f, Some(3.5)), T::Cirrus);
        assert_eq!(classify(High, &f, Some(3.6)), T::Cirrostratus);
        // GFS says no convection here: CAPE alone does not make cumulus.
        let unstable = ColumnFacts {
            cape: Some(3000.0),
            lifted_index: Some(-8.0),
            ..f
        };
        assert_eq!(classify(Low, &unstable, Some(2.0)), T::Stratocumulus);
    }

    #[test]
    fn without_convective_fields_the_stability_indices_decide() {
        let f = |cape, li| ColumnFacts {
            has_convective_fields: false,
            convective_cloud_hpa: None,
            conv_precip_mm_h: None,
            cape: Some(cape),
            lifted_index: Some(li),
        };
        assert_eq!(classify(High, &f(2000.0, -5.0), Some(1.0)), T::Cumulonimbus);
        assert_eq!(classify(Low, &f(300.0, -1.0), Some(1.0)), T::Cumulus);
        assert_eq!(classify(Middle, &f(300.0, -1.0), Some(1.0)), T::Altocumulus);
        assert_eq!(classify(Low, &f(300.0, 2.0), Some(1.0)), T::Stratocumulus);
        // Nothing at all: the layer defaults.
        let none = ColumnFacts::default();
        assert_eq!(classify(Middle, &none, None), T::Altostratus);
    }

    #[test]
    fn optical_thickness_is_stephens() {
        // 0.1 kg/m² of 10 µm droplets: τ = 15.
        assert!((optical_thickness(0.1, false) - 15.0).abs() < 1e-9);
        assert!(optical_thickness(0.1, true) < 6.0);
    }
}
