//! The ground's fields from the forecast grid onto the ground lattice: the map's interpolation
//! (the not-a-knot spline by default, as the coverage), rows then columns, each value then
//! limited to the range of the four grid points around it. The limit is what keeps a spline's
//! ringing out of the terrain: next to a 5 km plateau the sea stays at sea level instead of
//! dipping to −200 m, a valley is never dug below its lowest neighbour, a peak never rises
//! above the highest grid point, and fractions stay in 0..1. Water (land fraction below ½) is
//! then never below sea level.

use crate::lattice::{Placement, StructureGrid};
use crate::spline::{Interp, Tap, WRAP_PAD};

use super::inputs::GroundInputs;
use super::Ground;

/// One field on the grid, with its north–south slopes.
struct Prepared<'a> {
    y: &'a [f32],
    s: Vec<f64>,
}

impl<'a> Prepared<'a> {
    fn new(y: &'a [f32], ni: usize, nj: usize, interp: Interp) -> Prepared<'a> {
        let mut s = vec![0.0; y.len()];
        let mut col = vec![0.0; nj];
        let mut cs = vec![0.0; nj];
        for i in 0..ni {
            for j in 0..nj {
                col[j] = y[j * ni + i] as f64;
            }
            interp.slopes(&col, &mut cs);
            for j in 0..nj {
                s[j * ni + i] = cs[j];
            }
        }
        Prepared { y, s }
    }
}

/// Resample `inputs` (on the grid `at` places) onto `lattice` with `interp`.
pub fn resample(
    inputs: &GroundInputs,
    at: &Placement,
    lattice: StructureGrid,
    interp: Interp,
) -> Ground {
    let (ni, nj) = (inputs.ni, inputs.nj);
    let (w, h) = (lattice.width as usize, lattice.height as usize);
    let pad = if at.wrap { WRAP_PAD } else { 0 };
    let n_pad = ni + 2 * pad;
    let pad_map: Vec<usize> = (0..n_pad)
        .map(|k| (k as isize - pad as isize).rem_euclid(ni as isize) as usize)
        .collect();
    let rows: Vec<Tap> = (0..h)
        .map(|j| {
            let lat = lattice.north - j as f64 * lattice.dlat;
            Tap::at(interp, (at.north - lat) / at.dj, nj)
        })
        .collect();
    let cols: Vec<Tap> = (0..w)
        .map(|i| {
            let lon = lattice.west + i as f64 * lattice.dlon;
            let u = (lon - at.west).rem_euclid(360.0) / at.di;
            Tap::at(interp, u + pad as f64, n_pad)
        })
        .collect();
    let fields = [
        &inputs.height_m,
        &inputs.land,
        &inputs.ice,
        &inputs.snow_kg_m2,
        &inputs.albedo,
        &inputs.cwat_kg_m2,
    ];
    let mut out: Vec<Vec<f32>> = Vec::with_capacity(fields.len());
    let mut line = vec![0.0; n_pad];
    let mut slopes = vec![0.0; n_pad];
    for y in fields {
        let p = Prepared::new(y, ni, nj, interp);
        let mut v = Vec::with_capacity(w * h);
        for tap in &rows {
            let (a, b) = (tap.i0 * ni, (tap.i0 + 1).min(nj - 1) * ni);
            for (k, &c) in pad_map.iter().enumerate() {
                line[k] = tap.w[0] * p.y[a + c] as f64
                    + tap.w[1] * p.y[b + c] as f64
                    + tap.w[2] * p.s[a + c]
                    + tap.w[3] * p.s[b + c];
            }
            interp.slopes(&line, &mut slopes);
            for ct in &cols {
                let (c0, c1) = (pad_map[ct.i0], pad_map[(ct.i0 + 1).min(n_pad - 1)]);
                let corners = [p.y[a + c0], p.y[a + c1], p.y[b + c0], p.y[b + c1]];
                let lo = corners.iter().copied().fold(f32::INFINITY, f32::min);
                let hi = corners.iter().copied().fold(f32::NEG_INFINITY, f32::max);
                v.push((ct.eval(&line, &slopes) as f32).clamp(lo, hi));
            }
        }
        out.push(v);
    }
    // Sea (mostly water) is never below sea level: GFS's orography there is a few tenths of a
    // metre either side of 0, and a sea-level camera or a shore must not sit above the water.
    // (A lake below sea level, the Caspian at −28 m, is drawn at 0 m: it is water either way.)
    if let [height, land, ..] = &mut out[..] {
        for (h, l) in height.iter_mut().zip(land.iter()) {
            if *l < 0.5 && *h < 0.0 {
                *h = 0.0;
            }
        }
    }
    let mut it = out.into_iter();
    let mut next = || it.next().unwrap_or_default();
    Ground {
        grid: lattice,
        region: at.region,
        height_m: next(),
        land: next(),
        ice: next(),
        snow_kg_m2: next(),
        albedo: next(),
        cwat_kg_m2: next(),
        fields: inputs.fields.clone(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ground::GroundField;
    use crate::region::Region;

    /// A plateau beside a sea, on a 1° grid: the spline alone rings below 0 m over the sea and
    /// above the plateau; the limited one never leaves the grid's range there.
    #[test]
    fn no_ringing_below_the_sea_or_above_the_plateau() {
        let (ni, nj) = (12, 6);
        let height: Vec<f32> = (0..ni * nj)
            .map(|k| if k % ni >= 6 { 5000.0 } else { 0.0 })
            .collect();
        let zeros = vec![0.0; ni * nj];
        let inputs = GroundInputs {
            ni,
            nj,
            height_m: height.clone(),
            land: height.iter().map(|&h| f32::from(h > 0.0)).collect(),
            ice: zeros.clone(),
            snow_kg_m2: zeros.clone(),
            albedo: zeros.clone(),
            cwat_kg_m2: zeros,
            fields: vec![GroundField::Orography],
        };
        let region = Region::parse("40,45,0,11").unwrap();
        let at = Placement {
            region,
            map_size: (110, 50),
            north: 45.0,
            west: 0.0,
            di: 1.0,
            dj: 1.0,
            wrap: false,
        };
        let lattice = crate::lattice::structure_grid((110, 50), &region, (45.0, 0.0), (1.0, 1.0));
        let g = resample(&inputs, &at, lattice, Interp::Spline);
        let (lo, hi) = g
            .height_m
            .iter()
            .fold((f32::MAX, f32::MIN), |(a, b), &v| (a.min(v), b.max(v)));
        assert_eq!((lo, hi), (0.0, 5000.0));
        // The unlimited spline does ring here (so the limit is what holds it).
        let line: Vec<f64> = (0..ni).map(|i| height[i] as f64).collect();
        let mut s = vec![0.0; ni];
        Interp::Spline.slopes(&line, &mut s);
        let dip = Tap::at(Interp::Spline, 4.5, ni).eval(&line, &s);
        assert!(dip < -50.0, "{dip}");
        // Between two grid points the coast is a smooth ramp, every lattice point in range.
        let row: Vec<f32> = g.height_m[..g.grid.width as usize].to_vec();
        assert!(row.windows(2).all(|p| p[1] >= p[0]), "{row:?}");
    }
}
