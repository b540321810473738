//! The CloudMap on the GPU: the weather texture the march samples by latitude/longitude, and the
//! coarse max-map it skips empty space with (DESIGN §4). Maps larger than the adapter allows are
//! box-downscaled with a warning.

use rayon::prelude::*;
use stratus_ingest::cloudmap::CloudMap;
use stratus_ingest::series::motion::Motion;

use super::blend::Blend;
use super::camera::EARTH_R;
use super::gpu::Gpu;
use super::structure::{self, StructureTextures};

/// Map pixels per coarse cell side.
pub const COARSE_CELL: usize = 8;

/// Altitude band of a layer slot (low, middle, high); `None` when the map has no such layer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Band {
    pub base_m: f32,
    pub top_m: f32,
}

pub struct WeatherMap {
    pub texture: wgpu::Texture,
    pub coarse: wgpu::Texture,
    /// Size on the GPU (after any downscale).
    pub width: u32,
    pub height: u32,
    /// Longest step that cannot jump over a covered coarse cell (m).
    pub skip_m: f32,
    pub bands: [Option<Band>; 3],
    /// The coarse map on the CPU (row-major, dilated), for tests and counters.
    pub coarse_cells: Vec<f32>,
    pub coarse_w: usize,
    pub coarse_h: usize,
    /// Per-pixel base, top, type and wind (a 1×1 stand-in for maps without them).
    pub structure: StructureTextures,
    /// The later step and the motion between the steps when two are blended (render::blend).
    pub blend: Blend,
}

/// Box-average `texels` (w×h, RGBA in 0..1) by an integer factor.
fn downscale(texels: &[[f32; 4]], w: usize, h: usize, k: usize) -> (Vec<[f32; 4]>, usize, usize) {
    let (nw, nh) = (w.div_ceil(k), h.div_ceil(k));
    let out = (0..nw * nh)
        .into_par_iter()
        .map(|idx| {
            let (i, j) = (idx % nw, idx / nw);
            let mut acc = [0.0f32; 4];
            let mut n = 0.0f32;
            for y in j * k..((j + 1) * k).min(h) {
                for x in i * k..((i + 1) * k).min(w) {
                    let t = texels[y * w + x];
                    for c in 0..4 {
                        acc[c] += t[c];
                    }
                    n += 1.0;
                }
            }
            acc.map(|a| a / n)
        })
        .collect();
    (out, nw, nh)
}

/// Max of A over each cell, then dilated by one cell so a half-texel of bilinear bleed and
/// a step of up to one cell can never pass over cover unseen.
pub fn coarse_map(texels: &[[f32; 4]], w: usize, h: usize) -> (Vec<f32>, usize, usize) {
    let (cw, ch) = (w.div_ceil(COARSE_CELL), h.div_ceil(COARSE_CELL));
    let raw: Vec<f32> = (0..cw * ch)
        .into_par_iter()
        .map(|idx| {
            let (i, j) = (idx % cw, idx / cw);
            let mut m = 0.0f32;
            for y in j * COARSE_CELL..((j + 1) * COARSE_CELL).min(h) {
                for x in i * COARSE_CELL..((i + 1) * COARSE_CELL).min(w) {
                    m = m.max(texels[y * w + x][3]);
                }
            }
            m
        })
        .collect();
    let dilated = (0..cw * ch)
        .map(|idx| {
            let (i, j) = ((idx % cw) as isize, (idx / cw) as isize);
            let mut m = 0.0f32;
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let (x, y) = (i + dx, j + dy);
                    if x >= 0 && y >= 0 && (x as usize) < cw && (y as usize) < ch {
                        m = m.max(raw[y as usize * cw + x as usize]);
                    }
                }
            }
            m
        })
        .collect();
    (dilated, cw, ch)
}

/// A map made ready for the GPU on the CPU: texels as f16, the coarse map, the bands.
struct Prepared {
    halfs: Vec<half::f16>,
    w: usize,
    h: usize,
    cells: Vec<f32>,
    cw: usize,
    ch: usize,
    skip_m: f32,
    bands: [Option<Band>; 3],
    structure: structure::Prepared,
}

impl Prepared {
    fn new(gpu: &Gpu, map: &CloudMap) -> Prepared {
        let (mut w, mut h) = (map.width(), map.height());
        let mut texels: Vec<[f32; 4]> = map
            .texels
            .par_iter()
            .map(|t| t.map(|v| v as f32 / 65535.0))
            .collect();
        let max = gpu.device.limits().max_texture_dimension_2d as usize;
        if w > max || h > max {
            let k = w.max(h).div_ceil(max);
            tracing::warn!(
                "CloudMap {w}×{h} exceeds this adapter's {max}-texel limit: rendering it downscaled {k}×"
            );
            (texels, w, h) = downscale(&texels, w, h, k);
        }
        let halfs: Vec<half::f16> = texels
            .iter()
            .flat_map(|t| t.map(half::f16::from_f32))
            .collect();
        let (cells, cw, ch) = coarse_map(&texels, w, h);
        let r = &map.meta.region;
        let deg_m = EARTH_R.to_radians();
        let max_abs_lat = r.south.abs().max(r.north.abs()).min(89.9);
        let cell_lat_m = (r.north - r.south) / h as f64 * COARSE_CELL as f64 * deg_m;
        let cell_lon_m =
            r.lon_span() / w as f64 * COARSE_CELL as f64 * deg_m * max_abs_lat.to_radians().cos();
        let skip_m = (0.95 * cell_lat_m.min(cell_lon_m)) as f32;
        let mut bands = [None; 3];
        for l in &map.meta.layers {
            bands[l.kind.channel()] = Some(Band {
                base_m: l.base_m as f32,
                top_m: l.top_m as f32,
            });
        }
        let structure = structure::Prepared::new(map, max as u32);
        Prepared {
            structure,
            halfs,
            w,
            h,
            cells,
            cw,
            ch,
            skip_m,
            bands,
        }
    }
}

impl WeatherMap {
    /// Make the map's textures and upload it.
    pub fn upload(gpu: &Gpu, map: &CloudMap) -> WeatherMap {
        WeatherMap::with(gpu, Prepared::new(gpu, map))
    }

    fn with(gpu: &Gpu, p: Prepared) -> WeatherMap {
        let texture = super::texture::map_texture(
            gpu,
            "weather map",
            (p.w, p.h),
            wgpu::TextureFormat::Rgba16Float,
        );
        let coarse = super::texture::map_texture(
            gpu,
            "coarse map",
            (p.cw, p.ch),
            wgpu::TextureFormat::R32Float,
        );
        let mut m = WeatherMap {
            texture,
            coarse,
            width: p.w as u32,
            height: p.h as u32,
            skip_m: 0.0,
            bands: [None; 3],
            coarse_cells: Vec::new(),
            coarse_w: p.cw,
            coarse_h: p.ch,
            structure: StructureTextures::new(gpu, &p.structure),
            blend: Blend::none(gpu),
        };
        m.store(gpu, p);
        m
    }

    /// Upload another map: into these textures when it has their size (an rh_cr change, a
    /// new forecast over the same region), so nothing is made again, else into new textures.
    /// True when the textures were kept (a bind group over them stays valid).
    pub fn replace(&mut self, gpu: &Gpu, map: &CloudMap) -> bool {
        self.blend.pair = None;
        self.blend.now = None;
        let p = Prepared::new(gpu, map);
        let fits = (p.w as u32, p.h as u32) == (self.width, self.height)
            && (p.cw, p.ch) == (self.coarse_w, self.coarse_h)
            && self.structure.fits(&p.structure);
        if fits {
            self.store(gpu, p);
        } else {
            *self = WeatherMap::with(gpu, p);
        }
        fits
    }

    /// Upload two forecast steps to be blended (DESIGN §9): `a` into these textures (as
    /// [`replace`](Self::replace)), `b` and the guarded motion between them beside it; the
    /// coarse map is the max of both, dilated by the farthest the motion carries cover in the
    /// interval, so empty-space skipping never passes over displaced cover. True when every
    /// texture was kept.
    pub fn set_pair(
        &mut self,
        gpu: &Gpu,
        (a, b): (&CloudMap, &CloudMap),
        motion: &Motion,
    ) -> Result<bool, String> {
        stratus_ingest::series::advect::check_compatible(a, b)?;
        let (pa, pb) = (Prepared::new(gpu, a), Prepared::new(gpu, b));
        let structures = (pa.structure.info.present
            && pb.structure.info.present
            && (pa.structure.width, pa.structure.height)
                == (pb.structure.width, pb.structure.height))
            .then(|| [pa.structure.clone(), pb.structure.clone()]);
        // No lookup moves further than the largest guarded shift (bilinear bleed is in the
        // coarse map's own one-cell dilation).
        let reach_cells = (motion.max_shift_px() / COARSE_CELL as f32).ceil() as usize;
        let cells: Vec<f32> = pa
            .cells
            .iter()
            .zip(&pb.cells)
            .map(|(x, y)| x.max(*y))
            .collect();
        let cells = dilate(&cells, pa.cw, pa.ch, reach_cells);
        let mut kept = self.replace(gpu, a);
        super::texture::write(gpu, &self.coarse, bytemuck::cast_slice(&cells), 4);
        self.coarse_cells = cells;
        kept &= self
            .blend
            .store(gpu, (&pb.halfs, pb.w, pb.h), (a, b, motion), structures)?;
        Ok(kept)
    }

    /// Bytes of every texture this map holds on the GPU (both steps when blending).
    pub fn gpu_bytes(&self) -> u64 {
        let t = |t: &wgpu::Texture| {
            let bpp = t.format().block_copy_size(None).unwrap_or(0) as u64;
            t.width() as u64 * t.height() as u64 * bpp
        };
        t(&self.texture)
            + t(&self.coarse)
            + self.structure.textures.iter().map(t).sum::<u64>()
            + t(&self.blend.next)
            + t(&self.blend.motion)
    }

    fn store(&mut self, gpu: &Gpu, p: Prepared) {
        super::texture::write(gpu, &self.texture, bytemuck::cast_slice(&p.halfs), 8);
        super::texture::write(gpu, &self.coarse, bytemuck::cast_slice(&p.cells), 4);
        self.skip_m = p.skip_m;
        self.bands = p.bands;
        self.coarse_cells = p.cells;
        self.structure.store(gpu, &p.structure);
    }
}

/// Max over a square of `n` cells around each cell.
fn dilate(cells: &[f32], cw: usize, ch: usize, n: usize) -> Vec<f32> {
    if n == 0 {
        return cells.to_vec();
    }
    // Separable: rows, then columns.
    let pass = |src: &[f32], horizontal: bool| -> Vec<f32> {
        (0..cw * ch)
            .into_par_iter()
            .map(|idx| {
                let (i, j) = (idx % cw, idx / cw);
                let (at, len) = if horizontal { (i, cw) } else { (j, ch) };
                let (lo, hi) = (at.saturating_sub(n), (at + n).min(len - 1));
                (lo..=hi)
                    .map(|k| {
                        if horizontal {
                            src[j * cw + k]
                        } else {
                            src[k * cw + i]
                        }
                    })
                    .fold(0.0f32, f32::max)
            })
            .collect()
    };
    pass(&pass(cells, true), false)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn coarse_map_is_dilated_max() {
        let (w, h) = (32, 24);
        let mut t = vec![[0.0f32; 4]; w * h];
        t[10 * w + 20][3] = 0.4;
        let (c, cw, ch) = coarse_map(&t, w, h);
        assert_eq!((cw, ch), (4, 3));
        // Pixel (20, 10) is in cell (2, 1); dilation covers cells x 1..=3, y 0..=2.
        for j in 0..ch {
            for i in 0..cw {
                let want = if (1..=3).contains(&i) { 0.4 } else { 0.0 };
                assert_eq!(c[j * cw + i], want, "cell {i},{j}");
            }
        }
    }

    #[test]
    fn dilation_spreads_by_n_cells() {
        let mut c = vec![0.0f32; 9 * 5];
        c[2 * 9 + 4] = 0.7;
        let d = dilate(&c, 9, 5, 2);
        for j in 0..5 {
            for i in 0..9 {
                let want = if (2..=6).contains(&i) { 0.7 } else { 0.0 };
                assert_eq!(d[j * 9 + i], want, "cell {i},{j}");
            }
        }
    }

    #[test]
    fn downscale_averages() {
        let t = vec![
            [1.0, 0.0, 0.0, 1.0],
            [0.0, 0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0, 1.0],
        ];
        let (d, w, h) = downscale(&t, 3, 1, 2);
        assert_eq!((w, h), (2, 1));
        assert_eq!(d[0][0], 0.5);
        assert_eq!(d[1][3], 1.0);
    }
}
