//! The map's vertical structure on the GPU (issue 13, DESIGN §7): per pixel and layer the
//! cloud base and top, the cloud type and the wind the march shapes each column with, on the
//! structure images' own lattice, plus what the frame needs to know before it marches: each
//! layer's envelope (the march bounds), the convective towers' envelope, and which genera the
//! region holds, so a genus that is absent costs nothing.
//!
//! Textures (all Rgba16Float, row 0 north, texel centres on the sidecar's `structure_grid`):
//! - base, top: m above sea level, R/G/B = low/middle/high layer, A = the convective cloud.
//!   Where the file gives no value the layer's band (A: the low layer's) fills in, so bilinear
//!   filtering never blends an altitude with "none".
//! - kind: R/G/B = the layer's [`CloudType`] code (0..=10), read with the nearest texel.
//! - wind: u, v (m/s, east, north) of the high layer in R/G, of the middle in B/A: the layers
//!   whose genera (cirrus) the march streaks along the wind.
//!
//! A map without structure (sidecar versions 1 and 2, synthetic maps) gets 1×1 textures and
//! `present = false`: the march then draws the layer bands with the paper's profile, as before.

use stratus_ingest::cloudmap::CloudMap;
use stratus_ingest::meta::StructureGrid;
use stratus_ingest::region::Region;
use stratus_ingest::structure::{sample_to_altitude, sample_to_wind, MapStructure};
use stratus_ingest::weather::CloudType;

use super::frame::flags;
use super::gpu::Gpu;
use super::reach::FeatureColumns;

/// What the frame needs from the structure before the march.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StructureInfo {
    /// Whether the map has structure images (else the rest is unused).
    pub present: bool,
    /// Per layer: lowest base and highest top over its cloudy pixels (m), `None` for a layer
    /// the map lacks.
    pub envelopes: [Option<(f32, f32)>; 3],
    /// Lowest convective base and highest convective top over the columns of cumulonimbus.
    pub towers: Option<(f32, f32)>,
    /// Whether a streaked genus (cirrus, cirrocumulus, cirrostratus) is in the map.
    pub streaks: bool,
    /// Whether cumulus is in the map: its columns are cells (render::cells).
    pub cells: bool,
    /// Per layer (low, middle, high), the mean wind over the lattice (east, north m/s): the
    /// direction cirrus is streaked along when the settings give none (a plain map).
    pub mean_wind: [[f64; 2]; 3],
    /// Map uv → structure texture uv: `uv * scale + offset`.
    pub uv_scale: [f32; 2],
    pub uv_offset: [f32; 2],
}

/// The four textures' texels (f16) and what the frame needs, made on the CPU.
#[derive(Clone)]
pub struct Prepared {
    pub width: u32,
    pub height: u32,
    /// base, top, kind, wind.
    pub texels: [Vec<half::f16>; 4],
    pub info: StructureInfo,
    /// The columns holding cells, towers and streaks (render::reach).
    pub columns: FeatureColumns,
}

const CB: u8 = CloudType::Cumulonimbus.code();
const CU: u8 = CloudType::Cumulus.code();
/// Shallowest column drawn as cumulonimbus towers (m). A tower is a trunk that spreads into an
/// anvil over the top fifth of its column (cloud.wgsl `tower_cover`): in a column a kilometre or
/// two deep that is a grid of thin discs a few hundred metres up, which from above drew
/// speckle where the map has a broken field (a 700 hPa analysis over the Coral Sea, typed Cb
/// from CAPE alone, scored Dice 0.946 at `fast`). Deep convection reaches the upper
/// troposphere (rule 1's top above 400 hPa, about 7 km): a convective column shallower than
/// 3 km is a cumulus's, and is drawn as one. The map keeps its genus; only the drawing changes.
pub const MIN_TOWER_M: f32 = 3000.0;

/// The column a texel's cumulonimbus tower spans: the convective cloud, and at least the Cb
/// layers it replaces (the march draws a Cb layer only through the tower, cloud.wgsl, so a Cb
/// layer outside the texel's convective column would be drawn as nothing). An analysis has no
/// convective cloud (its Cb are typed from CAPE, docs/ingest.md rule 1′): there the column was
/// the low layer's alone, and the anvils of the high layer over it were missing (issue 30, the
/// Dice gate beyond its cases). `None` where no layer the map has is Cb, or where that column
/// is shallower than [`MIN_TOWER_M`]: there the Cb codes become cumulus.
fn tower_column(
    conv: (f32, f32),
    (b, t): ([f32; 3], [f32; 3]),
    codes: &mut [u8; 4],
    has: impl Fn(usize) -> bool,
) -> Option<(f32, f32)> {
    let is_cb = |c: &usize| has(*c) && codes[*c] == CB;
    if !(0..3).any(|c| is_cb(&c)) {
        return None;
    }
    let column = (0..3)
        .filter(is_cb)
        .fold(conv, |(lo, hi), c| (lo.min(b[c]), hi.max(t[c])));
    if column.1 - column.0 < MIN_TOWER_M {
        for c in codes[..3].iter_mut().filter(|c| **c == CB) {
            *c = CU;
        }
        return None;
    }
    Some(column)
}

/// Thinnest column drawn (m): where RH crosses rh_cr between two close levels the column can
/// be under 100 m, thinner than a fast march step, so it would flicker in and out with the
/// step's phase. Such a column is deepened upward: the base, where a pilot sees the cloud
/// start, stays the forecast's, and its density is normalised to its thickness, so its optical
/// depth is kept.
pub const MIN_COLUMN_M: f32 = 1200.0;

/// A column (base, top) at least [`MIN_COLUMN_M`] thick.
fn widened((base, top): (f32, f32)) -> (f32, f32) {
    (base, top.max(base + MIN_COLUMN_M))
}

pub use stratus_ingest::series::winds::mean_wind;

fn is_streaked(code: u8) -> bool {
    matches!(
        CloudType::from_code(code),
        Some(CloudType::Cirrus | CloudType::Cirrocumulus | CloudType::Cirrostratus)
    )
}

/// Marks the texels whose streaked genera the march can streak: where the layer's wind, as
/// the march filters it between texels, can reach the 1 m/s it asks (cloud.wgsl
/// `column_density`). A bilinear mean of winds is never faster than the fastest it takes, and
/// the genus look-up reaches a texel beyond its own (its dither): so a texel with no wind of
/// 1 m/s within two of it draws its cirrus unstreaked, and a map of such texels (a synthetic
/// map without wind) leaves the streaks' code out.
fn mark_streaks(bits: &mut [u32], streaked: &[u8], wind: &[half::f16], g: &StructureGrid) {
    let (w, h) = (g.width as usize, g.height as usize);
    // Per texel, once: whether the high layer's wind (R, G), the middle's (B, A) is 1 m/s; a
    // little under, for the filter's rounding.
    let fast = |at: usize| -> Vec<bool> {
        wind.chunks_exact(4)
            .map(|t| t[at].to_f32().hypot(t[at + 1].to_f32()) >= 0.99)
            .collect()
    };
    let (high, middle) = (fast(0), fast(2));
    for k in (0..w * h).filter(|&k| streaked[k] != 0) {
        let (x, y) = (k % w, k / w);
        let near = |fast: &[bool]| {
            (y.saturating_sub(2)..(y + 3).min(h))
                .any(|j| (x.saturating_sub(2)..(x + 3).min(w)).any(|i| fast[j * w + i]))
        };
        // The high layer's channel streaks along its own wind, the others along the middle's.
        if (streaked[k] & 0b100 != 0 && near(&high)) || (streaked[k] & 0b011 != 0 && near(&middle))
        {
            bits[k] |= flags::STREAKS;
        }
    }
}

/// Map uv → texture uv of the lattice `g` over `region` (texel centres at whole pixels).
fn uv_transform(region: &Region, g: &StructureGrid) -> ([f32; 2], [f32; 2]) {
    let (w, h) = (g.width.max(1) as f64, g.height.max(1) as f64);
    let lat_span = region.north - region.south;
    let scale = [region.lon_span() / (g.dlon * w), lat_span / (g.dlat * h)];
    let offset = [
        ((region.west - g.west) / g.dlon + 0.5) / w,
        ((g.north - region.north) / g.dlat + 0.5) / h,
    ];
    (scale.map(|v| v as f32), offset.map(|v| v as f32))
}

impl Prepared {
    pub fn new(map: &CloudMap, max_side: u32) -> Prepared {
        let bands = {
            let mut b = [None; 3];
            for l in &map.meta.layers {
                b[l.kind.channel()] = Some((l.base_m as f32, l.top_m as f32));
            }
            b
        };
        let envelopes = {
            let mut e = [None; 3];
            for l in &map.meta.layers {
                let (base, top) = match &l.structure {
                    Some(s) => (s.base_min_m as f32, s.top_max_m as f32),
                    None => (l.base_m as f32, l.top_m as f32),
                };
                // Room for the thinnest columns' deepening.
                e[l.kind.channel()] = Some((base, top + MIN_COLUMN_M));
            }
            e
        };
        let usable = map.structure.as_ref().filter(|s| {
            let fits = s.grid.width <= max_side && s.grid.height <= max_side;
            if !fits {
                tracing::warn!(
                    "structure images {}×{} exceed this adapter's {max_side}-texel limit: drawing the layer bands",
                    s.grid.width,
                    s.grid.height
                );
            }
            s.is_whole() && fits
        });
        match usable {
            Some(s) => Prepared::of(map, s, bands, envelopes),
            None => Prepared::none(envelopes),
        }
    }

    fn none(envelopes: [Option<(f32, f32)>; 3]) -> Prepared {
        let zero = vec![half::f16::ZERO; 4];
        Prepared {
            width: 1,
            height: 1,
            texels: [zero.clone(), zero.clone(), zero.clone(), zero],
            columns: FeatureColumns::default(),
            info: StructureInfo {
                present: false,
                envelopes,
                towers: None,
                streaks: false,
                cells: false,
                mean_wind: [[0.0; 2]; 3],
                uv_scale: [1.0; 2],
                uv_offset: [0.0; 2],
            },
        }
    }

    fn of(
        map: &CloudMap,
        s: &MapStructure,
        bands: [Option<(f32, f32)>; 3],
        envelopes: [Option<(f32, f32)>; 3],
    ) -> Prepared {
        let n = s.base.len();
        let f = half::f16::from_f32;
        let band = |c: usize| bands[c].unwrap_or((0.0, 0.0));
        let (mut base, mut top) = (Vec::with_capacity(n * 4), Vec::with_capacity(n * 4));
        let (mut kind, mut wind) = (Vec::with_capacity(n * 4), Vec::with_capacity(n * 4));
        let mut towers: Option<(f32, f32)> = None;
        // Per texel: the flags of the features it holds; the channels of its streaked genera.
        let mut bits = vec![0u32; n];
        let mut streaked = vec![0u8; n];
        for k in 0..n {
            let alt = |v: u16, fill: f32| sample_to_altitude(v).map_or(fill, |m| m as f32);
            let col: [(f32, f32); 3] = std::array::from_fn(|c| {
                widened((alt(s.base[k][c], band(c).0), alt(s.top[k][c], band(c).1)))
            });
            let (b, t) = (col.map(|c| c.0), col.map(|c| c.1));
            let mut conv = widened((alt(s.base[k][3], b[0]), alt(s.top[k][3], t[0])));
            let mut codes = s.types[k];
            // Only layers the map has: a code in an absent layer's channel is never drawn.
            let has = |c: usize| bands[c].is_some();
            if let Some(tower) = tower_column(conv, (b, t), &mut codes, has) {
                conv = tower;
                towers = Some(towers.map_or(conv, |(a, z)| (a.min(conv.0), z.max(conv.1))));
                bits[k] |= flags::TOWERS;
            }
            streaked[k] = (0..3)
                .filter(|&c| has(c) && is_streaked(codes[c]))
                .fold(0, |acc, c| acc | 1 << c);
            if (0..3).any(|c| has(c) && codes[c] == CU) {
                bits[k] |= flags::CELLS;
            }
            base.extend([b[0], b[1], b[2], conv.0].map(f));
            top.extend([t[0], t[1], t[2], conv.1].map(f));
            kind.extend([codes[0], codes[1], codes[2], 0].map(|c| f(c as f32)));
            let w = |v: &[u16; 3], c: usize| sample_to_wind(v[c]) as f32;
            wind.extend(
                [
                    w(&s.wind_u[k], 2),
                    w(&s.wind_v[k], 2),
                    w(&s.wind_u[k], 1),
                    w(&s.wind_v[k], 1),
                ]
                .map(f),
            );
        }
        mark_streaks(&mut bits, &streaked, &wind, &s.grid);
        let held = |flag: u32| bits.iter().any(|&b| b & flag != 0);
        // The towers' envelope widens the convective layers' own: the march bounds must hold it.
        let (uv_scale, uv_offset) = uv_transform(&map.meta.region, &s.grid);
        Prepared {
            width: s.grid.width,
            height: s.grid.height,
            columns: FeatureColumns::new(&s.grid, &bits),
            texels: [base, top, kind, wind],
            info: StructureInfo {
                present: true,
                envelopes,
                towers,
                streaks: held(flags::STREAKS),
                cells: held(flags::CELLS),
                mean_wind: mean_wind(s),
                uv_scale,
                uv_offset,
            },
        }
    }
}

/// The structure textures of one map.
pub struct StructureTextures {
    /// base, top, kind, wind.
    pub textures: [wgpu::Texture; 4],
    pub info: StructureInfo,
    /// Where the map's cells, towers and streaks are (render::reach).
    pub columns: FeatureColumns,
}

const LABELS: [&str; 4] = [
    "structure: base",
    "structure: top",
    "structure: kind",
    "structure: wind",
];

impl StructureTextures {
    /// Textures of `p`'s size, not yet written ([`store`](Self::store) fills them).
    pub fn new(gpu: &Gpu, p: &Prepared) -> StructureTextures {
        let size = (p.width as usize, p.height as usize);
        let textures = LABELS.map(|label| {
            super::texture::map_texture(gpu, label, size, wgpu::TextureFormat::Rgba16Float)
        });
        StructureTextures {
            textures,
            info: p.info,
            columns: p.columns.clone(),
        }
    }

    /// Whether `p` fits these textures (then [`store`](Self::store) can take it).
    pub fn fits(&self, p: &Prepared) -> bool {
        self.textures[0].width() == p.width && self.textures[0].height() == p.height
    }

    pub fn store(&mut self, gpu: &Gpu, p: &Prepared) {
        for (tex, texels) in self.textures.iter().zip(&p.texels) {
            super::texture::write(gpu, tex, bytemuck::cast_slice(texels), 8);
        }
        self.info = p.info;
        self.columns = p.columns.clone();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 7×1 lattice of cirrus in the high layer but the last texel, calm but for texel x's
    /// wind (`slot` 0: the high layer's u, 2: the middle's).
    fn streaks_with_wind_at(x: usize, slot: usize, speed: f32) -> Vec<u32> {
        let g = StructureGrid {
            width: 7,
            height: 1,
            north: 0.0,
            west: 0.0,
            dlat: 1.0,
            dlon: 1.0,
        };
        let mut wind = vec![half::f16::ZERO; 7 * 4];
        wind[4 * x + slot] = half::f16::from_f32(speed);
        let mut bits = vec![0; 7];
        let mut streaked = vec![0b100; 7];
        streaked[6] = 0;
        mark_streaks(&mut bits, &streaked, &wind, &g);
        bits
    }

    #[test]
    fn cirrus_is_streaked_only_within_two_texels_of_a_wind() {
        let s = flags::STREAKS;
        assert_eq!(streaks_with_wind_at(0, 0, 5.0), [s, s, s, 0, 0, 0, 0]);
        assert_eq!(streaks_with_wind_at(3, 0, 5.0), [0, s, s, s, s, s, 0]);
        // Calm air (under 1 m/s) streaks nothing; the middle layer's wind not the high layer.
        assert_eq!(streaks_with_wind_at(3, 0, 0.9), [0; 7]);
        assert_eq!(streaks_with_wind_at(3, 0, 1.0), [0, s, s, s, s, s, 0]);
        assert_eq!(streaks_with_wind_at(3, 2, 5.0), [0; 7]);
    }

    #[test]
    fn thin_columns_are_deepened_upward() {
        assert_eq!(widened((7117.0, 7203.0)), (7117.0, 8317.0));
        assert_eq!(widened((1000.0, 3000.0)), (1000.0, 3000.0));
    }

    #[test]
    fn a_tower_spans_the_convective_cloud_and_its_cb_layers() {
        let (b, t) = ([500.0, 3500.0, 8000.0], [2000.0, 6000.0, 11000.0]);
        let mut codes = [CB, 5, CB, 0b10_10];
        let all = |_: usize| true;
        // The analysis' column (the low layer's, no convective cloud) widened by the anvils.
        assert_eq!(
            tower_column((500.0, 2000.0), (b, t), &mut codes, all),
            Some((500.0, 11000.0))
        );
        assert_eq!(codes, [CB, 5, CB, 0b10_10]);
        // No Cb layer the map has: no tower.
        let mut codes = [CB, 5, 1, 0];
        assert_eq!(
            tower_column((500.0, 2000.0), (b, t), &mut codes, |c| c != 0),
            None
        );
    }

    #[test]
    fn a_shallow_convective_column_is_drawn_as_cumulus() {
        // One level's layer (a 700 hPa map), typed Cb from CAPE, widened to MIN_COLUMN_M: no
        // room for a trunk and an anvil. The source bits (10 here, like Cb's code) stay.
        let col = widened((3114.0, 3220.0));
        let (b, t) = ([col.0; 3], [col.1; 3]);
        let mut codes = [CB, 0, 0, CB];
        assert_eq!(tower_column(col, (b, t), &mut codes, |c| c == 0), None);
        assert_eq!(codes, [CU, 0, 0, CB]);
        // Just deep enough: a tower.
        let deep = (1000.0, 1000.0 + MIN_TOWER_M);
        let mut codes = [CB, 0, 0, 0];
        assert_eq!(
            tower_column(deep, ([deep.0; 3], [deep.1; 3]), &mut codes, |c| c == 0),
            Some(deep)
        );
    }

    #[test]
    fn texel_centres_land_on_the_lattice() {
        let r = Region::parse("0,55,39,105").unwrap();
        let g =
            stratus_ingest::structure::structure_grid((1300, 1100), &r, (90.0, 0.0), (2.5, 2.5));
        let (s, o) = uv_transform(&r, &g);
        // The region's north-west corner is at lattice (x, y) = ((39 − west)/dlon, 0).
        let x = (s[0] * 0.0 + o[0]) * g.width as f32 - 0.5;
        let y = (s[1] * 0.0 + o[1]) * g.height as f32 - 0.5;
        assert!((x as f64 - (39.0 - g.west) / g.dlon).abs() < 1e-3, "{x}");
        assert!(y.abs() < 1e-3, "{y}");
        // The south-east corner: 105°E, 0°N, the last texel centres.
        let x = (s[0] + o[0]) * g.width as f32 - 0.5;
        let y = (s[1] + o[1]) * g.height as f32 - 0.5;
        assert!((x - (g.width - 1) as f32).abs() < 1e-2, "{x}");
        assert!((y - (g.height - 1) as f32).abs() < 1e-2, "{y}");
    }
}
