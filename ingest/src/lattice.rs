//! The structure lattice: where a map's structure images' pixels lie ([`StructureGrid`]), how
//! that lattice follows the forecast grid ([`structure_grid`]), and where the map sits on that
//! grid ([`Placement`]), which the structure and the ground are both resampled by.

use serde::{Deserialize, Serialize};

use crate::error::show_num;
use crate::region::Region;

/// Where the structure images' pixels lie (version 3; all five share it): `width`×`height`
/// pixel centres on a lat/lon lattice, row 0 north, column 0 west. The structure comes from
/// the forecast grid, so its images are stored at a resolution tied to that grid, never
/// larger than the map ([`structure_grid`]); readers sample them by
/// lat/lon: x = (lon − west) / dlon, y = (north − lat) / dlat, clamped to the outer centres.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct StructureGrid {
    pub width: u32,
    pub height: u32,
    /// Latitude of row 0's pixel centres, degrees; row j is at north − j × dlat.
    pub north: f64,
    /// Longitude of column 0's pixel centres, degrees (the region's convention); column i is
    /// at west + i × dlon.
    pub west: f64,
    pub dlat: f64,
    pub dlon: f64,
}

impl StructureGrid {
    /// The map's own pixels: centres half a pixel inside the region's edges.
    pub fn of_map(region: &Region, width: u32, height: u32) -> StructureGrid {
        let dlat = (region.north - region.south) / height.max(1) as f64;
        let dlon = region.lon_span() / width.max(1) as f64;
        StructureGrid {
            width,
            height,
            north: region.north - 0.5 * dlat,
            west: region.west + 0.5 * dlon,
            dlat,
            dlon,
        }
    }

    /// Fractional column (centres at whole numbers) of a longitude, clamped to the outer
    /// centres; `lon` is taken east of `region`'s west edge, as the map's pixels are.
    pub fn x(&self, region: &Region, lon: f64) -> f64 {
        let lon = region.west + (lon - region.west).rem_euclid(360.0);
        ((lon - self.west) / self.dlon).clamp(0.0, (self.width.max(1) - 1) as f64)
    }

    /// Fractional row of a latitude, clamped to the outer centres.
    pub fn y(&self, lat: f64) -> f64 {
        ((self.north - lat) / self.dlat).clamp(0.0, (self.height.max(1) - 1) as f64)
    }

    /// Near a pole the region reaches: the row of centres nearest that pole and how far `lat`
    /// lies from those centres toward the pole (0 at them, 1 at the pole); `None` elsewhere.
    /// Every pixel of that row neighbours the pole, so a point sample there blends toward the
    /// row's mean by this weight: the pole is one point with one value, whatever the longitude
    /// it is asked at, and the sample stays continuous on the way there.
    pub fn pole_weight(&self, region: &Region, lat: f64) -> Option<(usize, f64)> {
        const EPS: f64 = 1e-9;
        let last = self.north - (self.height.max(1) - 1) as f64 * self.dlat;
        let toward = |centre: f64, pole: f64, beyond: bool| -> Option<f64> {
            if !beyond {
                return None;
            }
            let gap = (pole - centre).abs();
            Some(if gap < EPS {
                1.0
            } else {
                ((lat - centre).abs() / gap).min(1.0)
            })
        };
        if region.north >= 90.0 - EPS {
            if let Some(t) = toward(self.north, 90.0, lat >= self.north - EPS) {
                return Some((0, t));
            }
        }
        if region.south <= -90.0 + EPS {
            if let Some(t) = toward(last, -90.0, lat <= last + EPS) {
                return Some((self.height.max(1) as usize - 1, t));
            }
        }
        None
    }

    /// A point sample `near` (bilinear between centres) blended toward the mean of `f` over
    /// its pole row by `pole` ([`pole_weight`](Self::pole_weight)); `f` gives pixel k's value
    /// (row-major, this lattice's width), `None` where it has none. At the pole itself (weight
    /// 1) the row's mean alone: one value, whatever the longitude.
    pub fn toward_pole(
        &self,
        pole: Option<(usize, f64)>,
        near: Option<f64>,
        f: impl Fn(usize) -> Option<f64>,
    ) -> Option<f64> {
        let Some((row, t)) = pole else {
            return near;
        };
        let w = self.width as usize;
        let (mut sum, mut n) = (0.0, 0usize);
        for v in (row * w..(row + 1) * w).filter_map(&f) {
            sum += v;
            n += 1;
        }
        let mean = (n > 0).then(|| sum / n as f64);
        match (near, mean) {
            (Some(a), Some(b)) if t < 1.0 => Some(a * (1.0 - t) + b * t),
            (a, b) if t < 0.5 => a.or(b),
            (a, b) => b.or(a),
        }
    }

    /// Check it against the map: each side 1..= the map's, finite positive spacings, and pixels
    /// whose extents cover the region (so a reader never samples outside them).
    pub(crate) fn validate(&self, region: &Region, map: (u32, u32)) -> Result<(), String> {
        self.validate_as("structure_grid", region, map)
    }

    /// [`validate`](Self::validate) of the lattice the sidecar names `what`.
    pub(crate) fn validate_as(
        &self,
        what: &str,
        region: &Region,
        map: (u32, u32),
    ) -> Result<(), String> {
        for (name, v, side) in [("width", self.width, map.0), ("height", self.height, map.1)] {
            if v == 0 || v > side {
                return Err(format!(
                    "{what}.{name}: {v} px is outside 1..={side} (the map's {name})"
                ));
            }
        }
        for (name, v) in [("north", self.north), ("west", self.west)] {
            if !v.is_finite() {
                return Err(format!("{what}.{name}: {} is not a number", show_num(v)));
            }
        }
        for (name, v) in [("dlat", self.dlat), ("dlon", self.dlon)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!(
                    "{what}.{name}: {} is not a positive spacing",
                    show_num(v)
                ));
            }
        }
        let slack = 1e-6;
        let (w, h) = (self.width as f64, self.height as f64);
        let east = self.west + (w - 0.5) * self.dlon;
        let south = self.north - (h - 0.5) * self.dlat;
        let west_gap = self.west - 0.5 * self.dlon - region.west;
        if self.north + 0.5 * self.dlat < region.north - slack
            || south > region.south + slack
            || west_gap > slack
            || east < region.west + region.lon_span() - slack
        {
            return Err(format!(
                "{what}: its {}x{} pixels from {}N {}E by {} x {} degrees do not cover the region",
                self.width,
                self.height,
                show_num(self.north),
                show_num(self.west),
                show_num(self.dlat),
                show_num(self.dlon)
            ));
        }
        Ok(())
    }
}

/// Structure pixels per forecast grid cell along each axis, most preferred first. The
/// pixel centres are put on the grid's own lattice, every grid point a pixel centre and k − 1
/// more between neighbours, so bilinear between pixels reproduces bilinear between grid points
/// exactly (each pixel cell lies inside one grid cell, where the field is bilinear), and with k
/// odd the nearest pixel's nearest grid point is the point's own (no pixel centre sits on the
/// half-way line). 7 rather than 1: a texture filter's limited weight precision and the
/// convective cloud's presence mask (nearest grid point) then step at 1/7 of a cell. Smaller
/// k are for maps too small to hold 7 a cell.
pub const STRUCTURE_OVERSAMPLE: [u32; 4] = [7, 5, 3, 1];

/// One axis of the structure lattice: the region spans `from..from + span` grid cells (from
/// the grid's first point); the first pixel centre in cells and the pixel count at the largest
/// oversampling whose count fits in `cap`, from the grid line at or before the region's
/// start to the one at or after its end (so the region is covered by centres).
fn lattice_axis(from: f64, span: f64, cap: u32) -> Option<(f64, u32, u32)> {
    if !(from.is_finite() && span.is_finite() && span > 0.0) {
        return None;
    }
    STRUCTURE_OVERSAMPLE.iter().find_map(|&k| {
        let kf = k as f64;
        // The slack keeps a region edge on a lattice line from adding a pixel by rounding.
        let first = (from * kf + 1e-6).floor();
        let last = ((from + span) * kf - 1e-6).ceil();
        let n = last - first + 1.0;
        (n <= cap as f64).then(|| (first / kf, n as u32, k))
    })
}

/// Where a `map`-sized map of `region`'s structure images lie, on the forecast grid whose
/// first point is (`grid_north`, `grid_west`) with spacing (`di`, `dj`) degrees: per axis, the
/// grid's lattice at [`STRUCTURE_OVERSAMPLE`] pixels a cell (7 where it fits in the map's side,
/// else 5, 3, 1), covering the region; an axis where even one pixel per grid point does not
/// fit (a map coarser than its grid) keeps the map's own pixels. Never larger than the map.
pub fn structure_grid(
    map: (u32, u32),
    region: &Region,
    (grid_north, grid_west): (f64, f64),
    (di, dj): (f64, f64),
) -> StructureGrid {
    let mut g = StructureGrid::of_map(region, map.0, map.1);
    let from_lon = (region.west - grid_west).rem_euclid(360.0) / di;
    if let Some((first, n, k)) = lattice_axis(from_lon, region.lon_span() / di, map.0) {
        g.width = n;
        g.west = region.west - (from_lon - first) * di;
        g.dlon = di / k as f64;
    }
    let from_lat = (grid_north - region.north) / dj;
    if let Some((first, n, k)) = lattice_axis(from_lat, (region.north - region.south) / dj, map.1) {
        g.height = n;
        g.north = region.north + (from_lat - first) * dj;
        g.dlat = dj / k as f64;
    }
    g
}

/// Where the map lies on the forecast grid: its region and size, the grid's north-west point
/// (`north`, `west`) and spacing (`di`, `dj`), and whether the grid wraps around the globe.
#[derive(Debug, Clone, Copy)]
pub struct Placement {
    pub region: Region,
    pub map_size: (usize, usize),
    pub north: f64,
    pub west: f64,
    pub di: f64,
    pub dj: f64,
    pub wrap: bool,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_structure_lattice_follows_the_grid_and_never_exceeds_the_map() {
        let ea = Region::parse("0,55,39,105").unwrap();
        let gfs = |map| structure_grid(map, &ea, (90.0, 0.0), (2.5, 2.5));
        // 39..105°E: lattice lines every 2.5/7° from the one at or west of 39°E (38.93°) to
        // 105°E, 186 centres; 0..55°N: 22 cells × 7 + 1.
        let g = gfs((6500, 5500));
        assert_eq!((g.width, g.height), (186, 155));
        assert!((g.west - (15.0 + 4.0 / 7.0) * 2.5).abs() < 1e-9, "{g:?}");
        assert_eq!(g.north, 55.0);
        assert!((g.dlon - 2.5 / 7.0).abs() < 1e-12 && (g.dlat - 2.5 / 7.0).abs() < 1e-12);
        assert_eq!(gfs((1300, 1100)), g);
        // Too small for 7 a cell: 5, 3, 1, then the map's own pixels.
        let g = gfs((150, 100));
        assert_eq!(
            (g.width, g.height, g.dlon, g.dlat),
            (133, 67, 0.5, 2.5 / 3.0)
        );
        let g = gfs((20, 3));
        assert_eq!((g.width, g.height), (20, 3));
        assert_eq!(g, StructureGrid::of_map(&ea, 20, 3));
        // 0.25°: 264 × 220 cells.
        let g = structure_grid((6500, 5500), &ea, (90.0, 0.0), (0.25, 0.25));
        assert_eq!((g.width, g.height), (1849, 1541));
        // Across the date line (grid lines 170°E..190°E).
        let pac = Region::parse("-10,10,170,-170").unwrap();
        let g = structure_grid((4000, 4000), &pac, (90.0, 0.0), (2.5, 2.5));
        assert_eq!((g.width, g.height, g.west), (57, 57, 170.0));
        // A degenerate grid spacing keeps the map's pixels.
        let g = structure_grid((40, 30), &pac, (90.0, 0.0), (0.0, f64::NAN));
        assert_eq!(g, StructureGrid::of_map(&pac, 40, 30));
    }
}
