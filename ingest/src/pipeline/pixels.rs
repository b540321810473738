//! Sampling the grid structure onto the structure images' pixels ([`crate::structure`]: a
//! few pixels per grid cell over the map's region, not the map's size): base, top and wind
//! bilinear between grid points (only over the points that have a value, for the convective
//! cloud), type and source from the nearest grid point. Each image is produced a row at a
//! time. The sidecar's per-layer summary is tallied over the map's cloudy pixels as a reader
//! sees them through the structure images ([`PixelSampler::tally`]).

use crate::cloud::CloudType;
use crate::lattice::{Placement, StructureGrid};
use crate::layer::{AltitudeSource, PointSource};
use crate::meta::{ExtraRole, LayerStructure};
use crate::sample::{
    altitude_to_sample, pack_sources, sample_to_altitude, sample_to_wind, unpack_source,
    wind_to_sample,
};
use crate::structure::{MapStructure, StructureBand};
use crate::weather::inputs::Grid32;
use crate::weather::GridStructure;

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

/// A coverage pixel's place among the structure pixels of one axis: the bilinear pair a
/// reader blends and the nearest one.
#[derive(Debug, Clone, Copy)]
struct MapTap {
    a: usize,
    b: usize,
    near: usize,
}

/// A coverage pixel's taps among `n` structure pixels at fractional coordinate `x` (clamped).
fn map_tap(x: f64, n: usize) -> MapTap {
    let a = x.floor() as usize;
    MapTap {
        a,
        b: (a + 1).min(n - 1),
        near: x.round() as usize,
    }
}

/// The grid structure and winds, with each structure pixel's grid taps and each coverage
/// pixel's structure taps.
pub struct PixelSampler {
    pub grid: GridStructure,
    pub winds: [Option<(Grid32, Grid32)>; 3],
    rows: Vec<Tap2>,
    cols: Vec<Tap2>,
    /// Where the structure images' pixels lie.
    lattice: StructureGrid,
    width: usize,
    map_rows: Vec<MapTap>,
    map_cols: Vec<MapTap>,
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
            if let (true, Some(s)) = (k > 0, PointSource::from_code(code as u8)) {
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
    /// Taps for structure images on `lattice` of the map `at` describes.
    pub fn new(
        grid: GridStructure,
        winds: [Option<(Grid32, Grid32)>; 3],
        at: Placement,
        lattice: StructureGrid,
    ) -> PixelSampler {
        let mut s = PixelSampler {
            grid,
            winds,
            rows: vec![],
            cols: vec![],
            lattice,
            width: 0,
            map_rows: vec![],
            map_cols: vec![],
        };
        s.set_lattice(at, lattice);
        s
    }

    /// Sample the structure on `lattice` instead.
    pub fn set_lattice(&mut self, at: Placement, lattice: StructureGrid) {
        let g = lattice;
        let (width, height) = (g.width.max(1) as usize, g.height.max(1) as usize);
        let (r, ni, nj) = (&at.region, self.grid.ni, self.grid.nj);
        self.rows = (0..height)
            .map(|j| {
                tap(
                    (at.north - (g.north - j as f64 * g.dlat)) / at.dj,
                    nj,
                    false,
                )
            })
            .collect();
        self.cols = (0..width)
            .map(|i| {
                let u = (g.west + i as f64 * g.dlon - at.west).rem_euclid(360.0) / at.di;
                tap(u, ni, at.wrap)
            })
            .collect();
        let (map_w, map_h) = at.map_size;
        self.map_rows = (0..map_h)
            .map(|j| map_tap(g.y(r.pixel_lat(j, map_h)), height))
            .collect();
        self.map_cols = (0..map_w)
            .map(|i| map_tap(g.x(r, r.pixel_lon(i, map_w)), width))
            .collect();
        self.lattice = g;
        self.width = width;
    }

    /// Where the structure images' pixels lie.
    pub fn lattice(&self) -> StructureGrid {
        self.lattice
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

    /// Append row `j` of a GeoTIFF's structure image to `out`: per pixel the value of each of
    /// `bands` in physical units, `nodata` where there is none. The values are the structure
    /// images' samples decoded, so the GeoTIFF and the PNG set say the same (a layer without a
    /// wind field, which the images hold as 0 m/s, is `nodata` here).
    pub fn append_physical_row(
        &self,
        bands: &[StructureBand],
        j: usize,
        nodata: f32,
        out: &mut Vec<f32>,
    ) {
        let m = |v: Option<f64>| v.map_or(nodata, |v| v as f32);
        for i in 0..self.width {
            let (base, top) = (self.heights(i, j, false), self.heights(i, j, true));
            let types = self.types(i, j);
            let (u, v) = (self.wind(i, j, false), self.wind(i, j, true));
            for &b in bands {
                out.push(match b {
                    StructureBand::Base(k) => m(sample_to_altitude(base[k.channel()])),
                    StructureBand::Top(k) => m(sample_to_altitude(top[k.channel()])),
                    StructureBand::Type(k) => {
                        m(CloudType::from_code(types[k.channel()]).map(|t| t.code() as f64))
                    }
                    StructureBand::Source(k) => {
                        m(unpack_source(types[3], k.channel()).map(|s| s as u8 as f64))
                    }
                    StructureBand::WindU(k) => m(self.winds[k.channel()]
                        .as_ref()
                        .map(|_| sample_to_wind(u[k.channel()]))),
                    StructureBand::WindV(k) => m(self.winds[k.channel()]
                        .as_ref()
                        .map(|_| sample_to_wind(v[k.channel()]))),
                    StructureBand::ConvectiveBase => m(sample_to_altitude(base[3])),
                    StructureBand::ConvectiveTop => m(sample_to_altitude(top[3])),
                });
            }
        }
    }

    /// Tally the cloudy coverage pixels of map rows `j0..` (their texels: `texels`), each
    /// with the type and source of its nearest structure pixel, as a reader sees them. The
    /// base/top bounds are over the structure pixels those cloudy pixels blend (bilinear never
    /// leaves its corners' range, so a reader's march bounds hold). Map rows `j0..` touch a few
    /// structure rows, so the marks stay small; bands tally independently and merge.
    pub fn tally(&self, j0: usize, texels: &[[u16; 4]], st: &mut StructureStats) {
        let map_w = self.map_cols.len();
        let rows = texels.len() / map_w.max(1);
        if rows == 0 {
            return;
        }
        let (r_lo, r_hi) = (self.map_rows[j0].a, self.map_rows[j0 + rows - 1].b);
        let w = self.width;
        // Bit c: some cloudy pixel of layer c blends this structure pixel.
        let mut marks = vec![0u8; (r_hi - r_lo + 1) * w];
        let ni = self.grid.ni;
        for (dj, row) in texels.chunks_exact(map_w).enumerate() {
            let r = self.map_rows[j0 + dj];
            let grid_row = self.rows[r.near].near * ni;
            for (t, c) in row.iter().zip(&self.map_cols) {
                if t[3] == 0 {
                    continue;
                }
                let k = grid_row + self.cols[c.near].near;
                let mut bits = 0u8;
                for (ch, l) in self.grid.layers.iter().enumerate() {
                    let Some(l) = l else { continue };
                    if t[ch] == 0 {
                        continue;
                    }
                    bits |= 1 << ch;
                    st.n[ch] += 1;
                    if let Some(s) = l.source.get(k) {
                        st.sources[ch][*s as usize] += 1;
                    }
                    if let Some(&ty) = l.cloud_type.get(k) {
                        st.types[ch][(ty as usize).min(10)] += 1;
                    }
                }
                if bits != 0 {
                    for rr in [r.a, r.b] {
                        let m = (rr - r_lo) * w;
                        marks[m + c.a] |= bits;
                        marks[m + c.b] |= bits;
                    }
                }
            }
        }
        for (n, &bits) in marks.iter().enumerate() {
            if bits == 0 {
                continue;
            }
            let (i, j) = (n % w, r_lo + n / w);
            for (ch, l) in self.grid.layers.iter().enumerate() {
                let Some(l) = l else { continue };
                if bits & (1 << ch) == 0 {
                    continue;
                }
                if let Some(b) = self.bilinear(&l.base_m, i, j) {
                    st.base_min[ch] = st.base_min[ch].min(b);
                }
                if let Some(b) = self.bilinear(&l.top_m, i, j) {
                    st.top_max[ch] = st.top_max[ch].max(b);
                }
            }
        }
    }

    /// The whole structure in memory (its rows in parallel).
    pub fn map_structure(&self) -> MapStructure {
        let height = self.rows.len();
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
            grid: self.lattice,
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
