//! Forecast → CloudMap: spline upsampling per level, the critical-humidity formula per pixel
//! (after interpolation), max over each layer's levels, 16-bit RGBA out (DESIGN §1.3–1.5).
//!
//! Rows are produced in parallel bands and streamed to the PNG encoder, so a 6500×5500 map never
//! holds more than a few bands in memory.

use std::io::Write;
use std::path::{Path, PathBuf};

use rayon::prelude::*;

use crate::cloudmap::{
    coverage_to_sample, extra_path, extra_writer, file_name, ground_writers, rgba16_writer,
    sidecar_json, CloudMap, COVERAGE_FULL, MAX_SIDE,
};
use crate::error::shown;
use crate::error::{IngestError, Result};
use crate::forecast::{Forecast, RhLevel};
use crate::geotiff::{GeoRef, GeoTiffSpec, GeoTiffWriter, PageBand, PageSpec};
use crate::ground::Ground;
use crate::meta::{
    AltitudeSource, CloudMapMeta, ExtraImage, ExtraRole, LayerKind, LayerMeta, SourceMeta,
    StructureGrid, FORMAT,
};
use crate::output::{check_output, ensure_not_input, write_atomic, write_set, ExtraWriter};
use crate::region::Region;
use crate::spline::{Interp, Tap, WRAP_PAD};
use crate::structure::{structure_grid, StructureBand, STRUCTURE_NODATA};
use crate::weather::pixels::{PixelSampler, Placement, StructureStats};
use crate::weather::{GridStructure, LayerSpec, WeatherInputs};

/// Descriptions of a GeoTIFF CloudMap's bands, in band order (the PNG's R, G, B, A).
pub const LAYER_BANDS: [&str; 4] = [
    "low cloud coverage",
    "middle cloud coverage",
    "high cloud coverage",
    "total cloud coverage (max of the layers)",
];

/// The GDAL metadata item under which a GeoTIFF CloudMap carries its sidecar's JSON.
pub const GEOTIFF_META_ITEM: &str = "STRATUS_CLOUDMAP";

/// What the user asked of one ingest.
#[derive(Debug, Clone)]
pub struct IngestOptions {
    pub region: Region,
    pub width: u32,
    pub height: u32,
    /// Critical humidity per layer (low, middle, high), fractions in [0, 1).
    pub rh_cr: [f64; 3],
    pub interp: Interp,
}

/// Check a critical humidity: the formula divides by 1 − rh_cr.
pub fn validate_rh_cr(x: f64) -> Result<f64> {
    if !x.is_finite() || !(0.0..1.0).contains(&x) {
        return Err(IngestError::BadRhCr(format!(
            "rh_cr must be in [0, 1) (a fraction; the formula divides by 1 - rh_cr), got {x}"
        )));
    }
    Ok(x)
}

/// Paper eq. 1–2: coverage from relative humidity (fractions).
#[inline]
pub fn coverage(rh: f64, rh_cr: f64) -> f64 {
    let c = ((rh - rh_cr) / (1.0 - rh_cr)).clamp(0.0, 1.0);
    c * c
}

/// One RH level prepared for fast row evaluation.
struct PreparedLevel {
    layer: usize,
    rh_cr: f64,
    ni: usize,
    /// Row-major values and their north–south slopes.
    y: Vec<f64>,
    s: Vec<f64>,
}

/// A ready-to-run resampling of one forecast onto one region.
pub struct Plan {
    levels: Vec<PreparedLevel>,
    rows: Vec<Tap>,
    cols: Vec<Tap>,
    /// Column of the padded axis → grid column.
    pad_map: Vec<usize>,
    interp: Interp,
    width: usize,
    height: usize,
    /// The forecast file read, which the output must not replace.
    source: PathBuf,
    pub meta: CloudMapMeta,
    /// Per-pixel structure, types and winds (issue 13), and what recomputes it when rh_cr
    /// changes (the RH-column source depends on it).
    sampler: PixelSampler,
    placement: Placement,
    rh: Vec<RhLevel>,
    weather: WeatherInputs,
    /// The ground on the structure lattice, when the forecast has orography (issue 14).
    ground: Option<Ground>,
}

impl Plan {
    pub fn new(fc: &Forecast, opts: &IngestOptions) -> Result<Plan> {
        opts.region.validate()?;
        for x in opts.rh_cr {
            validate_rh_cr(x)?;
        }
        for side in [opts.width, opts.height] {
            if side == 0 || side > MAX_SIDE {
                return Err(IngestError::BadSize(format!(
                    "each side must be 1..={MAX_SIDE} px, got {}x{}",
                    opts.width, opts.height
                )));
            }
        }
        let grid = fc.levels[0].field.grid.clone();
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
        let meta = build_meta(fc, opts, &grid)?;
        // Refuse now, not after the work, a map the loader would refuse.
        meta.validate_content().map_err(IngestError::BadMap)?;
        let structure =
            GridStructure::compute(&fc.levels, &fc.weather, &layer_specs(&meta), ni, nj);
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
            wrap: global,
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
            rows,
            cols,
            pad_map,
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
    fn band(&self, j0: usize, j1: usize) -> (Vec<[u16; 4]>, StructureStats) {
        let texels = self.rows(j0, j1);
        let mut st = StructureStats::new();
        self.sampler.tally(j0, &texels, &mut st);
        (texels, st)
    }

    /// Build the whole map in memory (for the renderer, tests and live re-derivation).
    pub fn build(&self) -> CloudMap {
        let bands = self.bands(self.height);
        let parts: Vec<_> = bands.par_iter().map(|&(a, b)| self.band(a, b)).collect();
        let mut st = StructureStats::new();
        let mut texels = Vec::with_capacity(self.width * self.height);
        for (t, s) in parts {
            texels.extend(t);
            st.merge(&s);
        }
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
    fn apply_structure(&self, meta: &mut CloudMapMeta, st: &StructureStats) {
        for l in &mut meta.layers {
            let c = l.channel;
            let wind = self.sampler.winds[c].is_some();
            l.structure = Some(st.layer(c, (l.base_m, l.top_m), l.altitude_source, wind));
        }
    }

    /// The extra images of a map written to `png_path`: (path, streaming writer), and the
    /// sidecar's list of them.
    fn extra_writers<'a>(&'a self, png_path: &Path) -> Result<(ExtraSet<'a>, Vec<ExtraImage>)> {
        let mut writers: Vec<(PathBuf, ExtraWriter<'a>)> = Vec::new();
        let mut listed = Vec::new();
        let g = self.sampler.lattice();
        let (w, h) = (g.width as usize, g.height as usize);
        for role in ExtraRole::ALL {
            let path = extra_path(png_path, role);
            listed.push(ExtraImage {
                role,
                image: file_name(&path)?,
            });
            writers.push((
                path,
                Box::new(move |out, id| {
                    let mut wr = extra_writer(out, role, w as u32, h as u32, id)?;
                    let mut sw = wr.stream_writer().map_err(|e| e.to_string())?;
                    let bands = self.bands(h);
                    for chunk in bands.chunks(rayon::current_num_threads().max(1) * 2) {
                        let parts: Vec<Vec<u8>> = chunk
                            .par_iter()
                            .map(|&(a, b)| {
                                let mut v = Vec::new();
                                for j in a..b {
                                    self.sampler.append_row(role, j, &mut v);
                                }
                                v
                            })
                            .collect();
                        for p in parts {
                            sw.write_all(&p).map_err(|e| e.to_string())?;
                        }
                    }
                    sw.finish().map_err(|e| e.to_string())
                }),
            ));
        }
        Ok((writers, listed))
    }

    /// Rows `0..height` in bands of 32.
    fn bands(&self, height: usize) -> Vec<(usize, usize)> {
        let band = 32;
        (0..height.div_ceil(band))
            .map(|b| (b * band, ((b + 1) * band).min(height)))
            .collect()
    }

    /// Stream the map to `png_path` and its sidecar (`.json`), computing bands in parallel,
    /// and commit them as one pair ([`crate::output::write_pair`]): on any error the previous
    /// pair (if any) is left as it was. Neither file may be the forecast file read.
    /// `progress` is called with the number of rows done.
    pub fn write(&self, png_path: &Path, progress: &(dyn Fn(usize) + Sync)) -> Result<PathBuf> {
        let bands = self.bands(self.height);
        let stats = std::cell::RefCell::new(Stats::default());
        let structure_stats = std::cell::RefCell::new(StructureStats::new());
        let (mut extras, listed) = self.extra_writers(png_path)?;
        let ground = match &self.ground {
            Some(g) => {
                let (meta, writers) = ground_writers(png_path, g)?;
                extras.extend(writers);
                Some(meta)
            }
            None => None,
        };
        write_set(
            png_path,
            &[self.source.as_path()],
            |w, id| {
                let mut wr = rgba16_writer(w, self.width as u32, self.height as u32, id)?;
                let mut sw = wr.stream_writer().map_err(|e| e.to_string())?;
                let mut done = 0;
                let mut st = Stats::default();
                let mut sst = StructureStats::new();
                // A few bands per core at a time bounds memory; order is kept by `collect`.
                for chunk in bands.chunks(rayon::current_num_threads().max(1) * 2) {
                    let parts: Vec<_> = chunk.par_iter().map(|&(a, b)| self.band(a, b)).collect();
                    for ((p, s), &(a, b)) in parts.iter().zip(chunk) {
                        st.add(p);
                        sst.merge(s);
                        let mut bytes = Vec::with_capacity(p.len() * 8);
                        for t in p {
                            for c in t {
                                bytes.extend_from_slice(&c.to_be_bytes());
                            }
                        }
                        sw.write_all(&bytes).map_err(|e| e.to_string())?;
                        done += b - a;
                    }
                    progress(done);
                }
                sw.finish().map_err(|e| e.to_string())?;
                *stats.borrow_mut() = st;
                *structure_stats.borrow_mut() = sst;
                Ok(())
            },
            extras,
            |name, id| {
                let mut meta = self.meta.clone();
                stats.borrow().apply(&mut meta);
                self.apply_structure(&mut meta, &structure_stats.borrow());
                meta.extra_images = listed;
                meta.structure_grid = Some(self.sampler.lattice());
                meta.ground = ground;
                sidecar_json(&meta, name, id, png_path)
            },
        )
    }

    /// Stream the map to a GeoTIFF at `tif_path` ([`crate::geotiff`]: tiled, with overviews,
    /// COG layout, EPSG:4326), written atomically ([`crate::output::write_atomic`]); it may
    /// not be the forecast file read. No sidecar is written: the sidecar's content (layers,
    /// times, source) is carried in the file as the GDAL metadata item `STRATUS_CLOUDMAP`.
    /// When the forecast held more than RH, the structure follows as a second image
    /// ([`Plan::geotiff_structure`]). Returns that metadata, coverage statistics filled in.
    /// `progress` is called with the number of coverage rows done.
    pub fn write_geotiff(
        &self,
        tif_path: &Path,
        progress: &(dyn Fn(usize) + Sync),
    ) -> Result<CloudMapMeta> {
        check_output(tif_path)?;
        ensure_not_input(tif_path, &[self.source.as_path()])?;
        let name = tif_path
            .file_name()
            .and_then(|n| n.to_str())
            .ok_or_else(|| {
                IngestError::write(
                    tif_path,
                    "the file name is not valid UTF-8, and the map's metadata records it as text; choose a UTF-8 name",
                )
            })?;
        let spec = GeoTiffSpec {
            width: self.width as u32,
            height: self.height as u32,
            georef: GeoRef::of_region(&self.meta.region, self.width as u32, self.height as u32),
            band_names: LAYER_BANDS.map(String::from),
            deflate: true,
        };
        let bands = self.bands(self.height);
        let structure = self.geotiff_structure();
        let mut done_meta = None;
        write_atomic(tif_path, |w| {
            let mut gt = GeoTiffWriter::new(spec).map_err(|e| e.to_string())?;
            if let Some((page, layout)) = &structure {
                gt.add_page(page.clone()).map_err(|e| e.to_string())?;
                let rows = self.bands(page.height as usize);
                for chunk in rows.chunks(rayon::current_num_threads().max(1) * 2) {
                    let parts: Vec<Vec<f32>> = chunk
                        .par_iter()
                        .map(|&(a, b)| {
                            let mut v = Vec::new();
                            for j in a..b {
                                self.sampler
                                    .append_physical_row(layout, j, page.nodata, &mut v);
                            }
                            v
                        })
                        .collect();
                    for p in parts {
                        gt.push_page_rows(&p).map_err(|e| e.to_string())?;
                    }
                }
            }
            let mut done = 0;
            let mut st = Stats::default();
            for chunk in bands.chunks(rayon::current_num_threads().max(1) * 2) {
                let parts: Vec<Vec<[u16; 4]>> =
                    chunk.par_iter().map(|&(a, b)| self.rows(a, b)).collect();
                for (p, &(a, b)) in parts.iter().zip(chunk) {
                    st.add(p);
                    gt.push_rows(p).map_err(|e| e.to_string())?;
                    done += b - a;
                }
                progress(done);
            }
            let mut meta = self.meta.clone();
            st.apply(&mut meta);
            meta.image = name.to_string();
            meta.image_id = None;
            let json = serde_json::to_string(&meta).map_err(|e| e.to_string())?;
            gt.finish(w, &[(GEOTIFF_META_ITEM, &json)])
                .map_err(|e| e.to_string())?;
            done_meta = Some(meta);
            Ok(())
        })?;
        done_meta.ok_or_else(|| IngestError::write(tif_path, "nothing was written"))
    }

    /// The GeoTIFF's structure image and its bands, when the forecast held more than RH
    /// (`source.fields`): the structure images' lattice and values, decoded to physical units
    /// (docs/ingest.md, "GeoTIFF"). From RH alone the structure says little the coverage and
    /// the layers' bands do not (RH-column crossings on the standard atmosphere, each layer's
    /// default type, no wind), and the file stays the four coverage bands.
    pub fn geotiff_structure(&self) -> Option<(PageSpec, Vec<StructureBand>)> {
        if self.meta.source.fields.is_empty() {
            return None;
        }
        let kinds: Vec<LayerKind> = self.meta.layers.iter().map(|l| l.kind).collect();
        let layout = StructureBand::of_layers(&kinds);
        let g = self.sampler.lattice();
        let r = &self.meta.region;
        // The coverage image's longitudes, shifted by whole turns into [-180, 180) at the
        // region's west edge; the lattice moves with them.
        let shift = GeoRef::of_region(r, 1, 1).west - r.west;
        let bands = layout
            .iter()
            .map(|b| PageBand {
                description: b.description(),
                unit: b.unit().into(),
                items: b
                    .codes()
                    .map(|c| vec![("CODES".to_string(), c)])
                    .unwrap_or_default(),
            })
            .collect();
        let page = PageSpec {
            width: g.width,
            height: g.height,
            georef: GeoRef {
                west: g.west + shift,
                north: g.north,
                dx: g.dlon,
                dy: g.dlat,
            },
            bands,
            nodata: STRUCTURE_NODATA,
            metadata: vec![(
                "STRATUS_STRUCTURE".into(),
                "cloud structure of the coverage map (GTIFF_DIR:1): point samples on the \
                 forecast grid's lattice; read base, top and wind bilinear, type and source \
                 at the nearest pixel; altitudes in m above mean sea level"
                    .into(),
            )],
        };
        Some((page, layout))
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
        for x in rh_cr {
            validate_rh_cr(x)?;
        }
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

#[derive(Default)]
struct Stats {
    sum: [f64; 3],
    max: [u16; 3],
    n: usize,
}

impl Stats {
    fn add(&mut self, texels: &[[u16; 4]]) {
        for t in texels {
            for ((sum, max), &v) in self.sum.iter_mut().zip(&mut self.max).zip(t) {
                *sum += v as f64;
                *max = (*max).max(v);
            }
        }
        self.n += texels.len();
    }
    fn apply(&self, meta: &mut CloudMapMeta) {
        for l in &mut meta.layers {
            let c = l.channel;
            l.mean_coverage = self.sum[c] / COVERAGE_FULL / self.n.max(1) as f64;
            l.max_coverage = self.max[c] as f64 / COVERAGE_FULL;
        }
    }
}

pub(crate) fn fill_stats(meta: &mut CloudMapMeta, texels: &[[u16; 4]]) {
    let mut s = Stats::default();
    s.add(texels);
    s.apply(meta);
}

/// ICAO standard atmosphere altitude (m) of a pressure (hPa), troposphere and lower stratosphere.
pub fn standard_altitude_m(p_hpa: f64) -> f64 {
    if p_hpa >= 226.32 {
        44330.8 * (1.0 - (p_hpa / 1013.25).powf(0.190263))
    } else {
        11000.0 - 6341.6 * (p_hpa / 226.32).ln()
    }
}

fn build_meta(
    fc: &Forecast,
    opts: &IngestOptions,
    grid: &crate::grib::LatLonGrid,
) -> Result<CloudMapMeta> {
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

/// Extra images to write: (path, streaming writer).
type ExtraSet<'a> = Vec<(PathBuf, ExtraWriter<'a>)>;

/// The layers of `meta` as the structure needs them.
fn layer_specs(meta: &CloudMapMeta) -> Vec<LayerSpec> {
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A plan over the fixture's 6×5-point grid, from `fields`.
    fn fixture_plan(dir: &Path, fields: &[crate::encode::Grib2Field]) -> Plan {
        let grib = dir.join("f.grib2");
        std::fs::write(&grib, crate::encode::encode_file(fields)).unwrap();
        let fc = Forecast::open(&grib, crate::forecast::LevelSelect::AllBelow(100.0)).unwrap();
        let opts = IngestOptions {
            region: Region::parse("46.5,49.5,10.5,14.5").unwrap(),
            width: 40,
            height: 30,
            rh_cr: [0.3; 3],
            interp: Interp::Spline,
        };
        Plan::new(&fc, &opts).unwrap()
    }

    #[test]
    fn the_geotiff_structure_is_the_images_decoded_and_needs_more_than_rh() {
        use crate::encode::{fixtures, param};
        use crate::structure::{sample_to_altitude, sample_to_wind, unpack_source};
        use crate::weather::CloudType;
        let dir = tempfile::tempdir().unwrap();
        let all = fixtures::valid_rh_fields();
        let plan = fixture_plan(dir.path(), &all);
        let (page, layout) = plan
            .geotiff_structure()
            .expect("RH + gh has a structure page");
        let kinds: Vec<LayerKind> = plan.meta.layers.iter().map(|l| l.kind).collect();
        assert_eq!(layout, StructureBand::of_layers(&kinds));
        assert_eq!(layout.len(), 6 * kinds.len() + 2);
        assert_eq!(page.bands.len(), layout.len());
        let g = plan.structure_grid();
        assert_eq!((page.width, page.height), (g.width, g.height));
        assert_eq!(
            (
                page.georef.west,
                page.georef.north,
                page.georef.dx,
                page.georef.dy
            ),
            (g.west, g.north, g.dlon, g.dlat)
        );
        assert_eq!(page.bands[0].unit, "m");
        // Every pixel of every band: the structure images' samples, decoded.
        let ms = plan.build().structure.unwrap();
        let nd = STRUCTURE_NODATA;
        let m = |v: Option<f64>| v.map_or(nd, |v| v as f32);
        let mut with_value = 0;
        for j in 0..g.height as usize {
            let mut row = Vec::new();
            plan.sampler.append_physical_row(&layout, j, nd, &mut row);
            assert_eq!(row.len(), g.width as usize * layout.len());
            for (i, px) in row.chunks_exact(layout.len()).enumerate() {
                let p = j * g.width as usize + i;
                for (&b, &got) in layout.iter().zip(px) {
                    let want = match b {
                        StructureBand::Base(k) => m(sample_to_altitude(ms.base[p][k.channel()])),
                        StructureBand::Top(k) => m(sample_to_altitude(ms.top[p][k.channel()])),
                        StructureBand::Type(k) => {
                            m(CloudType::from_code(ms.types[p][k.channel()])
                                .map(|t| t.code() as f64))
                        }
                        StructureBand::Source(k) => {
                            m(unpack_source(ms.types[p][3], k.channel()).map(|s| s as u8 as f64))
                        }
                        // The fixture has no wind: none, not the images' 0 m/s.
                        StructureBand::WindU(k) | StructureBand::WindV(k) => {
                            assert!(plan.sampler.winds[k.channel()].is_none());
                            assert_eq!(sample_to_wind(ms.wind_u[p][k.channel()]), 0.0);
                            nd
                        }
                        StructureBand::ConvectiveBase => m(sample_to_altitude(ms.base[p][3])),
                        StructureBand::ConvectiveTop => m(sample_to_altitude(ms.top[p][3])),
                    };
                    assert_eq!(got.to_bits(), want.to_bits(), "{b:?} at ({i}, {j})");
                    with_value += usize::from(got != nd);
                }
            }
        }
        assert!(with_value > 0);
        // RH alone (no gh): no structure page, so the file stays the coverage bands.
        let rh: Vec<_> = all
            .into_iter()
            .filter(|f| (f.category, f.number) == (param::RH.1, param::RH.2))
            .collect();
        let plan = fixture_plan(dir.path(), &rh);
        assert!(plan.meta.source.fields.is_empty());
        assert!(plan.geotiff_structure().is_none());
    }

    #[test]
    fn coverage_formula_at_its_edges() {
        assert_eq!(coverage(0.65, 0.65), 0.0);
        assert_eq!(coverage(0.0, 0.65), 0.0);
        assert_eq!(coverage(1.0, 0.65), 1.0);
        assert!((coverage(0.825, 0.65) - 0.25).abs() < 1e-12);
        assert_eq!(coverage(0.5, 0.0), 0.25);
        assert!(coverage(0.99995, 0.9999).is_finite());
        assert!(validate_rh_cr(1.0).is_err());
        assert!(validate_rh_cr(1.5).is_err());
        assert!(validate_rh_cr(f64::NAN).is_err());
        assert!(validate_rh_cr(-0.1).is_err());
        assert_eq!(validate_rh_cr(0.0).unwrap(), 0.0);
    }

    #[test]
    fn standard_atmosphere_is_monotonic_and_sane() {
        assert!(standard_altitude_m(1013.25).abs() < 1.0);
        assert!((standard_altitude_m(500.0) - 5574.0).abs() < 30.0);
        assert!((standard_altitude_m(226.32) - 11000.0).abs() < 5.0);
        let mut prev = -1.0;
        for p in (10..=1000).rev().step_by(10) {
            let z = standard_altitude_m(p as f64);
            assert!(z > prev);
            prev = z;
        }
    }
}
