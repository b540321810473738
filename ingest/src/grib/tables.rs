//! WMO GRIB2 code tables as enums (WMO Manual on Codes, FM 92 GRIB edition 2).
//!
//! Only the entries stratus names or acts on get a variant; every other code a file may hold
//! is kept as `Other(code)`, so nothing read from a file is lost or refused here. The tables'
//! "missing" code (all ones) is never a variant: fields that can be missing are `Option`s, and
//! `from_code` returns `None` for it.

/// Table 0.0: discipline of the processed data (section 0, octet 7).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Discipline {
    Meteorological,
    Hydrological,
    LandSurface,
    /// Satellite remote-sensing products (code 3).
    Space,
    SpaceWeather,
    Oceanographic,
    /// Any other code, including reserved, local and missing (255) ones: section 0 always
    /// holds a byte here and `inspect` prints it as read.
    Other(u8),
}

impl Discipline {
    pub fn from_code(c: u8) -> Discipline {
        match c {
            0 => Discipline::Meteorological,
            1 => Discipline::Hydrological,
            2 => Discipline::LandSurface,
            3 => Discipline::Space,
            4 => Discipline::SpaceWeather,
            10 => Discipline::Oceanographic,
            c => Discipline::Other(c),
        }
    }

    pub fn code(self) -> u8 {
        match self {
            Discipline::Meteorological => 0,
            Discipline::Hydrological => 1,
            Discipline::LandSurface => 2,
            Discipline::Space => 3,
            Discipline::SpaceWeather => 4,
            Discipline::Oceanographic => 10,
            Discipline::Other(c) => c,
        }
    }
}

/// Table 1.3: production status of the data (section 1, octet 20).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ProductionStatus {
    Operational,
    OperationalTest,
    Research,
    ReAnalysis,
    Other(u8),
}

impl ProductionStatus {
    /// `None` for the missing code 255.
    pub fn from_code(c: u8) -> Option<ProductionStatus> {
        Some(match c {
            0 => ProductionStatus::Operational,
            1 => ProductionStatus::OperationalTest,
            2 => ProductionStatus::Research,
            3 => ProductionStatus::ReAnalysis,
            255 => return None,
            c => ProductionStatus::Other(c),
        })
    }

    pub fn code(self) -> u8 {
        match self {
            ProductionStatus::Operational => 0,
            ProductionStatus::OperationalTest => 1,
            ProductionStatus::Research => 2,
            ProductionStatus::ReAnalysis => 3,
            ProductionStatus::Other(c) => c,
        }
    }
}

/// Table 3.1: grid definition template number (section 3, octets 13–14).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum GridTemplate {
    /// 3.0: regular latitude/longitude (the only grid stratus decodes).
    LatLon,
    Other(u16),
}

impl GridTemplate {
    /// `None` for the missing code 65535.
    pub fn from_code(c: u16) -> Option<GridTemplate> {
        match c {
            0 => Some(GridTemplate::LatLon),
            65535 => None,
            c => Some(GridTemplate::Other(c)),
        }
    }

    pub fn code(self) -> u16 {
        match self {
            GridTemplate::LatLon => 0,
            GridTemplate::Other(c) => c,
        }
    }
}

/// Table 5.0: data representation template number (section 5, octets 10–11): the packing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Packing {
    /// 5.0 simple packing.
    Simple,
    /// 5.2 complex packing.
    Complex,
    /// 5.3 complex packing with spatial differencing.
    ComplexSpatialDiff,
    /// 5.40 JPEG 2000 code stream.
    Jpeg2000,
    /// 5.41 PNG.
    Png,
    /// 5.42 CCSDS recommended lossless compression.
    Ccsds,
    Other(u16),
}

impl Packing {
    /// `None` for the missing code 65535.
    pub fn from_code(c: u16) -> Option<Packing> {
        Some(match c {
            0 => Packing::Simple,
            2 => Packing::Complex,
            3 => Packing::ComplexSpatialDiff,
            40 => Packing::Jpeg2000,
            41 => Packing::Png,
            42 => Packing::Ccsds,
            65535 => return None,
            c => Packing::Other(c),
        })
    }

    pub fn code(self) -> u16 {
        match self {
            Packing::Simple => 0,
            Packing::Complex => 2,
            Packing::ComplexSpatialDiff => 3,
            Packing::Jpeg2000 => 40,
            Packing::Png => 41,
            Packing::Ccsds => 42,
            Packing::Other(c) => c,
        }
    }

    /// Short name as `inspect` prints it.
    pub fn name(self) -> &'static str {
        match self {
            Packing::Simple => "simple",
            Packing::Complex => "complex",
            Packing::ComplexSpatialDiff => "complex+spatial-diff",
            Packing::Jpeg2000 => "jpeg2000",
            Packing::Png => "png",
            Packing::Ccsds => "ccsds",
            Packing::Other(_) => "other",
        }
    }

    /// Whether the decoder (gribberish) handles this packing.
    pub fn is_supported(self) -> bool {
        !matches!(self, Packing::Other(_))
    }
}

/// Table 4.4: indicator of unit of time range (section 4, octet 18 of templates 4.0–4.15).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum TimeUnit {
    Minute,
    Hour,
    Day,
    Month,
    Year,
    Decade,
    Normal30Years,
    Century,
    Hours3,
    Hours6,
    Hours12,
    Second,
    Other(u8),
}

impl TimeUnit {
    /// `None` for the missing code 255.
    pub fn from_code(c: u8) -> Option<TimeUnit> {
        Some(match c {
            0 => TimeUnit::Minute,
            1 => TimeUnit::Hour,
            2 => TimeUnit::Day,
            3 => TimeUnit::Month,
            4 => TimeUnit::Year,
            5 => TimeUnit::Decade,
            6 => TimeUnit::Normal30Years,
            7 => TimeUnit::Century,
            10 => TimeUnit::Hours3,
            11 => TimeUnit::Hours6,
            12 => TimeUnit::Hours12,
            13 => TimeUnit::Second,
            255 => return None,
            c => TimeUnit::Other(c),
        })
    }

    pub fn code(self) -> u8 {
        match self {
            TimeUnit::Minute => 0,
            TimeUnit::Hour => 1,
            TimeUnit::Day => 2,
            TimeUnit::Month => 3,
            TimeUnit::Year => 4,
            TimeUnit::Decade => 5,
            TimeUnit::Normal30Years => 6,
            TimeUnit::Century => 7,
            TimeUnit::Hours3 => 10,
            TimeUnit::Hours6 => 11,
            TimeUnit::Hours12 => 12,
            TimeUnit::Second => 13,
            TimeUnit::Other(c) => c,
        }
    }

    /// A time range of `n` of these units in hours, for the units of fixed length (not months
    /// and longer, whose length depends on the calendar). Minutes and seconds divide, so whole
    /// numbers of hours come out exact.
    pub fn to_hours(self, n: f64) -> Option<f64> {
        match self {
            TimeUnit::Minute => Some(n / 60.0),
            TimeUnit::Hour => Some(n),
            TimeUnit::Day => Some(n * 24.0),
            TimeUnit::Hours3 => Some(n * 3.0),
            TimeUnit::Hours6 => Some(n * 6.0),
            TimeUnit::Hours12 => Some(n * 12.0),
            TimeUnit::Second => Some(n / 3600.0),
            _ => None,
        }
    }
}

/// Table 4.5: type of fixed surface (section 4, octets 23 and 29 of templates 4.0–4.15). The
/// 200-range entries are NCEP's local ones, which GFS files use for cloud layers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SurfaceType {
    /// 1: ground or water surface.
    Surface,
    /// 4: level of 0 °C isotherm.
    Isotherm0C,
    /// 6: maximum wind level.
    MaxWind,
    /// 7: tropopause.
    Tropopause,
    /// 8: nominal top of the atmosphere.
    NominalTop,
    /// 10: entire atmosphere (as a single layer).
    EntireAtmosphere,
    /// 100: isobaric surface, value in Pa.
    Isobaric,
    /// 101: mean sea level.
    MeanSeaLevel,
    /// 102: specific altitude above mean sea level, m.
    Altitude,
    /// 103: specified height level above ground, m.
    HeightAboveGround,
    /// 104: sigma level.
    Sigma,
    /// 106: depth below land surface, m.
    DepthBelowLand,
    /// 108: level at specified pressure difference from ground, Pa.
    PressureFromGround,
    /// 109: potential vorticity surface, K m² kg⁻¹ s⁻¹.
    PotentialVorticity,
    /// 200 (NCEP): entire atmosphere.
    EntireAtmosphereNcep,
    /// 204 (NCEP): highest tropospheric freezing level.
    HighestFreezing,
    /// 211 (NCEP): boundary-layer cloud layer.
    BoundaryLayerCloud,
    /// 212–214 (NCEP): low cloud bottom, top, layer.
    LowCloudBottom,
    LowCloudTop,
    LowCloudLayer,
    /// 220 (NCEP): planetary boundary layer.
    PlanetaryBoundaryLayer,
    /// 222–224 (NCEP): middle cloud bottom, top, layer.
    MiddleCloudBottom,
    MiddleCloudTop,
    MiddleCloudLayer,
    /// 232–234 (NCEP): high cloud bottom, top, layer.
    HighCloudBottom,
    HighCloudTop,
    HighCloudLayer,
    /// 242–244 (NCEP): convective cloud bottom, top, layer.
    ConvectiveCloudBottom,
    ConvectiveCloudTop,
    ConvectiveCloudLayer,
    Other(u8),
}

/// (code, variant) for every named surface type: one table for both directions.
const SURFACES: [(u8, SurfaceType); 30] = [
    (1, SurfaceType::Surface),
    (4, SurfaceType::Isotherm0C),
    (6, SurfaceType::MaxWind),
    (7, SurfaceType::Tropopause),
    (8, SurfaceType::NominalTop),
    (10, SurfaceType::EntireAtmosphere),
    (100, SurfaceType::Isobaric),
    (101, SurfaceType::MeanSeaLevel),
    (102, SurfaceType::Altitude),
    (103, SurfaceType::HeightAboveGround),
    (104, SurfaceType::Sigma),
    (106, SurfaceType::DepthBelowLand),
    (108, SurfaceType::PressureFromGround),
    (109, SurfaceType::PotentialVorticity),
    (200, SurfaceType::EntireAtmosphereNcep),
    (204, SurfaceType::HighestFreezing),
    (211, SurfaceType::BoundaryLayerCloud),
    (212, SurfaceType::LowCloudBottom),
    (213, SurfaceType::LowCloudTop),
    (214, SurfaceType::LowCloudLayer),
    (220, SurfaceType::PlanetaryBoundaryLayer),
    (222, SurfaceType::MiddleCloudBottom),
    (223, SurfaceType::MiddleCloudTop),
    (224, SurfaceType::MiddleCloudLayer),
    (232, SurfaceType::HighCloudBottom),
    (233, SurfaceType::HighCloudTop),
    (234, SurfaceType::HighCloudLayer),
    (242, SurfaceType::ConvectiveCloudBottom),
    (243, SurfaceType::ConvectiveCloudTop),
    (244, SurfaceType::ConvectiveCloudLayer),
];

impl SurfaceType {
    /// `None` for the missing code 255.
    pub fn from_code(c: u8) -> Option<SurfaceType> {
        if c == 255 {
            return None;
        }
        Some(
            SURFACES
                .iter()
                .find(|(k, _)| *k == c)
                .map_or(SurfaceType::Other(c), |&(_, s)| s),
        )
    }

    pub fn code(self) -> u8 {
        match self {
            SurfaceType::Other(c) => c,
            s => SURFACES
                .iter()
                .find(|(_, t)| *t == s)
                .map_or(255, |&(k, _)| k),
        }
    }
}

/// Table 6.0: bit-map indicator (section 6, octet 6).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum BitmapIndicator {
    /// 0: a bit-map follows in this section (or, resolved by the scanner, the bit-map of an
    /// earlier field of the same message, code 254).
    Present,
    /// 1–253: a predefined bit-map (none of which stratus knows).
    Predefined(u8),
    /// 254: the bit-map defined earlier in this message (the scanner resolves it to `Present`).
    Previous,
    /// 255: no bit-map; every grid point has a value.
    None,
}

impl BitmapIndicator {
    pub fn from_code(c: u8) -> BitmapIndicator {
        match c {
            0 => BitmapIndicator::Present,
            254 => BitmapIndicator::Previous,
            255 => BitmapIndicator::None,
            c => BitmapIndicator::Predefined(c),
        }
    }

    pub fn code(self) -> u8 {
        match self {
            BitmapIndicator::Present => 0,
            BitmapIndicator::Predefined(c) => c,
            BitmapIndicator::Previous => 254,
            BitmapIndicator::None => 255,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_code_round_trips() {
        for c in 0..=255u8 {
            assert_eq!(Discipline::from_code(c).code(), c);
            assert_eq!(BitmapIndicator::from_code(c).code(), c);
            if c != 255 {
                assert_eq!(SurfaceType::from_code(c).map(SurfaceType::code), Some(c));
                assert_eq!(TimeUnit::from_code(c).map(TimeUnit::code), Some(c));
                assert_eq!(
                    ProductionStatus::from_code(c).map(ProductionStatus::code),
                    Some(c)
                );
            }
        }
        for c in (0..=65534u16).step_by(7).chain([0, 2, 3, 40, 41, 42]) {
            assert_eq!(Packing::from_code(c).map(Packing::code), Some(c));
            assert_eq!(GridTemplate::from_code(c).map(GridTemplate::code), Some(c));
        }
        assert_eq!(SurfaceType::from_code(255), None);
        assert_eq!(Packing::from_code(65535), None);
        assert_eq!(GridTemplate::from_code(65535), None);
        assert_eq!(
            SurfaceType::from_code(214),
            Some(SurfaceType::LowCloudLayer)
        );
        assert_eq!(SurfaceType::from_code(5), Some(SurfaceType::Other(5)));
    }
}
