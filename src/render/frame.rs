//! The per-frame uniform block: camera, lights, region, layers and march parameters, formed in
//! f64 on the CPU and handed to the GPU as camera-relative f32 (DESIGN §4).

use bytemuck::{Pod, Zeroable};
use glam::DVec3;

use super::camera::View;
use super::preset::MarchParams;
use super::weather::{Band, WeatherMap};
use super::{RenderError, Settings};
use crate::sun::{Light, Sky};
use stratus_ingest::region::Region;

/// Shape-noise tile period (m): Worley cells of 6 km at the base octave, 1.5 km at the top.
pub const SHAPE_PERIOD_M: f64 = 24_000.0;
/// Detail-noise tile period (m); the shape period is a whole multiple of it.
pub const DETAIL_PERIOD_M: f64 = 2_000.0;
/// Sun intensity in the sky model's units (mirrors SUN_I in march.wgsl).
const SUN_I: f64 = 20.0;

/// Mirrors `struct Frame` in shaders/common.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct FrameUniforms {
    pub cam_up: [f32; 4],
    pub cam_fwd: [f32; 4],
    pub cam_right: [f32; 4],
    pub cam_upv: [f32; 4],
    pub noise_origin: [f32; 4],
    pub sun_dir: [f32; 4],
    pub sun_col: [f32; 4],
    pub moon_dir: [f32; 4],
    pub moon_col: [f32; 4],
    pub region: [f32; 4],
    pub region2: [f32; 4],
    pub layer_base: [f32; 4],
    pub layer_top: [f32; 4],
    pub layer_on: [f32; 4],
    pub light: [f32; 4],
    pub march: [f32; 4],
    pub march2: [f32; 4],
    pub misc: [f32; 4],
    pub size: [f32; 4],
}

pub const FLAG_SKIP: u32 = 1;
pub const FLAG_CULL: u32 = 2;
pub const FLAG_DETAIL: u32 = 4;
pub const FLAG_JITTER: u32 = 8;
pub const FLAG_NO_SKY: u32 = 16;
pub const FLAG_LIGHT_LOD: u32 = 32;
pub const FLAG_STRIDE: u32 = 64;

fn v4(v: DVec3, w: f64) -> [f32; 4] {
    [v.x as f32, v.y as f32, v.z as f32, w as f32]
}

fn luminance(c: [f64; 3]) -> f64 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// Exposure that keeps the lit side of a cloud near mid-grey by day, and lets night read as
/// night (dimmer) while moonlit cloud still stands out from the sky.
pub fn auto_exposure(sky: &Sky) -> f64 {
    let day = ((sky.sun_elevation_deg.to_radians().sin() + 0.15) / 0.2).clamp(0.0, 1.0);
    let day = day * day * (3.0 - 2.0 * day);
    let key = luminance(sky.sun.colour) * SUN_I * 0.1
        + 0.15 * day
        + luminance(sky.moon.colour) * SUN_I * 0.12;
    0.6 / key.max(1e-9) * (0.2 + 0.8 * day)
}

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
    pub width: u32,
    pub height: u32,
    pub sky: Sky,
    pub region: &'a Region,
    pub weather: &'a WeatherMap,
    pub settings: &'a Settings,
    pub frame_index: u32,
}

pub fn build(inp: &FrameInput<'_>) -> Result<FrameUniforms, RenderError> {
    let s = inp.settings;
    let p: MarchParams = s.march.effective();
    let sky = inp.sky;
    let r = inp.region;

    let mut layer_base = [0.0f32; 4];
    let mut layer_top = [0.0f32; 4];
    let mut layer_on = [0.0f32; 4];
    let (mut lo, mut hi) = (f32::MAX, f32::MIN);
    let bands = disjoint_bands(&inp.weather.bands, s.layers_on);
    for (k, band) in bands.iter().enumerate() {
        if let Some((base, top)) = *band {
            layer_base[k] = base;
            layer_top[k] = top;
            layer_on[k] = thickness_scale(top - base);
            lo = lo.min(base);
            hi = hi.max(top);
        }
    }
    if lo > hi {
        // No layer to draw: an empty shell far above everything.
        (lo, hi) = (1.0e6, 1.0e6);
    }
    layer_base[3] = lo;
    layer_top[3] = hi;
    layer_on[3] = s.coverage_mul;

    let mut flags = 0u32;
    let sc = p.shortcuts;
    if sc.empty_skip {
        flags |= FLAG_SKIP;
    }
    if sc.region_cull {
        flags |= FLAG_CULL;
    }
    if p.detail {
        flags |= FLAG_DETAIL;
    }
    if sc.jitter {
        flags |= FLAG_JITTER;
    }
    if sc.light_lod {
        flags |= FLAG_LIGHT_LOD;
    }
    if sc.clear_stride {
        flags |= FLAG_STRIDE;
    }

    let (cam_up, cam_fwd, cam_right, cam_upv, noise_origin, exposure_base);
    match inp.view {
        View::Perspective(cam) => {
            cam.validate()?;
            let b = cam.basis();
            let tn = (cam.fov_deg.to_radians() * 0.5).tan();
            cam_up = v4(b.up, cam.alt_m);
            cam_fwd = v4(b.forward, tn);
            cam_right = v4(b.right, inp.width as f64 / inp.height as f64);
            cam_upv = v4(b.view_up, 0.0);
            // The camera's position modulo the noise period, in f64: noise stays put as it flies.
            let m = DVec3::new(
                b.position.x.rem_euclid(SHAPE_PERIOD_M),
                b.position.y.rem_euclid(SHAPE_PERIOD_M),
                b.position.z.rem_euclid(SHAPE_PERIOD_M),
            );
            noise_origin = v4(m, SHAPE_PERIOD_M);
            exposure_base = auto_exposure(&sky);
        }
        View::TopDown => {
            flags |= FLAG_NO_SKY;
            let (lat, lon) = r.centre();
            let up = crate::sun::up_at(lat, lon);
            cam_up = v4(up, hi as f64 + 1000.0);
            cam_fwd = v4(-up, 1.0);
            cam_right = v4(DVec3::X, 1.0);
            cam_upv = v4(DVec3::Y, 1.0);
            noise_origin = [0.0, 0.0, 0.0, SHAPE_PERIOD_M as f32];
            exposure_base = 1.0;
        }
    }
    let sun_key = sky.sun_elevation_deg > -0.5;
    let light = |l: &Light, w: f64| v4(l.dir, w);
    let col = |l: &Light, w: f64| {
        [
            l.colour[0] as f32,
            l.colour[1] as f32,
            l.colour[2] as f32,
            w as f32,
        ]
    };
    let visibility = s.visibility_m.max(100.0);

    Ok(FrameUniforms {
        cam_up,
        cam_fwd,
        cam_right,
        cam_upv,
        noise_origin,
        sun_dir: light(&sky.sun, if sun_key { 1.0 } else { 0.0 }),
        sun_col: col(&sky.sun, sky.moon_phase),
        moon_dir: light(&sky.moon, 0.0),
        moon_col: col(&sky.moon, 0.0),
        region: [
            r.south as f32,
            r.north as f32,
            r.west as f32,
            r.lon_span() as f32,
        ],
        region2: [
            hi + 1000.0,
            inp.weather.width as f32,
            inp.weather.height as f32,
            inp.weather.skip_m,
        ],
        layer_base,
        layer_top,
        layer_on,
        light: [s.density_mul, s.extinction, s.hg_g, s.beer_clamp],
        march: [
            p.step_min_m,
            p.step_growth,
            p.step_max_m,
            p.max_steps as f32,
        ],
        march2: [
            p.light_steps as f32,
            p.light_reach_m / (p.light_steps as f32 + 5.0),
            p.early_exit,
            flags as f32,
        ],
        misc: [
            DETAIL_PERIOD_M as f32,
            (exposure_base * 2f64.powf(s.exposure_ev)) as f32,
            (3.912 / visibility) as f32,
            1.0,
        ],
        size: [
            inp.width as f32,
            inp.height as f32,
            inp.frame_index as f32,
            (5.0 * visibility).min(2.0e6) as f32,
        ],
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
