//! The CloudMap: per-pixel low/middle/high/total coverage, its 16-bit PNG and sidecar I/O.
//!
//! Writing is atomic (temporary file, then rename) so a failed ingest leaves nothing behind.

use std::fs;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use crate::error::{IngestError, Result};
use crate::meta::{CloudMapMeta, FORMAT};
use crate::region::MAX_SIDE;

/// The PNG sample value of full coverage: coverage c in 0..1 is stored as round(c × 65535).
pub const COVERAGE_FULL: f64 = 65535.0;

/// Coverage (clamped to 0..1) as its 16-bit PNG sample.
pub fn coverage_to_sample(c: f64) -> u16 {
    (c.clamp(0.0, 1.0) * COVERAGE_FULL).round() as u16
}

/// Coverage in 0..1 for R (low), G (middle), B (high), A (= max of the three).
#[derive(Debug, Clone)]
pub struct CloudMap {
    pub meta: CloudMapMeta,
    /// Row-major, row 0 = north, `width * height` texels.
    pub texels: Vec<[u16; 4]>,
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
        bands: &[(crate::meta::LayerKind, f64, f64)],
        valid_time: chrono::DateTime<chrono::Utc>,
        cover: impl Fn(f64, f64) -> [f64; 3] + Sync,
    ) -> CloudMap {
        use crate::meta::{AltitudeSource, LayerMeta, SourceMeta};
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
            })
            .collect();
        CloudMap {
            meta: CloudMapMeta {
                format: FORMAT.to_string(),
                image: "synthetic.png".into(),
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
                },
            },
            texels,
        }
    }

    /// Load a CloudMap from its sidecar (`MAP.json`), checking the PNG agrees with it.
    pub fn load(sidecar: &Path) -> Result<CloudMap> {
        let bad = |msg: String| IngestError::BadCloudMap {
            path: sidecar.to_path_buf(),
            msg,
        };
        let text = fs::read_to_string(sidecar).map_err(|e| IngestError::Io {
            path: sidecar.to_path_buf(),
            source: e,
        })?;
        let meta: CloudMapMeta =
            serde_json::from_str(&text).map_err(|e| bad(format!("sidecar is not valid: {e}")))?;
        if meta.format != FORMAT {
            return Err(bad(format!("format '{}' is not '{FORMAT}'", meta.format)));
        }
        meta.region.validate().map_err(|e| bad(e.to_string()))?;
        if meta.width == 0 || meta.height == 0 || meta.width > MAX_SIDE || meta.height > MAX_SIDE {
            return Err(bad(format!(
                "size {}x{} out of range",
                meta.width, meta.height
            )));
        }
        for l in &meta.layers {
            if l.channel > 2
                || !(l.base_m.is_finite() && l.top_m.is_finite())
                || l.top_m <= l.base_m
            {
                return Err(bad(format!(
                    "layer {} has channel {} and band {}..{} m",
                    l.kind.name(),
                    l.channel,
                    l.base_m,
                    l.top_m
                )));
            }
        }
        let png_path = meta.image_path(sidecar);
        let texels = read_png16(&png_path, meta.width, meta.height)?;
        Ok(CloudMap { meta, texels })
    }

    /// Write `png_path` and its sidecar (same stem, `.json`), each atomically.
    pub fn save(&self, png_path: &Path) -> Result<PathBuf> {
        let sidecar = png_path.with_extension("json");
        let mut bytes = Vec::with_capacity(self.texels.len() * 8);
        for t in &self.texels {
            for c in t {
                bytes.extend_from_slice(&c.to_be_bytes());
            }
        }
        write_atomic(png_path, |w| {
            encode_png16(w, self.meta.width, self.meta.height, 4, &bytes)
        })?;
        // The sidecar names the PNG it sits beside, whatever the map was called before.
        let mut meta = self.meta.clone();
        if let Some(name) = png_path.file_name() {
            meta.image = name.to_string_lossy().into_owned();
        }
        let json = serde_json::to_string_pretty(&meta).map_err(|e| IngestError::Write {
            path: sidecar.clone(),
            msg: e.to_string(),
        })?;
        write_atomic(&sidecar, |w| {
            w.write_all(json.as_bytes()).map_err(|e| e.to_string())
        })?;
        Ok(sidecar)
    }
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

/// Write a file through a temporary sibling and rename it into place; on any error the
/// temporary is removed and `path` is untouched.
pub fn write_atomic<F>(path: &Path, body: F) -> Result<()>
where
    F: FnOnce(&mut BufWriter<fs::File>) -> std::result::Result<(), String>,
{
    let err = |msg: String| IngestError::Write {
        path: path.to_path_buf(),
        msg,
    };
    let name = path
        .file_name()
        .ok_or_else(|| err("no file name".into()))?
        .to_string_lossy();
    let tmp = path.with_file_name(format!(".{name}.tmp{}", std::process::id()));
    let result = (|| {
        let f = fs::File::create(&tmp).map_err(|e| e.to_string())?;
        let mut w = BufWriter::new(f);
        body(&mut w)?;
        w.flush().map_err(|e| e.to_string())?;
        let f = w.into_inner().map_err(|e| e.to_string())?;
        f.sync_all().map_err(|e| e.to_string())?;
        fs::rename(&tmp, path).map_err(|e| e.to_string())
    })();
    if result.is_err() {
        let _ = fs::remove_file(&tmp);
    }
    result.map_err(err)
}

/// Read a 16-bit RGBA PNG of the expected size (8-bit RGBA is widened).
fn read_png16(path: &Path, width: u32, height: u32) -> Result<Vec<[u16; 4]>> {
    let bad = |msg: String| IngestError::BadCloudMap {
        path: path.to_path_buf(),
        msg,
    };
    let f = fs::File::open(path).map_err(|e| IngestError::Io {
        path: path.to_path_buf(),
        source: e,
    })?;
    let mut dec = png::Decoder::new(std::io::BufReader::new(f));
    dec.set_transformations(png::Transformations::IDENTITY);
    let mut reader = dec
        .read_info()
        .map_err(|e| bad(format!("not a PNG: {e}")))?;
    let info = reader.info();
    if (info.width, info.height) != (width, height) {
        return Err(bad(format!(
            "PNG is {}x{} but its sidecar says {width}x{height}",
            info.width, info.height
        )));
    }
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
