//! A second image in the GeoTIFF: Float32 bands on their own lattice (the map's structure,
//! [`crate::structure`]), after the coverage image in the IFD chain, which GDAL opens as the
//! subdataset `GTIFF_DIR:2:FILE`.
//!
//! What is written: one image of N samples per pixel, IEEE 32-bit floats (`SampleFormat` 3),
//! planar (`PlanarConfiguration` 2: each band's tiles apart, all of band 1's first, so a reader
//! of one band reads only its tiles, and Deflate sees one smooth field at a time: a third smaller
//! than chunky on East Asia's), min-is-black with N − 1 unspecified `ExtraSamples`; 256×256
//! tiles, Deflate with the floating-point predictor (3, TIFF Technical Note 3: per tile row,
//! each value's bytes split into planes, most significant first, then each byte minus the one
//! before it); no overviews (the image is a few hundred pixels a side at 2.5°). Georeferenced as
//! pixel-is-point (`GTRasterTypeGeoKey` 2): pixel (i, j) is a sample at `west + i·dx`,
//! `north − j·dy`, exactly where the structure lattice puts it. `GDAL_METADATA` holds band
//! descriptions, units and items; `GDAL_NODATA` (tag 42113) the value standing for "none".

use rayon::prelude::*;

use crate::region::side_ok;

use super::{
    xml_escape, Entry, GeoRef, GeoTiffError, Ifd, COMPRESSION, EXTRA_SAMPLES, GDAL_METADATA,
    IMAGE_LENGTH, IMAGE_WIDTH, NEW_SUBFILE_TYPE, PHOTOMETRIC, PLANAR_CONFIGURATION, PREDICTOR,
    SAMPLES_PER_PIXEL, SAMPLE_FORMAT, TILE, TILE_BYTE_COUNTS, TILE_LENGTH, TILE_OFFSETS,
    TILE_WIDTH,
};
use super::{BITS_PER_SAMPLE, GDAL_NODATA};

const RASTER_PIXEL_IS_POINT: u16 = 2;
const SAMPLE_IEEE_FLOAT: u16 = 3;
const PREDICTOR_FLOAT: u16 = 3;

/// One band of a page.
#[derive(Debug, Clone, PartialEq)]
pub struct PageBand {
    /// GDAL's band description.
    pub description: String,
    /// GDAL's unit type (`m`, `m/s`); empty for codes.
    pub unit: String,
    /// Band-level GDAL metadata items (name, value), e.g. a code table.
    pub items: Vec<(String, String)>,
}

/// What a page describes besides its pixels.
#[derive(Debug, Clone)]
pub struct PageSpec {
    pub width: u32,
    pub height: u32,
    /// Pixel (0, 0)'s *centre* (`west`, `north`) and the spacing: the pixels are point samples.
    pub georef: GeoRef,
    pub bands: Vec<PageBand>,
    /// The value that stands for "no value" in every band.
    pub nodata: f32,
    /// Dataset-level GDAL metadata items (name, value).
    pub metadata: Vec<(String, String)>,
}

/// A page being filled: a strip of up to [`TILE`] rows and each band's tiles made so far.
pub(super) struct Page {
    pub(super) spec: PageSpec,
    strip: Vec<f32>,
    pub(super) rows_in: usize,
    band_tiles: Vec<Vec<Vec<u8>>>,
    /// Every tile in file order (band by band), once [`Page::seal`] has run.
    pub(super) tiles: Vec<Vec<u8>>,
}

impl Page {
    pub(super) fn new(spec: PageSpec) -> Result<Page, GeoTiffError> {
        let (width, height) = (spec.width, spec.height);
        if !(side_ok(width) && side_ok(height)) {
            return Err(GeoTiffError::BadSize { width, height });
        }
        // A tile row of every sample must stay addressable, and TIFF counts samples in a SHORT.
        if spec.bands.is_empty() || spec.bands.len() > 256 {
            return Err(GeoTiffError::BadBands(spec.bands.len()));
        }
        Ok(Page {
            band_tiles: vec![Vec::new(); spec.bands.len()],
            spec,
            strip: Vec::new(),
            rows_in: 0,
            tiles: Vec::new(),
        })
    }

    fn samples(&self) -> usize {
        self.spec.bands.len()
    }

    /// Add whole rows (row-major, the bands of each pixel together).
    pub(super) fn push_rows(&mut self, values: &[f32]) -> Result<(), GeoTiffError> {
        let row = self.spec.width as usize * self.samples();
        let rows = values.len() / row;
        if rows * row != values.len() {
            return Err(GeoTiffError::PartialRow(values.len()));
        }
        let height = self.spec.height as usize;
        if self.rows_in + rows > height {
            return Err(GeoTiffError::TooManyRows {
                height: self.spec.height,
            });
        }
        for r in values.chunks_exact(row) {
            self.strip.extend_from_slice(r);
            self.rows_in += 1;
            if self.rows_in.is_multiple_of(TILE as usize) || self.rows_in == height {
                let strip = std::mem::take(&mut self.strip);
                let tiles = self.cut_tiles(&strip);
                for (band, t) in self.band_tiles.iter_mut().zip(tiles) {
                    band.extend(t);
                }
            }
        }
        Ok(())
    }

    /// Check every row is in and put the tiles in file order.
    pub(super) fn seal(&mut self) -> Result<(), GeoTiffError> {
        let (pushed, height) = (self.rows_in as u32, self.spec.height);
        if pushed != height {
            return Err(GeoTiffError::MissingRows { pushed, height });
        }
        self.tiles = std::mem::take(&mut self.band_tiles).concat();
        Ok(())
    }

    /// Cut a strip (whole rows, at most [`TILE`]) into each band's zero-padded tiles (left to
    /// right), encoded in parallel.
    fn cut_tiles(&self, strip: &[f32]) -> Vec<Vec<Vec<u8>>> {
        let (n, t) = (self.samples(), TILE as usize);
        let width = self.spec.width as usize;
        let rows = strip.len() / (width * n);
        let across = width.div_ceil(t);
        let mut flat: Vec<Vec<u8>> = (0..n * across)
            .into_par_iter()
            .map(|k| {
                let (band, tx) = (k / across, k % across);
                let mut tile = vec![0f32; t * t];
                let (x0, x1) = (tx * t, ((tx + 1) * t).min(width));
                for y in 0..rows {
                    for (d, x) in tile[y * t..y * t + x1 - x0].iter_mut().zip(x0..x1) {
                        *d = strip[(y * width + x) * n + band];
                    }
                }
                encode_float_tile(&tile, 1)
            })
            .collect();
        let mut out = Vec::with_capacity(n);
        for _ in 0..n {
            let rest = flat.split_off(across);
            out.push(std::mem::replace(&mut flat, rest));
        }
        out
    }

    /// The page's IFD, its tile offsets and counts still to fill.
    pub(super) fn ifd(&self) -> Ifd {
        let s = &self.spec;
        let n = self.samples();
        let mut e = vec![
            Entry::long(NEW_SUBFILE_TYPE, &[0]),
            Entry::long(IMAGE_WIDTH, &[s.width]),
            Entry::long(IMAGE_LENGTH, &[s.height]),
            Entry::short(BITS_PER_SAMPLE, &vec![32; n]),
            Entry::short(COMPRESSION, &[8]),
            Entry::short(PHOTOMETRIC, &[1]),
            Entry::short(SAMPLES_PER_PIXEL, &[n as u16]),
            Entry::short(PLANAR_CONFIGURATION, &[2]),
            Entry::short(PREDICTOR, &[PREDICTOR_FLOAT]),
            Entry::short(TILE_WIDTH, &[TILE as u16]),
            Entry::short(TILE_LENGTH, &[TILE as u16]),
            Entry::placeholder(TILE_OFFSETS, self.tiles.len()),
            Entry::placeholder(TILE_BYTE_COUNTS, self.tiles.len()),
        ];
        if n > 1 {
            e.push(Entry::short(EXTRA_SAMPLES, &vec![0; n - 1]));
        }
        e.push(Entry::short(SAMPLE_FORMAT, &vec![SAMPLE_IEEE_FLOAT; n]));
        s.georef.push_tags(&mut e, RASTER_PIXEL_IS_POINT);
        e.push(Entry::ascii(GDAL_METADATA, &self.metadata_xml()));
        e.push(Entry::ascii(GDAL_NODATA, &format_nodata(s.nodata)));
        Ifd { entries: e }
    }

    /// The `GDAL_METADATA` XML: dataset items, then per band its description, unit and items.
    fn metadata_xml(&self) -> String {
        let mut x = String::from("<GDALMetadata>\n");
        let item = |x: &mut String, attrs: &str, value: &str| {
            x.push_str(&format!("  <Item {attrs}>{}</Item>\n", xml_escape(value)));
        };
        for (name, value) in &self.spec.metadata {
            item(&mut x, &format!("name=\"{}\"", xml_escape(name)), value);
        }
        for (i, b) in self.spec.bands.iter().enumerate() {
            item(
                &mut x,
                &format!("name=\"DESCRIPTION\" sample=\"{i}\" role=\"description\""),
                &b.description,
            );
            if !b.unit.is_empty() {
                item(
                    &mut x,
                    &format!("name=\"UNITTYPE\" sample=\"{i}\" role=\"unittype\""),
                    &b.unit,
                );
            }
            for (name, value) in &b.items {
                item(
                    &mut x,
                    &format!("name=\"{}\" sample=\"{i}\"", xml_escape(name)),
                    value,
                );
            }
        }
        x.push_str("</GDALMetadata>");
        x
    }
}

/// GDAL_NODATA's text: the shortest that reads back as the same f32.
fn format_nodata(v: f32) -> String {
    if v.is_nan() {
        "nan".into()
    } else {
        format!("{v}")
    }
}

/// A tile's bytes: the floating-point predictor per tile row, then Deflate.
pub(super) fn encode_float_tile(tile: &[f32], samples: usize) -> Vec<u8> {
    let row_values = TILE as usize * samples;
    let mut raw = Vec::with_capacity(tile.len() * 4);
    let mut planes = vec![0u8; row_values * 4];
    for row in tile.chunks_exact(row_values) {
        // Byte planes, most significant first: plane b holds byte 3 − b of every value's
        // little-endian form (Technical Note 3 is written for big-endian order).
        for (k, v) in row.iter().enumerate() {
            let le = v.to_le_bytes();
            for b in 0..4 {
                planes[b * row_values + k] = le[3 - b];
            }
        }
        // Then each byte minus the byte one pixel (`samples` bytes) before it, over the whole
        // shuffled row, from the end so each difference uses the original neighbour.
        for k in (samples..planes.len()).rev() {
            planes[k] = planes[k].wrapping_sub(planes[k - samples]);
        }
        raw.extend_from_slice(&planes);
    }
    super::deflate_bytes(&raw)
}

#[cfg(test)]
pub(super) fn decode_float_tile(raw: &[u8], samples: usize) -> Vec<f32> {
    let row_values = TILE as usize * samples;
    let mut out = Vec::with_capacity(raw.len() / 4);
    for row in raw.chunks_exact(row_values * 4) {
        let mut planes = row.to_vec();
        for k in samples..planes.len() {
            planes[k] = planes[k].wrapping_add(planes[k - samples]);
        }
        for k in 0..row_values {
            let b = [
                planes[3 * row_values + k],
                planes[2 * row_values + k],
                planes[row_values + k],
                planes[k],
            ];
            out.push(f32::from_le_bytes(b));
        }
    }
    out
}
