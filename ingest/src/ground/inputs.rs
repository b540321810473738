//! The surface fields a GRIB2 file may hold for the ground, on the RH grid: orography (the one
//! that makes a ground at all), land cover, sea ice, snow water equivalent, albedo and the
//! column's cloud water. Each but the orography is optional; a missing one (absent, on another
//! grid, not decodable) is filled with a plain default ([`GroundInputs::filled`]), and points a
//! field's bit-map leaves out take the default at that point.

use std::path::Path;

use crate::grib::{self, LatLonGrid, MessageInfo, SurfaceType};
use crate::weather::inputs::Grid32;

use super::{snow_cover, GroundField};

/// Orography above this (m) makes a grid point land when the file has no land cover: GFS's
/// spectral orography is a few tenths of a metre off zero over the open sea.
pub const LAND_FROM_OROGRAPHY_M: f32 = 1.0;

/// Default albedos (0..1) where the file has none: open sea, snow-free land, sea ice, and
/// fully snow-covered ground (broadband values of the usual surface tables).
pub const SEA_ALBEDO: f64 = 0.06;
pub const LAND_ALBEDO: f64 = 0.20;
pub const ICE_ALBEDO: f64 = 0.60;
pub const SNOW_ALBEDO: f64 = 0.75;

/// The default albedo of ground with these fractions of land, sea ice (over the water part) and
/// snow cover.
pub fn default_albedo(land: f64, ice: f64, snow_cover: f64) -> f64 {
    let land = land.clamp(0.0, 1.0);
    let water = SEA_ALBEDO + (ICE_ALBEDO - SEA_ALBEDO) * ice.clamp(0.0, 1.0);
    let bare = land * LAND_ALBEDO + (1.0 - land) * water;
    bare + (SNOW_ALBEDO - bare) * snow_cover.clamp(0.0, 1.0)
}

/// The ground's fields on the RH grid (row-major, north first), every point filled.
#[derive(Debug, Clone)]
pub struct GroundInputs {
    pub ni: usize,
    pub nj: usize,
    /// Surface geopotential height, m.
    pub height_m: Grid32,
    /// Land fraction 0..1.
    pub land: Grid32,
    /// Sea-ice fraction 0..1.
    pub ice: Grid32,
    /// Snow water equivalent, kg m⁻².
    pub snow_kg_m2: Grid32,
    /// Surface albedo 0..1.
    pub albedo: Grid32,
    /// Total column cloud water, kg m⁻² (0 where the file has none; see `fields`).
    pub cwat_kg_m2: Grid32,
    /// The fields read from the file, in [`GroundField::ALL`] order; the rest are defaults.
    pub fields: Vec<GroundField>,
}

impl GroundInputs {
    /// The ground of `msgs` on `grid`, given the file's orography (`None`: no ground). Each
    /// field is the first message of its parameter on its level; NaN points and missing fields
    /// get the defaults.
    pub fn load(
        path: &Path,
        bytes: &[u8],
        msgs: &[MessageInfo],
        grid: &Option<LatLonGrid>,
        orography: Option<&Grid32>,
    ) -> Option<GroundInputs> {
        let height = orography?;
        let g = grid.as_ref()?;
        let n = g.ni * g.nj;
        if height.len() != n || height.iter().any(|v| !v.is_finite()) {
            tracing::warn!(
                "{}: the orography has missing points: no ground",
                path.display()
            );
            return None;
        }
        let get = |param: (u8, u8, u8), levels: &[SurfaceType]| -> Option<Grid32> {
            let m = msgs.iter().find(|m| {
                m.parameter() == param
                    && m.level_type.is_some_and(|l| levels.contains(&l))
                    && &m.grid == grid
            })?;
            match grib::decode_values(bytes, m) {
                Ok(f) if f.values.len() == n => Some(f.values.iter().map(|&v| v as f32).collect()),
                Ok(_) => None,
                Err(e) => {
                    tracing::warn!("{}: {} skipped: {e}", path.display(), m.short_name());
                    None
                }
            }
        };
        use SurfaceType as S;
        let mut fields = vec![GroundField::Orography];
        let mut found = |f: GroundField, v: Option<Grid32>| {
            if v.is_some() {
                fields.push(f);
            }
            v
        };
        let land = found(GroundField::LandCover, get((2, 0, 0), &[S::Surface]));
        let ice = found(GroundField::IceCover, get((10, 2, 0), &[S::Surface]));
        let snow = found(
            GroundField::SnowWaterEquivalent,
            get((0, 1, 13), &[S::Surface]),
        );
        // Albedo in %.
        let albedo = found(GroundField::Albedo, get((0, 19, 1), &[S::Surface]));
        let cwat = found(
            GroundField::CloudWater,
            get((0, 6, 6), &[S::EntireAtmosphere, S::EntireAtmosphereNcep]),
        );
        let fill = |v: Option<Grid32>, default: &dyn Fn(usize) -> f32, lo: f32, hi: f32| {
            (0..n)
                .map(|k| {
                    v.as_ref()
                        .map(|v| v[k])
                        .filter(|x| x.is_finite())
                        .map_or_else(|| default(k), |x| x.clamp(lo, hi))
                })
                .collect::<Grid32>()
        };
        let land = fill(
            land,
            &|k| f32::from(height[k] > LAND_FROM_OROGRAPHY_M),
            0.0,
            1.0,
        );
        let ice = fill(ice, &|_| 0.0, 0.0, 1.0);
        let snow = fill(snow, &|_| 0.0, 0.0, f32::MAX);
        let albedo = albedo.map(|a| a.into_iter().map(|v| v / 100.0).collect::<Grid32>());
        let albedo = fill(
            albedo,
            &|k| default_albedo(land[k] as f64, ice[k] as f64, snow_cover(snow[k] as f64)) as f32,
            0.0,
            1.0,
        );
        let cwat = fill(cwat, &|_| 0.0, 0.0, f32::MAX);
        Some(GroundInputs {
            ni: g.ni,
            nj: g.nj,
            height_m: height.clone(),
            land,
            ice,
            snow_kg_m2: snow,
            albedo,
            cwat_kg_m2: cwat,
            fields,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::encode::fixtures::{small_field, valid_rh_fields, NI, NJ};
    use crate::forecast::{Forecast, LevelSelect};

    /// A file with RH, orography (sea in the west half, 800 m land in the east) and sea ice
    /// bit-mapped out over land: land from the orography, ice 0 where missing, the default
    /// albedo, no snow or cloud water, and the sidecar's list says which were read.
    #[test]
    fn missing_fields_and_points_take_the_defaults() {
        let n = (NI * NJ) as usize;
        let is_land = |k: usize| k % NI as usize >= 3;
        let surface = |p, values: Vec<f64>| {
            let mut f = small_field(p, 0.0, values);
            f.level_type = Some(SurfaceType::Surface);
            f.level_value = 0.0;
            f.bits = 16;
            f
        };
        let mut fields = valid_rh_fields();
        let orog = (0..n)
            .map(|k| if is_land(k) { 800.0 } else { 0.3 })
            .collect();
        fields.push(surface((0, 3, 5), orog));
        let ice = (0..n)
            .map(|k| if is_land(k) { f64::NAN } else { 0.5 })
            .collect();
        fields.push(surface((10, 2, 0), ice));
        let bytes = crate::encode::encode_file(&fields);
        let fc = Forecast::from_bytes(Path::new("t.grib2"), &bytes, LevelSelect::AllBelow(100.0))
            .unwrap();
        let g = fc.ground.expect("orography makes a ground");
        assert_eq!(g.fields, [GroundField::Orography, GroundField::IceCover]);
        for k in 0..n {
            let land = is_land(k);
            assert_eq!(g.land[k], f32::from(land), "point {k}");
            assert_eq!(g.ice[k], if land { 0.0 } else { 0.5 }, "point {k}");
            let want = default_albedo(f64::from(g.land[k]), f64::from(g.ice[k]), 0.0);
            assert!((f64::from(g.albedo[k]) - want).abs() < 1e-6, "point {k}");
            assert_eq!((g.snow_kg_m2[k], g.cwat_kg_m2[k]), (0.0, 0.0));
        }
        // RH alone: no ground.
        let bytes = crate::encode::encode_file(&valid_rh_fields());
        let fc = Forecast::from_bytes(Path::new("t.grib2"), &bytes, LevelSelect::AllBelow(100.0))
            .unwrap();
        assert!(fc.ground.is_none());
    }

    #[test]
    fn default_albedo_orders_the_surfaces() {
        let near = |a: f64, b: f64| (a - b).abs() < 1e-12;
        assert!(near(default_albedo(0.0, 0.0, 0.0), SEA_ALBEDO));
        assert!(near(default_albedo(1.0, 0.0, 0.0), LAND_ALBEDO));
        assert!(near(default_albedo(0.0, 1.0, 0.0), ICE_ALBEDO));
        assert!(near(default_albedo(1.0, 0.0, 1.0), SNOW_ALBEDO));
        // Ice is sea ice: it does not brighten land.
        assert!(near(default_albedo(1.0, 1.0, 0.0), LAND_ALBEDO));
        let coast = default_albedo(0.5, 0.0, 0.0);
        assert!(coast > SEA_ALBEDO && coast < LAND_ALBEDO);
    }
}
