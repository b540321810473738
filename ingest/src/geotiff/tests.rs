//! The writer read back by a small TIFF reader written here for the purpose: tag layout, the
//! COG ordering, tile counts, overview sizes and every pixel.

use std::collections::BTreeMap;
use std::io::Read;

use super::*;

/// One IFD's entries: tag → (type, count, value bytes).
type Tags = BTreeMap<u16, (u16, u32, Vec<u8>)>;

fn u16_at(b: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([b[at], b[at + 1]])
}
fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// Every IFD in chain order, with its file offset.
fn read_ifds(file: &[u8]) -> Vec<(u32, Tags)> {
    assert_eq!(
        &file[..4],
        b"II\x2a\x00",
        "not a little-endian classic TIFF"
    );
    let mut at = u32_at(file, 4);
    let mut ifds = Vec::new();
    while at != 0 {
        let a = at as usize;
        let n = u16_at(file, a) as usize;
        let mut tags = Tags::new();
        let mut prev = 0;
        for i in 0..n {
            let e = a + 2 + 12 * i;
            let (tag, typ, count) = (u16_at(file, e), u16_at(file, e + 2), u32_at(file, e + 4));
            assert!(tag > prev, "tags not ascending: {tag} after {prev}");
            prev = tag;
            let size = match typ {
                2 => 1,
                3 => 2,
                4 => 4,
                12 => 8,
                t => panic!("unexpected type {t}"),
            } * count as usize;
            let bytes = if size <= 4 {
                file[e + 8..e + 8 + size].to_vec()
            } else {
                let o = u32_at(file, e + 8) as usize;
                assert_eq!(o % 2, 0, "tag {tag}: value not on a word boundary");
                file[o..o + size].to_vec()
            };
            tags.insert(tag, (typ, count, bytes));
        }
        ifds.push((at, tags));
        at = u32_at(file, a + 2 + 12 * n);
    }
    ifds
}

/// A tag's values as integers (SHORT or LONG).
fn ints(tags: &Tags, tag: u16) -> Vec<u64> {
    let (typ, _, b) = &tags[&tag];
    match typ {
        3 => b.chunks_exact(2).map(|c| u16_at(c, 0) as u64).collect(),
        4 => b.chunks_exact(4).map(|c| u32_at(c, 0) as u64).collect(),
        t => panic!("tag {tag} has type {t}"),
    }
}
fn doubles(tags: &Tags, tag: u16) -> Vec<f64> {
    let (typ, _, b) = &tags[&tag];
    assert_eq!(*typ, DOUBLE);
    b.chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
        .collect()
}
fn int(tags: &Tags, tag: u16) -> u64 {
    let v = ints(tags, tag);
    assert_eq!(v.len(), 1, "tag {tag}");
    v[0]
}

/// Decode one image's pixels.
fn read_image(file: &[u8], tags: &Tags) -> (usize, usize, Vec<[u16; 4]>) {
    let (w, h) = (
        int(tags, IMAGE_WIDTH) as usize,
        int(tags, IMAGE_LENGTH) as usize,
    );
    let t = int(tags, TILE_WIDTH) as usize;
    assert_eq!(int(tags, TILE_LENGTH) as usize, t);
    let deflate = int(tags, COMPRESSION) == 8;
    let offsets = ints(tags, TILE_OFFSETS);
    let counts = ints(tags, TILE_BYTE_COUNTS);
    let across = w.div_ceil(t);
    assert_eq!(offsets.len(), across * h.div_ceil(t));
    let mut px = vec![[0u16; 4]; w * h];
    for (i, (&o, &n)) in offsets.iter().zip(&counts).enumerate() {
        let data = &file[o as usize..(o + n) as usize];
        let raw = if deflate {
            let mut out = Vec::new();
            flate2::read::ZlibDecoder::new(data)
                .read_to_end(&mut out)
                .unwrap();
            out
        } else {
            data.to_vec()
        };
        assert_eq!(raw.len(), t * t * 8, "tile {i} is not a whole tile");
        let mut tile: Vec<[u16; 4]> = raw
            .chunks_exact(8)
            .map(|c| std::array::from_fn(|s| u16_at(c, 2 * s)))
            .collect();
        if deflate {
            assert_eq!(int(tags, PREDICTOR), 2);
            for row in tile.chunks_exact_mut(t) {
                for x in 1..t {
                    let left = row[x - 1];
                    for (v, l) in row[x].iter_mut().zip(left) {
                        *v = v.wrapping_add(l);
                    }
                }
            }
        }
        let (tx, ty) = (i % across, i / across);
        for y in 0..t {
            for x in 0..t {
                let (gx, gy) = (tx * t + x, ty * t + y);
                if gx < w && gy < h {
                    px[gy * w + gx] = tile[y * t + x];
                } else {
                    assert_eq!(tile[y * t + x], [0; 4], "padding is not zero");
                }
            }
        }
    }
    (w, h, px)
}

/// A pattern with structure in every band: ramps, a checkerboard and a hash.
fn pattern(w: usize, h: usize) -> Vec<[u16; 4]> {
    (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let hash = (x as u32).wrapping_mul(2654435761) ^ (y as u32).wrapping_mul(40503);
            [
                (x * 65535 / w.max(2).saturating_sub(1).max(1)).min(65535) as u16,
                (y * 97 % 65536) as u16,
                if (x / 7 + y / 5) % 2 == 0 { 65535 } else { 0 },
                (hash >> 16) as u16,
            ]
        })
        .collect()
}

/// The reference 2×2 mean, written independently of the writer's streaming version.
fn halve(w: usize, h: usize, px: &[[u16; 4]]) -> (usize, usize, Vec<[u16; 4]>) {
    let (w2, h2) = (w.div_ceil(2), h.div_ceil(2));
    let mut out = Vec::with_capacity(w2 * h2);
    for y in 0..h2 {
        for x in 0..w2 {
            let mut s = [0u32; 4];
            let mut n = 0;
            for yy in 2 * y..(2 * y + 2).min(h) {
                for xx in 2 * x..(2 * x + 2).min(w) {
                    for c in 0..4 {
                        s[c] += px[yy * w + xx][c] as u32;
                    }
                    n += 1;
                }
            }
            out.push(s.map(|v| ((v + n / 2) / n) as u16));
        }
    }
    (w2, h2, out)
}

fn spec(w: u32, h: u32, deflate: bool) -> GeoTiffSpec {
    let region = Region::parse("10,50,150,-150").unwrap();
    GeoTiffSpec {
        width: w,
        height: h,
        georef: GeoRef::of_region(&region, w, h),
        band_names: ["low", "middle", "high", "total"].map(String::from),
        deflate,
    }
}

/// Write `px` (pushed in uneven batches of rows, as the pipeline's bands are).
fn write(w: u32, h: u32, px: &[[u16; 4]], deflate: bool) -> Vec<u8> {
    let mut g = GeoTiffWriter::new(spec(w, h, deflate)).unwrap();
    let wu = w as usize;
    let mut j = 0;
    let mut step = 1;
    while j < h as usize {
        let j1 = (j + step).min(h as usize);
        g.push_rows(&px[j * wu..j1 * wu]).unwrap();
        j = j1;
        step = step % 37 + 3;
    }
    let mut out = Vec::new();
    g.finish(&mut out, &[("STRATUS_TEST", "a<b & \"c\"")])
        .unwrap();
    out
}

#[test]
fn pyramid_halves_until_one_tile() {
    assert_eq!(pyramid(256, 256), [(256, 256)]);
    assert_eq!(pyramid(1, 1), [(1, 1)]);
    assert_eq!(pyramid(257, 1), [(257, 1), (129, 1)]);
    assert_eq!(pyramid(600, 300), [(600, 300), (300, 150), (150, 75)]);
    let p = pyramid(8192, 4096);
    assert_eq!(p.len(), 6);
    assert_eq!(p[5], (256, 128));
}

#[test]
fn georef_is_the_region_with_continuous_longitudes() {
    let g = GeoRef::of_region(&Region::parse("10,50,150,-150").unwrap(), 600, 400);
    assert_eq!((g.west, g.north, g.dx, g.dy), (150.0, 50.0, 0.1, 0.1));
    // Both conventions give the same georeference: west in [-180, 180).
    let g2 = GeoRef::of_region(&Region::parse("10,50,150,210").unwrap(), 600, 400);
    assert_eq!(g, g2);
    let g3 = GeoRef::of_region(&Region::parse("-10,10,200,220").unwrap(), 20, 20);
    assert_eq!((g3.west, g3.dx), (-160.0, 1.0));
    let g4 = GeoRef::of_region(&Region::parse("-90,90,0,360").unwrap(), 720, 360);
    assert_eq!((g4.west, g4.dx, g4.dy), (0.0, 0.5, 0.5));
    // The centre of pixel (i, j) is the map's own pixel centre.
    let r = Region::parse("0,55,39,105").unwrap();
    let g5 = GeoRef::of_region(&r, 130, 110);
    for (i, j) in [(0, 0), (129, 109), (64, 17)] {
        assert!((g5.west + (i as f64 + 0.5) * g5.dx - r.pixel_lon(i, 130)).abs() < 1e-12);
        assert!((g5.north - (j as f64 + 0.5) * g5.dy - r.pixel_lat(j, 110)).abs() < 1e-12);
    }
}

#[test]
fn layout_tags_and_pixels_read_back() {
    for deflate in [true, false] {
        let (w, h) = (600, 300);
        let px = pattern(w, h);
        let file = write(w as u32, h as u32, &px, deflate);
        let ifds = read_ifds(&file);
        // Main image first at offset 8, then overviews, large to small.
        assert_eq!(ifds[0].0, 8);
        let sizes: Vec<(u64, u64)> = ifds
            .iter()
            .map(|(_, t)| (int(t, IMAGE_WIDTH), int(t, IMAGE_LENGTH)))
            .collect();
        assert_eq!(sizes, [(600, 300), (300, 150), (150, 75)]);
        let subfile: Vec<u64> = ifds.iter().map(|(_, t)| int(t, NEW_SUBFILE_TYPE)).collect();
        assert_eq!(subfile, [0, 1, 1]);
        let tiles: Vec<usize> = ifds
            .iter()
            .map(|(_, t)| ints(t, TILE_OFFSETS).len())
            .collect();
        assert_eq!(tiles, [3 * 2, 2, 1]);
        for (_, t) in &ifds {
            assert_eq!(ints(t, BITS_PER_SAMPLE), [16; 4]);
            assert_eq!(ints(t, SAMPLE_FORMAT), [1; 4]);
            assert_eq!(int(t, SAMPLES_PER_PIXEL), 4);
            assert_eq!(int(t, PHOTOMETRIC), 1);
            assert_eq!(ints(t, EXTRA_SAMPLES), [0; 3]);
            assert_eq!(int(t, PLANAR_CONFIGURATION), 1);
            assert_eq!((int(t, TILE_WIDTH), int(t, TILE_LENGTH)), (256, 256));
            assert_eq!(int(t, COMPRESSION), if deflate { 8 } else { 1 });
        }
        // Georeferencing on the main image only.
        let main = &ifds[0].1;
        assert_eq!(
            doubles(main, MODEL_PIXEL_SCALE),
            [60.0 / 600.0, 40.0 / 300.0, 0.0]
        );
        assert_eq!(
            doubles(main, MODEL_TIEPOINT),
            [0.0, 0.0, 0.0, 150.0, 50.0, 0.0]
        );
        assert_eq!(
            ints(main, GEO_KEY_DIRECTORY),
            [1, 1, 1, 4, 1024, 0, 1, 2, 1025, 0, 1, 1, 2048, 0, 1, 4326, 2054, 0, 1, 9102]
        );
        let xml = String::from_utf8(main[&GDAL_METADATA].2.clone()).unwrap();
        assert!(xml.ends_with("</GDALMetadata>\0"), "{xml}");
        assert!(xml.contains("<Item name=\"STRATUS_TEST\">a&lt;b &amp; &quot;c&quot;</Item>"));
        assert!(xml
            .contains("<Item name=\"DESCRIPTION\" sample=\"3\" role=\"description\">total</Item>"));
        for (_, t) in &ifds[1..] {
            assert!(!t.contains_key(&MODEL_TIEPOINT) && !t.contains_key(&GDAL_METADATA));
        }
        // COG order: every IFD before any tile; the smallest image's tiles first, full
        // resolution last; each image's tiles contiguous, in row-major order.
        let first_tile = ifds
            .iter()
            .flat_map(|(_, t)| ints(t, TILE_OFFSETS))
            .min()
            .unwrap();
        let ifd_end = ifds.iter().map(|(o, _)| *o as u64).max().unwrap();
        assert!(ifd_end < first_tile);
        let mut expect = first_tile;
        for (_, t) in ifds.iter().rev() {
            for (o, n) in ints(t, TILE_OFFSETS)
                .into_iter()
                .zip(ints(t, TILE_BYTE_COUNTS))
            {
                assert_eq!(o, expect, "tiles not contiguous in COG order");
                expect += n;
            }
        }
        assert_eq!(expect, file.len() as u64, "bytes after the last tile");
        // Pixels: the full image exactly, each overview the 2×2 mean of the one before.
        let (mut rw, mut rh, mut reference) = (w, h, px.clone());
        for (k, (_, t)) in ifds.iter().enumerate() {
            let (gw, gh, got) = read_image(&file, t);
            assert_eq!((gw, gh), (rw, rh));
            assert!(got == reference, "image {k} (deflate {deflate}) differs");
            (rw, rh, reference) = halve(rw, rh, &reference);
        }
    }
}

#[test]
fn odd_sizes_and_single_tiles() {
    for (w, h) in [(1, 1), (255, 1), (257, 513), (513, 3), (300, 300)] {
        let px = pattern(w, h);
        let file = write(w as u32, h as u32, &px, true);
        let ifds = read_ifds(&file);
        let want = pyramid(w as u32, h as u32);
        assert_eq!(ifds.len(), want.len(), "{w}x{h}");
        let (mut rw, mut rh, mut reference) = (w, h, px);
        for (_, t) in &ifds {
            let (gw, gh, got) = read_image(&file, t);
            assert_eq!((gw, gh), (rw, rh));
            assert!(got == reference, "{w}x{h}: image {gw}x{gh} differs");
            (rw, rh, reference) = halve(rw, rh, &reference);
        }
        let (lw, lh) = *want.last().unwrap();
        assert!(lw <= TILE && lh <= TILE);
    }
}

#[test]
fn wrong_row_counts_are_errors() {
    let mut g = GeoTiffWriter::new(spec(10, 3, true)).unwrap();
    assert!(matches!(
        g.push_rows(&[[0; 4]; 15]),
        Err(GeoTiffError::PartialRow(15))
    ));
    g.push_rows(&[[0; 4]; 20]).unwrap();
    assert!(matches!(
        g.push_rows(&[[0; 4]; 20]),
        Err(GeoTiffError::TooManyRows { height: 3 })
    ));
    let e = g.finish(&mut Vec::new(), &[]).unwrap_err();
    assert!(
        matches!(
            e,
            GeoTiffError::MissingRows {
                pushed: 2,
                height: 3
            }
        ),
        "{e}"
    );
    assert!(GeoTiffWriter::new(spec(0, 3, true)).is_err());
    assert!(GeoTiffWriter::new(spec(8193, 3, true)).is_err());
}

/// A page of `n` bands: ramps, negative and fractional values, and nodata patches.
fn page_pattern(w: usize, h: usize, n: usize) -> Vec<f32> {
    let mut v = Vec::with_capacity(w * h * n);
    for y in 0..h {
        for x in 0..w {
            for b in 0..n {
                v.push(match b % 3 {
                    _ if (x + 3 * y + b) % 17 == 0 => -9999.0,
                    0 => 250.0 + 0.5 * (x * 7 + y * 3) as f32,
                    1 => (x as f32 - y as f32) * 0.01 - 3.25,
                    _ => ((x * y + b) % 11) as f32,
                });
            }
        }
    }
    v
}

fn page_spec(w: u32, h: u32, n: usize) -> PageSpec {
    PageSpec {
        width: w,
        height: h,
        georef: GeoRef {
            west: 149.9,
            north: 50.1,
            dx: 0.25,
            dy: 0.5,
        },
        bands: (0..n)
            .map(|b| PageBand {
                description: format!("band {b} <x>"),
                unit: if b == 1 { String::new() } else { "m".into() },
                items: vec![("CODES".into(), format!("1=a & {b}"))],
            })
            .collect(),
        nodata: -9999.0,
        metadata: vec![("STRATUS_PAGE".into(), "page".into())],
    }
}

/// Decode a page's pixels (Float32, planar, predictor 3, Deflate) into pixel-interleaved order.
fn read_page(file: &[u8], tags: &Tags) -> (usize, usize, Vec<f32>) {
    let (w, h) = (
        int(tags, IMAGE_WIDTH) as usize,
        int(tags, IMAGE_LENGTH) as usize,
    );
    let n = int(tags, SAMPLES_PER_PIXEL) as usize;
    let t = TILE as usize;
    assert_eq!(int(tags, COMPRESSION), 8);
    assert_eq!(int(tags, PREDICTOR), 3);
    let offsets = ints(tags, TILE_OFFSETS);
    let counts = ints(tags, TILE_BYTE_COUNTS);
    let across = w.div_ceil(t);
    let per_band = across * h.div_ceil(t);
    assert_eq!(offsets.len(), per_band * n);
    let mut px = vec![f32::NAN; w * h * n];
    for (i, (&o, &c)) in offsets.iter().zip(&counts).enumerate() {
        let mut raw = Vec::new();
        flate2::read::ZlibDecoder::new(&file[o as usize..(o + c) as usize])
            .read_to_end(&mut raw)
            .unwrap();
        assert_eq!(raw.len(), t * t * 4, "tile {i} is not a whole tile");
        let tile = page::decode_float_tile(&raw, 1);
        let (band, k) = (i / per_band, i % per_band);
        let (tx, ty) = (k % across, k / across);
        for y in 0..t {
            for x in 0..t {
                let (gx, gy) = (tx * t + x, ty * t + y);
                if gx < w && gy < h {
                    px[(gy * w + gx) * n + band] = tile[y * t + x];
                } else {
                    assert_eq!(tile[y * t + x], 0.0, "padding");
                }
            }
        }
    }
    (w, h, px)
}

#[test]
fn a_page_follows_the_main_image_and_reads_back() {
    let (w, h) = (600, 300);
    let px = pattern(w, h);
    let plain = write(w as u32, h as u32, &px, true);
    for (pw, ph, n) in [(300, 280, 5), (1, 1, 1), (257, 3, 20)] {
        let values = page_pattern(pw, ph, n);
        let mut g = GeoTiffWriter::new(spec(w as u32, h as u32, true)).unwrap();
        g.add_page(page_spec(pw as u32, ph as u32, n)).unwrap();
        // Page rows in uneven batches, interleaved with the coverage's.
        let mut pj = 0;
        for (k, rows) in px.chunks(w * 37).enumerate() {
            g.push_rows(rows).unwrap();
            let pj1 = (pj + k % 4 + 1).min(ph);
            g.push_page_rows(&values[pj * pw * n..pj1 * pw * n])
                .unwrap();
            pj = pj1;
        }
        g.push_page_rows(&values[pj * pw * n..]).unwrap();
        let mut file = Vec::new();
        g.finish(&mut file, &[("STRATUS_TEST", "a<b & \"c\"")])
            .unwrap();
        let ifds = read_ifds(&file);
        // Chain: full resolution, the page (GDAL's GTIFF_DIR:2), then the overviews.
        let sizes: Vec<(u64, u64)> = ifds
            .iter()
            .map(|(_, t)| (int(t, IMAGE_WIDTH), int(t, IMAGE_LENGTH)))
            .collect();
        assert_eq!(
            sizes,
            [(600, 300), (pw as u64, ph as u64), (300, 150), (150, 75)]
        );
        let subfile: Vec<u64> = ifds.iter().map(|(_, t)| int(t, NEW_SUBFILE_TYPE)).collect();
        assert_eq!(subfile, [0, 0, 1, 1]);
        let p = &ifds[1].1;
        assert_eq!(ints(p, BITS_PER_SAMPLE), vec![32; n]);
        assert_eq!(ints(p, SAMPLE_FORMAT), vec![3; n]);
        assert_eq!(int(p, SAMPLES_PER_PIXEL), n as u64);
        assert_eq!(int(p, PHOTOMETRIC), 1);
        assert_eq!(int(p, PLANAR_CONFIGURATION), 2);
        if n > 1 {
            assert_eq!(ints(p, EXTRA_SAMPLES), vec![0; n - 1]);
        } else {
            assert!(!p.contains_key(&EXTRA_SAMPLES));
        }
        assert_eq!(doubles(p, MODEL_PIXEL_SCALE), [0.25, 0.5, 0.0]);
        assert_eq!(
            doubles(p, MODEL_TIEPOINT),
            [0.0, 0.0, 0.0, 149.9, 50.1, 0.0]
        );
        // Pixel-is-point: each pixel is a sample at its tie point's lattice position.
        assert_eq!(
            ints(p, GEO_KEY_DIRECTORY),
            [1, 1, 1, 4, 1024, 0, 1, 2, 1025, 0, 1, 2, 2048, 0, 1, 4326, 2054, 0, 1, 9102]
        );
        assert_eq!(p[&GDAL_NODATA].2, b"-9999\0");
        let xml = String::from_utf8(p[&GDAL_METADATA].2.clone()).unwrap();
        assert!(
            xml.contains("<Item name=\"STRATUS_PAGE\">page</Item>"),
            "{xml}"
        );
        assert!(xml.contains(
            "<Item name=\"DESCRIPTION\" sample=\"0\" role=\"description\">band 0 &lt;x&gt;</Item>"
        ));
        assert!(xml.contains("<Item name=\"UNITTYPE\" sample=\"0\" role=\"unittype\">m</Item>"));
        assert!(!xml.contains("<Item name=\"UNITTYPE\" sample=\"1\""));
        assert!(xml.contains("<Item name=\"CODES\" sample=\"0\">1=a &amp; 0</Item>"));
        assert!(!p.contains_key(&SOFTWARE));
        // Data: the page's tiles first, then the smallest overview's … full resolution last,
        // contiguous, ending the file.
        let ifd_end = ifds.iter().map(|(o, _)| *o as u64).max().unwrap();
        let mut expect = ints(p, TILE_OFFSETS)[0];
        assert!(ifd_end < expect);
        for k in [1, 3, 2, 0] {
            let t = &ifds[k].1;
            for (o, c) in ints(t, TILE_OFFSETS)
                .into_iter()
                .zip(ints(t, TILE_BYTE_COUNTS))
            {
                assert_eq!(o, expect, "image {k}: tiles not contiguous in order");
                expect += c;
            }
        }
        assert_eq!(expect, file.len() as u64);
        // The page's values exactly; the coverage images as without a page, to the byte.
        let (gw, gh, got) = read_page(&file, p);
        assert_eq!((gw, gh), (pw, ph));
        assert!(
            got.iter()
                .zip(&values)
                .all(|(a, b)| a.to_bits() == b.to_bits()),
            "page {pw}x{ph}x{n} differs"
        );
        let plain_ifds = read_ifds(&plain);
        for (a, b) in [(0, 0), (2, 1), (3, 2)] {
            let tiles = |f: &[u8], t: &Tags| -> Vec<Vec<u8>> {
                ints(t, TILE_OFFSETS)
                    .into_iter()
                    .zip(ints(t, TILE_BYTE_COUNTS))
                    .map(|(o, c)| f[o as usize..(o + c) as usize].to_vec())
                    .collect()
            };
            assert_eq!(
                tiles(&file, &ifds[a].1),
                tiles(&plain, &plain_ifds[b].1),
                "coverage image {b}"
            );
        }
        assert_eq!(
            ifds[0].1[&GDAL_METADATA], plain_ifds[0].1[&GDAL_METADATA],
            "the coverage's metadata changed"
        );
    }
}

#[test]
fn the_float_predictor_round_trips_any_bits() {
    let mut r = 0x1234_5678_9abc_def0u64;
    for n in [1, 3, 20] {
        let tile: Vec<f32> = (0..TILE as usize * TILE as usize * n)
            .map(|_| {
                r ^= r << 13;
                r ^= r >> 7;
                r ^= r << 17;
                f32::from_bits((r >> 32) as u32)
            })
            .collect();
        let z = page::encode_float_tile(&tile, n);
        let mut raw = Vec::new();
        flate2::read::ZlibDecoder::new(z.as_slice())
            .read_to_end(&mut raw)
            .unwrap();
        let back = page::decode_float_tile(&raw, n);
        assert!(tile
            .iter()
            .zip(&back)
            .all(|(a, b)| a.to_bits() == b.to_bits()));
    }
}

#[test]
fn page_errors_are_typed() {
    let mut g = GeoTiffWriter::new(spec(10, 3, true)).unwrap();
    assert!(matches!(
        g.push_page_rows(&[0.0; 4]),
        Err(GeoTiffError::NoPage)
    ));
    let e = g.add_page(page_spec(4, 2, 0)).unwrap_err();
    assert!(
        matches!(&e, GeoTiffError::Page(b) if matches!(**b, GeoTiffError::BadBands(0))),
        "{e}"
    );
    assert!(g.add_page(page_spec(0, 2, 1)).is_err());
    g.add_page(page_spec(4, 2, 2)).unwrap();
    assert!(matches!(
        g.push_page_rows(&[0.0; 7]),
        Err(GeoTiffError::Page(_))
    ));
    g.push_page_rows(&[0.0; 8]).unwrap();
    g.push_rows(&[[0; 4]; 30]).unwrap();
    let e = g.finish(&mut Vec::new(), &[]).unwrap_err();
    assert!(
        matches!(&e, GeoTiffError::Page(b) if matches!(**b, GeoTiffError::MissingRows { pushed: 1, height: 2 })),
        "{e}"
    );
    assert_eq!(e.to_string(), "the structure page: 1 of 2 rows were pushed");
}
