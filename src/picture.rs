//! Writing pictures: frames and diagnostic images as PNG, atomically (a temporary file in the
//! target's folder, renamed into place), so no half-written file is ever left.

use std::path::Path;

use image::ImageEncoder;
use stratus_ingest::output::write_atomic;
use stratus_ingest::IngestError;

/// Write an RGBA8 image as PNG.
pub fn save_png(path: &Path, img: &image::RgbaImage) -> Result<(), IngestError> {
    write_png(
        path,
        img.as_raw(),
        img.width(),
        img.height(),
        image::ExtendedColorType::Rgba8,
    )
}

/// Write raw 8-bit pixels as PNG.
pub fn write_png(
    path: &Path,
    raw: &[u8],
    width: u32,
    height: u32,
    color: image::ExtendedColorType,
) -> Result<(), IngestError> {
    write_atomic(path, |w| {
        image::codecs::png::PngEncoder::new(w)
            .write_image(raw, width, height, color)
            .map_err(|e| e.to_string())
    })
}
