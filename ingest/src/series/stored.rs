//! The motion stored with a series (issue 31): for every step but the last, the guarded motion
//! to the next step ([`super::motion`], g·m per layer) as two 16-bit RGBA PNGs beside the
//! step's wind images, `NAME-fHHH.motion-u.png` (east) and `.motion-v.png` (south), R/G/B =
//! low/middle/high, on the motion's working grid ([`super::motion::work_size`]), in map pixels
//! per interval as (sample − 32768) × scale; the series sidecar names them with their size
//! and scale ([`super::meta::StepMotion`]).
//!
//! Checked twice: at load the files are there and their PNG headers have the size and kind the
//! sidecar says (cheap: no pixel decoded); when an interval is needed its two images are
//! decoded. Every fault is one line naming the file.

use std::io::BufReader;
use std::path::{Path, PathBuf};

use crate::cloudmap::encode_png16;
use crate::error::Result;
use crate::output::write_atomic;

use super::meta::{SeriesMeta, StepMotion};
use super::motion::{LayerMotion, Motion};

/// The sample that means no motion.
pub const ZERO: u16 = 32768;

/// Memory the PNG decoder may use beside the image (a working grid is at most 256² texels).
const DECODER_LIMIT: usize = 16 << 20;

/// A step map's motion images: `DIR/NAME-fHHH.motion-u.png` and `.motion-v.png` beside
/// `DIR/NAME-fHHH.png`.
pub fn motion_paths(png: &Path) -> (PathBuf, PathBuf) {
    let stem = png
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    (
        png.with_file_name(format!("{stem}.motion-u.png")),
        png.with_file_name(format!("{stem}.motion-v.png")),
    )
}

/// One layer's guarded motion, east and south (map pixels per interval).
type Field = (Vec<f32>, Vec<f32>);

/// A motion as it is stored: per image (east `u`, south `v`) each working-grid texel's
/// samples for channels R/G/B = low/middle/high ([`ZERO`] where the series has no such
/// layer), (sample − [`ZERO`]) × `scale` map pixels per interval. The PNG images and a Zarr
/// store's `motion_u`/`motion_v` arrays (`crate::zarr`) hold exactly these.
#[derive(Debug, Clone, PartialEq)]
pub struct MotionSamples {
    pub width: usize,
    pub height: usize,
    pub scale: f64,
    pub u: Vec<[u16; 3]>,
    pub v: Vec<[u16; 3]>,
}

/// `motion`'s guarded fields as samples, the scale chosen so that the largest displacement
/// fills the range.
pub fn samples(motion: &Motion) -> MotionSamples {
    let (w, h) = motion.layers.first().map_or((1, 1), |l| (l.u.w, l.u.h));
    let fields: Vec<(usize, Field)> = motion
        .layers
        .iter()
        .map(|l| (l.channel, l.guarded_px()))
        .collect();
    let most = fields
        .iter()
        .flat_map(|(_, (u, v))| u.iter().chain(v))
        .fold(0.0f32, |m, x| m.max(x.abs()));
    let scale = (f64::from(most) / 32767.0).max(1e-4);
    let image = |pick: fn(&Field) -> &Vec<f32>| {
        (0..w * h)
            .map(|k| {
                let mut t = [ZERO; 3];
                for (c, s) in t.iter_mut().enumerate() {
                    if let Some((_, f)) = fields.iter().find(|(ch, _)| *ch == c) {
                        let x = f64::from(pick(f)[k]) / scale;
                        *s = (f64::from(ZERO) + x.round()).clamp(0.0, 65535.0) as u16;
                    }
                }
                t
            })
            .collect()
    };
    MotionSamples {
        width: w,
        height: h,
        scale,
        u: image(|f| &f.0),
        v: image(|f| &f.1),
    }
}

/// One image's samples as big-endian RGBA (A opaque).
fn image_bytes(texels: &[[u16; 3]]) -> Vec<u8> {
    let mut out = Vec::with_capacity(texels.len() * 8);
    for t in texels {
        for s in [t[0], t[1], t[2], u16::MAX] {
            out.extend_from_slice(&s.to_be_bytes());
        }
    }
    out
}

/// Write `motion` (guarded, from [`super::motion::estimate`]) as the motion images `paths`,
/// each atomically; the entry the series sidecar gives them.
pub fn write(motion: &Motion, paths: (&Path, &Path)) -> Result<StepMotion> {
    let s = samples(motion);
    let (w, h) = (s.width as u32, s.height as u32);
    for (p, texels) in [(paths.0, &s.u), (paths.1, &s.v)] {
        let bytes = image_bytes(texels);
        write_atomic(p, |out| encode_png16(out, w, h, 4, &bytes))?;
    }
    let name = |p: &Path| {
        p.file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default()
    };
    Ok(StepMotion {
        u: name(paths.0),
        v: name(paths.1),
        width: w,
        height: h,
        scale: s.scale,
    })
}

/// Open the motion image `path` and check its header against `m` (size, 16-bit RGBA)
/// before any pixel is decoded; the fault is a phrase after the file's name.
fn open(
    path: &Path,
    m: &StepMotion,
) -> std::result::Result<png::Reader<BufReader<std::fs::File>>, String> {
    let f = crate::input::open_regular(path).map_err(|e| e.to_string())?;
    let mut dec = png::Decoder::new_with_limits(
        BufReader::new(f),
        png::Limits {
            bytes: DECODER_LIMIT,
        },
    );
    dec.set_transformations(png::Transformations::IDENTITY);
    let reader = dec.read_info().map_err(|e| format!("not a PNG: {e}"))?;
    let info = reader.info();
    if (info.width, info.height) != (m.width, m.height) {
        return Err(format!(
            "PNG is {}x{} but the series sidecar says {}x{}",
            info.width, info.height, m.width, m.height
        ));
    }
    if (info.color_type, info.bit_depth) != (png::ColorType::Rgba, png::BitDepth::Sixteen) {
        return Err(format!(
            "PNG is {:?} {:?}; a motion image is RGBA 16-bit",
            info.color_type, info.bit_depth
        ));
    }
    Ok(reader)
}

/// Check the motion images of `m` in `dir` from their headers (load time); the fault names
/// the file.
pub fn check(dir: &Path, m: &StepMotion) -> std::result::Result<(), String> {
    for name in [&m.u, &m.v] {
        let p = dir.join(name);
        open(&p, m).map_err(|e| format!("{}: {e}", crate::error::shown(&p)))?;
    }
    Ok(())
}

/// One image's samples: per texel the R/G/B samples.
fn decode(path: &Path, m: &StepMotion) -> std::result::Result<Vec<[u16; 3]>, String> {
    let mut reader = open(path, m)?;
    let mut buf = vec![0u8; reader.output_buffer_size()];
    reader
        .next_frame(&mut buf)
        .map_err(|e| format!("PNG data is corrupt: {e}"))?;
    let n = m.width as usize * m.height as usize;
    let at = |c: &[u8], k: usize| u16::from_be_bytes([c[2 * k], c[2 * k + 1]]);
    Ok(buf
        .chunks_exact(8)
        .take(n)
        .map(|c| [at(c, 0), at(c, 1), at(c, 2)])
        .collect())
}

/// The samples of the motion images `m` of a step in `dir`; the fault names the file.
pub fn read_samples(dir: &Path, m: &StepMotion) -> std::result::Result<MotionSamples, String> {
    let read = |name: &str| {
        let p = dir.join(name);
        decode(&p, m).map_err(|e| format!("{}: {e}", crate::error::shown(&p)))
    };
    Ok(MotionSamples {
        width: m.width as usize,
        height: m.height as usize,
        scale: m.scale,
        u: read(&m.u)?,
        v: read(&m.v)?,
    })
}

/// The motion `m` of a step of `series` (folder `dir`), decoded; the fault names the file.
pub fn read(
    dir: &Path,
    m: &StepMotion,
    series: &SeriesMeta,
) -> std::result::Result<Motion, String> {
    Ok(from_samples(&read_samples(dir, m)?, series))
}

/// The motion stored as `s` for `series`' layers.
pub fn from_samples(s: &MotionSamples, series: &SeriesMeta) -> Motion {
    let at = |t: &[u16; 3], c: usize| ((f64::from(t[c]) - f64::from(ZERO)) * s.scale) as f32;
    let wrap = series.region.lon_span() >= 360.0 - 1e-9;
    let (w, h) = (s.width, s.height);
    let map = (series.width as usize, series.height as usize);
    let layers = series
        .layers
        .iter()
        .filter(|l| l.channel < 3)
        .map(|l| {
            let c = l.channel;
            let field = (
                s.u.iter().map(|t| at(t, c)).collect(),
                s.v.iter().map(|t| at(t, c)).collect(),
            );
            LayerMotion::from_guarded_px((l.kind, c), (w, h, wrap), field, map)
        })
        .collect();
    Motion { layers }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::layer::LayerKind;

    #[test]
    fn a_motion_round_trips_through_its_images_within_the_scale() {
        let dir = tempfile::tempdir().unwrap();
        let (w, h) = (12, 8);
        let f = |k: usize, s: f32| (k as f32 * 0.37 + s).sin() * 9.0;
        let lm = |kind: LayerKind, s: f32| {
            LayerMotion::from_guarded_px(
                (kind, kind.channel()),
                (w, h, false),
                (
                    (0..w * h).map(|k| f(k, s)).collect(),
                    (0..w * h).map(|k| -f(k, s + 1.0)).collect(),
                ),
                (48, 32),
            )
        };
        let motion = Motion {
            layers: vec![lm(LayerKind::Low, 0.0), lm(LayerKind::High, 2.0)],
        };
        let (pu, pv) = (
            dir.path().join("m.motion-u.png"),
            dir.path().join("m.motion-v.png"),
        );
        let entry = write(&motion, (&pu, &pv)).unwrap();
        assert_eq!((entry.width, entry.height), (12, 8));
        check(dir.path(), &entry).unwrap();
        let series = SeriesMeta {
            format: super::super::SERIES_FORMAT.into(),
            reference_time: crate::meta::parse_time("2020-08-04T12:00:00Z").unwrap(),
            region: crate::region::Region::parse("48,56,13,25").unwrap(),
            width: 48,
            height: 32,
            layers: [LayerKind::Low, LayerKind::High]
                .iter()
                .map(|&k| super::super::meta::SeriesLayer {
                    kind: k,
                    channel: k.channel(),
                    levels_hpa: vec![],
                })
                .collect(),
            steps: vec![],
        };
        let back = read(dir.path(), &entry, &series).unwrap();
        for (a, b) in motion.layers.iter().zip(&back.layers) {
            let ((au, av), (bu, bv)) = (a.guarded_px(), b.guarded_px());
            for (x, y) in au.iter().chain(&av).zip(bu.iter().chain(&bv)) {
                assert!((x - y).abs() <= entry.scale as f32, "{x} vs {y}");
            }
        }
        // A wrong size in the sidecar is caught from the header.
        let wrong = StepMotion {
            width: 13,
            ..entry.clone()
        };
        let e = check(dir.path(), &wrong).unwrap_err();
        assert!(e.contains("m.motion-u.png") && e.contains("12x8"), "{e}");
    }
}
