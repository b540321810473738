//! The per-frame uniform block: camera, lights, region, layers and march parameters, formed in
//! f64 on the CPU and handed to the GPU as camera-relative f32 (DESIGN §4).

use glam::DVec3;

use super::camera::View;
use super::preset::MarchParams;
use super::settings::Settings;
use super::weather::{Band, WeatherMap};
use super::RenderError;
use crate::sun::Sky;
use stratus_ingest::region::Region;

/// Shape-noise tile period (m): Worley cells of 6 km at the base octave, 1.5 km at the top.
pub const SHAPE_PERIOD_M: f64 = 24_000.0;
/// Detail-noise tile period (m); the shape period is a whole multiple of it.
pub const DETAIL_PERIOD_M: f64 = 2_000.0;
/// Sun intensity in the sky model's units (`SUN_I` in shaders/common.wgsl).
pub const SUN_INTENSITY: f64 = 20.0;
/// The clear air's Rayleigh scattering at sea level in green (550 nm, 1/m): `RAYLEIGH_GREEN` in
/// atmosphere.wgsl (its `RAYLEIGH`'s middle term), shared through render::contract.
pub const RAYLEIGH_GREEN: f64 = 13.558e-6;
/// The background aerosol's (Mie) extinction at sea level (1/m): `MIE_EXTINCT` in
/// atmosphere.wgsl.
pub const MIE_EXTINCTION: f64 = 4.40e-6;
/// The clear air's extinction at sea level at 550 nm (1/m): atmosphere.wgsl's Rayleigh (green)
/// and Mie coefficients. A visibility past 3.912/this (≈ 217 km) has no haze.
pub const CLEAR_AIR_EXTINCTION: f64 = RAYLEIGH_GREEN + MIE_EXTINCTION;

crate::gpu_struct! {
    /// The per-frame uniforms: `struct Frame` in shaders/common.wgsl, field for field (the
    /// contract test in render::contract compares the two). Directions are ECEF unit vectors,
    /// lengths metres; formed in f64 and handed over camera-relative in f32.
    pub struct FrameUniforms as "Frame" {
        /// Local up at the camera.
        pub cam_up: [f32; 3],
        /// Camera altitude above sea level.
        pub cam_alt_m: f32,
        pub cam_fwd: [f32; 3],
        pub tan_half_fov: f32,
        pub cam_right: [f32; 3],
        /// Width / height.
        pub aspect: f32,
        pub cam_view_up: [f32; 3],
        /// MarchParams::graze_from.
        pub graze_from: f32,
        /// The camera's ECEF position modulo the shape-noise period.
        pub noise_origin: [f32; 3],
        pub shape_period_m: f32,
        pub sun_dir: [f32; 3],
        /// 1 when the Sun is the key light, 0 when the Moon is.
        pub sun_is_key: u32,
        pub sun_col: [f32; 3],
        pub detail_period_m: f32,
        pub moon_dir: [f32; 3],
        /// Linear exposure multiplier.
        pub exposure: f32,
        pub moon_col: [f32; 3],
        /// Sea-level haze extinction (1/m): Koschmieder's 3.912 / visibility.
        pub haze_beta: f32,
        pub region_south: f32,
        pub region_north: f32,
        pub region_west: f32,
        /// Eastward span from `region_west` (degrees).
        pub region_lon_span: f32,
        /// Base of the low, middle and high bands, made disjoint ([`disjoint_bands`]).
        pub layer_base: [f32; 3],
        /// Lowest base of a drawn layer.
        pub shell_base_m: f32,
        pub layer_top: [f32; 3],
        /// Highest top of a drawn layer.
        pub shell_top_m: f32,
        /// Per layer: density scale ([`thickness_scale`]), 0 when the layer is off.
        pub layer_scale: [f32; 3],
        pub coverage_mul: f32,
        pub density_mul: f32,
        /// Extinction per unit of DESIGN's density d (1/m).
        pub extinction: f32,
        pub hg_g: f32,
        pub beer_clamp: f32,
        pub step_min_m: f32,
        /// Step growth per metre of distance.
        pub step_growth: f32,
        pub step_max_m: f32,
        pub max_steps: u32,
        pub light_steps: u32,
        pub light_step0_m: f32,
        /// Transmittance below which a ray stops.
        pub early_exit: f32,
        /// [`flags`] bits.
        pub flags: u32,
        /// March output width and height (px).
        pub out_size: [f32; 2],
        pub frame_index: f32,
        /// Beyond this distance the haze hides everything (five visibility lengths).
        pub haze_cutoff_m: f32,
        /// Base of the cumulonimbus towers' envelope (m); above `tower_top_m` when none.
        pub tower_base_m: f32,
        /// Empty-space skip length (one coarse cell).
        pub skip_m: f32,
        /// March pixels per target pixel (the window may march at a fraction of its size).
        pub march_scale: f32,
        pub tower_top_m: f32,
        /// Map uv → structure-texture uv: `uv * st_scale + st_offset`.
        pub st_scale: [f32; 2],
        pub st_offset: [f32; 2],
        /// Per layer, the noise's drift with the layer's wind since the series' reference
        /// time (ECEF m, modulo the shape period); zero for a plain map.
        pub drift_low: [f32; 3],
        /// Blend of two steps (render::blend): fraction of the interval elapsed.
        pub blend_w: f32,
        pub drift_mid: [f32; 3],
        /// Seconds the earlier step is carried (it is sampled this far upwind).
        pub blend_back_s: f32,
        pub drift_high: [f32; 3],
        /// Seconds to the later step (it is sampled this far downwind).
        pub blend_ahead_s: f32,
        /// Which pixel of each `subset_n`×`subset_n` cell the march takes this frame
        /// (render::reproject); the march's output is then one texel per cell.
        pub subset_offset: [f32; 2],
        /// Side of the subset cell (px): 1 marches every pixel.
        pub subset_n: f32,
        /// Where in its pixel this frame's march aims, x (pixels from the centre): a still
        /// view's later marches of a pixel cover it ([`super::reproject::still_sample_offset`]).
        pub sample_dx: f32,
        /// The layers' region-mean wind direction (east, north): the high layer's in x, y, the
        /// middle's in z, w; zero in calm air (< 1 m/s). Cirrus is streaked along it and a
        /// cumulonimbus leans downwind along the high layer's.
        pub streak_dir: [f32; 4],
        /// The region's centre on the sea-level sphere (ECEF m): where the streaked noise and
        /// the cumulus cells are measured from (a frame constant, not worked out per sample).
        pub region_origin: [f32; 3],
        /// … and y (down).
        pub sample_dy: f32,
        /// Per layer, the drift (east, north m) modulo the cumulus cells' tile
        /// (render::cells::PERIOD_M): low in x, y, middle in z, w of the first, high in x, y
        /// of the second. Not the ECEF drift above, whose components wrap by the noise's
        /// period: projected on the cells' plane that wrap is no whole tile, and the field
        /// would jump.
        pub cell_drift: [f32; 4],
        pub cell_drift_high: [f32; 4],
        /// East and north at the region's centre (unit ECEF vectors): the cells' plane.
        pub region_east: [f32; 3],
        /// MarchParams::graze_apart.
        pub graze_apart: f32,
        pub region_north_dir: [f32; 3],
        /// MarchParams::graze_column.
        pub graze_column: f32,
    }
}

/// Bits of [`FrameUniforms::flags`] (`FLAG_*` in shaders/common.wgsl).
pub mod flags {
    /// Empty-space skipping over the coarse map.
    pub const SKIP: u32 = 1;
    /// No sampling outside the region or over a cloudless map.
    pub const CULL: u32 = 2;
    /// Detail noise.
    pub const DETAIL: u32 = 4;
    /// Per-pixel jittered ray start.
    pub const JITTER: u32 = 8;
    /// The score's top-down view: nadir rays from `cam_alt_m`, black background, Sun overhead.
    pub const NO_SKY: u32 = 16;
    /// Fewer light steps once the view ray is mostly opaque.
    pub const LIGHT_LOD: u32 = 32;
    /// Longer steps in clear air, back up on meeting cloud.
    pub const STRIDE: u32 = 64;
    /// The map has per-pixel base, top and type: columns and genus profiles, not bands.
    pub const STRUCTURE: u32 = 128;
    /// The map holds cumulonimbus: towers through the convective cloud.
    pub const TOWERS: u32 = 256;
    /// The map holds cirrus-like genera: noise streaked along the wind.
    pub const STREAKS: u32 = 512;
    /// Two forecast steps are blended, the coverage moved along the motion between them.
    pub const BLEND: u32 = 1024;
    /// The map holds cumulus: its columns are cells (render::cells).
    pub const CELLS: u32 = 2048;
    /// The exposure is fixed (`Frame.exposure` is what the present stage shows at), not adapted.
    pub const FIXED_EXPOSURE: u32 = 4096;
    /// Pixels whose rays graze the layers (between the sea's limb and just above the
    /// horizontal) take four more rays down their height where their picture differs from a
    /// neighbour's (`MarchParams::graze`).
    pub const GRAZE: u32 = 8192;
    /// The map holds cumulus or cumulonimbus: a step in or into a cloudy layer's envelope spans
    /// little altitude (march.wgsl `envelope_step`). Set for the whole map, where
    /// [`CELLS`] and [`TOWERS`] are left out of a frame that cannot reach them (render::reach):
    /// the steps, and so the pictures, do not change with what is in view.
    pub const ENVELOPE: u32 = 16384;
}

fn v3(v: DVec3) -> [f32; 3] {
    [v.x as f32, v.y as f32, v.z as f32]
}

fn luminance(c: [f64; 3]) -> f64 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// Exposure that keeps the lit side of a cloud near mid-grey by day, and lets night read as
/// night (dimmer) while moonlit cloud still stands out from the sky.
pub fn auto_exposure(sky: &Sky) -> f64 {
    let day = ((sky.sun_elevation_deg.to_radians().sin() + 0.15) / 0.2).clamp(0.0, 1.0);
    let day = day * day * (3.0 - 2.0 * day);
    let key = luminance(sky.sun.colour) * SUN_INTENSITY * 0.1
        + 0.15 * day
        + luminance(sky.moon.colour) * SUN_INTENSITY * 0.12;
    // No night is exposed brighter than a full Moon overhead: with less light (a crescent, the
    // Moon down) the picture is darker, as night is. Without this floor the key went to 0 with
    // the Sun and Moon both down and the exposure to 1.2e8, which clipped the faint pre-dawn
    // sky into saturated colour bands (issue 28).
    let e = 0.6 / key.max(night_key()) * (0.2 + 0.8 * day);
    // Twilight's sky (the atmosphere's tables) is far brighter than this key counts: at most
    // 2 stops over daylight while the Sun is less than 8° down, so dusk reads as dusk, then
    // opening up about an e-fold a degree, as the tables' twilight glow fades, to the night's
    // key at astronomical night (18° down), when the glow is gone. (Reaching it at 12° down
    // clipped the glow still there between 12° and 15°.)
    let twilight = ((sky.sun_elevation_deg + 18.0) / 10.0).clamp(0.0, 1.0);
    let cap = (4.0 * FIXED_EXPOSURE).ln() * twilight + e.ln() * (1.0 - twilight);
    e.min(cap.exp())
}

/// The key light (as [`auto_exposure`] counts it) of a full Moon overhead: the brightest night.
fn night_key() -> f64 {
    luminance(crate::sun::transmittance(90.0)) * crate::sun::MOON_TO_SUN * SUN_INTENSITY * 0.12
}

/// The exposure `--exposure EV` fixes at EV 0: about what the Sun's-height exposure gives with
/// the Sun high (so a fixed exposure reads as a daylight picture).
pub const FIXED_EXPOSURE: f64 = 0.25;

/// Layer thickness the density is calibrated for (m).
pub const REFERENCE_THICKNESS_M: f32 = 2000.0;

/// Density scale for a layer of the given thickness: a column's optical depth follows its
/// coverage, not the spacing of the pressure levels the band came from (a single 400 hPa level
/// gives a band under 1 km thick; all levels above 440 hPa one near 10 km). Limited to 0.25..4.
pub fn thickness_scale(thickness_m: f32) -> f32 {
    (REFERENCE_THICKNESS_M / thickness_m.max(1.0)).clamp(0.25, 4.0)
}

/// The drawn layers' altitude bands (m), made disjoint: where a band reaches into the one above
/// it (a hand-edited sidecar, or a 100 m minimum thickness), the two meet half-way. The march
/// shader relies on it: it evaluates the density of the one layer whose band holds a sample.
pub fn disjoint_bands(bands: &[Option<Band>; 3], on: [bool; 3]) -> [Option<(f32, f32)>; 3] {
    let mut out = [None; 3];
    let mut below: Option<usize> = None;
    for k in 0..3 {
        let Some(b) = bands[k].filter(|_| on[k]) else {
            continue;
        };
        let (mut base, top) = (b.base_m, b.top_m);
        if let Some(j) = below {
            if let Some((jb, jt)) = out[j] {
                if base < jt {
                    let mid = (0.5 * (base + jt)).clamp(jb, top);
                    out[j] = Some((jb, mid));
                    base = mid;
                }
            }
        }
        out[k] = Some((base, top));
        below = Some(k);
    }
    out
}

pub struct FrameInput<'a> {
    pub view: View,
    /// March size (px).
    pub width: u32,
    pub height: u32,
    /// Width of the target the march is presented into (px).
    pub target_width: u32,
    pub sky: Sky,
    pub region: &'a Region,
    pub weather: &'a WeatherMap,
    pub settings: &'a Settings,
}

/// A march under this many pixels a target pixel (`march_scale`) is enlarged into its target
/// (render::present::Resample), not resolved at its size.
pub const ENLARGED_BELOW: f32 = 0.99;

/// The [`flags`] a march with these parameters runs with.
fn march_flags(p: &MarchParams) -> u32 {
    let sc = p.shortcuts;
    [
        (sc.empty_skip, flags::SKIP),
        (sc.region_cull, flags::CULL),
        (p.detail, flags::DETAIL),
        (sc.jitter, flags::JITTER),
        (sc.light_lod, flags::LIGHT_LOD),
        (sc.clear_stride, flags::STRIDE),
        (p.graze, flags::GRAZE),
    ]
    .into_iter()
    .filter(|(on, _)| *on)
    .fold(0, |acc, (_, bit)| acc | bit)
}

/// A frame's uniforms, in steps: its layers, its camera, its lights and exposure, the march's
/// parameters, and the cloud's motion (the blend of two steps, the drift).
pub fn build(inp: &FrameInput<'_>) -> Result<FrameUniforms, RenderError> {
    let p: MarchParams = inp.settings.march.effective();
    let mut u = FrameUniforms {
        flags: march_flags(&p),
        ..Default::default()
    };
    layers(&mut u, inp);
    let exposure_base = camera(&mut u, inp)?;
    lights(&mut u, &inp.sky, inp.settings, exposure_base);
    march(&mut u, inp, &p);
    motion(&mut u, inp);
    Ok(u)
}

/// The drawn layers' bounds and density scales, the shell around them, and the flags of what
/// the map holds (a frame's layers).
fn layers(u: &mut FrameUniforms, inp: &FrameInput<'_>) {
    (u.tower_base_m, u.tower_top_m) = (1.0e6, 0.0);
    let (mut lo, mut hi) = if inp.weather.structure.info.present {
        structure_layers(u, inp)
    } else {
        band_layers(u, inp)
    };
    if lo > hi {
        // No layer to draw: an empty shell far above everything.
        (lo, hi) = (1.0e6, 1.0e6);
    }
    u.shell_base_m = lo;
    u.shell_top_m = hi;
    u.coverage_mul = inp.settings.coverage_mul;
}

/// The layers of a map with per-column structure: their envelopes, the towers, cells and
/// streaks it holds, and the region's frame they are measured in. Returns the lowest base and
/// highest top drawn.
fn structure_layers(u: &mut FrameUniforms, inp: &FrameInput<'_>) -> (f32, f32) {
    let s = inp.settings;
    let st = &inp.weather.structure.info;
    let (mut lo, mut hi) = (f32::MAX, f32::MIN);
    // Each column has its own base and top: a layer's bounds are its envelope over the
    // region, and the density scale for its thickness is the column's (march.wgsl).
    u.flags |= flags::STRUCTURE;
    for k in (0..3).filter(|&k| s.layers_on[k]) {
        if let Some((base, top)) = st.envelopes[k] {
            u.layer_base[k] = base;
            u.layer_top[k] = top;
            u.layer_scale[k] = 1.0;
            lo = lo.min(base);
            hi = hi.max(top);
        }
    }
    // Towers and streaks only where the map has them and a layer that holds them is drawn.
    if let Some((base, top)) = st.towers.filter(|_| u.layer_scale.iter().any(|&v| v > 0.0)) {
        u.flags |= flags::TOWERS;
        (u.tower_base_m, u.tower_top_m) = (base, top);
        lo = lo.min(base);
        hi = hi.max(top);
    }
    if st.cells && u.layer_scale.iter().any(|&v| v > 0.0) {
        u.flags |= flags::CELLS;
    }
    if u.flags & (flags::CELLS | flags::TOWERS) != 0 {
        u.flags |= flags::ENVELOPE;
    }
    // The high layer's wind streaks cirrus and carries the anvils of cumulonimbus downwind.
    let towers = u.flags & flags::TOWERS != 0;
    if (st.streaks || towers) && (s.layers_on[1] || s.layers_on[2]) {
        if st.streaks {
            u.flags |= flags::STREAKS;
        }
        let wind = s.streak_wind.unwrap_or(st.mean_wind);
        let unit = |w: [f64; 2]| {
            let n = w[0].hypot(w[1]);
            if n < 1.0 {
                [0.0; 2]
            } else {
                [(w[0] / n) as f32, (w[1] / n) as f32]
            }
        };
        let (high, mid) = (unit(wind[2]), unit(wind[1]));
        u.streak_dir = [high[0], high[1], mid[0], mid[1]];
    }
    let (lat, lon) = inp.region.centre();
    u.region_origin = super::camera::ecef(lat, lon, 0.0).as_vec3().to_array();
    let (east, north, _) = super::camera::enu_basis(lat, lon);
    u.region_east = east.as_vec3().to_array();
    u.region_north_dir = north.as_vec3().to_array();
    u.st_scale = st.uv_scale;
    u.st_offset = st.uv_offset;
    (lo, hi)
}

/// The layers of a map of three bands: made disjoint, each scaled for its thickness. Returns
/// the lowest base and highest top drawn.
fn band_layers(u: &mut FrameUniforms, inp: &FrameInput<'_>) -> (f32, f32) {
    let (mut lo, mut hi) = (f32::MAX, f32::MIN);
    let bands = disjoint_bands(&inp.weather.bands, inp.settings.layers_on);
    for (k, band) in bands.iter().enumerate() {
        if let Some((base, top)) = *band {
            u.layer_base[k] = base;
            u.layer_top[k] = top;
            u.layer_scale[k] = thickness_scale(top - base);
            lo = lo.min(base);
            hi = hi.max(top);
        }
    }
    (lo, hi)
}

/// The camera (a perspective, or the score's top-down view just above the shell's top, which
/// [`layers`] set). Returns the exposure the view starts from.
fn camera(u: &mut FrameUniforms, inp: &FrameInput<'_>) -> Result<f64, RenderError> {
    Ok(match inp.view {
        View::Perspective(cam) => {
            cam.validate()?;
            let b = cam.basis();
            u.cam_up = v3(b.up);
            u.cam_alt_m = cam.alt_m as f32;
            u.cam_fwd = v3(b.forward);
            u.tan_half_fov = (cam.fov_deg.to_radians() * 0.5).tan() as f32;
            u.cam_right = v3(b.right);
            u.aspect = (inp.width as f64 / inp.height as f64) as f32;
            u.cam_view_up = v3(b.view_up);
            // The camera's position modulo the noise period, in f64: noise stays put as it flies.
            u.noise_origin = v3(DVec3::new(
                b.position.x.rem_euclid(SHAPE_PERIOD_M),
                b.position.y.rem_euclid(SHAPE_PERIOD_M),
                b.position.z.rem_euclid(SHAPE_PERIOD_M),
            ));
            auto_exposure(&inp.sky)
        }
        View::TopDown => {
            u.flags |= flags::NO_SKY;
            let (lat, lon) = inp.region.centre();
            let up = crate::sun::up_at(lat, lon);
            u.cam_up = v3(up);
            u.cam_alt_m = u.shell_top_m + 1000.0;
            u.cam_fwd = v3(-up);
            u.tan_half_fov = 1.0;
            u.cam_right = v3(DVec3::X);
            u.aspect = 1.0;
            u.cam_view_up = v3(DVec3::Y);
            1.0
        }
    })
}

/// The Sun and Moon, the exposure and the haze (a frame's sky).
fn lights(u: &mut FrameUniforms, sky: &Sky, s: &Settings, exposure_base: f64) {
    u.shape_period_m = SHAPE_PERIOD_M as f32;
    u.detail_period_m = DETAIL_PERIOD_M as f32;
    u.sun_dir = v3(sky.sun.dir);
    u.sun_is_key = u32::from(sky.sun_elevation_deg > -0.5);
    u.sun_col = sky.sun.colour.map(|c| c as f32);
    u.moon_dir = v3(sky.moon.dir);
    u.moon_col = sky.moon.colour.map(|c| c as f32);
    let visibility = s.visibility_m.max(100.0);
    let base = if s.exposure_auto {
        exposure_base
    } else {
        u.flags |= flags::FIXED_EXPOSURE;
        FIXED_EXPOSURE
    };
    u.exposure = (base * 2f64.powf(s.exposure_ev)) as f32;
    // Koschmieder: the visibility is the total extinction's; the clear air's share (the
    // atmosphere's Rayleigh and background aerosol at 550 nm, drawn by the aerial-perspective
    // table) is taken off, so what is left is the haze's.
    u.haze_beta = (3.912 / visibility - CLEAR_AIR_EXTINCTION).max(0.0) as f32;
    u.haze_cutoff_m = (5.0 * visibility).min(2.0e6) as f32;
}

/// The region, the look and the march's steps and size (a frame's march).
fn march(u: &mut FrameUniforms, inp: &FrameInput<'_>, p: &MarchParams) {
    let (s, r) = (inp.settings, inp.region);
    u.region_south = r.south as f32;
    u.region_north = r.north as f32;
    u.region_west = r.west as f32;
    u.region_lon_span = r.lon_span() as f32;
    u.skip_m = inp.weather.skip_m;
    u.density_mul = s.density_mul;
    u.extinction = s.extinction;
    u.hg_g = s.hg_g;
    u.beer_clamp = s.beer_clamp;
    u.step_min_m = p.step_min_m;
    u.step_growth = p.step_growth;
    u.step_max_m = p.step_max_m;
    u.max_steps = p.max_steps;
    u.light_steps = p.light_steps;
    u.light_step0_m = p.light_reach_m / (p.light_steps as f32 + 5.0);
    u.early_exit = p.early_exit;
    u.graze_apart = p.graze_apart;
    u.graze_column = p.graze_column;
    u.graze_from = p.graze_from;
    u.out_size = [inp.width as f32, inp.height as f32];
    u.frame_index = s.frame_index as f32;
    u.march_scale = inp.width as f32 / inp.target_width.max(1) as f32;
    // A march enlarged into its target (the window's render scale) takes the grazing rays
    // whatever the preset: its pixel is 1 / scale target pixels tall, and a far deck's rim or
    // the haze line over it, thinner than that, was hit or missed along the horizon's row in
    // runs, bars 4 px high and tens of pixels long in the ¼ window (docs/footprint.md).
    if u.march_scale < ENLARGED_BELOW {
        u.flags |= flags::GRAZE;
    }
    // Every pixel marched; a reprojected frame takes one per cell (render::reproject).
    u.subset_n = 1.0;
}

/// The blend of two forecast steps and each layer's drift (the cloud's motion).
fn motion(u: &mut FrameUniforms, inp: &FrameInput<'_>) {
    let s = inp.settings;
    if let Some(b) = inp.weather.blend.now {
        u.flags |= flags::BLEND;
        (u.blend_w, u.blend_back_s, u.blend_ahead_s) = (b.w, b.back_s, b.ahead_s);
    }
    [u.drift_low, u.drift_mid, u.drift_high] = drift(inp.region, &s.drift_m);
    let cell = |k: usize| s.drift_m[k].map(|v| v.rem_euclid(super::cells::PERIOD_M as f64) as f32);
    let (low, mid, high) = (cell(0), cell(1), cell(2));
    u.cell_drift = [low[0], low[1], mid[0], mid[1]];
    u.cell_drift_high = [high[0], high[1], 0.0, 0.0];
}

/// Each layer's noise drift (east, north m) as an ECEF offset along the region centre's east
/// and north, modulo the noise period (the noise tiles, so only the remainder moves it; the
/// f32 offset stays exact however long the series). One rigid offset per layer keeps the
/// noise from shearing where the wind varies.
fn drift(r: &Region, d: &[[f64; 2]; 3]) -> [[f32; 3]; 3] {
    let (lat, lon) = r.centre();
    let (east, north, _) = super::camera::enu_basis(lat, lon);
    d.map(|[e, n]| {
        let v = east * e + north * n;
        v3(DVec3::new(
            v.x.rem_euclid(SHAPE_PERIOD_M),
            v.y.rem_euclid(SHAPE_PERIOD_M),
            v.z.rem_euclid(SHAPE_PERIOD_M),
        ))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn band(base_m: f32, top_m: f32) -> Option<Band> {
        Some(Band { base_m, top_m })
    }

    #[test]
    fn bands_that_touch_are_kept() {
        let b = [
            band(0.0, 3000.0),
            band(3000.0, 7000.0),
            band(7000.0, 16000.0),
        ];
        let d = disjoint_bands(&b, [true; 3]);
        assert_eq!(
            d,
            [
                Some((0.0, 3000.0)),
                Some((3000.0, 7000.0)),
                Some((7000.0, 16000.0))
            ]
        );
    }

    #[test]
    fn overlapping_bands_meet_half_way_and_off_layers_are_left_out() {
        let b = [
            band(0.0, 3400.0),
            band(3000.0, 7000.0),
            band(6800.0, 16000.0),
        ];
        let d = disjoint_bands(&b, [true; 3]);
        assert_eq!(d[0], Some((0.0, 3200.0)));
        assert_eq!(d[1], Some((3200.0, 6900.0)));
        assert_eq!(d[2], Some((6900.0, 16000.0)));
        // With the middle layer off, low and high do not overlap: nothing moves.
        let d = disjoint_bands(&b, [true, false, true]);
        assert_eq!(d, [Some((0.0, 3400.0)), None, Some((6800.0, 16000.0))]);
        // A band inside the one below is cut to what lies above it.
        let b = [band(0.0, 5000.0), band(1000.0, 4000.0), None];
        let d = disjoint_bands(&b, [true; 3]);
        for k in 0..2 {
            let (lo, hi) = d[k].unwrap();
            assert!(lo <= hi, "{d:?}");
        }
        assert!(d[0].unwrap().1 <= d[1].unwrap().0, "{d:?}");
    }
}
