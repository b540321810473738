//! The ground's two PNGs beside a map, both `grid.width`×`grid.height` (the sidecar's
//! `ground.grid`), row 0 north, carrying the map's image id like the structure images:
//! - `MAP.ground.png`, 16-bit RGBA: R terrain height (the structure images' altitude
//!   encoding: m = (v − 1) × 0.5 − 500, 0 not allowed), G land fraction, B sea-ice fraction,
//!   A albedo (fractions as v / 65535).
//! - `MAP.ground-water.png`, 16-bit grey + alpha: grey snow water equivalent (v / 10 kg m⁻²,
//!   up to 6 553.5), alpha total column cloud water (v / 1000 kg m⁻², up to 65.535).

use std::path::{Path, PathBuf};

use crate::lattice::StructureGrid;
use crate::region::Region;
use crate::sample::{altitude_to_sample, sample_to_altitude};

use super::{Ground, GroundField};

/// Samples per kg m⁻² of snow water equivalent and of cloud water.
const SNOW_SCALE: f64 = 10.0;
const CWAT_SCALE: f64 = 1000.0;
const FRACTION_FULL: f64 = 65535.0;

/// The two images of a map written to `png_path` (`MAP.png`): `MAP.ground.png` and
/// `MAP.ground-water.png`, beside it.
pub fn ground_paths(png_path: &Path) -> (PathBuf, PathBuf) {
    let stem = png_path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    (
        png_path.with_file_name(format!("{stem}.ground.png")),
        png_path.with_file_name(format!("{stem}.ground-water.png")),
    )
}

/// Colour type of the surface image and of the water image (both 16-bit).
pub const SURFACE_COLOR: png::ColorType = png::ColorType::Rgba;
pub const WATER_COLOR: png::ColorType = png::ColorType::GrayscaleAlpha;

fn fraction(v: f32) -> u16 {
    (v as f64 * FRACTION_FULL).round().clamp(0.0, FRACTION_FULL) as u16
}

fn scaled(v: f32, scale: f64) -> u16 {
    (v as f64 * scale).round().clamp(0.0, 65535.0) as u16
}

/// The surface image's samples, big-endian (as PNG stores them).
pub fn surface_bytes(g: &Ground) -> Vec<u8> {
    let mut out = Vec::with_capacity(g.len() * 8);
    for k in 0..g.len() {
        for s in [
            altitude_to_sample(Some(g.height_m[k] as f64)),
            fraction(g.land[k]),
            fraction(g.ice[k]),
            fraction(g.albedo[k]),
        ] {
            out.extend_from_slice(&s.to_be_bytes());
        }
    }
    out
}

/// The water image's samples, big-endian.
pub fn water_bytes(g: &Ground) -> Vec<u8> {
    let mut out = Vec::with_capacity(g.len() * 4);
    for k in 0..g.len() {
        for s in [
            scaled(g.snow_kg_m2[k], SNOW_SCALE),
            scaled(g.cwat_kg_m2[k], CWAT_SCALE),
        ] {
            out.extend_from_slice(&s.to_be_bytes());
        }
    }
    out
}

/// The ground from the two images' decoded samples (big-endian, as the PNG decoder gives them;
/// each at least `grid`'s texel count), or what is wrong with which: (is the water image,
/// message).
pub fn decode(
    grid: StructureGrid,
    region: Region,
    fields: Vec<GroundField>,
    surface: &[u8],
    water: &[u8],
) -> Result<Ground, (bool, String)> {
    let (w, n) = (
        grid.width as usize,
        grid.width as usize * grid.height as usize,
    );
    if surface.len() < n * 8 || water.len() < n * 4 {
        return Err((surface.len() >= n * 8, "fewer pixels than its size".into()));
    }
    let u16s = |b: &[u8]| -> Vec<u16> {
        b.chunks_exact(2)
            .map(|c| u16::from_be_bytes([c[0], c[1]]))
            .collect()
    };
    let (s, wt) = (u16s(&surface[..n * 8]), u16s(&water[..n * 4]));
    let mut g = Ground {
        grid,
        region,
        height_m: Vec::with_capacity(n),
        land: Vec::with_capacity(n),
        ice: Vec::with_capacity(n),
        snow_kg_m2: Vec::with_capacity(n),
        albedo: Vec::with_capacity(n),
        cwat_kg_m2: Vec::with_capacity(n),
        fields,
    };
    for (k, px) in s.chunks_exact(4).enumerate() {
        let h = sample_to_altitude(px[0]).ok_or_else(|| {
            (
                false,
                format!("pixel ({}, {}): no terrain height (sample 0)", k % w, k / w),
            )
        })?;
        g.height_m.push(h as f32);
        let f = |v: u16| (v as f64 / FRACTION_FULL) as f32;
        g.land.push(f(px[1]));
        g.ice.push(f(px[2]));
        g.albedo.push(f(px[3]));
    }
    for px in wt.chunks_exact(2) {
        g.snow_kg_m2.push((px[0] as f64 / SNOW_SCALE) as f32);
        g.cwat_kg_m2.push((px[1] as f64 / CWAT_SCALE) as f32);
    }
    Ok(g)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_round_trip_within_their_step() {
        let region = Region::parse("0,1,0,2").unwrap();
        let grid = StructureGrid::of_map(&region, 2, 1);
        let g = Ground {
            grid,
            region,
            height_m: vec![-28.3, 8848.0],
            land: vec![0.0, 0.73],
            ice: vec![0.5, 0.0],
            snow_kg_m2: vec![0.0, 812.34],
            albedo: vec![0.06, 0.683],
            cwat_kg_m2: vec![0.86, 0.0004],
            fields: GroundField::ALL.to_vec(),
        };
        let back = decode(
            grid,
            region,
            g.fields.clone(),
            &surface_bytes(&g),
            &water_bytes(&g),
        )
        .unwrap();
        for (a, b, step) in [
            (&g.height_m, &back.height_m, 0.25),
            (&g.land, &back.land, 1e-5),
            (&g.ice, &back.ice, 1e-5),
            (&g.albedo, &back.albedo, 1e-5),
            (&g.snow_kg_m2, &back.snow_kg_m2, 0.05),
            (&g.cwat_kg_m2, &back.cwat_kg_m2, 0.0005),
        ] {
            for (x, y) in a.iter().zip(b) {
                assert!((x - y).abs() <= step + 1e-6, "{x} → {y}");
            }
        }
        let mut bad = surface_bytes(&g);
        bad[8] = 0;
        bad[9] = 0;
        let e = decode(grid, region, vec![], &bad, &water_bytes(&g)).unwrap_err();
        assert_eq!(
            e,
            (false, "pixel (1, 0): no terrain height (sample 0)".into())
        );
    }
}
