//! A CloudMap as a georeferenced, tiled GeoTIFF with overviews, laid out like a
//! Cloud-Optimized GeoTIFF, written from the TIFF 6.0 and GeoTIFF 1.1 (OGC 19-008r4)
//! specifications.
//!
//! What is written:
//! - little-endian classic TIFF; one image of 4 samples per pixel, unsigned 16-bit
//!   (low, middle, high, total coverage × 65535: the PNG's values exactly), chunky
//!   (`PlanarConfiguration` 1), `PhotometricInterpretation` 1 (min-is-black) with 3
//!   unspecified `ExtraSamples`, which GDAL reads as 4 bands;
//! - 256×256 tiles, Deflate (compression 8, zlib streams) with the horizontal predictor (2);
//!   edge tiles are padded with zeros, as TIFF requires whole tiles;
//! - reduced-resolution images (`NewSubfileType` 1), each the previous one averaged 2×2 (sides
//!   rounded up; an odd last row or column averages the pixels there are), until the image fits
//!   in one tile;
//! - COG layout: the header, then every IFD (full resolution first, then the overviews from
//!   large to small) with its out-of-line values, then the tile data, the smallest overview's
//!   first and full resolution last, each image's tiles in row-major order. A reader streaming
//!   by range requests gets all the structure in the first request and a coarse view next.
//! - georeferencing on the full-resolution image: `ModelTiepointTag` (pixel corner (0, 0) at
//!   the region's west, north), `ModelPixelScaleTag` (degrees per pixel), and GeoKeys
//!   `GTModelTypeGeoKey` = 2 (geographic), `GTRasterTypeGeoKey` = 1 (pixel is area: a pixel's
//!   value stands for its square, whose centre is [`Region::pixel_lon`]/[`Region::pixel_lat`]),
//!   `GeographicTypeGeoKey` = 4326 (WGS 84);
//! - `GDAL_METADATA` (tag 42112): band descriptions, scale 1/65535 (so GDAL users can read
//!   coverage fractions), and dataset items given by the caller.
//! - optionally a second image ([`PageSpec`], `page.rs`): Float32 bands on their own lattice
//!   (the map's structure), second in the IFD chain and its tiles first after the IFDs. One
//!   TIFF image has one sample type and GDAL one nodata value per image, so it cannot be more
//!   bands of the coverage image; without it the file is exactly what it was before pages.
//!
//! Longitudes stay continuous: the west edge is taken into [-180, 180) and the east edge is
//! west + span, so a region across the date line (`150..-150`) is written as 150..210.
//!
//! Memory: rows are pushed in order; each image keeps one 256-row strip of pixels and its
//! compressed tiles, which are laid out once every row is in (the IFDs, written first, must
//! hold every tile's offset and size).

use std::io::Write;

use rayon::prelude::*;

use crate::region::{side_ok, Region};

mod page;
use page::Page;
pub use page::{PageBand, PageSpec};

/// Tile side, in pixels (both directions).
pub const TILE: u32 = 256;

/// Samples per pixel: low, middle, high, total.
const SAMPLES: usize = 4;

/// Bytes a pixel takes uncompressed.
const PIXEL_BYTES: usize = SAMPLES * 2;

// TIFF tags (TIFF 6.0 unless noted).
const NEW_SUBFILE_TYPE: u16 = 254;
const IMAGE_WIDTH: u16 = 256;
const IMAGE_LENGTH: u16 = 257;
const BITS_PER_SAMPLE: u16 = 258;
const COMPRESSION: u16 = 259;
const PHOTOMETRIC: u16 = 262;
const SAMPLES_PER_PIXEL: u16 = 277;
const PLANAR_CONFIGURATION: u16 = 284;
const SOFTWARE: u16 = 305;
const PREDICTOR: u16 = 317;
const TILE_WIDTH: u16 = 322;
const TILE_LENGTH: u16 = 323;
const TILE_OFFSETS: u16 = 324;
const TILE_BYTE_COUNTS: u16 = 325;
const EXTRA_SAMPLES: u16 = 338;
const SAMPLE_FORMAT: u16 = 339;
// GeoTIFF.
const MODEL_PIXEL_SCALE: u16 = 33550;
const MODEL_TIEPOINT: u16 = 33922;
const GEO_KEY_DIRECTORY: u16 = 34735;
// GDAL's private tags: XML metadata (band descriptions, scale, dataset items), and the
// nodata value as text.
const GDAL_METADATA: u16 = 42112;
const GDAL_NODATA: u16 = 42113;

// GeoKeys (OGC 19-008r4, §7.1.4 and annex).
const GT_MODEL_TYPE: u16 = 1024;
const GT_RASTER_TYPE: u16 = 1025;
const GEOGRAPHIC_TYPE: u16 = 2048;
const GEOG_ANGULAR_UNITS: u16 = 2054;
const MODEL_TYPE_GEOGRAPHIC: u16 = 2;
const RASTER_PIXEL_IS_AREA: u16 = 1;
const EPSG_WGS84: u16 = 4326;
const ANGULAR_DEGREE: u16 = 9102;

// Field types.
const ASCII: u16 = 2;
const SHORT: u16 = 3;
const LONG: u16 = 4;
const DOUBLE: u16 = 12;

/// Errors of the GeoTIFF writer. Callers add the file name.
#[derive(Debug, thiserror::Error)]
pub enum GeoTiffError {
    #[error("bad GeoTIFF size {width}x{height}")]
    BadSize { width: u32, height: u32 },
    #[error("rows pushed past the image's {height} rows")]
    TooManyRows { height: u32 },
    #[error("{pushed} of {height} rows were pushed")]
    MissingRows { pushed: u32, height: u32 },
    #[error("{0} pixels are not whole rows")]
    PartialRow(usize),
    #[error("the GeoTIFF would be {0} bytes, past classic TIFF's 4 GiB")]
    TooLarge(u64),
    #[error("a page of {0} bands (1..=256 can be written)")]
    BadBands(usize),
    #[error("rows pushed for a page the file does not have")]
    NoPage,
    #[error("the structure page: {0}")]
    Page(Box<GeoTiffError>),
    #[error("{0}")]
    Io(#[from] std::io::Error),
}

/// Where the image lies on the Earth: its north-west corner and pixel size, in degrees.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GeoRef {
    /// West edge of the first column, in [-180, 180).
    pub west: f64,
    /// North edge of the first row.
    pub north: f64,
    /// Degrees of longitude per pixel.
    pub dx: f64,
    /// Degrees of latitude per pixel (positive; rows go south).
    pub dy: f64,
}

impl GeoRef {
    /// The georeferencing tags of an image's first IFD: pixel scale, tie point and the GeoKey
    /// directory (EPSG:4326, degrees), with `raster_type` 1 (pixel is area: the coverage, whose
    /// pixels are cells) or 2 (pixel is point: the structure, whose pixels are grid points).
    fn push_tags(&self, e: &mut Vec<Entry>, raster_type: u16) {
        e.push(Entry::double(MODEL_PIXEL_SCALE, &[self.dx, self.dy, 0.0]));
        e.push(Entry::double(
            MODEL_TIEPOINT,
            &[0.0, 0.0, 0.0, self.west, self.north, 0.0],
        ));
        let keys = [
            (GT_MODEL_TYPE, MODEL_TYPE_GEOGRAPHIC),
            (GT_RASTER_TYPE, raster_type),
            (GEOGRAPHIC_TYPE, EPSG_WGS84),
            (GEOG_ANGULAR_UNITS, ANGULAR_DEGREE),
        ];
        // Header: version 1, revision 1.1, key count; then (id, location 0 = the value itself,
        // count 1, value) per key, ids ascending.
        let mut dir = vec![1, 1, 1, keys.len() as u16];
        for (id, v) in keys {
            dir.extend_from_slice(&[id, 0, 1, v]);
        }
        e.push(Entry::short(GEO_KEY_DIRECTORY, &dir));
    }

    /// The georeference of a `width`×`height` map of `region`, pixel-is-area as the map is:
    /// pixel (i, j) covers the square whose centre is `region.pixel_lon(i)`,
    /// `region.pixel_lat(j)`. The west edge is taken into [-180, 180) and the east is
    /// west + span, so longitudes stay continuous across the date line.
    pub fn of_region(region: &Region, width: u32, height: u32) -> GeoRef {
        let west = (region.west + 180.0).rem_euclid(360.0) - 180.0;
        GeoRef {
            west,
            north: region.north,
            dx: region.lon_span() / width as f64,
            dy: (region.north - region.south) / height as f64,
        }
    }
}

/// What the file describes besides its pixels.
#[derive(Debug, Clone)]
pub struct GeoTiffSpec {
    pub width: u32,
    pub height: u32,
    pub georef: GeoRef,
    /// One description per band (low, middle, high, total).
    pub band_names: [String; 4],
    /// Deflate with the horizontal predictor; uncompressed when false.
    pub deflate: bool,
}

/// Sizes of the full image and every overview, large to small: each halves the previous
/// (rounded up) until the image fits in one tile.
pub fn pyramid(width: u32, height: u32) -> Vec<(u32, u32)> {
    let mut sizes = vec![(width, height)];
    let (mut w, mut h) = (width, height);
    while w > TILE || h > TILE {
        w = w.div_ceil(2);
        h = h.div_ceil(2);
        sizes.push((w, h));
    }
    sizes
}

/// One image of the pyramid being filled: a strip of up to [`TILE`] rows, the tiles made so
/// far, and the row waiting for its pair to be averaged into the next image.
struct Level {
    width: usize,
    height: usize,
    strip: Vec<[u16; 4]>,
    rows_in: usize,
    tiles: Vec<Vec<u8>>,
    pending: Option<Vec<[u16; 4]>>,
}

impl Level {
    fn tiles_across(&self) -> usize {
        self.width.div_ceil(TILE as usize)
    }
}

/// Builds a GeoTIFF from rows pushed top to bottom; [`GeoTiffWriter::finish`] writes it.
pub struct GeoTiffWriter {
    spec: GeoTiffSpec,
    levels: Vec<Level>,
    page: Option<Page>,
}

impl GeoTiffWriter {
    pub fn new(spec: GeoTiffSpec) -> Result<GeoTiffWriter, GeoTiffError> {
        let (width, height) = (spec.width, spec.height);
        if !(side_ok(width) && side_ok(height)) {
            return Err(GeoTiffError::BadSize { width, height });
        }
        let levels = pyramid(width, height)
            .into_iter()
            .map(|(w, h)| Level {
                width: w as usize,
                height: h as usize,
                strip: Vec::new(),
                rows_in: 0,
                tiles: Vec::new(),
                pending: None,
            })
            .collect();
        Ok(GeoTiffWriter {
            spec,
            levels,
            page: None,
        })
    }

    /// Give the file a second image ([`PageSpec`]): Float32 bands on their own lattice, after
    /// the coverage image in the IFD chain (GDAL's `GTIFF_DIR:2:FILE`). Its rows are pushed
    /// with [`GeoTiffWriter::push_page_rows`].
    pub fn add_page(&mut self, spec: PageSpec) -> Result<(), GeoTiffError> {
        self.page = Some(Page::new(spec).map_err(|e| GeoTiffError::Page(Box::new(e)))?);
        Ok(())
    }

    /// Add whole rows of the page (row-major, the bands of each pixel together, rows in order
    /// from the north).
    pub fn push_page_rows(&mut self, values: &[f32]) -> Result<(), GeoTiffError> {
        self.page
            .as_mut()
            .ok_or(GeoTiffError::NoPage)?
            .push_rows(values)
            .map_err(|e| GeoTiffError::Page(Box::new(e)))
    }

    /// Add whole rows (row-major texels, rows in order from the north).
    pub fn push_rows(&mut self, texels: &[[u16; 4]]) -> Result<(), GeoTiffError> {
        let w = self.spec.width as usize;
        let rows = texels.len() / w;
        if rows * w != texels.len() {
            return Err(GeoTiffError::PartialRow(texels.len()));
        }
        if self.levels[0].rows_in + rows > self.levels[0].height {
            return Err(GeoTiffError::TooManyRows {
                height: self.spec.height,
            });
        }
        let deflate = self.spec.deflate;
        for row in texels.chunks_exact(w) {
            push_row(&mut self.levels, 0, row.to_vec(), deflate);
        }
        Ok(())
    }

    /// Write the file: header, IFDs, tiles. `metadata` are dataset-level GDAL metadata items
    /// (name, value).
    pub fn finish<W: Write>(
        mut self,
        w: &mut W,
        metadata: &[(&str, &str)],
    ) -> Result<(), GeoTiffError> {
        let (pushed, height) = (self.levels[0].rows_in as u32, self.spec.height);
        if pushed != height {
            return Err(GeoTiffError::MissingRows { pushed, height });
        }
        let deflate = self.spec.deflate;
        // The last odd row of each image still waits for a pair that will not come.
        for k in 0..self.levels.len() {
            if let Some(row) = self.levels[k].pending.take() {
                let down = downsample(&row, None);
                push_row(&mut self.levels, k + 1, down, deflate);
            }
        }
        if let Some(p) = &mut self.page {
            p.seal().map_err(|e| GeoTiffError::Page(Box::new(e)))?;
        }
        let xml = gdal_metadata(&self.spec.band_names, metadata);
        // The IFD chain: full resolution, the page (so GDAL numbers it 2 whatever the
        // overviews), then the overviews large to small. Tile data: the page's first (small,
        // and a client streaming by range gets it early), then the smallest overview's, full
        // resolution last.
        let mut images: Vec<(Ifd, &[Vec<u8>])> = (0..self.levels.len())
            .map(|k| (self.ifd(k, &xml), self.levels[k].tiles.as_slice()))
            .collect();
        if let Some(p) = &self.page {
            images.insert(1, (p.ifd(), p.tiles.as_slice()));
        }
        let page_at = self.page.as_ref().map(|_| 1);
        let data_order: Vec<usize> = page_at
            .into_iter()
            .chain((0..images.len()).rev().filter(|&i| Some(i) != page_at))
            .collect();
        let mut at = 8u64;
        let mut ifd_at = Vec::with_capacity(images.len());
        for (ifd, _) in &images {
            ifd_at.push(at);
            at += ifd.size();
        }
        let mut tiles_at = vec![0u64; images.len()];
        for &i in &data_order {
            tiles_at[i] = at;
            at += images[i].1.iter().map(|t| t.len() as u64).sum::<u64>();
        }
        if at > u32::MAX as u64 {
            return Err(GeoTiffError::TooLarge(at));
        }
        w.write_all(b"II")?;
        w.write_all(&42u16.to_le_bytes())?;
        w.write_all(&8u32.to_le_bytes())?;
        let tiles: Vec<&[Vec<u8>]> = images.iter().map(|(_, t)| *t).collect();
        for (i, (ifd, t)) in images.into_iter().enumerate() {
            let mut offsets = Vec::with_capacity(t.len());
            let mut o = tiles_at[i];
            for tile in t {
                offsets.push(o as u32);
                o += tile.len() as u64;
            }
            let counts: Vec<u32> = t.iter().map(|t| t.len() as u32).collect();
            let next = ifd_at.get(i + 1).copied().unwrap_or(0) as u32;
            ifd.write(w, ifd_at[i] as u32, &offsets, &counts, next)?;
        }
        for &i in &data_order {
            for t in tiles[i] {
                w.write_all(t)?;
            }
        }
        Ok(())
    }

    /// The IFD of image `k` (0 = full resolution), its tile offsets and counts still to fill.
    fn ifd(&self, k: usize, xml: &str) -> Ifd {
        let l = &self.levels[k];
        let n = l.tiles.len();
        let mut e = Vec::new();
        e.push(Entry::long(NEW_SUBFILE_TYPE, &[u32::from(k > 0)]));
        e.push(Entry::long(IMAGE_WIDTH, &[l.width as u32]));
        e.push(Entry::long(IMAGE_LENGTH, &[l.height as u32]));
        e.push(Entry::short(BITS_PER_SAMPLE, &[16; SAMPLES]));
        e.push(Entry::short(
            COMPRESSION,
            &[if self.spec.deflate { 8 } else { 1 }],
        ));
        e.push(Entry::short(PHOTOMETRIC, &[1]));
        e.push(Entry::short(SAMPLES_PER_PIXEL, &[SAMPLES as u16]));
        e.push(Entry::short(PLANAR_CONFIGURATION, &[1]));
        if k == 0 {
            let sw = concat!("stratus-ingest ", env!("CARGO_PKG_VERSION"));
            e.push(Entry::ascii(SOFTWARE, sw));
        }
        if self.spec.deflate {
            e.push(Entry::short(PREDICTOR, &[2]));
        }
        e.push(Entry::short(TILE_WIDTH, &[TILE as u16]));
        e.push(Entry::short(TILE_LENGTH, &[TILE as u16]));
        e.push(Entry::placeholder(TILE_OFFSETS, n));
        e.push(Entry::placeholder(TILE_BYTE_COUNTS, n));
        e.push(Entry::short(EXTRA_SAMPLES, &[0; SAMPLES - 1]));
        e.push(Entry::short(SAMPLE_FORMAT, &[1; SAMPLES]));
        if k == 0 {
            self.spec.georef.push_tags(&mut e, RASTER_PIXEL_IS_AREA);
            e.push(Entry::ascii(GDAL_METADATA, xml));
        }
        Ifd { entries: e }
    }
}

/// Add `row` to image `k`, cutting tiles when its strip is full and averaging row pairs into
/// image `k + 1`.
fn push_row(levels: &mut [Level], k: usize, row: Vec<[u16; 4]>, deflate: bool) {
    let Some(l) = levels.get_mut(k) else {
        return;
    };
    l.strip.extend_from_slice(&row);
    l.rows_in += 1;
    if l.rows_in % TILE as usize == 0 || l.rows_in == l.height {
        let strip = std::mem::take(&mut l.strip);
        let tiles = cut_tiles(&strip, l.width, l.tiles_across(), deflate);
        l.tiles.extend(tiles);
    }
    if k + 1 == levels.len() {
        return;
    }
    let down = match levels[k].pending.take() {
        None => {
            levels[k].pending = Some(row);
            return;
        }
        Some(first) => downsample(&first, Some(&row)),
    };
    push_row(levels, k + 1, down, deflate);
}

/// One row of the next image from two rows (or the last, odd one): each output pixel is the
/// rounded mean of the 2×2 (or fewer, at an odd edge) pixels it covers.
fn downsample(a: &[[u16; 4]], b: Option<&[[u16; 4]]>) -> Vec<[u16; 4]> {
    let w = a.len();
    (0..w.div_ceil(2))
        .map(|x| {
            let mut sum = [0u32; 4];
            let mut n = 0u32;
            for row in std::iter::once(a).chain(b) {
                for p in &row[2 * x..(2 * x + 2).min(w)] {
                    for (s, &v) in sum.iter_mut().zip(p) {
                        *s += u32::from(v);
                    }
                    n += 1;
                }
            }
            sum.map(|s| ((s + n / 2) / n) as u16)
        })
        .collect()
}

/// Cut a strip (whole rows of an image `width` wide, at most [`TILE`] of them) into tiles,
/// zero-padded to full size, encoded in parallel.
fn cut_tiles(strip: &[[u16; 4]], width: usize, across: usize, deflate: bool) -> Vec<Vec<u8>> {
    let rows = strip.len() / width;
    let t = TILE as usize;
    (0..across)
        .into_par_iter()
        .map(|tx| {
            let mut tile = vec![[0u16; 4]; t * t];
            let (x0, x1) = (tx * t, ((tx + 1) * t).min(width));
            for y in 0..rows {
                tile[y * t..y * t + (x1 - x0)]
                    .copy_from_slice(&strip[y * width + x0..y * width + x1]);
            }
            encode_tile(&mut tile, deflate)
        })
        .collect()
}

/// A tile's bytes: little-endian samples, after the horizontal predictor and Deflate when
/// compressing.
fn encode_tile(tile: &mut [[u16; 4]], deflate: bool) -> Vec<u8> {
    let t = TILE as usize;
    if deflate {
        // Predictor 2: each sample minus the same sample of the pixel to its left, per row,
        // modulo 2^16 (TIFF 6.0 §14).
        for row in tile.chunks_exact_mut(t) {
            for x in (1..t).rev() {
                let left = row[x - 1];
                for (v, l) in row[x].iter_mut().zip(left) {
                    *v = v.wrapping_sub(l);
                }
            }
        }
    }
    let mut raw = Vec::with_capacity(tile.len() * PIXEL_BYTES);
    for p in tile.iter() {
        for v in p {
            raw.extend_from_slice(&v.to_le_bytes());
        }
    }
    if !deflate {
        return raw;
    }
    deflate_bytes(&raw)
}

/// `raw` as one zlib stream.
fn deflate_bytes(raw: &[u8]) -> Vec<u8> {
    // Level 6, zlib's and GDAL's default: measured (docs/ingest.md) 40 % smaller than level 1
    // on a regional map, at 2.5-3x the time; a COG is written once and served many times.
    let mut z = flate2::write::ZlibEncoder::new(
        Vec::with_capacity(raw.len() / 4),
        flate2::Compression::new(6),
    );
    // Writing to a Vec cannot fail.
    let _ = z.write_all(raw);
    z.finish().unwrap_or_default()
}

/// The `GDAL_METADATA` XML: dataset items, then per band its description and scale.
fn gdal_metadata(band_names: &[String; 4], items: &[(&str, &str)]) -> String {
    let mut x = String::from("<GDALMetadata>\n");
    for (name, value) in items {
        x.push_str(&format!(
            "  <Item name=\"{}\">{}</Item>\n",
            xml_escape(name),
            xml_escape(value)
        ));
    }
    let scale = 1.0 / crate::sample::COVERAGE_FULL;
    for (i, name) in band_names.iter().enumerate() {
        x.push_str(&format!(
            "  <Item name=\"DESCRIPTION\" sample=\"{i}\" role=\"description\">{}</Item>\n",
            xml_escape(name)
        ));
        x.push_str(&format!(
            "  <Item name=\"SCALE\" sample=\"{i}\" role=\"scale\">{scale:e}</Item>\n"
        ));
        x.push_str(&format!(
            "  <Item name=\"OFFSET\" sample=\"{i}\" role=\"offset\">0</Item>\n"
        ));
    }
    x.push_str("</GDALMetadata>");
    x
}

fn xml_escape(s: &str) -> String {
    let mut o = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => o.push_str("&amp;"),
            '<' => o.push_str("&lt;"),
            '>' => o.push_str("&gt;"),
            '"' => o.push_str("&quot;"),
            '\'' => o.push_str("&apos;"),
            // A TIFF ASCII value ends at its NUL; other controls are not XML.
            c if c.is_control() && !matches!(c, '\n' | '\t') => o.push(' '),
            c => o.push(c),
        }
    }
    o
}

/// One IFD entry: tag, type, count and its value bytes (little-endian), placed inline when
/// they fit in 4 bytes and after the IFD otherwise.
struct Entry {
    tag: u16,
    typ: u16,
    count: u32,
    bytes: Vec<u8>,
}

impl Entry {
    fn short(tag: u16, v: &[u16]) -> Entry {
        Entry {
            tag,
            typ: SHORT,
            count: v.len() as u32,
            bytes: v.iter().flat_map(|x| x.to_le_bytes()).collect(),
        }
    }
    fn long(tag: u16, v: &[u32]) -> Entry {
        Entry {
            tag,
            typ: LONG,
            count: v.len() as u32,
            bytes: v.iter().flat_map(|x| x.to_le_bytes()).collect(),
        }
    }
    fn double(tag: u16, v: &[f64]) -> Entry {
        Entry {
            tag,
            typ: DOUBLE,
            count: v.len() as u32,
            bytes: v.iter().flat_map(|x| x.to_le_bytes()).collect(),
        }
    }
    fn ascii(tag: u16, s: &str) -> Entry {
        let mut bytes: Vec<u8> = s.bytes().map(|b| if b == 0 { b' ' } else { b }).collect();
        bytes.push(0);
        Entry {
            tag,
            typ: ASCII,
            count: bytes.len() as u32,
            bytes,
        }
    }
    /// LONGs filled in at write time (tile offsets and byte counts).
    fn placeholder(tag: u16, n: usize) -> Entry {
        Entry::long(tag, &vec![0; n])
    }
    /// Out-of-line bytes, padded to a word boundary as TIFF asks.
    fn outside(&self) -> u64 {
        if self.bytes.len() <= 4 {
            0
        } else {
            (self.bytes.len() as u64).next_multiple_of(2)
        }
    }
}

struct Ifd {
    entries: Vec<Entry>,
}

impl Ifd {
    /// Bytes of the IFD and its out-of-line values.
    fn size(&self) -> u64 {
        2 + 12 * self.entries.len() as u64
            + 4
            + self.entries.iter().map(Entry::outside).sum::<u64>()
    }

    /// Write at file offset `at` (entries must be sorted by tag, as TIFF requires).
    fn write<W: Write>(
        mut self,
        w: &mut W,
        at: u32,
        offsets: &[u32],
        counts: &[u32],
        next: u32,
    ) -> std::io::Result<()> {
        for e in &mut self.entries {
            match e.tag {
                TILE_OFFSETS => *e = Entry::long(TILE_OFFSETS, offsets),
                TILE_BYTE_COUNTS => *e = Entry::long(TILE_BYTE_COUNTS, counts),
                _ => {}
            }
        }
        debug_assert!(self.entries.windows(2).all(|p| p[0].tag < p[1].tag));
        let mut out = Vec::with_capacity(self.size() as usize);
        let mut values_at = at + 2 + 12 * self.entries.len() as u32 + 4;
        let mut values = Vec::new();
        out.extend_from_slice(&(self.entries.len() as u16).to_le_bytes());
        for e in &self.entries {
            out.extend_from_slice(&e.tag.to_le_bytes());
            out.extend_from_slice(&e.typ.to_le_bytes());
            out.extend_from_slice(&e.count.to_le_bytes());
            if e.bytes.len() <= 4 {
                let mut v = [0u8; 4];
                v[..e.bytes.len()].copy_from_slice(&e.bytes);
                out.extend_from_slice(&v);
            } else {
                out.extend_from_slice(&values_at.to_le_bytes());
                values.extend_from_slice(&e.bytes);
                if e.bytes.len() % 2 == 1 {
                    values.push(0);
                }
                values_at += e.outside() as u32;
            }
        }
        out.extend_from_slice(&next.to_le_bytes());
        out.extend_from_slice(&values);
        debug_assert_eq!(out.len() as u64, self.size());
        w.write_all(&out)
    }
}

#[cfg(test)]
mod tests;
