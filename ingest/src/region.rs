//! Geographic region of a CloudMap and the pixel ↔ lat/lon mapping (DESIGN §1.2).

use serde::{Deserialize, Serialize};

use crate::error::IngestError;

/// A lat/lon box. `west`/`east` keep the user's convention; `east < west` (or a span through
/// 180°) means the region crosses the date line.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Region {
    pub south: f64,
    pub north: f64,
    pub west: f64,
    pub east: f64,
}

impl Region {
    /// Parse `S,N,W,E` in degrees and validate it.
    pub fn parse(s: &str) -> Result<Region, IngestError> {
        let parts: Vec<&str> = s.split(',').map(str::trim).collect();
        if parts.len() != 4 {
            return Err(IngestError::BadRegion(format!(
                "'{s}' is not S,N,W,E (four comma-separated degrees)"
            )));
        }
        let mut v = [0.0f64; 4];
        for (slot, p) in v.iter_mut().zip(&parts) {
            *slot = p
                .parse::<f64>()
                .map_err(|_| IngestError::BadRegion(format!("'{p}' in '{s}' is not a number")))?;
        }
        let r = Region {
            south: v[0],
            north: v[1],
            west: v[2],
            east: v[3],
        };
        r.validate()?;
        Ok(r)
    }

    pub fn validate(&self) -> Result<(), IngestError> {
        use crate::error::show_num;
        let Region {
            south,
            north,
            west,
            east,
        } = *self;
        if ![south, north, west, east].iter().all(|x| x.is_finite()) {
            return Err(IngestError::BadRegion(
                "region has a non-finite bound".into(),
            ));
        }
        if !(-90.0..=90.0).contains(&south) || !(-90.0..=90.0).contains(&north) {
            return Err(IngestError::BadRegion(format!(
                "latitudes must lie in [-90, 90], got south {}, north {}",
                show_num(south),
                show_num(north)
            )));
        }
        if south >= north {
            return Err(IngestError::BadRegion(format!(
                "south ({south}) must be less than north ({north})"
            )));
        }
        if !(-180.0..=360.0).contains(&west) || !(-180.0..=360.0).contains(&east) {
            return Err(IngestError::BadRegion(format!(
                "longitudes must lie in [-180, 360], got west {}, east {}",
                show_num(west),
                show_num(east)
            )));
        }
        if self.lon_span() <= 0.0 {
            return Err(IngestError::BadRegion(
                "west and east are the same meridian".into(),
            ));
        }
        Ok(())
    }

    /// Eastward span in degrees, in (0, 360]. Handles the date line and both conventions.
    pub fn lon_span(&self) -> f64 {
        let d = (self.east - self.west).rem_euclid(360.0);
        if d == 0.0 && self.east != self.west {
            360.0
        } else {
            d
        }
    }

    /// Longitude of pixel column `i` centre (may exceed 180; callers wrap).
    pub fn pixel_lon(&self, i: usize, width: usize) -> f64 {
        self.west + (i as f64 + 0.5) * self.lon_span() / width as f64
    }

    /// Latitude of pixel row `j` centre (row 0 = north).
    pub fn pixel_lat(&self, j: usize, height: usize) -> f64 {
        self.north - (j as f64 + 0.5) * (self.north - self.south) / height as f64
    }

    /// Fractional pixel coordinates (x right, y down, 0..W / 0..H) of a point, or None outside.
    pub fn to_pixel(&self, lat: f64, lon: f64, width: usize, height: usize) -> Option<(f64, f64)> {
        let dx = (lon - self.west).rem_euclid(360.0);
        if dx > self.lon_span() || lat < self.south || lat > self.north {
            return None;
        }
        let x = dx / self.lon_span() * width as f64;
        let y = (self.north - lat) / (self.north - self.south) * height as f64;
        Some((x, y))
    }

    /// Centre of the region (lat, lon in -180..180).
    pub fn centre(&self) -> (f64, f64) {
        let lon = self.west + 0.5 * self.lon_span();
        let lon = (lon + 180.0).rem_euclid(360.0) - 180.0;
        (0.5 * (self.south + self.north), lon)
    }
}

/// Largest CloudMap side, in pixels: what the renderer can upload as one texture on every
/// adapter it supports (wgpu's default limit, 8192). Ingest refuses to write a larger map and
/// the loader refuses to read one, before decoding anything.
pub const MAX_SIDE: u32 = 8192;

/// Parse `WxH`, each side in 1..=[`MAX_SIDE`].
pub fn parse_size(s: &str) -> Result<(u32, u32), IngestError> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| IngestError::BadSize(format!("'{s}' is not WIDTHxHEIGHT")))?;
    let parse = |v: &str| -> Result<u32, IngestError> {
        v.trim()
            .parse::<u32>()
            .map_err(|_| IngestError::BadSize(format!("'{v}' in '{s}' is not a whole number")))
    };
    let (w, h) = (parse(w)?, parse(h)?);
    check_size(w, h)?;
    Ok((w, h))
}

/// The one size rule: whether a map, an image or a page may be `v` px on a side
/// (1..=[`MAX_SIDE`]). Every check of a size goes through it.
pub fn side_ok(v: u32) -> bool {
    v != 0 && v <= MAX_SIDE
}

/// [`side_ok`] for both sides of a `w`×`h` map the user asked for.
pub fn check_size(w: u32, h: u32) -> Result<(), IngestError> {
    if side_ok(w) && side_ok(h) {
        return Ok(());
    }
    Err(IngestError::BadSize(format!(
        "each side must be 1..={MAX_SIDE} px, got {w}x{h}"
    )))
}

/// [`side_ok`] for a sidecar's `name` field (`width`, `height`), as a one-line message.
pub fn check_side(name: &str, v: u32) -> Result<(), String> {
    if side_ok(v) {
        return Ok(());
    }
    Err(format!("{name}: {v} px is outside 1..={MAX_SIDE}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dateline_region_spans_sixty_degrees() {
        let r = Region::parse("10,50,150,-150").unwrap();
        assert_eq!(r.lon_span(), 60.0);
        let r2 = Region::parse("10,50,150,210").unwrap();
        assert_eq!(r2.lon_span(), 60.0);
        assert!((r.pixel_lon(0, 60) - 150.5).abs() < 1e-12);
        let (x, _) = r.to_pixel(30.0, -170.0, 60, 40).unwrap();
        assert!((x - 40.0).abs() < 1e-9);
    }

    #[test]
    fn bad_regions_and_sizes_are_rejected() {
        for s in [
            "50,10,0,10",
            "-91,0,0,10",
            "0,95,0,10",
            "0,10,0",
            "a,b,c,d",
            "0,10,5,5",
        ] {
            assert!(Region::parse(s).is_err(), "{s}");
        }
        for s in [
            "0x10", "10x0", "16385x10", "8193x10", "10x8193", "10", "ax3", "-1x4",
        ] {
            assert!(parse_size(s).is_err(), "{s}");
        }
        assert_eq!(parse_size("1300x1100").unwrap(), (1300, 1100));
        assert_eq!(parse_size("8192x8192").unwrap(), (8192, 8192));
    }
}
