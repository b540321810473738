//! What the scanner learns about one GRIB2 field from its headers ([`MessageInfo`], with the
//! grid it lies on), and how `inspect` shows it: one fixed-width row per field.

use chrono::{DateTime, Duration, Utc};
use std::fmt;

use super::tables::{BitmapIndicator, Discipline, GridTemplate, Packing, SurfaceType};

/// A regular latitude/longitude grid (template 3.0), normalised to rows from north to south.
#[derive(Debug, Clone, PartialEq)]
pub struct LatLonGrid {
    pub ni: usize,
    pub nj: usize,
    /// Latitude of the first and last row as stored (scan order), degrees.
    pub lat1: f64,
    pub lat2: f64,
    pub lon1: f64,
    pub lon2: f64,
    pub di: f64,
    pub dj: f64,
    pub scan_mode: u8,
}

impl LatLonGrid {
    /// Northernmost latitude (row 0 after normalisation).
    pub fn north(&self) -> f64 {
        self.lat1.max(self.lat2)
    }
    pub fn south(&self) -> f64 {
        self.lat1.min(self.lat2)
    }
    /// Westernmost longitude (column 0 after normalisation).
    pub fn west(&self) -> f64 {
        if self.scan_mode & 0x80 != 0 {
            self.lon2
        } else {
            self.lon1
        }
    }
    /// True when the columns cover the whole circle (wrap in longitude).
    pub fn is_global(&self) -> bool {
        (self.ni as f64 * self.di - 360.0).abs() < 1e-3 * self.di.max(1e-9)
    }
}

/// Byte ranges (message-relative, `start..end`) of the sections one field uses; section 6 may
/// be one inherited from an earlier field (indicator 254).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct SectionRanges {
    pub(crate) s1: (usize, usize),
    pub(crate) s2: Option<(usize, usize)>,
    pub(crate) s3: (usize, usize),
    pub(crate) s4: (usize, usize),
    pub(crate) s5: (usize, usize),
    pub(crate) s6: (usize, usize),
    pub(crate) s7: (usize, usize),
}

/// Everything `inspect` shows and `decode_values` needs about one field, from headers only.
/// Code-table values a message does not carry (its section is absent, or the template does not
/// hold them) are `None`.
#[derive(Debug, Clone)]
pub struct MessageInfo {
    /// Message number in the file (0-based) and field number inside it (0-based; GRIB2 lets
    /// one message carry several fields by repeating sections 2/3/4–7, as NCEP does for u/v).
    pub index: usize,
    pub field: usize,
    pub offset: usize,
    pub length: usize,
    pub discipline: Discipline,
    /// Parameter category and number (tables 4.1 and 4.2 of the discipline); 255 is the
    /// tables' own "missing" code, also shown when the product template is not read.
    pub category: u8,
    pub number: u8,
    /// Product definition template number (4.x); `None` without a section 4.
    pub product_template: Option<u16>,
    /// Section 1 octet 20; `None` when missing or when section 1 is too short to hold it.
    pub production_status: Option<super::tables::ProductionStatus>,
    pub level_type: Option<SurfaceType>,
    /// Level value in the level type's SI unit (Pa for isobaric), None when missing.
    pub level_value: Option<f64>,
    pub level2_type: Option<SurfaceType>,
    pub level2_value: Option<f64>,
    pub grid_template: Option<GridTemplate>,
    pub grid: Option<LatLonGrid>,
    /// Number of grid points (section 3).
    pub grid_points: u64,
    /// Number of values packed (section 5).
    pub packed_values: u64,
    /// Data representation template of section 5; `None` without a section 5.
    pub packing: Option<Packing>,
    /// Bit-map indicator of section 6 (254, "as before", is resolved to `Present`).
    pub bitmap: BitmapIndicator,
    pub reference_time: Option<DateTime<Utc>>,
    pub step_hours: Option<f64>,
    pub(crate) sections: SectionRanges,
}

/// The "missing" codes the tables use, printed where `inspect` shows an absent value, so its
/// output reads as the raw octets would.
const MISSING_U8: u8 = 255;
const MISSING_U16: u16 = 65535;

impl MessageInfo {
    /// A field of message `index` at `offset` about which nothing is known yet.
    pub(crate) fn empty(index: usize, offset: usize, length: usize, discipline: u8) -> Self {
        MessageInfo {
            index,
            field: 0,
            offset,
            length,
            discipline: Discipline::from_code(discipline),
            category: MISSING_U8,
            number: MISSING_U8,
            product_template: None,
            production_status: None,
            level_type: None,
            level_value: None,
            level2_type: None,
            level2_value: None,
            grid_template: None,
            grid: None,
            grid_points: 0,
            packed_values: 0,
            packing: None,
            bitmap: BitmapIndicator::None,
            reference_time: None,
            step_hours: None,
            sections: SectionRanges::default(),
        }
    }

    /// (discipline, category, number): the parameter, as the WMO tables number it.
    pub fn parameter(&self) -> (u8, u8, u8) {
        (self.discipline.code(), self.category, self.number)
    }

    /// Short name (ecCodes convention) where known, else `d.c.n`.
    pub fn short_name(&self) -> String {
        let known = match self.parameter() {
            (0, 0, 0) => "t",
            (0, 0, 2) => "pt",
            (0, 0, 4) => "tmax",
            (0, 0, 5) => "tmin",
            (0, 0, 6) => "dpt",
            (0, 1, 0) => "q",
            (0, 1, 1) => "r",
            (0, 1, 3) => "pwat",
            (0, 1, 8) => "tp",
            (0, 1, 22) => "clwmr",
            (0, 1, 23) => "icmr",
            (0, 1, 24) => "rwmr",
            (0, 1, 25) => "snmr",
            (0, 2, 2) => "u",
            (0, 2, 3) => "v",
            (0, 2, 8) => "w",
            (0, 2, 10) => "absv",
            (0, 2, 14) => "pv",
            (0, 2, 22) => "gust",
            (0, 3, 0) => "pres",
            (0, 3, 1) => "prmsl",
            (0, 3, 5) => "gh",
            (0, 6, 1) => "tcc",
            (0, 7, 6) => "cape",
            (0, 7, 7) => "cin",
            (0, 19, 0) => "vis",
            (0, 14, 192) => "o3mr",
            _ => "",
        };
        if known.is_empty() {
            let (d, c, n) = self.parameter();
            format!("{d}.{c}.{n}")
        } else {
            known.to_string()
        }
    }

    pub fn is_relative_humidity(&self) -> bool {
        self.parameter() == (0, 1, 1)
    }

    /// Geopotential height (gh).
    pub fn is_geopotential_height(&self) -> bool {
        self.parameter() == (0, 3, 5)
    }

    /// Pressure in hPa when the first surface is isobaric.
    pub fn pressure_hpa(&self) -> Option<f64> {
        (self.level_type == Some(SurfaceType::Isobaric))
            .then_some(self.level_value)
            .flatten()
            .map(|pa| pa / 100.0)
    }

    /// Human-readable level, e.g. `isobaric 400 hPa`, `low cloud layer`.
    pub fn level_text(&self) -> String {
        use SurfaceType as S;
        let v = self.level_value;
        let num = |unit: &str, scale: f64| match v {
            Some(x) => format!("{} {unit}", trim_num(x / scale)),
            None => String::new(),
        };
        let Some(ty) = self.level_type else {
            return format!("level type {MISSING_U8} {}", num("", 1.0))
                .trim()
                .to_string();
        };
        match ty {
            S::Surface => "surface".into(),
            S::Isotherm0C => "0°C isotherm".into(),
            S::MaxWind => "max wind".into(),
            S::Tropopause => "tropopause".into(),
            S::EntireAtmosphere | S::EntireAtmosphereNcep => "entire atmosphere".into(),
            S::Isobaric => format!("isobaric {}", num("hPa", 100.0)),
            S::MeanSeaLevel => "mean sea level".into(),
            S::Altitude => format!("altitude {}", num("m", 1.0)),
            S::HeightAboveGround => format!("height above ground {}", num("m", 1.0)),
            S::Sigma => format!("sigma {}", num("", 1.0)),
            S::DepthBelowLand => format!("depth below land {}", num("m", 1.0)),
            S::PressureFromGround => format!("pressure from ground {}", num("hPa", 100.0)),
            S::PotentialVorticity => format!("PV surface {}", num("PVU", 1e-6)),
            S::NominalTop => "nominal top of atmosphere".into(),
            S::HighestFreezing => "highest freezing level".into(),
            S::BoundaryLayerCloud => "boundary-layer cloud layer".into(),
            S::LowCloudBottom => "low cloud bottom".into(),
            S::LowCloudTop => "low cloud top".into(),
            S::LowCloudLayer => "low cloud layer".into(),
            S::PlanetaryBoundaryLayer => "planetary boundary layer".into(),
            S::MiddleCloudBottom => "middle cloud bottom".into(),
            S::MiddleCloudTop => "middle cloud top".into(),
            S::MiddleCloudLayer => "middle cloud layer".into(),
            S::HighCloudBottom => "high cloud bottom".into(),
            S::HighCloudTop => "high cloud top".into(),
            S::HighCloudLayer => "high cloud layer".into(),
            S::ConvectiveCloudBottom => "convective cloud bottom".into(),
            S::ConvectiveCloudTop => "convective cloud top".into(),
            S::ConvectiveCloudLayer => "convective cloud layer".into(),
            S::Other(t) => format!("level type {t} {}", num("", 1.0)),
        }
        .trim()
        .to_string()
    }

    /// Packing name of the data representation template.
    pub fn packing_text(&self) -> String {
        match self.packing {
            Some(p) => format!("5.{} {}", p.code(), p.name()),
            None => format!("5.{MISSING_U16} other"),
        }
    }

    pub fn valid_time(&self) -> Option<DateTime<Utc>> {
        Some(after_step(self.reference_time?, self.step_hours?))
    }
}

/// `reference` + a forecast step in hours, to the nearest second.
pub fn after_step(reference: DateTime<Utc>, step_hours: f64) -> DateTime<Utc> {
    reference + Duration::seconds((step_hours * 3600.0).round() as i64)
}

fn trim_num(x: f64) -> String {
    if (x - x.round()).abs() < 1e-9 {
        format!("{}", x.round() as i64)
    } else {
        format!("{x:.3}")
    }
}

impl fmt::Display for MessageInfo {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let template = self.grid_template.map_or(MISSING_U16, GridTemplate::code);
        let grid = match &self.grid {
            Some(g) => format!(
                "3.{template} {}x{} lat {}..{} lon {}..{}",
                g.ni,
                g.nj,
                trim_num(g.lat1),
                trim_num(g.lat2),
                trim_num(g.lon1),
                trim_num(g.lon2)
            ),
            None => format!("3.{template} ({} points)", self.grid_points),
        };
        let rt = self
            .reference_time
            .map(|t| t.format("%Y-%m-%dT%H:%MZ").to_string())
            .unwrap_or_else(|| "?".into());
        let step = self
            .step_hours
            .map(|s| format!("+{}h", trim_num(s)))
            .unwrap_or_else(|| "?".into());
        let (d, c, n) = self.parameter();
        write!(
            f,
            "{:>6} {:>9}  {:<7} {:<6} {:<28} {:<44} {:<24} {} {}",
            if self.field == 0 {
                format!("{}", self.index + 1)
            } else {
                format!("{}.{}", self.index + 1, self.field + 1)
            },
            self.offset,
            format!("{d}.{c}.{n}"),
            self.short_name(),
            self.level_text(),
            grid,
            self.packing_text(),
            rt,
            step
        )
    }
}
