//! The CloudMap: per-pixel low/middle/high/total coverage, its 16-bit PNG and sidecar I/O,
//! with its structure images and ground; the point probe over it is in [`probe`].
//!
//! A map's PNG and sidecar are written as one pair ([`crate::output::write_pair`]): a failed
//! or interrupted write leaves the previous pair, and a reader never trusts a PNG that is not
//! its sidecar's.

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};

use crate::error::{IngestError, Result};
use crate::ground::{image as ground_image, Ground, GroundMeta};
use crate::meta::{CloudMapMeta, ExtraImage, ExtraRole, FORMAT};
pub use crate::output::write_atomic;
use crate::output::{write_set, ExtraWriter};
/// Largest map side, shared by ingest, the loader and the renderer.
pub use crate::region::MAX_SIDE;
// The coverage encoding is the vocabulary's (`sample`); its old path stays.
pub use crate::sample::{coverage_to_sample, COVERAGE_FULL};
use crate::structure::MapStructure;

pub mod probe;

/// Coverage in 0..1 for R (low), G (middle), B (high), A (= max of the three).
#[derive(Debug, Clone)]
pub struct CloudMap {
    pub meta: CloudMapMeta,
    /// Row-major, row 0 = north, `width * height` texels.
    pub texels: Vec<[u16; 4]>,
    /// Base, top, type, source and wind on their own, smaller lattice (version 3 maps made
    /// from a forecast; [`MapStructure::grid`]); `None` for maps without them, whose layers
    /// each have one band and a default type.
    pub structure: Option<MapStructure>,
    /// Terrain and surface under the clouds, on their own lattice ([`crate::ground`]); `None`
    /// for maps made from a file without orography (and older maps): sea level.
    pub ground: Option<Ground>,
}

impl CloudMap {
    pub fn width(&self) -> usize {
        self.meta.width as usize
    }
    pub fn height(&self) -> usize {
        self.meta.height as usize
    }

    /// Total cover (A channel) at pixel (i, j), 0..1.
    pub fn total(&self, i: usize, j: usize) -> f32 {
        self.texels[j * self.width() + i][3] as f32 / COVERAGE_FULL as f32
    }

    /// A made-up map (tests, benchmarks, stability cases): coverage per layer slot (low, middle,
    /// high) from `cover(lat, lon)`, clamped to 0..1; `bands` gives each present layer's altitudes.
    pub fn from_fn(
        region: crate::region::Region,
        width: u32,
        height: u32,
        bands: &[(crate::layer::LayerKind, f64, f64)],
        valid_time: chrono::DateTime<chrono::Utc>,
        cover: impl Fn(f64, f64) -> [f64; 3] + Sync,
    ) -> CloudMap {
        use crate::layer::AltitudeSource;
        use crate::meta::{LayerMeta, SourceMeta};
        let (w, h) = (width as usize, height as usize);
        let texels: Vec<[u16; 4]> = (0..w * h)
            .map(|idx| {
                let (i, j) = (idx % w, idx / w);
                let c = cover(region.pixel_lat(j, h), region.pixel_lon(i, w));
                let mut t = [0u16; 4];
                for &(kind, _, _) in bands {
                    let k = kind.channel();
                    t[k] = coverage_to_sample(c[k]);
                }
                t[3] = t[0].max(t[1]).max(t[2]);
                t
            })
            .collect();
        let layers = bands
            .iter()
            .map(|&(kind, base_m, top_m)| LayerMeta {
                kind,
                channel: kind.channel(),
                levels_hpa: vec![],
                rh_cr: kind.default_rh_cr(),
                base_m,
                top_m,
                altitude_source: AltitudeSource::StandardAtmosphere,
                mean_coverage: 0.0,
                max_coverage: 0.0,
                structure: None,
            })
            .collect();
        CloudMap {
            meta: CloudMapMeta {
                format: FORMAT.to_string(),
                image: "synthetic.png".into(),
                image_id: None,
                extra_images: vec![],
                structure_grid: None,
                ground: None,
                region,
                width,
                height,
                layers,
                interpolation: "synthetic".into(),
                source: SourceMeta {
                    file: "synthetic".into(),
                    reference_time: Some(valid_time),
                    forecast_step_h: 0.0,
                    valid_time: Some(valid_time),
                    grid_ni: 0,
                    grid_nj: 0,
                    grid_di_deg: 0.0,
                    grid_dj_deg: 0.0,
                    fields: vec![],
                },
            },
            texels,
            structure: None,
            ground: None,
        }
    }

    /// Load a CloudMap from its sidecar (`MAP.json`), checking the sidecar ([`load_meta`])
    /// and that the PNG is its own: the size it declares (checked before anything is decoded)
    /// and, for formats 2 and 3, the image id it carries. The extra images of format 3 are
    /// checked the same way, each against the size of the sidecar's `structure_grid` (the
    /// map's size where it has none), and the type image's codes against the table; any fault
    /// is one error naming the file. A set caught between a writer's renames is read again a few
    /// times before it is refused.
    pub fn load(sidecar: &Path) -> Result<CloudMap> {
        Self::load_with(sidecar, load_meta(sidecar)?)
    }

    /// [`CloudMap::load`] from a sidecar already read and checked (`meta`, from [`load_meta`]
    /// or [`meta_from_text`]): the images are read against it; a set caught between a
    /// writer's renames has its sidecar read again.
    pub fn load_with(sidecar: &Path, meta: CloudMapMeta) -> Result<CloudMap> {
        let mut attempt = 0;
        let mut meta = Some(meta);
        loop {
            let meta = match meta.take() {
                Some(m) => m,
                None => load_meta(sidecar)?,
            };
            let read = read_png16(&meta.image_path(sidecar), &meta).and_then(|texels| {
                let structure = match meta.extra_images.is_empty() {
                    true => None,
                    false => Some(read_structure(sidecar, &meta)?),
                };
                let ground = match &meta.ground {
                    Some(g) => Some(read_ground(sidecar, &meta, g)?),
                    None => None,
                };
                Ok((texels, structure, ground))
            });
            match read {
                Ok((texels, structure, ground)) => {
                    return Ok(CloudMap {
                        meta,
                        texels,
                        structure,
                        ground,
                    })
                }
                Err(PngFault::NotThisPair(_)) if attempt < PAIR_RETRIES => {
                    attempt += 1;
                    std::thread::sleep(PAIR_RETRY_WAIT);
                }
                Err(PngFault::NotThisPair(e) | PngFault::Other(e)) => return Err(e),
            }
        }
    }

    /// Write `png_path` and its sidecar (same stem, `.json`) as one pair (see
    /// [`crate::output::write_pair`]); the map must pass [`CloudMapMeta::validate_content`].
    pub fn save(&self, png_path: &Path) -> Result<PathBuf> {
        let (width, height) = (self.meta.width, self.meta.height);
        if self.texels.len() != width as usize * height as usize {
            return Err(IngestError::BadMap(format!(
                "{} texels for a {width}x{height} map",
                self.texels.len()
            )));
        }
        self.meta.validate_content().map_err(IngestError::BadMap)?;
        let mut bytes = Vec::with_capacity(self.texels.len() * 8);
        for t in &self.texels {
            for c in t {
                bytes.extend_from_slice(&c.to_be_bytes());
            }
        }
        let mut meta = self.meta.clone();
        let mut extras: Vec<(PathBuf, ExtraWriter)> = Vec::new();
        meta.extra_images.clear();
        meta.structure_grid = None;
        if let Some(s) = &self.structure {
            let (sw, sh) = (s.grid.width, s.grid.height);
            if !s.is_whole() {
                return Err(IngestError::BadMap(format!(
                    "structure images are not {sw}x{sh} pixels each"
                )));
            }
            // Checked with the rest of the sidecar before anything is written.
            meta.structure_grid = Some(s.grid);
            for role in ExtraRole::ALL {
                let path = extra_path(png_path, role);
                meta.extra_images.push(ExtraImage {
                    role,
                    image: file_name(&path)?,
                });
                let bytes = match role {
                    ExtraRole::Base => be_bytes(s.base.iter().flatten()),
                    ExtraRole::Top => be_bytes(s.top.iter().flatten()),
                    ExtraRole::Type => s.types.iter().flatten().copied().collect(),
                    ExtraRole::WindU => be_bytes(s.wind_u.iter().flatten()),
                    ExtraRole::WindV => be_bytes(s.wind_v.iter().flatten()),
                };
                extras.push((
                    path,
                    Box::new(move |w, id| {
                        let mut wr = extra_writer(w, role, sw, sh, id)?;
                        wr.write_image_data(&bytes).map_err(|e| e.to_string())?;
                        wr.finish().map_err(|e| e.to_string())
                    }),
                ));
            }
        }
        meta.ground = None;
        if let Some(g) = &self.ground {
            let (gm, writers) = ground_writers(png_path, g)?;
            meta.ground = Some(gm);
            extras.extend(writers);
        }
        write_set(
            png_path,
            &[],
            |w, id| {
                let mut wr = rgba16_writer(w, width, height, id)?;
                wr.write_image_data(&bytes).map_err(|e| e.to_string())?;
                wr.finish().map_err(|e| e.to_string())
            },
            extras,
            |name, id| sidecar_json(&meta, name, id, png_path),
        )
    }
}

fn be_bytes<'a>(v: impl Iterator<Item = &'a u16>) -> Vec<u8> {
    v.flat_map(|x| x.to_be_bytes()).collect()
}

/// `MAP.png` → `MAP.<role>.png`, beside it.
pub fn extra_path(png_path: &Path, role: ExtraRole) -> PathBuf {
    let stem = png_path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    png_path.with_file_name(format!("{stem}.{}.png", role.suffix()))
}

pub(crate) fn file_name(p: &Path) -> Result<String> {
    p.file_name()
        .and_then(|n| n.to_str())
        .map(str::to_string)
        .ok_or_else(|| {
            IngestError::write(p, "the file name is not valid UTF-8; choose a UTF-8 name")
        })
}

/// Colour type and bit depth of each extra image.
pub fn extra_format(role: ExtraRole) -> (png::ColorType, png::BitDepth) {
    use png::{BitDepth as D, ColorType as C};
    match role {
        ExtraRole::Base | ExtraRole::Top => (C::Rgba, D::Sixteen),
        ExtraRole::Type => (C::Rgba, D::Eight),
        ExtraRole::WindU | ExtraRole::WindV => (C::Rgb, D::Sixteen),
    }
}

/// A PNG writer for an extra image, carrying the set's image id.
pub(crate) fn extra_writer<W: Write>(
    w: W,
    role: ExtraRole,
    width: u32,
    height: u32,
    id: &str,
) -> std::result::Result<png::Writer<W>, String> {
    let (ct, bd) = extra_format(role);
    let mut enc = png::Encoder::new(w, width, height);
    enc.set_color(ct);
    enc.set_depth(bd);
    enc.set_compression(png::Compression::Fast);
    enc.add_text_chunk(IMAGE_ID_KEYWORD.into(), id.into())
        .map_err(|e| e.to_string())?;
    enc.write_header().map_err(|e| e.to_string())
}

/// Read and check the five extra images `meta` lists, each of the size the sidecar records
/// ([`CloudMapMeta::structure_pixels`]).
fn read_structure(
    sidecar: &Path,
    meta: &CloudMapMeta,
) -> std::result::Result<MapStructure, PngFault> {
    let mut raw = Vec::with_capacity(5);
    for role in ExtraRole::ALL {
        let x = meta.extra(role).ok_or_else(|| {
            PngFault::Other(IngestError::BadCloudMap {
                path: sidecar.to_path_buf(),
                msg: format!("extra_images: no {} image", role.suffix()),
            })
        })?;
        let path = sidecar
            .parent()
            .unwrap_or_else(|| Path::new("."))
            .join(&x.image);
        let g = meta.structure_pixels();
        let buf = read_image(
            &path,
            meta,
            extra_format(role),
            role.suffix(),
            (g.width, g.height),
        )?;
        raw.push((path, buf));
    }
    let grid = meta.structure_pixels();
    let (w, h) = (grid.width as usize, grid.height as usize);
    let n = w * h;
    let u16s = |b: &[u8]| -> Vec<u16> {
        b.chunks_exact(2)
            .map(|c| u16::from_be_bytes([c[0], c[1]]))
            .collect()
    };
    let quad = |b: &[u8]| -> Vec<[u16; 4]> {
        u16s(b)
            .chunks_exact(4)
            .take(n)
            .map(|c| [c[0], c[1], c[2], c[3]])
            .collect()
    };
    let triple = |b: &[u8]| -> Vec<[u16; 3]> {
        u16s(b)
            .chunks_exact(3)
            .take(n)
            .map(|c| [c[0], c[1], c[2]])
            .collect()
    };
    let s = MapStructure {
        grid,
        base: quad(&raw[0].1),
        top: quad(&raw[1].1),
        types: raw[2]
            .1
            .chunks_exact(4)
            .take(n)
            .map(|c| [c[0], c[1], c[2], c[3]])
            .collect(),
        wind_u: triple(&raw[3].1),
        wind_v: triple(&raw[4].1),
    };
    if let Some((k, what)) = s.first_bad_type() {
        return Err(PngFault::Other(IngestError::BadCloudMap {
            path: raw[2].0.clone(),
            msg: format!("pixel ({}, {}): {what}", k % w, k / w),
        }));
    }
    Ok(s)
}

/// The ground's two images of a map written to `png_path`, their sidecar entry and writers.
pub(crate) fn ground_writers<'a>(
    png_path: &Path,
    g: &Ground,
) -> Result<(GroundMeta, Vec<(PathBuf, ExtraWriter<'a>)>)> {
    let (sw, sh) = (g.grid.width, g.grid.height);
    if !g.is_whole() {
        return Err(IngestError::BadMap(format!(
            "ground fields are not {sw}x{sh} texels each"
        )));
    }
    let (surface, water) = ground_image::ground_paths(png_path);
    // Centimetres: the f32 values' binary tails say nothing.
    let cm = |v: f64| (v * 100.0).round() / 100.0;
    let (min, max) = g.height_range();
    let (min, max) = (cm(min), cm(max));
    let meta = GroundMeta {
        image: file_name(&surface)?,
        water_image: file_name(&water)?,
        grid: g.grid,
        fields: g.fields.clone(),
        height_min_m: min,
        height_max_m: max,
    };
    let mut writers: Vec<(PathBuf, ExtraWriter<'a>)> = Vec::with_capacity(2);
    for (path, ct, bytes) in [
        (
            surface,
            ground_image::SURFACE_COLOR,
            ground_image::surface_bytes(g),
        ),
        (
            water,
            ground_image::WATER_COLOR,
            ground_image::water_bytes(g),
        ),
    ] {
        writers.push((
            path,
            Box::new(move |w, id| {
                let mut wr = png16_writer(w, ct, sw, sh, id)?;
                wr.write_image_data(&bytes).map_err(|e| e.to_string())?;
                wr.finish().map_err(|e| e.to_string())
            }),
        ));
    }
    Ok((meta, writers))
}

/// A 16-bit PNG writer of colour type `ct`, carrying the set's image id.
fn png16_writer<W: Write>(
    w: W,
    ct: png::ColorType,
    width: u32,
    height: u32,
    id: &str,
) -> std::result::Result<png::Writer<W>, String> {
    let mut enc = png::Encoder::new(w, width, height);
    enc.set_color(ct);
    enc.set_depth(png::BitDepth::Sixteen);
    enc.set_compression(png::Compression::Fast);
    enc.add_text_chunk(IMAGE_ID_KEYWORD.into(), id.into())
        .map_err(|e| e.to_string())?;
    enc.write_header().map_err(|e| e.to_string())
}

/// Read and check the ground images `g` names, each of `g.grid`'s size (checked before any
/// pixel is decoded), 16-bit of its colour type, every terrain height present.
fn read_ground(
    sidecar: &Path,
    meta: &CloudMapMeta,
    g: &GroundMeta,
) -> std::result::Result<Ground, PngFault> {
    let dir = sidecar.parent().unwrap_or_else(|| Path::new("."));
    let size = (g.grid.width, g.grid.height);
    let surface_path = dir.join(&g.image);
    let water_path = dir.join(&g.water_image);
    let d16 = png::BitDepth::Sixteen;
    let surface = read_image(
        &surface_path,
        meta,
        (ground_image::SURFACE_COLOR, d16),
        "ground",
        size,
    )?;
    let water = read_image(
        &water_path,
        meta,
        (ground_image::WATER_COLOR, d16),
        "ground-water",
        size,
    )?;
    ground_image::decode(g.grid, meta.region, g.fields.clone(), &surface, &water).map_err(
        |(is_water, msg)| {
            PngFault::Other(IngestError::BadCloudMap {
                path: if is_water { water_path } else { surface_path },
                msg,
            })
        },
    )
}

/// The PNG text chunk under which a map's PNG carries its sidecar's `image_id`.
pub const IMAGE_ID_KEYWORD: &str = "stratus-image-id";

/// How often, and how far apart, [`CloudMap::load`] reads again a pair whose PNG is not its
/// sidecar's: a writer is between its two renames for well under a millisecond.
const PAIR_RETRIES: u32 = 5;
const PAIR_RETRY_WAIT: std::time::Duration = std::time::Duration::from_millis(40);

/// Read and check a sidecar: at most [`crate::input::MAX_SIDECAR_BYTES`], valid JSON of a
/// known format, and every value within [`CloudMapMeta::validate`]'s ranges. Errors name the
/// sidecar and the field.
pub fn load_meta(sidecar: &Path) -> Result<CloudMapMeta> {
    let text = crate::input::read_sidecar_text(sidecar)?;
    meta_from_text(sidecar, &text)
}

/// [`load_meta`] of a sidecar's text already read ([`crate::input::read_sidecar_text`]);
/// `sidecar` names it in errors.
pub fn meta_from_text(sidecar: &Path, text: &str) -> Result<CloudMapMeta> {
    let bad = |msg: String| IngestError::BadCloudMap {
        path: sidecar.to_path_buf(),
        msg,
    };
    let meta: CloudMapMeta =
        serde_json::from_str(text).map_err(|e| bad(format!("sidecar is not valid: {e}")))?;
    meta.validate().map_err(bad)?;
    Ok(meta)
}

/// The sidecar's bytes for `meta` written beside a PNG named `image` carrying `id`.
pub(crate) fn sidecar_json(
    meta: &CloudMapMeta,
    image: &str,
    id: &str,
    png_path: &Path,
) -> Result<Vec<u8>> {
    let mut meta = meta.clone();
    meta.format = FORMAT.into();
    meta.image = image.into();
    meta.image_id = Some(id.into());
    meta.validate().map_err(IngestError::BadMap)?;
    serde_json::to_string_pretty(&meta)
        .map(String::into_bytes)
        .map_err(|e| IngestError::write(&png_path.with_extension("json"), e))
}

/// A 16-bit RGBA PNG writer whose header carries the pair's image id.
pub(crate) fn rgba16_writer<W: Write>(
    w: W,
    width: u32,
    height: u32,
    id: &str,
) -> std::result::Result<png::Writer<W>, String> {
    let mut enc = png::Encoder::new(w, width, height);
    enc.set_color(png::ColorType::Rgba);
    enc.set_depth(png::BitDepth::Sixteen);
    enc.set_compression(png::Compression::Fast);
    enc.add_text_chunk(IMAGE_ID_KEYWORD.into(), id.into())
        .map_err(|e| e.to_string())?;
    enc.write_header().map_err(|e| e.to_string())
}

/// Encode big-endian 16-bit samples as PNG (`channels` = 1 grey or 4 RGBA).
pub fn encode_png16<W: Write>(
    w: W,
    width: u32,
    height: u32,
    channels: u8,
    be_bytes: &[u8],
) -> std::result::Result<(), String> {
    let mut enc = png::Encoder::new(w, width, height);
    enc.set_color(if channels == 4 {
        png::ColorType::Rgba
    } else {
        png::ColorType::Grayscale
    });
    enc.set_depth(png::BitDepth::Sixteen);
    enc.set_compression(png::Compression::Fast);
    let mut wr = enc.write_header().map_err(|e| e.to_string())?;
    wr.write_image_data(be_bytes).map_err(|e| e.to_string())?;
    wr.finish().map_err(|e| e.to_string())
}

/// Why a map's PNG was not read: it is not the sidecar's (worth reading the pair again), or
/// anything else.
enum PngFault {
    NotThisPair(IngestError),
    Other(IngestError),
}

/// Memory the PNG decoder may use beside the image itself (text chunks, row buffers).
const PNG_DECODER_LIMIT: usize = 16 << 20;

/// Read the 16-bit (or 8-bit, widened) RGBA PNG `meta` describes. Its header is checked
/// against the sidecar — size, colour type, and image id — before any pixel is decoded, so a
/// PNG that would decompress to more than the sidecar's (bounded) size is never expanded.
fn read_png16(path: &Path, meta: &CloudMapMeta) -> std::result::Result<Vec<[u16; 4]>, PngFault> {
    let (width, height) = (meta.width, meta.height);
    let bad = |msg: String| {
        PngFault::Other(IngestError::BadCloudMap {
            path: path.to_path_buf(),
            msg,
        })
    };
    let mut reader = open_checked(path, meta, (width, height))?;
    let info = reader.info();
    let (ct, bd) = (info.color_type, info.bit_depth);
    if ct != png::ColorType::Rgba || !matches!(bd, png::BitDepth::Sixteen | png::BitDepth::Eight) {
        return Err(bad(format!(
            "PNG is {ct:?} {bd:?}; a CloudMap is RGBA 16-bit"
        )));
    }
    let mut buf = vec![0u8; reader.output_buffer_size()];
    reader
        .next_frame(&mut buf)
        .map_err(|e| bad(format!("PNG data is corrupt: {e}")))?;
    let n = width as usize * height as usize;
    let texels = if bd == png::BitDepth::Sixteen {
        buf.chunks_exact(8)
            .take(n)
            .map(|c| {
                [
                    u16::from_be_bytes([c[0], c[1]]),
                    u16::from_be_bytes([c[2], c[3]]),
                    u16::from_be_bytes([c[4], c[5]]),
                    u16::from_be_bytes([c[6], c[7]]),
                ]
            })
            .collect()
    } else {
        buf.chunks_exact(4)
            .take(n)
            .map(|c| [c[0], c[1], c[2], c[3]].map(|v| v as u16 * 257))
            .collect()
    };
    Ok(texels)
}

/// Open a PNG of `meta`'s set and check, before decoding any pixel, that it has the size the
/// sidecar gives it (`(width, height)`) and carries its image id (formats 2 and 3).
fn open_checked(
    path: &Path,
    meta: &CloudMapMeta,
    (width, height): (u32, u32),
) -> std::result::Result<png::Reader<std::io::BufReader<fs::File>>, PngFault> {
    let bad = |msg: String| {
        PngFault::Other(IngestError::BadCloudMap {
            path: path.to_path_buf(),
            msg,
        })
    };
    let f = crate::input::open_regular(path).map_err(PngFault::Other)?;
    let mut dec = png::Decoder::new_with_limits(
        std::io::BufReader::new(f),
        png::Limits {
            bytes: PNG_DECODER_LIMIT,
        },
    );
    dec.set_transformations(png::Transformations::IDENTITY);
    let reader = dec
        .read_info()
        .map_err(|e| bad(format!("not a PNG: {e}")))?;
    let info = reader.info();
    if (info.width, info.height) != (width, height) {
        return Err(PngFault::NotThisPair(IngestError::BadCloudMap {
            path: path.to_path_buf(),
            msg: format!(
                "PNG is {}x{} but its sidecar says {width}x{height}",
                info.width, info.height
            ),
        }));
    }
    if let Some(want) = &meta.image_id {
        let got = info
            .uncompressed_latin1_text
            .iter()
            .find(|t| t.keyword == IMAGE_ID_KEYWORD)
            .map(|t| t.text.as_str());
        if got != Some(want.as_str()) {
            return Err(PngFault::NotThisPair(IngestError::BadCloudMap {
                path: path.to_path_buf(),
                msg: format!(
                    "PNG is not the one its sidecar names (image id {} where the sidecar says {want}): another program replaced it, or a write was cut short; run ingest again",
                    got.unwrap_or("absent")
                ),
            }));
        }
    }
    Ok(reader)
}

/// Read an extra image of `meta`'s set, which must be exactly `ct` `bd` and of the structure
/// images' recorded size; its raw samples.
fn read_image(
    path: &Path,
    meta: &CloudMapMeta,
    (ct, bd): (png::ColorType, png::BitDepth),
    what: &str,
    size: (u32, u32),
) -> std::result::Result<Vec<u8>, PngFault> {
    let bad = |msg: String| {
        PngFault::Other(IngestError::BadCloudMap {
            path: path.to_path_buf(),
            msg,
        })
    };
    let mut reader = open_checked(path, meta, size)?;
    let info = reader.info();
    if (info.color_type, info.bit_depth) != (ct, bd) {
        return Err(bad(format!(
            "PNG is {:?} {:?}; a map's {what} image is {ct:?} {bd:?}",
            info.color_type, info.bit_depth
        )));
    }
    let mut buf = vec![0u8; reader.output_buffer_size()];
    reader
        .next_frame(&mut buf)
        .map_err(|e| bad(format!("PNG data is corrupt: {e}")))?;
    Ok(buf)
}
