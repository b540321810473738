// Shared by every Stratus GPU stage (prepended to each stage's source by the Rust side):
// the frame uniforms, the paper's remap/SAT, Henyey–Greenstein phase, numerically stable
// ray–shell geometry relative to the ray's own origin, the weather-map lookup and the sky.

const PI: f32 = 3.14159265;
const EARTH_R: f32 = 6371000.0;

// Sun intensity in the sky model's units.
const SUN_I: f32 = 20.0;
// How far the aerial-perspective table reaches along a view ray (m): the horizon from 12 km.
const AP_MAX_M: f32 = 400000.0;

// The per-frame uniforms: `render::frame::FrameUniforms` on the Rust side, field for field
// (render::contract's test compares names, offsets, sizes and types with naga).
struct Frame {
    cam_up: vec3<f32>,          // local up at the camera (ECEF unit vector)
    cam_alt_m: f32,             // camera altitude above sea level
    cam_fwd: vec3<f32>,         // view direction
    tan_half_fov: f32,          // tan(vertical field of view / 2)
    cam_right: vec3<f32>,
    aspect: f32,                // width / height
    cam_view_up: vec3<f32>,
    graze_from: f32,            // where a grazing pixel's extra rays start (march.wgsl `extra_ray`)
    noise_origin: vec3<f32>,    // camera ECEF modulo the shape-noise period (m)
    shape_period_m: f32,
    sun_dir: vec3<f32>,         // toward the Sun (ECEF)
    sun_is_key: u32,            // 1 when the Sun is the key light, 0 when the Moon is
    sun_col: vec3<f32>,         // Sun irradiance (linear RGB)
    detail_period_m: f32,       // detail-noise period
    moon_dir: vec3<f32>,
    exposure: f32,              // linear exposure multiplier
    moon_col: vec3<f32>,
    haze_beta: f32,             // sea-level haze extinction (1/m), 3.912 / visibility
    region_south: f32,          // the map's region (degrees)
    region_north: f32,
    region_west: f32,
    region_lon_span: f32,       // eastward span from region_west
    layer_base: vec3<f32>,      // base of the low, middle, high band (m), disjoint
    shell_base_m: f32,          // lowest base of a drawn layer
    layer_top: vec3<f32>,
    shell_top_m: f32,           // highest top of a drawn layer
    layer_scale: vec3<f32>,     // per layer: density scale, 0 when the layer is off
    coverage_mul: f32,
    density_mul: f32,
    extinction: f32,            // per unit of DESIGN's density d (1/m)
    hg_g: f32,                  // Henyey–Greenstein asymmetry
    beer_clamp: f32,            // eq. 22's ac
    step_min_m: f32,
    step_growth: f32,           // step growth per metre of distance
    step_max_m: f32,
    max_steps: u32,
    light_steps: u32,
    light_step0_m: f32,         // first light step
    early_exit: f32,            // transmittance below which a ray stops
    flags: u32,                 // FLAG_* bits
    out_size: vec2<f32>,        // march output width, height (px)
    frame_index: f32,
    haze_cutoff_m: f32,         // beyond this the haze hides everything (5 visibility lengths)
    tower_base_m: f32,          // the cumulonimbus towers' envelope (m); base > top when none
    skip_m: f32,                // empty-skip step length (one coarse cell)
    march_scale: f32,           // march pixels per target pixel (the window may march smaller)
    tower_top_m: f32,
    st_scale: vec2<f32>,        // map uv → structure-texture uv: uv * st_scale + st_offset
    st_offset: vec2<f32>,
    drift_low: vec3<f32>,       // per layer: the noise's drift with the wind (ECEF m, mod period)
    blend_w: f32,               // two steps blended: fraction of the interval elapsed
    drift_mid: vec3<f32>,
    blend_back_s: f32,          // seconds the earlier step is carried (sampled upwind)
    drift_high: vec3<f32>,
    blend_ahead_s: f32,         // seconds to the later step (sampled downwind)
    subset_offset: vec2<f32>,   // the pixel of each subset cell marched this frame (render::reproject)
    subset_n: f32,              // subset cell side (px): 1 marches every pixel
    sample_dx: f32,             // where in its pixel the march aims, x (render::reproject::still_sample_offset)
    streak_dir: vec4<f32>,      // mean wind direction (east, north): high in xy, middle in zw (streaks, anvils)
    region_origin: vec3<f32>,   // the region's centre at sea level (ECEF m): streaks and cumulus cells measured from it
    sample_dy: f32,             // … and y
    cell_drift: vec4<f32>,      // per layer, the drift (east, north m) mod the cells' tile: low xy, middle zw
    cell_drift_high: vec4<f32>, // the high layer's in xy
    region_east: vec3<f32>,     // east at the region's centre (unit ECEF): the cells' plane
    graze_apart: f32,           // how far a grazing pixel stands out to take more rays (march.wgsl)
    region_north_dir: vec3<f32>, // north there
    graze_column: f32,          // … and how much a column neighbour's own distance counts beside the bend
};

// The full-column light's volume (render::scene::ShadowParams): what the shadow stage made and
// how the stages that light or show the scene look it up (scene.wgsl).
struct ShadowParams {
    key_dir: vec3<f32>,         // toward the key light (Sun or Moon) the volume was made for
    bottom_m: f32,              // altitude of the volume's bottom and top faces (m)
    top_m: f32,
    enabled: u32,               // 0: no volume (the preset's switch is off); look-ups give 0
    steps: u32,                 // samples per path in the shadow stage
    max_path_m: f32,            // longest path toward the key light (m)
    ground_uv: vec4<f32>,       // region uv → ground texture uv: uv * xy + zw
    ground_top_m: f32,          // highest terrain in the map (m); the terrain march starts below it
    ground_on: u32,             // 0: no ground in the map (sea level, a plain albedo)
    terrain_on: u32,            // 0: the preset's terrain switch is off (sea-level sphere)
    aerial_on: u32,             // 0: the preset's aerial-perspective switch is off (no clear air)
    row0: u32,                  // the shadow stage makes rows [row0, row_end) of the volume
    row_end: u32,
    pad0: u32,
    pad1: u32,
};

// The exposure stage's settings (render::exposure::ExposureParams) and result.
struct ExposureParams {
    ev_mul: f32,                // 2^EV: the panel's or command line's offset
    rate: f32,                  // share of the way to the metered exposure taken this frame (1: all)
    auto_on: u32,               // 0: Frame.exposure is used as it is
    _pad: u32,
};
struct ExposureState {
    value: f32,                 // what the present stage multiplies by
    adapted: f32,               // the adapted exposure before the offset
    metered: f32,               // the log-mean luminance metered this frame
    _pad: f32,
};

// Frame.flags bits.
const FLAG_SKIP: u32 = 1u;     // empty-space skipping over the coarse map
const FLAG_CULL: u32 = 2u;     // no sampling outside the region / cloudless map
const FLAG_DETAIL: u32 = 4u;   // detail noise
const FLAG_JITTER: u32 = 8u;   // per-pixel jittered ray start
const FLAG_NO_SKY: u32 = 16u;  // the score's top-down view: nadir rays from cam_alt_m, black background, sun overhead
const FLAG_LIGHT_LOD: u32 = 32u;// fewer light steps once the view ray is mostly opaque
const FLAG_STRIDE: u32 = 64u;   // longer steps in clear air, back up on meeting cloud
const FLAG_STRUCTURE: u32 = 128u; // per-pixel base, top and genus (columns, not bands)
const FLAG_TOWERS: u32 = 256u;  // the map holds cumulonimbus towers
const FLAG_STREAKS: u32 = 512u; // the map holds cirrus-like genera, streaked along the wind
const FLAG_BLEND: u32 = 1024u;  // two forecast steps blended along the layer winds (render::blend)
const FLAG_CELLS: u32 = 2048u;  // the map holds cumulus: cells (render::cells)
const FLAG_FIXED_EXPOSURE: u32 = 4096u; // Frame.exposure is shown as it is (no adaptation)
const FLAG_GRAZE: u32 = 8192u;   // grazing pixels that differ from a neighbour take four more rays
const FLAG_ENVELOPE: u32 = 16384u; // the map holds Cu or Cb: short steps in a cloudy layer's envelope

// The paper's R(v, lo, ho, ln, hn) and SAT.
fn remap(v: f32, lo: f32, ho: f32, ln: f32, hn: f32) -> f32 {
    return ln + (v - lo) * (hn - ln) / max(ho - lo, 1e-6);
}
fn sat(v: f32) -> f32 {
    return clamp(v, 0.0, 1.0);
}

fn hg(cos_t: f32, g: f32) -> f32 {
    let g2 = g * g;
    return (1.0 - g2) / (4.0 * PI * pow(max(1.0 + g2 - 2.0 * g * cos_t, 1e-4), 1.5));
}

// Dual-lobe phase (DESIGN §3): mix(HG(-g), HG(g), 0.7).
fn phase(cos_t: f32, g: f32) -> f32 {
    return mix(hg(cos_t, -g), hg(cos_t, g), 0.7);
}

// Ray from a point at altitude h (m) with local up `up` in direction d (unit). Distances t
// where it crosses the sphere of altitude a: t² + 2 t (R+h) μ + (h − a)(2R + h + a) = 0.
// Everything is relative to the ray's origin, and the smaller root is taken as c/q, so there is
// no cancellation of two 6.4e6 m numbers. Returns (t_near, t_far); t_far < t_near when missed.
fn shell_hits(h: f32, mu: f32, a: f32) -> vec2<f32> {
    let b = (EARTH_R + h) * mu;
    let c = (h - a) * (2.0 * EARTH_R + h + a);
    let disc = b * b - c;
    if (disc < 0.0) {
        return vec2<f32>(1.0, -1.0);
    }
    let s = sqrt(disc);
    let q = -b - select(s, -s, b < 0.0);
    // q has the sign of -b and magnitude |b| + s; c/q is the other root.
    var t0 = q;
    var t1 = q;
    if (abs(q) > 1e-12) {
        t1 = c / q;
    }
    return vec2<f32>(min(t0, t1), max(t0, t1));
}

// Altitude of origin + t·d, stable for small t (no |x| − R of two huge numbers).
fn altitude_at(h: f32, mu: f32, t: f32) -> f32 {
    let rh = EARTH_R + h;
    let num = t * (2.0 * rh * mu + t);
    let r2 = rh * rh + num;
    return h + num / (sqrt(max(r2, 0.0)) + rh);
}

// Latitude/longitude (degrees) of the ECEF direction n.
fn lat_lon(n: vec3<f32>) -> vec2<f32> {
    let ln = normalize(n);
    return vec2<f32>(degrees(asin(clamp(ln.z, -1.0, 1.0))), degrees(atan2(ln.y, ln.x)));
}

fn luminance(c: vec3<f32>) -> f32 {
    return dot(c, vec3<f32>(0.2126, 0.7152, 0.0722));
}

// Elevation of the horizon seen from altitude h (radians, ≤ 0).
fn horizon_elev(h: f32) -> f32 {
    return -acos(clamp(EARTH_R / (EARTH_R + max(h, 0.0)), -1.0, 1.0));
}

// The jitter resolve's 3×3 weights (centre, edge, corner) for a march whose step grows by
// `growth` per metre of distance. The grain the jitter leaves scales with the step: `fast`'s
// (2 % of the distance) needs the full 3×3 mean; from `balanced`'s 1 % down, a centre-weighted
// kernel (2, 1, ¼) leaves less grain than a mean costs in blur (docs/footprint.md, "The
// resolve follows the step").
fn resolve_weights(growth: f32) -> vec3<f32> {
    let t = clamp((0.02 - growth) / 0.01, 0.0, 1.0);
    return mix(vec3<f32>(1.0), vec3<f32>(2.0, 1.0, 0.25), t);
}

// The weight of the neighbour (i, j) ∈ [−1, 1]² under `resolve_weights`' w.
fn resolve_weight(w: vec3<f32>, i: i32, j: i32) -> f32 {
    return select(select(w.z, w.y, i == 0 || j == 0), w.x, i == 0 && j == 0);
}

// Narkowicz's fitted ACES curve: the present stage's tone curve.
fn aces(x: vec3<f32>) -> vec3<f32> {
    return clamp((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), vec3<f32>(0.0), vec3<f32>(1.0));
}

// The curve's inverse on 0..0.999 (the root of its quadratic that is 0 at 0).
fn aces_inverse(y: vec3<f32>) -> vec3<f32> {
    let v = clamp(y, vec3<f32>(0.0), vec3<f32>(0.999));
    let a = 2.43 * v - 2.51;
    let b = 0.59 * v - 0.03;
    let c = 0.14 * v;
    return (-b - sqrt(max(b * b - 4.0 * a * c, vec3<f32>(0.0)))) / (2.0 * a);
}
