//! The resampling plan: where each map pixel reads the forecast grid, the RH levels prepared
//! for row evaluation, the map's sidecar content, and the coverage rows they yield; the whole
//! map in memory, and a re-derivation for new critical humidities.

use crate::cloudmap::CloudMap;
use crate::error::{shown, IngestError, Result};
use crate::forecast::Forecast;
use crate::grib::LatLonGrid;
use crate::lattice::{structure_grid, Placement, StructureGrid};
use crate::layer::{standard_altitude_m, validate_rh_crs, AltitudeSource, LayerKind};
use crate::meta::{CloudMapMeta, LayerMeta, SourceMeta, FORMAT};
use crate::region::check_size;
use crate::sample::coverage_to_sample;
use crate::spline::{Tap, WRAP_PAD};
use crate::weather::{GridStructure, LayerSpec};

use super::bands::stream_bands;
use super::physics::coverage;
use super::pixels::{PixelSampler, StructureStats};
use super::stats::fill_stats;
use super::{IngestOptions, Plan, PreparedLevel};

impl Plan {
    pub fn new(fc: &Forecast, opts: &IngestOptions) -> Result<Plan> {
        opts.region.validate()?;
        validate_rh_crs(opts.rh_cr)?;
        check_size(opts.width, opts.height)?;
        let grid = fc.levels[0].field.grid.clone();
        let (ni, nj) = (grid.ni, grid.nj);
        let (w, h) = (opts.width as usize, opts.height as usize);
        let taps = Taps::of(fc, opts, &grid)?;
        let levels = prepare_levels(fc, opts, ni, nj);
        let meta = build_meta(fc, opts, &grid)?;
        // Refuse now, not after the work, a map the loader would refuse.
        meta.validate_content().map_err(IngestError::BadMap)?;
        let structure =
            GridStructure::compute(&fc.levels, &fc.weather, &layer_specs(&meta), ni, nj);
        let r = &opts.region;
        // The structure images on the grid's lattice, not at the map's size (docs/ingest.md).
        let lattice = structure_grid(
            (opts.width, opts.height),
            r,
            (grid.north(), grid.west()),
            (grid.di, grid.dj),
        );
        let placement = Placement {
            region: *r,
            map_size: (w, h),
            north: grid.north(),
            west: grid.west(),
            di: grid.di,
            dj: grid.dj,
            wrap: grid.is_global(),
        };
        let sampler = PixelSampler::new(structure, fc.weather.wind.clone(), placement, lattice);
        let ground = fc
            .ground
            .as_ref()
            .map(|g| crate::ground::resample::resample(g, &placement, lattice, opts.interp));
        Ok(Plan {
            ground,
            sampler,
            placement,
            rh: fc.levels.clone(),
            weather: fc.weather.clone(),
            levels,
            rows: taps.rows,
            cols: taps.cols,
            pad_map: taps.pad_map,
            interp: opts.interp,
            width: w,
            height: h,
            source: fc.path.clone(),
            meta,
        })
    }

    /// Coverage texels of rows `j0..j1` (RGBA 16-bit: low, middle, high, max).
    pub fn rows(&self, j0: usize, j1: usize) -> Vec<[u16; 4]> {
        let n_pad = self.pad_map.len();
        let mut out = vec![[0u16; 4]; (j1 - j0) * self.width];
        let mut acc = vec![[0f64; 3]; self.width];
        let mut line = vec![0.0; n_pad];
        let mut slopes = vec![0.0; n_pad];
        for j in j0..j1 {
            acc.iter_mut().for_each(|a| *a = [0.0; 3]);
            let tap = &self.rows[j];
            for lv in &self.levels {
                // Evaluate the north–south spline of every grid column at this row's latitude.
                let ni = lv.ni;
                let (a, b) = (tap.i0 * ni, (tap.i0 + 1) * ni);
                for (k, &c) in self.pad_map.iter().enumerate() {
                    line[k] = tap.w[0] * lv.y[a + c]
                        + tap.w[1] * lv.y[b + c]
                        + tap.w[2] * lv.s[a + c]
                        + tap.w[3] * lv.s[b + c];
                }
                // Then the west–east spline through those values at each pixel.
                self.interp.slopes(&line, &mut slopes);
                for (px, ct) in acc.iter_mut().zip(&self.cols) {
                    let rh = (ct.eval(&line, &slopes).clamp(0.0, 100.0)) * 0.01;
                    let cm = coverage(rh, lv.rh_cr);
                    let slot = &mut px[lv.layer];
                    if cm > *slot {
                        *slot = cm;
                    }
                }
            }
            let row = &mut out[(j - j0) * self.width..(j - j0 + 1) * self.width];
            for (t, a) in row.iter_mut().zip(&acc) {
                let q = coverage_to_sample;
                let (r, g, b) = (q(a[0]), q(a[1]), q(a[2]));
                *t = [r, g, b, r.max(g).max(b)];
            }
        }
        out
    }

    /// Coverage texels of rows `j0..j1` and the structure tally of their cloudy pixels.
    pub(super) fn band(&self, j0: usize, j1: usize) -> (Vec<[u16; 4]>, StructureStats) {
        let texels = self.rows(j0, j1);
        let mut st = StructureStats::new();
        self.sampler.tally(j0, &texels, &mut st);
        (texels, st)
    }

    /// Build the whole map in memory (for the renderer, tests and live re-derivation).
    pub fn build(&self) -> CloudMap {
        let mut st = StructureStats::new();
        let mut texels = Vec::with_capacity(self.width * self.height);
        let all = stream_bands(
            self.height,
            |a, b| self.band(a, b),
            |(t, s)| {
                texels.extend(t);
                st.merge(&s);
                Ok::<(), std::convert::Infallible>(())
            },
            |_| {},
        );
        let Ok(()) = all;
        let mut meta = self.meta.clone();
        fill_stats(&mut meta, &texels);
        self.apply_structure(&mut meta, &st);
        let structure = Some(self.sampler.map_structure());
        CloudMap {
            meta,
            texels,
            structure,
            ground: self.ground.clone(),
        }
    }

    /// Put the structure summary of `st` into `meta`'s layers.
    pub(super) fn apply_structure(&self, meta: &mut CloudMapMeta, st: &StructureStats) {
        for l in &mut meta.layers {
            let c = l.channel;
            let wind = self.sampler.winds[c].is_some();
            l.structure = Some(st.layer(c, (l.base_m, l.top_m), l.altitude_source, wind));
        }
    }

    pub fn height(&self) -> usize {
        self.height
    }

    /// Where the structure images this plan writes lie: [`structure_grid`] unless changed.
    pub fn structure_grid(&self) -> StructureGrid {
        self.sampler.lattice()
    }

    /// Sample the structure images at the map's own pixels instead (every pixel, as a
    /// full-resolution reference for the reduced images).
    pub fn use_map_pixels_for_structure(&mut self) {
        let g = StructureGrid::of_map(&self.meta.region, self.width as u32, self.height as u32);
        self.sampler.set_lattice(self.placement, g);
    }

    /// Change the critical humidities (low, middle, high) without re-reading the file: the RH
    /// and its slopes stay in memory, so a live control panel re-derives the map by `build`.
    pub fn set_rh_cr(&mut self, rh_cr: [f64; 3]) -> Result<()> {
        validate_rh_crs(rh_cr)?;
        for lv in &mut self.levels {
            lv.rh_cr = rh_cr[lv.layer];
        }
        for l in &mut self.meta.layers {
            l.rh_cr = rh_cr[l.channel];
        }
        let (ni, nj) = (self.sampler.grid.ni, self.sampler.grid.nj);
        self.sampler.grid =
            GridStructure::compute(&self.rh, &self.weather, &layer_specs(&self.meta), ni, nj);
        Ok(())
    }
}

/// Where each map row and column reads the grid: the north–south taps of the rows, the
/// west–east taps of the columns on the (for a global grid, wrap-padded) axis, and that padded
/// axis' columns in the grid.
struct Taps {
    rows: Vec<Tap>,
    cols: Vec<Tap>,
    pad_map: Vec<usize>,
}

impl Taps {
    /// The taps of `opts`' map on the forecast's `grid`; a row or column outside the grid is
    /// refused, naming the grid's extent.
    fn of(fc: &Forecast, opts: &IngestOptions, grid: &LatLonGrid) -> Result<Taps> {
        let (ni, nj) = (grid.ni, grid.nj);
        let (w, h) = (opts.width as usize, opts.height as usize);
        let r = &opts.region;
        let global = grid.is_global();
        let outside = |what: String| {
            IngestError::BadRegion(format!(
                "{what} lies outside the grid of {} (lat {}..{}, lon {}..{})",
                shown(&fc.path),
                grid.south(),
                grid.north(),
                grid.west(),
                grid.west() + (ni - 1) as f64 * grid.di
            ))
        };
        // Rows: fractional row index from the north.
        let rows = (0..h)
            .map(|j| {
                let v = (grid.north() - r.pixel_lat(j, h)) / grid.dj;
                if v < -1e-9 || v > (nj - 1) as f64 + 1e-9 {
                    return Err(outside(format!("latitude {:.4}", r.pixel_lat(j, h))));
                }
                Ok(Tap::at(opts.interp, v, nj))
            })
            .collect::<Result<Vec<_>>>()?;
        let pad = if global { WRAP_PAD } else { 0 };
        let n_pad = ni + 2 * pad;
        let pad_map: Vec<usize> = (0..n_pad)
            .map(|k| (k as isize - pad as isize).rem_euclid(ni as isize) as usize)
            .collect();
        let cols = (0..w)
            .map(|i| {
                let lon = r.pixel_lon(i, w);
                let u = (lon - grid.west()).rem_euclid(360.0) / grid.di;
                if !global && u > (ni - 1) as f64 + 1e-9 {
                    return Err(outside(format!("longitude {lon:.4}")));
                }
                Ok(Tap::at(opts.interp, u + pad as f64, n_pad))
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Taps {
            rows,
            cols,
            pad_map,
        })
    }
}

/// Every RH level of `fc` with its layer, rh_cr and north–south slopes, ready for the rows.
fn prepare_levels(fc: &Forecast, opts: &IngestOptions, ni: usize, nj: usize) -> Vec<PreparedLevel> {
    let mut levels = Vec::with_capacity(fc.levels.len());
    for l in &fc.levels {
        let kind = LayerKind::of_pressure_hpa(l.pressure_hpa);
        let y = l.field.values.clone();
        // North–south slopes, one column at a time.
        let mut s = vec![0.0; y.len()];
        let mut col = vec![0.0; nj];
        let mut cs = vec![0.0; nj];
        for i in 0..ni {
            for j in 0..nj {
                col[j] = y[j * ni + i];
            }
            opts.interp.slopes(&col, &mut cs);
            for j in 0..nj {
                s[j * ni + i] = cs[j];
            }
        }
        levels.push(PreparedLevel {
            layer: kind.channel(),
            rh_cr: opts.rh_cr[kind.channel()],
            ni,
            y,
            s,
        });
    }
    levels
}

/// The map's sidecar content before any pixel is made: layers, their bands and sources.
fn build_meta(fc: &Forecast, opts: &IngestOptions, grid: &LatLonGrid) -> Result<CloudMapMeta> {
    let pressures = fc.pressures();
    // Altitude of every loaded level: gh where present, else the standard atmosphere.
    let z: Vec<(f64, bool)> = pressures
        .iter()
        .map(|&p| match fc.mean_gh(p, &opts.region) {
            Some(z) => (z, true),
            None => (standard_altitude_m(p), false),
        })
        .collect();
    let mut layers = Vec::new();
    for kind in LayerKind::ALL {
        let idx: Vec<usize> = (0..pressures.len())
            .filter(|&i| LayerKind::of_pressure_hpa(pressures[i]) == kind)
            .collect();
        let (Some(&lo), Some(&hi)) = (idx.first(), idx.last()) else {
            continue;
        };
        // A level stands for the air half-way to its neighbours; at the ends of the loaded set
        // the neighbour is a standard-atmosphere level 10 % of pressure away.
        let below = if lo > 0 {
            z[lo - 1].0
        } else {
            standard_altitude_m(pressures[lo] * 1.1)
                + (z[lo].0 - standard_altitude_m(pressures[lo]))
        };
        let above = if hi + 1 < z.len() {
            z[hi + 1].0
        } else {
            standard_altitude_m(pressures[hi] / 1.1)
                + (z[hi].0 - standard_altitude_m(pressures[hi]))
        };
        let base_m = (0.5 * (z[lo].0 + below)).max(0.0);
        let top_m = 0.5 * (z[hi].0 + above);
        layers.push(LayerMeta {
            kind,
            channel: kind.channel(),
            levels_hpa: idx.iter().map(|&i| pressures[i]).collect(),
            rh_cr: opts.rh_cr[kind.channel()],
            base_m,
            top_m: top_m.max(base_m + 100.0),
            altitude_source: if idx.iter().all(|&i| z[i].1) {
                AltitudeSource::GeopotentialHeight
            } else {
                AltitudeSource::StandardAtmosphere
            },
            mean_coverage: 0.0,
            max_coverage: 0.0,
            structure: None,
        });
    }
    Ok(CloudMapMeta {
        format: FORMAT.into(),
        image: String::new(),
        image_id: None,
        extra_images: vec![],
        structure_grid: None,
        ground: None,
        region: opts.region,
        width: opts.width,
        height: opts.height,
        layers,
        interpolation: opts.interp.name().into(),
        source: SourceMeta {
            file: fc.path.display().to_string(),
            reference_time: fc.reference_time,
            forecast_step_h: fc.step_hours.unwrap_or(0.0),
            valid_time: fc.valid_time(),
            grid_ni: grid.ni,
            grid_nj: grid.nj,
            grid_di_deg: grid.di,
            grid_dj_deg: grid.dj,
            fields: fc.weather.found.iter().map(|s| s.to_string()).collect(),
        },
    })
}

/// The layers of `meta` as the structure needs them.
pub(super) fn layer_specs(meta: &CloudMapMeta) -> Vec<LayerSpec> {
    meta.layers
        .iter()
        .map(|l| LayerSpec {
            kind: l.kind,
            rh_cr: l.rh_cr,
            band_base_m: l.base_m,
            band_top_m: l.top_m,
        })
        .collect()
}
