//! The cumulus cell field (DESIGN §7): where the cells of a broken cumulus field stand, as a
//! small tileable 2D texture the march reads in cumulus columns. A cumulus coverage c is the
//! fraction of the ground under cloud, so a field at c is separate clouds over a fraction c of
//! the area with clear air between them; a 3D noise threshold cannot give that, since a ray
//! looking down crosses many independent noise values and meets one of them almost surely.
//!
//! R is how central a point is in its cell, histogram-equalised over the tile: exactly a
//! fraction c of the plane lies above 1 − c, so thresholding at the map's coverage gives the
//! coverage as area. Cells are the regions nearest to jittered points, each scaled by its own
//! size, and grouped by a smooth field a few cells across (cumulus streets and clusters).
//! G is the cell's own height, a fraction of its column: humilis beside congestus.

use super::gpu::Gpu;

/// Texels per side.
pub const SIZE: usize = 256;
/// Cells per side of the tile.
const CELLS: usize = 24;
/// The tile's period on the ground (m): cells 2 km apart, fair-weather cumulus' spacing.
pub const PERIOD_M: f32 = 48_000.0;

/// A hash of a cell and a salt, in 0..1 (a fixed table: the same field on every run).
fn hash(i: usize, j: usize, salt: u32) -> f32 {
    let mut x = (i as u32).wrapping_mul(0x8da6_b343)
        ^ (j as u32).wrapping_mul(0xd816_3841)
        ^ salt.wrapping_mul(0xcb1a_b31f);
    x ^= x >> 15;
    x = x.wrapping_mul(0x2c1b_3c6d);
    x ^= x >> 12;
    x = x.wrapping_mul(0x297a_2d39);
    x ^= x >> 15;
    (x & 0xff_ffff) as f32 / 0xff_ffff as f32
}

/// Smooth periodic value noise with `n` lattice cells per side, at (x, y) in tile units 0..1.
fn cluster(x: f32, y: f32, n: usize) -> f32 {
    let (fx, fy) = (x * n as f32, y * n as f32);
    let (i, j) = (fx.floor(), fy.floor());
    let s = |t: f32| t * t * (3.0 - 2.0 * t);
    let (tx, ty) = (s(fx - i), s(fy - j));
    let at = |di: usize, dj: usize| {
        let wrap = |v: f32, d: usize| (v as i64 + d as i64).rem_euclid(n as i64) as usize;
        hash(wrap(i, di), wrap(j, dj), 7)
    };
    let top = at(0, 0) + (at(1, 0) - at(0, 0)) * tx;
    let bot = at(0, 1) + (at(1, 1) - at(0, 1)) * tx;
    top + (bot - top) * ty
}

/// The field's texels, row-major: (rank, height) in 0..1 each.
pub fn field() -> Vec<[f32; 2]> {
    let n = CELLS as f32;
    // Per cell: a jittered centre, a size and a height.
    let cell = |i: usize, j: usize| {
        let (ci, cj) = (i % CELLS, j % CELLS);
        (
            0.15 + 0.7 * hash(ci, cj, 1),
            0.15 + 0.7 * hash(ci, cj, 2),
            0.5 + 1.1 * hash(ci, cj, 3).powi(2),
            0.35 + 0.65 * hash(ci, cj, 4).powf(1.5),
        )
    };
    let mut raw = Vec::with_capacity(SIZE * SIZE);
    let mut height = Vec::with_capacity(SIZE * SIZE);
    for y in 0..SIZE {
        for x in 0..SIZE {
            let (u, v) = (
                (x as f32 + 0.5) / SIZE as f32,
                (y as f32 + 0.5) / SIZE as f32,
            );
            let (gx, gy) = (u * n, v * n);
            let (i0, j0) = (gx.floor() as i64, gy.floor() as i64);
            // The nearest centre by distance over size, among the 3×3 cells around (wrapping).
            let mut best = (f32::MAX, 0.0);
            for dj in -1..=1 {
                for di in -1..=1 {
                    let (ci, cj) = (i0 + di, j0 + dj);
                    let (ox, oy, size, h) = cell(
                        ci.rem_euclid(CELLS as i64) as usize,
                        cj.rem_euclid(CELLS as i64) as usize,
                    );
                    let d = (gx - (ci as f32 + ox)).hypot(gy - (cj as f32 + oy)) / size;
                    if d < best.0 {
                        best = (d, h);
                    }
                }
            }
            raw.push(-best.0 + 0.45 * cluster(u, v, 4));
            height.push(best.1);
        }
    }
    // Histogram-equalise: a texel's value is its rank.
    let mut order: Vec<usize> = (0..raw.len()).collect();
    order.sort_by(|&a, &b| raw[a].total_cmp(&raw[b]));
    let mut out = vec![[0.0; 2]; raw.len()];
    let last = (raw.len() - 1) as f32;
    for (rank, &k) in order.iter().enumerate() {
        out[k] = [rank as f32 / last, height[k]];
    }
    out
}

/// The field as a texture (device lifetime), RG of an RGBA8 texture.
pub fn texture(gpu: &Gpu) -> wgpu::Texture {
    let q = |v: f32| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    let texels: Vec<u8> = field()
        .iter()
        .flat_map(|&[r, g]| [q(r), q(g), 0, 255])
        .collect();
    let tex = super::texture::map_texture(
        gpu,
        "cumulus cells",
        (SIZE, SIZE),
        wgpu::TextureFormat::Rgba8Unorm,
    );
    super::texture::write(gpu, &tex, &texels, 4);
    tex
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn area_above_one_minus_c_is_c() {
        let f = field();
        for c in [0.05, 0.16, 0.3, 0.5, 0.72, 0.9] {
            let above = f.iter().filter(|t| t[0] > 1.0 - c).count() as f32 / f.len() as f32;
            assert!((above - c).abs() < 0.005, "coverage {c}: area {above}");
        }
    }

    /// Separate clouds, not one blob: at a broken coverage the cloudy texels form many
    /// components (4-connected, across the tile's wrap).
    fn components(f: &[[f32; 2]], c: f32) -> usize {
        let on: Vec<bool> = f.iter().map(|t| t[0] > 1.0 - c).collect();
        let mut seen = vec![false; on.len()];
        let mut count = 0;
        for start in 0..on.len() {
            if !on[start] || seen[start] {
                continue;
            }
            count += 1;
            let mut stack = vec![start];
            seen[start] = true;
            while let Some(k) = stack.pop() {
                let (x, y) = (k % SIZE, k / SIZE);
                for (dx, dy) in [(1, 0), (SIZE - 1, 0), (0, 1), (0, SIZE - 1)] {
                    let n = (y + dy) % SIZE * SIZE + (x + dx) % SIZE;
                    if on[n] && !seen[n] {
                        seen[n] = true;
                        stack.push(n);
                    }
                }
            }
        }
        count
    }

    #[test]
    fn broken_coverage_is_separate_cells() {
        let f = field();
        // Scattered (0.2) is most of the 576 cells apart (495 clouds when written); broken
        // (0.6) still over a hundred (155).
        let (few, broken) = (components(&f, 0.2), components(&f, 0.6));
        assert!(few > 350, "coverage 0.2: {few} clouds");
        assert!(broken > 100, "coverage 0.6: {broken} clouds");
        // Nearly overcast is one sheet with holes.
        assert!(components(&f, 0.97) < 5);
    }

    #[test]
    fn the_tile_wraps_seamlessly() {
        // Across the wrap, neighbours differ no more than inside the tile.
        let f = field();
        let step = |a: usize, b: usize| (f[a][0] - f[b][0]).abs();
        let (mut seam, mut inner) = (0.0, 0.0);
        for y in 0..SIZE {
            seam += step(y * SIZE + SIZE - 1, y * SIZE);
            inner += step(y * SIZE + SIZE / 2 - 1, y * SIZE + SIZE / 2);
        }
        assert!(seam < 2.0 * inner, "seam {seam} vs inner {inner}");
    }
}
