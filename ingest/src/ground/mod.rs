//! The ground under a map (issue 14, DESIGN §8 "Ground"): terrain height from the forecast's
//! orography, land and sea-ice fractions, snow, albedo, and the column's cloud water, on a
//! lattice over the map's region ([`Ground`]), with the point sample a probe, a camera check or
//! a pilot needs ([`Ground::at`]) and the lattice as the renderer uploads it.
//!
//! Where the values come from ([`inputs`]): the file's own fields where it has them, plain
//! defaults where it does not (land from orography, albedo from land/sea/ice/snow); the
//! sidecar's `ground.fields` lists the fields read. How they reach the lattice
//! ([`resample`]): the map's spline, limited to the grid's range around each point, so a
//! spline never makes seas below sea level or digs holes next to mountains. How they are
//! stored ([`image`]): two PNGs beside the map carrying its image id, decoded to physical units
//! on load.
//!
//! ## The lattice
//!
//! `grid` ([`StructureGrid`], the sidecar's `ground.grid`) puts `width`×`height` texel
//! **centres** on a lat/lon lattice: texel (i, j) (row 0 north, column 0 west) is the value at
//! latitude `north − j·dlat`, longitude `west + i·dlon`. Between centres values are bilinear;
//! outside the outer centres (at most half a texel, inside the region) they are clamped to the
//! edge texel, except toward a pole the region reaches, where the CPU sample blends toward the
//! edge row's mean so the pole has one value at every longitude. On a GPU this is a texture sampled with linear filtering and clamp-to-edge at
//! texture coordinates `((i + 0.5)/width, (j + 0.5)/height)` for texel (i, j); from the map's
//! region uv (u = 0 west edge … 1 east edge, v = 0 north edge … 1 south edge) the texture
//! coordinate is `uv × scale + offset` with [`Ground::texture_transform`].
//!
//! It is the structure images' lattice (a few texels per forecast grid cell, every grid point
//! a texel centre; [`crate::lattice::structure_grid`]): 2.5° terrain is smooth, so a texel
//! every 0.36° holds it, and files stay kilobytes.

pub mod image;
pub mod inputs;
pub mod resample;

use serde::{Deserialize, Serialize};

use crate::lattice::StructureGrid;
use crate::region::Region;

pub use inputs::{default_albedo, GroundInputs};

/// Snow water equivalent (kg m⁻²) at which the ground counts as fully snow-covered: about
/// 3–5 cm of settled snow, enough to hide grass and soil.
pub const FULL_SNOW_KG_M2: f64 = 10.0;

/// Snow cover (0..1) from snow water equivalent: linear up to [`FULL_SNOW_KG_M2`].
pub fn snow_cover(swe_kg_m2: f64) -> f64 {
    (swe_kg_m2 / FULL_SNOW_KG_M2).clamp(0.0, 1.0)
}

/// A field of the ground, as the sidecar names it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum GroundField {
    /// Surface geopotential height (0.3.5 at the surface), m.
    Orography,
    /// Land cover (2.0.0, `lsm`), fraction.
    LandCover,
    /// Ice cover (10.2.0, `ci`), fraction.
    IceCover,
    /// Water equivalent of accumulated snow depth (0.1.13, `sdwe`), kg m⁻².
    SnowWaterEquivalent,
    /// Albedo (0.19.1, `avg_al`), %.
    Albedo,
    /// Total column cloud water (0.6.6, entire atmosphere, `cwat`), kg m⁻².
    CloudWater,
}

impl GroundField {
    pub const ALL: [GroundField; 6] = [
        GroundField::Orography,
        GroundField::LandCover,
        GroundField::IceCover,
        GroundField::SnowWaterEquivalent,
        GroundField::Albedo,
        GroundField::CloudWater,
    ];

    pub const fn name(self) -> &'static str {
        match self {
            GroundField::Orography => "orography",
            GroundField::LandCover => "land-cover",
            GroundField::IceCover => "ice-cover",
            GroundField::SnowWaterEquivalent => "snow-water-equivalent",
            GroundField::Albedo => "albedo",
            GroundField::CloudWater => "cloud-water",
        }
    }
}

/// The sidecar's `ground` object: the two ground images, where their texels lie, and what was
/// read. Absent: the map has no ground (the file had no orography, or an older map), and
/// everything below the clouds is sea level.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GroundMeta {
    /// `MAP.ground.png`: 16-bit RGBA — terrain height, land, ice, albedo ([`image`]).
    pub image: String,
    /// `MAP.ground-water.png`: 16-bit grey + alpha — snow water equivalent, cloud water.
    pub water_image: String,
    /// Where both images' texels lie (see the module doc).
    pub grid: StructureGrid,
    /// The fields read from the forecast; the others hold defaults.
    pub fields: Vec<GroundField>,
    /// Lowest and highest terrain over the lattice, m above mean sea level.
    pub height_min_m: f64,
    pub height_max_m: f64,
}

/// The ground of a map, decoded: per texel of `grid` (row-major, row 0 north), physical values.
#[derive(Debug, Clone, PartialEq)]
pub struct Ground {
    pub grid: StructureGrid,
    /// The map's region: longitudes are taken east of its west edge, as the map's pixels are.
    pub region: Region,
    /// Terrain height, m above mean sea level.
    pub height_m: Vec<f32>,
    /// Land fraction 0..1 (1 land).
    pub land: Vec<f32>,
    /// Sea-ice fraction 0..1.
    pub ice: Vec<f32>,
    /// Snow water equivalent, kg m⁻² (cover: [`snow_cover`]).
    pub snow_kg_m2: Vec<f32>,
    /// Broadband surface albedo 0..1.
    pub albedo: Vec<f32>,
    /// Total column cloud water, kg m⁻² (0 where the file had none: see `fields`).
    pub cwat_kg_m2: Vec<f32>,
    /// The fields read from the forecast.
    pub fields: Vec<GroundField>,
}

/// The ground at one point ([`Ground::at`]), bilinear between texel centres.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct GroundSample {
    pub height_m: f64,
    pub land: f64,
    pub ice: f64,
    pub snow_kg_m2: f64,
    /// [`snow_cover`] of `snow_kg_m2`.
    pub snow_cover: f64,
    pub albedo: f64,
    /// `None` where the forecast had no cloud water.
    pub cwat_kg_m2: Option<f64>,
}

impl Ground {
    pub fn len(&self) -> usize {
        self.grid.width as usize * self.grid.height as usize
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Whether every field holds one value per texel.
    pub fn is_whole(&self) -> bool {
        let n = self.len();
        n > 0
            && [
                &self.height_m,
                &self.land,
                &self.ice,
                &self.snow_kg_m2,
                &self.albedo,
                &self.cwat_kg_m2,
            ]
            .iter()
            .all(|v| v.len() == n)
    }

    /// Whether the forecast held `f` (else the ground holds its default).
    pub fn has(&self, f: GroundField) -> bool {
        self.fields.contains(&f)
    }

    /// The ground at (`lat`, `lon`): bilinear between the lattice's texel centres, clamped to
    /// the outer ones (module doc); beyond the outer row of a pole the region reaches, blended
    /// toward that row's mean, so the pole has one value ([`StructureGrid::pole_weight`]).
    /// `None` outside the map's region or for a non-finite point.
    pub fn at(&self, lat: f64, lon: f64) -> Option<GroundSample> {
        let r = &self.region;
        if !(lat.is_finite() && lon.is_finite()) || lat < r.south || lat > r.north {
            return None;
        }
        if (lon - r.west).rem_euclid(360.0) > r.lon_span() + 1e-9 || !self.is_whole() {
            return None;
        }
        let g = &self.grid;
        let (w, h) = (g.width as usize, g.height as usize);
        let (x, y) = (g.x(r, lon), g.y(lat));
        let (i0, j0) = (x.floor() as usize, y.floor() as usize);
        let (i1, j1) = ((i0 + 1).min(w - 1), (j0 + 1).min(h - 1));
        let (tx, ty) = (x - i0 as f64, y - j0 as f64);
        let taps = [
            (j0 * w + i0, (1.0 - tx) * (1.0 - ty)),
            (j0 * w + i1, tx * (1.0 - ty)),
            (j1 * w + i0, (1.0 - tx) * ty),
            (j1 * w + i1, tx * ty),
        ];
        // Near a pole the region reaches, toward the pole row's mean (one pole, one answer).
        let pole = g.pole_weight(r, lat);
        let f = |v: &[f32]| {
            let near = taps.iter().map(|&(k, wt)| v[k] as f64 * wt).sum::<f64>();
            g.toward_pole(pole, Some(near), |k| Some(v[k] as f64))
                .unwrap_or(near)
        };
        let snow = f(&self.snow_kg_m2);
        Some(GroundSample {
            height_m: f(&self.height_m),
            land: f(&self.land),
            ice: f(&self.ice),
            snow_kg_m2: snow,
            snow_cover: snow_cover(snow),
            albedo: f(&self.albedo),
            cwat_kg_m2: self
                .has(GroundField::CloudWater)
                .then(|| f(&self.cwat_kg_m2)),
        })
    }

    /// Texel `(i, j)`'s values (row 0 north), as [`Ground::at`] gives them at its centre.
    pub fn texel(&self, i: usize, j: usize) -> GroundSample {
        let k = j * self.grid.width as usize + i;
        let snow = self.snow_kg_m2[k] as f64;
        GroundSample {
            height_m: self.height_m[k] as f64,
            land: self.land[k] as f64,
            ice: self.ice[k] as f64,
            snow_kg_m2: snow,
            snow_cover: snow_cover(snow),
            albedo: self.albedo[k] as f64,
            cwat_kg_m2: self
                .has(GroundField::CloudWater)
                .then_some(self.cwat_kg_m2[k] as f64),
        }
    }

    /// `[scale_u, offset_u, scale_v, offset_v]`: texture coordinate = region uv × scale +
    /// offset, for a `width`×`height` texture of the lattice whose texel (i, j) has its centre
    /// at ((i + 0.5)/width, (j + 0.5)/height) — the GPU's convention. Linear filtering with
    /// clamp-to-edge there gives [`Ground::at`].
    pub fn texture_transform(&self) -> [f64; 4] {
        let (g, r) = (&self.grid, &self.region);
        let (w, h) = (g.width as f64 * g.dlon, g.height as f64 * g.dlat);
        [
            r.lon_span() / w,
            (r.west - g.west + 0.5 * g.dlon) / w,
            (r.north - r.south) / h,
            (g.north - r.north + 0.5 * g.dlat) / h,
        ]
    }

    /// Lowest and highest terrain, m.
    pub fn height_range(&self) -> (f64, f64) {
        self.height_m
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v as f64), b.max(v as f64))
            })
    }

    /// Per texel mix of `self` and `other` (same lattice): (1 − w)·self + w·other; the fields
    /// read are those both read. `None` when the lattices differ.
    pub fn mix(&self, other: &Ground, w: f32) -> Option<Ground> {
        if self.grid != other.grid || !self.is_whole() || !other.is_whole() {
            return None;
        }
        let m = |a: &[f32], b: &[f32]| -> Vec<f32> {
            a.iter().zip(b).map(|(x, y)| x + (y - x) * w).collect()
        };
        Some(Ground {
            grid: self.grid,
            region: self.region,
            height_m: m(&self.height_m, &other.height_m),
            land: m(&self.land, &other.land),
            ice: m(&self.ice, &other.ice),
            snow_kg_m2: m(&self.snow_kg_m2, &other.snow_kg_m2),
            albedo: m(&self.albedo, &other.albedo),
            cwat_kg_m2: m(&self.cwat_kg_m2, &other.cwat_kg_m2),
            fields: self
                .fields
                .iter()
                .copied()
                .filter(|f| other.has(*f))
                .collect(),
        })
    }
}

/// Where the ground height a command uses came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum GroundSource {
    /// The map's ground grid, from the forecast's orography.
    Orography,
    /// No ground grid here (none in the map, or outside its region): sea level.
    None,
}

/// The ground in a probe (`stratus probe`): serialized flat into the probe's JSON.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ProbeGround {
    /// Terrain height, m above mean sea level; 0 (sea level) where there is no ground grid.
    pub ground_m: f64,
    pub ground_source: GroundSource,
    /// Land and sea-ice fractions, snow water equivalent (kg m⁻²) and cover, albedo (0..1);
    /// `None` without a ground grid.
    pub land: Option<f64>,
    pub ice: Option<f64>,
    pub snow_kg_m2: Option<f64>,
    pub snow_cover: Option<f64>,
    pub albedo: Option<f64>,
    /// Total column cloud water, kg m⁻²; `None` where the forecast had none.
    pub cwat_kg_m2: Option<f64>,
    /// The ground fields read from the forecast (the others are defaults).
    pub ground_fields: Vec<GroundField>,
}

impl ProbeGround {
    /// No ground grid: sea level, nothing else known.
    pub const NONE: ProbeGround = ProbeGround {
        ground_m: 0.0,
        ground_source: GroundSource::None,
        land: None,
        ice: None,
        snow_kg_m2: None,
        snow_cover: None,
        albedo: None,
        cwat_kg_m2: None,
        ground_fields: Vec::new(),
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp() -> Ground {
        let region = Region::parse("10,20,100,120").unwrap();
        // Texel centres every 2° from 101°E and from 19°N: the region's own 10×5 pixels.
        let grid = StructureGrid::of_map(&region, 10, 5);
        let n = 50;
        let v = |f: &dyn Fn(usize, usize) -> f32| -> Vec<f32> {
            (0..n).map(|k| f(k % 10, k / 10)).collect()
        };
        Ground {
            grid,
            region,
            height_m: v(&|i, j| 100.0 * i as f32 + 10.0 * j as f32),
            land: v(&|i, _| i as f32 / 9.0),
            ice: v(&|_, _| 0.0),
            snow_kg_m2: v(&|_, j| 5.0 * j as f32),
            albedo: v(&|_, _| 0.2),
            cwat_kg_m2: v(&|_, _| 0.5),
            fields: vec![GroundField::Orography],
        }
    }

    #[test]
    fn at_is_bilinear_between_centres_and_clamped_outside_them() {
        let g = ramp();
        // Centre of texel (3, 2): 107°E, 15°N.
        let s = g.at(15.0, 107.0).unwrap();
        assert!((s.height_m - 320.0).abs() < 1e-9, "{s:?}");
        // Half-way between texels (3, 2) and (4, 3).
        let s = g.at(14.0, 108.0).unwrap();
        assert!((s.height_m - 375.0).abs() < 1e-9, "{s:?}");
        assert_eq!(s.snow_cover, 1.0, "12.5 kg m⁻² covers the ground");
        // Within half a texel of the edge: the edge texel.
        let s = g.at(19.9, 100.2).unwrap();
        assert!(s.height_m.abs() < 1e-9, "{s:?}");
        assert_eq!(s.cwat_kg_m2, None, "cloud water not read: none");
        assert!(g.at(21.0, 110.0).is_none() && g.at(15.0, 121.0).is_none());
    }

    #[test]
    fn the_texture_transform_reproduces_at() {
        let g = ramp();
        let [su, ou, sv, ov] = g.texture_transform();
        let (w, h) = (g.grid.width as f64, g.grid.height as f64);
        for (lat, lon) in [(15.0, 107.0), (14.0, 108.0), (11.3, 118.7), (19.9, 100.2)] {
            let (u, v) = ((lon - 100.0) / 20.0, (20.0 - lat) / 10.0);
            // A clamp-to-edge linear sampler: texel space, centres at k + 0.5.
            let x = ((u * su + ou) * w - 0.5).clamp(0.0, w - 1.0);
            let y = ((v * sv + ov) * h - 0.5).clamp(0.0, h - 1.0);
            let want = 100.0 * x + 10.0 * y;
            let got = g.at(lat, lon).unwrap().height_m;
            assert!((got - want).abs() < 1e-6, "{lat},{lon}: {got} vs {want}");
        }
    }
}
