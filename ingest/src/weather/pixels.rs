//! Sampling the grid structure onto the map's pixels: base, top and wind bilinear between grid
//! points (only over the points that have a value, for the convective cloud), type and source
//! from the nearest grid point. Each image is produced a row at a time, so a large map is
//! streamed like its coverage.

use crate::meta::{AltitudeSource, ExtraRole, LayerStructure};
use crate::region::Region;
use crate::structure::{altitude_to_sample, pack_sources, wind_to_sample, MapStructure};

use super::grid::GridStructure;
use super::inputs::Grid32;
use super::CloudType;

/// Bilinear taps of one axis at a pixel: (lower index, upper index, weight of upper, nearest).
#[derive(Debug, Clone, Copy)]
struct Tap2 {
    a: usize,
    b: usize,
    t: f64,
    near: usize,
}

fn tap(x: f64, n: usize, wrap: bool) -> Tap2 {
    let x = if wrap {
        x.rem_euclid(n as f64)
    } else {
        x.clamp(0.0, (n - 1) as f64)
    };
    let a = (x.floor() as usize).min(n - 1);
    let b = if a + 1 < n {
        a + 1
    } else if wrap {
        0
    } else {
        a
    };
    let t = x - a as f64;
    let near = if t >= 0.5 { b } else { a };
    Tap2 { a, b, t, near }
}

/// The grid structure and winds, with each pixel's taps.
pub struct PixelSampler {
    pub grid: GridStructure,
    pub winds: [Option<(Grid32, Grid32)>; 3],
    rows: Vec<Tap2>,
    cols: Vec<Tap2>,
    width: usize,
}

/// Per-layer tallies over cloudy pixels, merged across bands.
#[derive(Debug, Clone, Default)]
pub struct StructureStats {
    pub n: [u64; 3],
    pub sources: [[u64; 4]; 3],
    pub types: [[u64; 11]; 3],
    pub base_min: [f64; 3],
    pub top_max: [f64; 3],
}

impl StructureStats {
    pub fn new() -> Self {
        StructureStats {
            base_min: [f64::INFINITY; 3],
            top_max: [f64::NEG_INFINITY; 3],
            ..Default::default()
        }
    }

    /// The sidecar summary of layer `c`, whose band is (base, top) from `band_source`.
    pub fn layer(
        &self,
        c: usize,
        band: (f64, f64),
        band_source: AltitudeSource,
        wind: bool,
    ) -> LayerStructure {
        let n = self.n[c];
        let share = |k: u64| if n == 0 { 0.0 } else { k as f64 / n as f64 };
        let mut sources = std::collections::BTreeMap::new();
        for (code, &k) in self.sources[c].iter().enumerate() {
            if let (true, Some(s)) = (k > 0, super::PointSource::from_code(code as u8)) {
                *sources.entry(s.altitude_source(band_source)).or_insert(0.0) += share(k);
            }
        }
        let types = (1..=CloudType::MAX_CODE)
            .filter(|&code| self.types[c][code as usize] > 0)
            .filter_map(|code| {
                Some((
                    CloudType::from_code(code)?,
                    share(self.types[c][code as usize]),
                ))
            })
            .collect();
        let (base_min_m, top_max_m) = if n == 0 {
            band
        } else {
            (self.base_min[c], self.top_max[c])
        };
        LayerStructure {
            base_min_m,
            top_max_m,
            cloudy_pixels: n,
            sources,
            types,
            wind,
        }
    }

    pub fn merge(&mut self, o: &StructureStats) {
        for c in 0..3 {
            self.n[c] += o.n[c];
            for k in 0..4 {
                self.sources[c][k] += o.sources[c][k];
            }
            for k in 0..11 {
                self.types[c][k] += o.types[c][k];
            }
            self.base_min[c] = self.base_min[c].min(o.base_min[c]);
            self.top_max[c] = self.top_max[c].max(o.top_max[c]);
        }
    }
}

impl PixelSampler {
    /// Taps for a `width`×`height` map of `region` on the grid whose north-west point is
    /// (`north`, `west`) with spacing (`di`, `dj`); `wrap` for a global grid.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        grid: GridStructure,
        winds: [Option<(Grid32, Grid32)>; 3],
        region: &Region,
        width: usize,
        height: usize,
        (north, west, di, dj): (f64, f64, f64, f64),
        wrap: bool,
    ) -> PixelSampler {
        let rows = (0..height)
            .map(|j| tap((north - region.pixel_lat(j, height)) / dj, grid.nj, false))
            .collect();
        let cols = (0..width)
            .map(|i| {
                let u = (region.pixel_lon(i, width) - west).rem_euclid(360.0) / di;
                tap(u, grid.ni, wrap)
            })
            .collect();
        PixelSampler {
            grid,
            winds,
            rows,
            cols,
            width,
        }
    }

    fn corners(&self, i: usize, j: usize) -> [(usize, f64); 4] {
        let (r, c) = (self.rows[j], self.cols[i]);
        let ni = self.grid.ni;
        [
            (r.a * ni + c.a, (1.0 - r.t) * (1.0 - c.t)),
            (r.a * ni + c.b, (1.0 - r.t) * c.t),
            (r.b * ni + c.a, r.t * (1.0 - c.t)),
            (r.b * ni + c.b, r.t * c.t),
        ]
    }

    fn nearest(&self, i: usize, j: usize) -> usize {
        self.rows[j].near * self.grid.ni + self.cols[i].near
    }

    /// Bilinear over the corners with a finite value; `None` if none has one.
    fn bilinear(&self, g: &[f32], i: usize, j: usize) -> Option<f64> {
        let (mut s, mut ws) = (0.0, 0.0);
        for (k, w) in self.corners(i, j) {
            let v = g.get(k).copied().unwrap_or(f32::NAN);
            if v.is_finite() {
                s += v as f64 * w;
                ws += w;
            }
        }
        (ws > 1e-12).then(|| s / ws)
    }

    /// Base (or top) of every present layer and of the convective cloud at a pixel.
    fn heights(&self, i: usize, j: usize, top: bool) -> [u16; 4] {
        let mut out = [0u16; 4];
        for (c, l) in self.grid.layers.iter().enumerate() {
            if let Some(l) = l {
                let g = if top { &l.top_m } else { &l.base_m };
                out[c] = altitude_to_sample(self.bilinear(g, i, j));
            }
        }
        let conv = if top {
            &self.grid.convective_m.1
        } else {
            &self.grid.convective_m.0
        };
        // The convective cloud is where its nearest grid point has one.
        if conv.get(self.nearest(i, j)).is_some_and(|v| v.is_finite()) {
            out[3] = altitude_to_sample(self.bilinear(conv, i, j));
        }
        out
    }

    fn types(&self, i: usize, j: usize) -> [u8; 4] {
        let k = self.nearest(i, j);
        let mut out = [0u8; 4];
        let mut src = [None; 3];
        for (c, l) in self.grid.layers.iter().enumerate() {
            if let Some(l) = l {
                out[c] = l.cloud_type.get(k).copied().unwrap_or(0);
                src[c] = l.source.get(k).copied();
            }
        }
        out[3] = pack_sources(src);
        out
    }

    fn wind(&self, i: usize, j: usize, v: bool) -> [u16; 3] {
        let mut out = [wind_to_sample(0.0); 3];
        for (c, w) in self.winds.iter().enumerate() {
            if let Some((u, vv)) = w {
                let g = if v { vv } else { u };
                out[c] = wind_to_sample(self.bilinear(g, i, j).unwrap_or(0.0));
            }
        }
        out
    }

    /// Append row `j` of `role`'s image (big-endian samples) to `out`.
    pub fn append_row(&self, role: ExtraRole, j: usize, out: &mut Vec<u8>) {
        for i in 0..self.width {
            match role {
                ExtraRole::Base | ExtraRole::Top => {
                    for s in self.heights(i, j, role == ExtraRole::Top) {
                        out.extend_from_slice(&s.to_be_bytes());
                    }
                }
                ExtraRole::Type => out.extend_from_slice(&self.types(i, j)),
                ExtraRole::WindU | ExtraRole::WindV => {
                    for s in self.wind(i, j, role == ExtraRole::WindV) {
                        out.extend_from_slice(&s.to_be_bytes());
                    }
                }
            }
        }
    }

    /// Tally the cloudy pixels of rows `j0..` whose coverage texels are `texels`.
    pub fn tally(&self, j0: usize, texels: &[[u16; 4]], st: &mut StructureStats) {
        for (n, t) in texels.iter().enumerate() {
            let (i, j) = (n % self.width, j0 + n / self.width);
            let k = self.nearest(i, j);
            for (c, l) in self.grid.layers.iter().enumerate() {
                let Some(l) = l else { continue };
                if t[c] == 0 {
                    continue;
                }
                st.n[c] += 1;
                if let Some(s) = l.source.get(k) {
                    st.sources[c][*s as usize] += 1;
                }
                if let Some(&ty) = l.cloud_type.get(k) {
                    st.types[c][(ty as usize).min(10)] += 1;
                }
                if let Some(b) = self.bilinear(&l.base_m, i, j) {
                    st.base_min[c] = st.base_min[c].min(b);
                }
                if let Some(b) = self.bilinear(&l.top_m, i, j) {
                    st.top_max[c] = st.top_max[c].max(b);
                }
            }
        }
    }

    /// The whole structure in memory (rows `0..height`, in parallel).
    pub fn map_structure(&self, height: usize) -> MapStructure {
        use rayon::prelude::*;
        type Row = (
            Vec<[u16; 4]>,
            Vec<[u16; 4]>,
            Vec<[u8; 4]>,
            Vec<[u16; 3]>,
            Vec<[u16; 3]>,
        );
        let rows: Vec<Row> = (0..height)
            .into_par_iter()
            .map(|j| {
                let w = self.width;
                let mut r: Row = (
                    Vec::with_capacity(w),
                    Vec::with_capacity(w),
                    Vec::with_capacity(w),
                    Vec::with_capacity(w),
                    Vec::with_capacity(w),
                );
                for i in 0..w {
                    r.0.push(self.heights(i, j, false));
                    r.1.push(self.heights(i, j, true));
                    r.2.push(self.types(i, j));
                    r.3.push(self.wind(i, j, false));
                    r.4.push(self.wind(i, j, true));
                }
                r
            })
            .collect();
        let mut s = MapStructure {
            base: Vec::new(),
            top: Vec::new(),
            types: Vec::new(),
            wind_u: Vec::new(),
            wind_v: Vec::new(),
        };
        for r in rows {
            s.base.extend(r.0);
            s.top.extend(r.1);
            s.types.extend(r.2);
            s.wind_u.extend(r.3);
            s.wind_v.extend(r.4);
        }
        s
    }
}
