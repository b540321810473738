//! Render-vs-map similarity (DESIGN §5): average the top-down render's opacity and the map's
//! coverage over blocks of pixels, threshold both into masks and compare them with the Dice
//! coefficient (paper eq. 28), IoU, precision and recall; draw a diff image.
//!
//! Blocks, not single rays: a coverage is a fraction of the area under cloud, and a broken
//! cumulus field draws it as separate cells with clear air between them (render::cells), so
//! one ray per pixel meets cloud with probability c and a pixel of coverage 0.7 is clear three
//! times in ten. The mean over a block of rays is that area fraction, as a satellite pixel's
//! cloud fraction is (docs/score.md).

use serde::Serialize;
use stratus_ingest::cloudmap::CloudMap;

use crate::render::{RenderError, Renderer, Settings, View};

/// Overlap counts and the scores derived from them. "A" is the render, "B" the map.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Similarity {
    pub render_px: usize,
    pub map_px: usize,
    pub both_px: usize,
    pub total_px: usize,
    /// 2|A∩B| / (|A| + |B|); 1 when both masks are empty.
    pub dice: f64,
    /// |A∩B| / |A∪B|; 1 when both masks are empty.
    pub iou: f64,
    /// |A∩B| / |A| (render pixels that the map has); 1 when the render is empty.
    pub precision: f64,
    /// |A∩B| / |B| (map pixels the render draws); 1 when the map is empty.
    pub recall: f64,
}

impl Similarity {
    pub fn both_empty(&self) -> bool {
        self.render_px == 0 && self.map_px == 0
    }
}

/// Compare two masks of equal length.
pub fn compare(render: &[bool], map: &[bool]) -> Similarity {
    assert_eq!(render.len(), map.len(), "masks must be the same size");
    let (mut a, mut b, mut ab) = (0usize, 0usize, 0usize);
    for (&x, &y) in render.iter().zip(map) {
        a += x as usize;
        b += y as usize;
        ab += (x && y) as usize;
    }
    let ratio = |num: usize, den: usize| {
        if den == 0 {
            1.0
        } else {
            num as f64 / den as f64
        }
    };
    Similarity {
        render_px: a,
        map_px: b,
        both_px: ab,
        total_px: render.len(),
        dice: ratio(2 * ab, a + b),
        iou: ratio(ab, a + b - ab),
        precision: ratio(ab, a),
        recall: ratio(ab, b),
    }
}

/// Mask of values strictly above `threshold`.
pub fn mask(values: &[f32], threshold: f32) -> Vec<bool> {
    values.iter().map(|&v| v > threshold).collect()
}

/// Pixels per side of the score's blocks by default: 16 rays a block, so a broken field's
/// fraction is read to about ±0.1 (binomial, n = 16), and the East Asia and North Atlantic gate
/// renders (520×440) still give 130×110 blocks.
pub const BLOCK: u32 = 4;

/// Means of the `k`×`k` blocks of a `w`×`h` image, row-major; blocks cut by the right or bottom
/// edge average the pixels they hold. Returns the means and the blocks' grid size.
pub fn block_mean(values: &[f32], (w, h): (u32, u32), k: u32) -> (Vec<f32>, (u32, u32)) {
    let grid = block_grid((w, h), k);
    let k = k.max(1) as usize;
    let (w, h, bw, bh) = (w as usize, h as usize, grid.0 as usize, grid.1 as usize);
    let mut sum = vec![0.0f64; bw * bh];
    let mut n = vec![0u32; bw * bh];
    for (i, &v) in values.iter().enumerate().take(w * h) {
        let b = (i / w / k) * bw + (i % w) / k;
        sum[b] += v as f64;
        n[b] += 1;
    }
    let means = sum
        .iter()
        .zip(&n)
        .map(|(&s, &c)| (s / c.max(1) as f64) as f32)
        .collect();
    (means, grid)
}

/// The size in blocks of a `w`×`h` image cut into `k`×`k` blocks (partial ones counted).
pub fn block_grid((w, h): (u32, u32), k: u32) -> (u32, u32) {
    let k = k.max(1);
    (w.div_ceil(k), h.div_ceil(k))
}

/// Diff picture, RGB8: both = white, render only = orange, map only = blue, neither = black.
pub fn diff_image(render: &[bool], map: &[bool]) -> Vec<[u8; 3]> {
    render
        .iter()
        .zip(map)
        .map(|(&a, &b)| match (a, b) {
            (true, true) => [235, 235, 235],
            (true, false) => [255, 140, 0],
            (false, true) => [30, 120, 255],
            (false, false) => [0, 0, 0],
        })
        .collect()
}

impl Report {
    /// The total's [`diff_image`] as an opaque picture.
    pub fn diff_picture(&self) -> image::RgbaImage {
        let px = diff_image(&self.total.render_mask, &self.total.map_mask);
        let w = self.mask_width;
        image::RgbaImage::from_fn(self.mask_width, self.mask_height, |x, y| {
            let p = px.get((y * w + x) as usize).copied().unwrap_or([0; 3]);
            image::Rgba([p[0], p[1], p[2], 255])
        })
    }
}

/// The score's default render size: the map's, at most 1024 on the longer side.
pub fn default_size(map: &CloudMap) -> (u32, u32) {
    let (w, h) = (map.meta.width, map.meta.height);
    let k = (w.max(h) as f64 / 1024.0).max(1.0);
    (
        ((w as f64 / k).round() as u32).max(1),
        ((h as f64 / k).round() as u32).max(1),
    )
}

/// Render threshold: a pixel is cloud when the top-down opacity exceeds this.
pub const RENDER_THRESHOLD: f32 = 0.5;
/// Map threshold: a pixel is cloud when the map's coverage exceeds this. Measured, not guessed:
/// on a 0 → 1 coverage ramp the renderer's mean top-down opacity crosses 0.5 between coverage
/// 0.50 and 0.55 for every layer and preset (`cargo run --release --example coverage_ramp`).
pub const MAP_THRESHOLD: f32 = 0.5;

/// A CloudMap channel (0 R low, 1 G middle, 2 B high, 3 A total) resampled bilinearly at the
/// pixel centres of a `w`×`h` grid over the same region.
pub fn map_channel(map: &CloudMap, channel: usize, w: u32, h: u32) -> Vec<f32> {
    let (mw, mh) = (map.width(), map.height());
    let at = |i: usize, j: usize| map.texels[j * mw + i][channel] as f32 / 65535.0;
    let mut out = Vec::with_capacity(w as usize * h as usize);
    for j in 0..h as usize {
        let y = ((j as f64 + 0.5) * mh as f64 / h as f64 - 0.5).clamp(0.0, (mh - 1) as f64);
        let (y0, fy) = (y.floor() as usize, (y - y.floor()) as f32);
        let y1 = (y0 + 1).min(mh - 1);
        for i in 0..w as usize {
            let x = ((i as f64 + 0.5) * mw as f64 / w as f64 - 0.5).clamp(0.0, (mw - 1) as f64);
            let (x0, fx) = (x.floor() as usize, (x - x.floor()) as f32);
            let x1 = (x0 + 1).min(mw - 1);
            let top = at(x0, y0) * (1.0 - fx) + at(x1, y0) * fx;
            let bot = at(x0, y1) * (1.0 - fx) + at(x1, y1) * fx;
            out.push(top * (1.0 - fy) + bot * fy);
        }
    }
    out
}

/// One scored comparison (a layer, or the total).
#[derive(Clone, Debug, Serialize)]
pub struct Scored {
    pub layer: String,
    #[serde(flatten)]
    pub similarity: Similarity,
    pub note: Option<String>,
    #[serde(skip)]
    pub render_mask: Vec<bool>,
    #[serde(skip)]
    pub map_mask: Vec<bool>,
}

/// Everything `stratus score` reports.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    pub map: String,
    pub preset: String,
    /// The render's size (pixels).
    pub width: u32,
    pub height: u32,
    /// Pixels per side of a block, and the masks' size in blocks (what the counts count).
    pub block: u32,
    pub mask_width: u32,
    pub mask_height: u32,
    pub render_threshold: f32,
    pub map_threshold: f32,
    pub total: Scored,
    pub layers: Vec<Scored>,
}

fn scored(layer: &str, render: Vec<bool>, map: Vec<bool>) -> Scored {
    let similarity = compare(&render, &map);
    let note = if similarity.both_empty() {
        Some("both masks are empty: nothing to draw and nothing drawn (DSC 1 by definition)".into())
    } else if similarity.render_px == 0 || similarity.map_px == 0 {
        Some(format!(
            "the {} mask is empty",
            if similarity.render_px == 0 {
                "render"
            } else {
                "map"
            }
        ))
    } else {
        None
    };
    Scored {
        layer: layer.into(),
        similarity,
        note,
        render_mask: render,
        map_mask: map,
    }
}

/// Render the map top-down (all layers, then each present layer alone) and score each render
/// against the map's matching channel, both averaged over `block`×`block` pixels.
pub fn score(
    renderer: &mut Renderer,
    map: &CloudMap,
    settings: &Settings,
    (width, height): (u32, u32),
    block: u32,
    thresholds: (f32, f32),
) -> Result<Report, RenderError> {
    let (rt, mt) = thresholds;
    let size = (width, height);
    let grid = block_grid(size, block);
    let mut one =
        |layers_on: [bool; 3], channel: usize, name: &str| -> Result<Scored, RenderError> {
            let mut s = settings.clone();
            for (on, wanted) in s.layers_on.iter_mut().zip(layers_on) {
                *on &= wanted;
            }
            let out = renderer.render(&View::TopDown, width, height, &s)?;
            let (opacity, _) = block_mean(&out.alpha(), size, block);
            let (coverage, _) = block_mean(&map_channel(map, channel, width, height), size, block);
            Ok(scored(name, mask(&opacity, rt), mask(&coverage, mt)))
        };
    let total = one([true; 3], 3, "total")?;
    let mut layers = Vec::new();
    for l in &map.meta.layers {
        let mut on = [false; 3];
        on[l.channel] = true;
        layers.push(one(on, l.channel, l.kind.name())?);
    }
    Ok(Report {
        map: map.meta.image.clone(),
        preset: String::new(),
        width,
        height,
        block: block.max(1),
        mask_width: grid.0,
        mask_height: grid.1,
        render_threshold: rt,
        map_threshold: mt,
        total,
        layers,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dice_of_known_masks() {
        let a = [true, true, false, false];
        let b = [true, false, true, false];
        let s = compare(&a, &b);
        assert_eq!((s.render_px, s.map_px, s.both_px), (2, 2, 1));
        assert!((s.dice - 0.5).abs() < 1e-12);
        assert!((s.iou - 1.0 / 3.0).abs() < 1e-12);
        assert!((s.precision - 0.5).abs() < 1e-12 && (s.recall - 0.5).abs() < 1e-12);
    }

    #[test]
    fn empty_masks_do_not_divide_by_zero() {
        let none = [false; 5];
        let some = [true, false, false, false, false];
        let s = compare(&none, &none);
        assert!(s.both_empty() && s.dice == 1.0 && s.iou == 1.0);
        let s = compare(&none, &some);
        assert_eq!(s.dice, 0.0);
        assert_eq!(s.recall, 0.0);
        assert_eq!(s.precision, 1.0);
        assert!(s.dice.is_finite() && s.iou.is_finite());
    }

    #[test]
    fn block_means_average_what_each_block_holds() {
        // 5×3 in 2×2 blocks: a 3×2 grid, the right column and bottom row partial.
        let v: Vec<f32> = (0..15).map(|i| i as f32).collect();
        let (m, grid) = block_mean(&v, (5, 3), 2);
        assert_eq!(grid, (3, 2));
        assert_eq!(m, vec![3.0, 5.0, 6.5, 10.5, 12.5, 14.0]);
        // One-pixel blocks are the image itself.
        assert_eq!(block_mean(&v, (5, 3), 1).0, v);
    }

    #[test]
    fn a_broken_field_is_its_area_fraction_in_blocks() {
        // One ray in three hits an opaque cell in the west half, two in three in the east: per
        // ray both halves have cloud and clear pixels, in blocks only the east is cloud.
        let (w, h) = (12u32, 12u32);
        let v: Vec<f32> = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let hit = (x + y) % 3 == 0;
                (if x < 6 { hit } else { !hit }) as u32 as f32
            })
            .collect();
        let (m, _) = block_mean(&v, (w, h), 3);
        let cloud = mask(&m, RENDER_THRESHOLD);
        for (b, on) in cloud.iter().enumerate() {
            assert_eq!(*on, b % 4 >= 2, "block {b}: {}", m[b]);
        }
    }

    #[test]
    fn identical_masks_score_one() {
        let a: Vec<bool> = (0..100).map(|i| i % 3 == 0).collect();
        assert_eq!(compare(&a, &a).dice, 1.0);
        let shifted: Vec<bool> = (0..100).map(|i| (i + 1) % 3 == 0).collect();
        assert_eq!(compare(&a, &shifted).dice, 0.0);
    }
}
