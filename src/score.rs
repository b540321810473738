//! Render-vs-map similarity (DESIGN §5): threshold two coverage images into masks and compare
//! them with the Dice coefficient (paper eq. 28), IoU, precision and recall; draw a diff image.

use serde::Serialize;

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
    fn identical_masks_score_one() {
        let a: Vec<bool> = (0..100).map(|i| i % 3 == 0).collect();
        assert_eq!(compare(&a, &a).dice, 1.0);
        let shifted: Vec<bool> = (0..100).map(|i| (i + 1) % 3 == 0).collect();
        assert_eq!(compare(&a, &shifted).dice, 0.0);
    }
}
