// Cloud density, shared by the stages that evaluate the march's cloud (prepended after
// common.wgsl and frame.wgsl, which binds the frame): the device's other bindings and the
// map's (groups 0 and 1, render::march's table), the weather lookup, the paper's layer density
// (DESIGN §2) and the genus columns (DESIGN §7).
@group(0) @binding(1) var shape_tex: texture_3d<f32>;    // shape noise statistics (mean, variance), mipped
@group(0) @binding(2) var detail_tex: texture_3d<f32>;   // detail noise statistics, mipped
@group(0) @binding(3) var clamp_lin: sampler;
@group(0) @binding(4) var repeat_lin: sampler;
@group(0) @binding(5) var<storage, read_write> counters: array<atomic<u32>, N_COUNTERS>;
@group(0) @binding(6) var profiles: texture_2d<f32>;     // per genus row: (P, D) by height fraction
@group(0) @binding(7) var cells: texture_2d<f32>;        // cumulus cells (render::cells): rank, height
@group(1) @binding(0) var weather: texture_2d<f32>;      // R low, G middle, B high, A total
@group(1) @binding(1) var coarse: texture_2d<f32>;       // max total cover per cell, dilated
// The map's structure (render::structure): R/G/B low/middle/high, A the convective cloud.
@group(1) @binding(2) var st_base: texture_2d<f32>;      // cloud base, m
@group(1) @binding(3) var st_top: texture_2d<f32>;       // cloud top, m
@group(1) @binding(4) var st_kind: texture_2d<f32>;      // genus code, nearest texel
@group(1) @binding(5) var st_wind: texture_2d<f32>;      // (u, v) high in RG, middle in BA, m/s
// Two steps blended (render::blend): the later step's coverage, and per layer (three blocks
// side by side on the motion's working grid) the guarded motion over the interval, (east,
// south) in map uv.
@group(1) @binding(6) var weather_next: texture_2d<f32>;
@group(1) @binding(7) var blend_motion: texture_2d<f32>;

// Genus codes (stratus_ingest::weather::CloudType) and the profile table's rows.
const T_CIRRUS: f32 = 1.0;
const T_CIRROSTRATUS: f32 = 3.0;
const T_CUMULUS: f32 = 9.0;
const T_CUMULONIMBUS: f32 = 10.0;
const PROFILE_ROWS: f32 = 11.0;
const PROFILE_WIDTH: f32 = 64.0;
// The column thickness a layer's density is normalised to (render::frame::REFERENCE_THICKNESS_M).
const REFERENCE_THICKNESS_M: f32 = 2000.0;
// Cirrus: the noise squeezed this many times along the wind, and shifted this far downwind
// from the column's base to its top (m).
const STREAK_STRETCH: f32 = 8.0;
const STREAK_SHEAR_M: f32 = 3000.0;
// Breaking the streaks' period (issue 30). The noise tile repeats every 24 km / the genus'
// frequency, and squeezed along the wind its repeats line up across the streaks as evenly
// spaced parallel bands (a washboard). Two things break it: (1) the streaked position is turned
// by a fixed, generic rotation (STREAK_ROT: axis (0.42, 0.71, 0.57), 0.83 rad) before the noise
// is read, so no axis of the tile, whose repeats are along its axes, lies across the streaks of
// any region (a region at 0° or 90° of longitude had the tile's own axis along the parallels);
// (2) the coordinate across the streaks is warped by two slow waves of incommensurate lengths
// (STREAK_WARP_L_M), their phases bent along the wind, so the spacing of successive streaks
// varies by up to ±35 % (the waves' amplitude over length, 0.22 + 0.13: it never folds). Both keep the noise's values and
// their distribution (a rotation and a shift): the layer's coverage is unchanged.
const STREAK_ROT: mat3x3<f32> = mat3x3<f32>(
    vec3<f32>(0.7319, 0.5159, -0.4451),
    vec3<f32>(-0.3231, 0.8379, 0.4400),
    vec3<f32>(0.5999, -0.1782, 0.7799),
);
const STREAK_WARP_L_M: vec2<f32> = vec2<f32>(9100.0, 23700.0);
const STREAK_WARP_A_M: vec2<f32> = vec2<f32>(2000.0, 3000.0);
// Cumulonimbus towers: their grid spacing and a trunk's radius at full coverage (km).
const TOWER_SPACING_KM: f32 = 40.0;
const TOWER_RADIUS_KM: f32 = 7.0;
// Cumulus cells: the field's period on the ground (render::cells::PERIOD_M, m); how sharp a
// cell's surface is (the noise moves it by up to 1/CELL_EDGE of the cell's size, every way); the
// density inside a cell; the billows' noise, this many times finer than the shape period
// (an integer, as Shape::freq: about 750 m lumps); the noise's level on the surface, set so
// that the mean top-down opacity equals the coverage (`examples/coverage_ramp.rs`); the least
// height of a cell (m).
const CELL_PERIOD_M: f32 = 48000.0;
const CELL_EDGE: f32 = 1.6;
const CELL_DENSITY: f32 = 1.5;
const CELL_FREQ: f32 = 8.0;
const CELL_MID: f32 = 0.8;
const CELL_MIN_M: f32 = 1000.0;
// The cells' spacing on the ground (render::cells: 24 cells over the 48 km tile). Where a
// sample's footprint is half of it the cells start fading into their mean (a uniform slab whose
// opacity straight down is the coverage, cumulus_slab), and at the whole spacing they are gone:
// two footprints a cell, the most a pixel can draw (issue 30).
const CELL_SPACING_M: f32 = 2000.0;
// The anvil's shield (GFS's high cover over deep convection) fills the column from this height
// fraction up: a flat sheet under the top that the towers rise into.
const ANVIL_FROM: f32 = 0.72;
// How far downwind a tower's top (and its anvil's centre) is carried from its trunk's foot, in
// tower spacings (0.35: 14 km, a 10-30 m/s upper wind over the cell's half-hour of growth).
const ANVIL_SHEAR: f32 = 0.35;
// A tower's trunk keeps the cloud's own density (as a cumulus cell), not one normalised to its
// column: a cumulonimbus holds several times a stratus deck's water (1-3 against 0.1-0.5 g/m3)
// and seen from the side it is a solid wall; its top-down opacity is its anvil's anyway.
const TRUNK_DENSITY: f32 = 1.5;

// Work counters: indices into `counters`, the fields of render::march::Counters in order.
const C_RAYS: u32 = 0u;
const C_STEPS: u32 = 1u;
const C_DENSITY: u32 = 2u;
const C_DETAIL: u32 = 3u;
const C_LIGHT: u32 = 4u;
const C_OUTSIDE: u32 = 5u;
const C_SKIPPED: u32 = 6u;
const C_EARLY: u32 = 7u;
// Rays whose march the driver stopped before it ended: Mesa's llvmpipe caps the loop iterations
// of one shader invocation (65 535, all loops together), which only `reference` reaches.
const C_CUT: u32 = 8u;
// Pixels the march's second dispatch took more rays for (march.wgsl `rework`).
const C_REWORK: u32 = 9u;
const N_COUNTERS: u32 = 10u;

var<private> local_count: array<u32, N_COUNTERS>;

// Set by the shadow stage's pipeline: the density is the noise's expectation, not one sample of
// it, so the full-column light is smooth by construction (carve below).
override MEAN_DENSITY: bool = false;
// Set by every cloud stage's pipeline (march, shadow, section: render::pipeline::StagePipelines,
// one per Variant): the frame's features (FEATURE_BITS of its flags) as constants, so the code
// of a feature the frame does not use is compiled out: a CPU driver runs both sides of every
// branch, and pays for a branch no lane takes (the two-step blend's nine look-ups and the
// bands' carve cost more than half of a structured map's march on lavapipe). A stage compiled
// with FIXED_FEATURES off would read the flags at run time.
override FIXED_FEATURES: bool = false;
override FEATURES: u32 = 0u;

fn feature(bit: u32) -> bool {
    if (FIXED_FEATURES) {
        return (FEATURES & bit) != 0u;
    }
    return has_flag(bit);
}

struct Sample {
    cm: vec3<f32>,   // coverage per layer
    inside: bool,    // inside the region
};

// The guarded motion of layer j over the interval at map uv (render::blend: three blocks of
// the motion grid side by side, the lookup kept inside its layer's block), in uv.
fn blend_motion_at(uv: vec2<f32>, j: i32) -> vec2<f32> {
    let half_texel = 0.5 / f32(textureDimensions(blend_motion).x);
    let bx = clamp(uv.x, 3.0 * half_texel, 1.0 - 3.0 * half_texel);
    let p = vec2<f32>((bx + f32(j)) / 3.0, clamp(uv.y, 0.0, 1.0));
    return textureSampleLevel(blend_motion, clamp_lin, p, 0.0).xy;
}

// Coverage between two steps (DESIGN §9, issue 31) as series::motion::blend makes it: per
// layer the guarded motion m, read where the feature passing here lands in the later step (two
// fixed-point steps), moves the lookups — the earlier step at uv − w·m, the later at
// uv + (1 − w)·m — then (1 − w)·a + w·b. Off layers are not looked up.
fn blended_cover(uv: vec2<f32>) -> vec3<f32> {
    let w = f.blend_w;
    var cm = vec3<f32>(0.0);
    for (var j = 0; j < 3; j++) {
        if (f.layer_scale[j] > 0.0) {
            var m = blend_motion_at(uv, j);
            m = blend_motion_at(uv + (1.0 - w) * m, j);
            m = blend_motion_at(uv + (1.0 - w) * m, j);
            let a = textureSampleLevel(weather, clamp_lin, uv - w * m, 0.0)[j];
            let b = textureSampleLevel(weather_next, clamp_lin, uv + (1.0 - w) * m, 0.0)[j];
            cm[j] = mix(a, b, w);
        }
    }
    return cm;
}

fn weather_at(uv: vec2<f32>) -> Sample {
    var s: Sample;
    s.inside = uv.x >= 0.0;
    s.cm = vec3<f32>(0.0);
    if (s.inside) {
        var c: vec3<f32>;
        if (feature(FLAG_BLEND)) {
            c = blended_cover(uv);
        } else {
            c = textureSampleLevel(weather, clamp_lin, uv, 0.0).rgb;
        }
        // Layers that are off are never looked up (density_uv picks a drawn layer).
        s.cm = clamp(c * f.coverage_mul, vec3<f32>(0.0), vec3<f32>(1.0));
    }
    return s;
}

// Layer k's noise position: np moved with the layer's wind since the series' reference time
// (zero for a plain map), so clouds drift between steps instead of standing still.
fn drifted(np: vec3<f32>, k: i32) -> vec3<f32> {
    return np - select(select(f.drift_high, f.drift_mid, k == 1), f.drift_low, k == 0);
}

// True when the coarse map says nothing is within a cell of this point.
fn coarse_empty(uv: vec2<f32>) -> bool {
    if (uv.x < 0.0) {
        return true;
    }
    let dims = vec2<f32>(textureDimensions(coarse));
    let c = min(vec2<i32>(uv * dims), vec2<i32>(dims) - 1);
    return textureLoad(coarse, c, 0).r <= 0.0;
}

// Footprint-aware sampling (issue 30). The width (m) of what the current sample stands for:
// the view ray's cone there (pixel angle × distance; a map pixel for the score's nadir rays)
// or two of the march's steps, whichever is longer,
// set by the march before each density look-up and kept for that sample's light samples; 0
// (a point) in the stages that set nothing (section, shadow).
var<private> footprint_m: f32;
// The cone's part of it alone (m), without the step: what the pixel covers across the ray.
// Patterns Stratus places itself, coarser than the noise (the towers), fade by this: a long
// step in `fast`'s far field would otherwise flatten a cumulonimbus 70 km away into its mean.
var<private> cone_m: f32;
// How many times faster than the world the noise is read where the current sample is (a
// warped streak's compression across the wind, streaked): its level of detail is that much
// coarser. 1 everywhere else; column_density sets it for its one carve and puts it back.
var<private> footprint_scale: f32 = 1.0;
// The altitude span (m) of the march step the current view sample stands for, or of the light
// step for a light sample; 0 (a point) in the stages that set nothing. The mean slabs
// (cumulus_slab, anvil_slab) are averaged over it: a far step of 1-1.5 km is longer than a
// slab is thick, and one point of the slab's profile in it stood for the whole step.
var<private> step_dz: f32 = 0.0;
// What the last density look-up found of the map where it stood, for the march's stride.
struct LastSample {
    // The coverage of the column (or band) it stood in, 0 outside every one: the march strides
    // through clear air only where cloud is sparse (march.wgsl).
    cover: f32,
    // Each layer's coverage there (0 outside the shells): the stride's test for layers ahead
    // (envelope_overlaps).
    cm: vec3<f32>,
};
var<private> last_sample: LastSample = LastSample(0.0, vec3<f32>(0.0));
// Texels per side of the shape and detail noise (render::noise::SHAPE_SIZE, DETAIL_SIZE).
const SHAPE_TEXELS: f32 = 128.0;
const DETAIL_TEXELS: f32 = 32.0;
// The detail FBM's mean (render::noise::DETAIL_MEAN).
const DETAIL_MEAN: f32 = 0.486;

// The mip level whose texel is the footprint's width, for a noise of `texel_m` metres a texel:
// detail finer than about two footprints is averaged away, not point-sampled. The sampler's
// mip filter is nearest, so a sample reads the one level nearest its footprint: a CPU driver
// reading two levels a sample paid 8–13 % of a frame over terrain for the blend, which moved
// no view's error against its 4×4 twin by more than 0.0003 (docs/footprint.md, "One mip
// level a sample"). Tried: a level drawn at random between the two (its noise showed,
// above-noon 0.0042 → 0.0080), the coarser of the two (the picture blurred), the blend for
// near samples only (slower than either: two read sites).
fn footprint_lod(texel_m: f32) -> f32 {
    return log2(max(footprint_m * footprint_scale / texel_m, 1.0));
}

// Carve the noise: what survives the threshold `lo` (after scaling the noise by `ns_scale`; the
// shape noise `freq` times finer than its period), eroded by detail noise at the edges, times
// the density profile gd (DESIGN §2 eqs 15–18). Both noises are read at the mip level of the
// sample's footprint (render::noise: each level the mean of the carved noise value over the
// texels it covers), so a far sample takes the noise averaged over what its pixel covers, the
// same value from one frame to the next, instead of one point of detail finer than the pixel.
// Only the mean is read: carving over the noise's spread in the footprint as well (its
// variance and bounds are in the same texels) made the far field denser than its
// supersampled picture (docs/footprint.md).
fn carve(np: vec3<f32>, ns_scale: f32, lo: f32, gd: f32, cm: f32, ph: f32, detail: bool, freq: f32) -> f32 {
    if (MEAN_DENSITY) {
        return mean_carve(ns_scale, lo) * gd;
    }
    let shape_texel = f.shape_period_m / (SHAPE_TEXELS * freq);
    let sn = textureSampleLevel(shape_tex, repeat_lin, np * freq / f.shape_period_m, footprint_lod(shape_texel)).r;
    let ns = sat(remap(sn * ns_scale, lo, 1.0, 0.0, 1.0));
    if (ns <= 0.0) {
        return 0.0;
    }
    var nd_mod = 0.0;
    if (detail) {
        local_count[C_DETAIL] += 1u;
        let dl = footprint_lod(f.detail_period_m / DETAIL_TEXELS);
        let nd_fbm = textureSampleLevel(detail_tex, repeat_lin, np / f.detail_period_m, dl).r;
        nd_mod = 0.35 * exp(-0.75 * cm) * mix(nd_fbm, 1.0 - nd_fbm, sat(5.0 * ph));
    } else if (!feature(FLAG_DETAIL)) {
        // A preset without detail still erodes the edge by the detail's mean, which is what a
        // far sample of `balanced` reads too: else `fast` drew every edge further out, and its
        // top-down opacity crossed 0.5 at coverage 0.475 where the other presets' does at 0.5
        // (a broken field's blocks scored as cloud a block early; issue 30's random Dice cases).
        // The light samples of a preset with detail keep leaving it out, as before.
        nd_mod = 0.35 * exp(-0.75 * cm) * mix(DETAIL_MEAN, 1.0 - DETAIL_MEAN, sat(5.0 * ph));
    }
    return sat(remap(ns, nd_mod, 1.0, 0.0, 1.0)) * gd;
}

// The expectation of carve's sat(remap(n·s, lo, 1, 0, 1)) over a noise value n uniform in 0..1
// (detail erosion left out): (1/s)·∫ sat((x − lo)/(1 − lo)) dx over x in 0..s, for s ≤ 1.
fn mean_carve(s: f32, lo: f32) -> f32 {
    let a = max(lo, 0.0);
    if (s <= a || s <= 0.0) {
        return 0.0;
    }
    let span = max(1.0 - lo, 1e-4);
    let m = min(s, 1.0);
    return ((m - lo) * (m - lo) - (a - lo) * (a - lo)) / (2.0 * span * s);
}

// How a column is carved (carve's arguments besides the point): the noise's scale, the
// threshold, the density profile gd (0: nothing there, carve skipped) and the shape noise's
// frequency. Each shape below gives one, and the caller carves once: on a CPU driver, which
// runs every call site for every lane, a carve per shape would be a noise look-up per shape on
// every sample.
struct Carving {
    ns_scale: f32,
    lo: f32,
    gd: f32,
    freq: f32,
};

// DESIGN §2, eqs 5–18, for one layer band: coverage cm, height fraction ph.
fn layer_carving(cm: f32, ph: f32) -> Carving {
    let gs = sat(remap(ph, 0.0, 0.07, 0.0, 1.0)) * sat(remap(ph, 0.2 * cm, cm, 1.0, 0.0));
    let gd = ph * sat(remap(ph, 0.0, 0.15, 0.0, 1.0)) * sat(remap(ph, 0.9, 1.0, 1.0, 0.0)) * cm * 2.0;
    return Carving(gs, 1.0 - cm, select(gd, 0.0, gs <= 0.0), 1.0);
}

// DESIGN §7, one column of a genus: the threshold 1 − cm·P(h) from the genus' profile row, so
// the base is solid and flat and only the noise's peaks reach the top.
fn genus_carving(cm: f32, ph: f32, code: f32) -> Carving {
    let x = (ph * (PROFILE_WIDTH - 1.0) + 0.5) / PROFILE_WIDTH;
    let pd = textureSampleLevel(profiles, clamp_lin, vec2<f32>(x, (code + 0.5) / PROFILE_ROWS), 0.0);
    let gd = pd.g * cm * 2.0;
    // The threshold sees coverage^γ (render::profile::Shape::gamma): opacity follows coverage.
    // A is the genus' cell frequency: an integer, so the camera-relative noise position still
    // wraps by whole periods.
    return Carving(1.0, 1.0 - pow(cm, pd.b) * pd.r, select(gd, 0.0, pd.r <= 0.0), pd.a);
}

fn carve_with(np: vec3<f32>, c: Carving, cm: f32, ph: f32, detail: bool) -> f32 {
    if (c.gd <= 0.0) {
        return 0.0;
    }
    return carve(np, c.ns_scale, c.lo, c.gd, cm, ph, detail, c.freq);
}

// A hash of a 2D cell, three values in 0..1.
fn hash3(c: vec2<i32>) -> vec3<f32> {
    var x = u32(c.x) * 73856093u ^ u32(c.y) * 19349663u;
    x = (x ^ (x >> 16u)) * 0x45d9f3bu;
    let y = (x ^ (x >> 15u)) * 0x2c1b3c6du;
    let z = (y ^ (y >> 12u)) * 0x297a2d39u;
    return vec3<f32>(f32(x & 0xffffu), f32(y & 0xffffu), f32(z & 0xffffu)) / 65535.0;
}

// Cumulonimbus towers (DESIGN §7): a deep convective column is not a field of noise but a few
// towers, each a trunk from the base to the forecast's convective top that spreads into an anvil
// under it. Towers stand on a jittered grid TOWER_SPACING_KM apart (at most one a cell, the
// nearest four cells looked at so anvils are not clipped at cell edges); a trunk's radius grows
// with the coverage of the layers it spans. Returned as a coverage, 1 inside a trunk falling to
// 0 half a radius outside it, that the genus' one noise carve then shapes (the tower's edge is
// the noise's billows, as every genus' is): no noise of its own, which a CPU driver would pay
// for on every sample of every map (it runs both sides of a branch).
fn tower_cover(uv: vec2<f32>, ph: f32, body_cm: f32) -> f32 {
    if (body_cm <= 0.0) {
        return 0.0;
    }
    // The grid is fixed to the Earth (degrees from the prime meridian and the equator), so two
    // maps of different regions put a place's towers in the same spots.
    let lat = f.region_north - uv.y * (f.region_north - f.region_south);
    let lon = f.region_west + uv.x * f.region_lon_span;
    // The tower leans downwind over its upper part and its anvil is carried off with the wind at
    // the top (f.streak_dir.xy, the high layer's one direction): a mushroom only where the upper
    // air is calm. (Begun at the anvil's own height, the trunk rose straight through it.)
    let g = vec2<f32>(lon * cos(radians(lat)), lat) * (111.2 / TOWER_SPACING_KM)
        - f.streak_dir.xy * (ANVIL_SHEAR * smoothstep(0.6, 1.0, ph));
    // The trunk widens a little with height, then the anvil spreads over the top fifth.
    let widen = (0.8 + 0.2 * ph) * (1.0 + 2.0 * smoothstep(0.78, 0.95, ph));
    let r_base = TOWER_RADIUS_KM / TOWER_SPACING_KM * sqrt(body_cm);
    let o = vec2<i32>(floor(g - 0.5));
    var t = -1.0;
    for (var j = 0; j < 4; j++) {
        let cell = o + vec2<i32>(j & 1, j >> 1u);
        let hs = hash3(cell);
        let d = length(g - (vec2<f32>(cell) + 0.2 + 0.6 * hs.xy));
        t = max(t, 1.0 - d / (r_base * (0.6 + 0.8 * hs.z) * widen));
    }
    // Where a trunk is narrower than two footprints it fades into its mean (issue 30): the share
    // of the ground the trunks cover, π (r·widen)² × E[(0.6 + 0.8 z)²] = 1.053 a tower cell.
    // Seen from afar (the score's nadir rays, a map pixel wide) a trunk is not an opaque point
    // wherever a ray happens to hit one, but what the convective cloud covers.
    let r_w = r_base * widen;
    let mean = min(3.14159 * r_w * r_w * 1.053, 1.0);
    let trunk_m = 2.0 * r_w * TOWER_SPACING_KM * 1000.0;
    let fade = smoothstep(0.5, 1.0, footprint_m * footprint_scale / trunk_m);
    return mix(sat(0.5 + 2.0 * t), mean, fade);
}

// A cheap hash of a 200 m cell of noise space, in 0..1.
fn cell_hash(np: vec3<f32>) -> f32 {
    let c = vec3<u32>(vec3<i32>(floor(np / 200.0)));
    var x = c.x * 73856093u ^ c.y * 19349663u ^ c.z * 83492791u;
    x = (x ^ (x >> 16u)) * 0x45d9f3bu;
    x = x ^ (x >> 16u);
    return f32(x & 0xffffu) / 65535.0;
}

// Streaked noise position of a point at map uv and altitude h, in a column of height fraction
// ph: the point's ECEF position measured from the region's centre (from uv, good to a metre,
// which the noise's kilometre features never show), squeezed STREAK_STRETCH times along `dir`
// (a unit east/north direction, f.streak_dir: one for the whole region) and shifted downwind
// with height (fall streaks trail). From a fixed centre, not the camera-relative noise
// position: that one wraps by a whole period as the camera flies, and a squeezed coordinate
// would jump there; and not from the point itself, whose position is radial, with no
// component along its wind to squeeze. One direction for the region: far from the centre the
// squeezed coordinate moves by distance × the direction's change, so a direction varying from
// column to column (or in time) would scramble the pattern. Warped across the wind
// (STREAK_WARP_*), and sets footprint_scale to the warp's compression there.
fn streaked(uv: vec2<f32>, h: f32, ph: f32, dir: vec2<f32>) -> vec3<f32> {
    let lat = radians(f.region_north - uv.y * (f.region_north - f.region_south));
    let lon = radians(f.region_west + uv.x * f.region_lon_span);
    let east = vec3<f32>(-sin(lon), cos(lon), 0.0);
    let north = vec3<f32>(-sin(lat) * cos(lon), -sin(lat) * sin(lon), cos(lat));
    let up = vec3<f32>(cos(lat) * cos(lon), cos(lat) * sin(lon), sin(lat));
    let d = dir.x * east + dir.y * north;
    let p = up * (EARTH_R + h) - f.region_origin;
    let q = p - d * (dot(p, d) * (1.0 - 1.0 / STREAK_STRETCH) - ph * STREAK_SHEAR_M);
    // The across-streak warp (STREAK_WARP_*): a shift across the wind that varies slowly across
    // it (spacing) and, through its phase, along it (the streaks bend a little).
    let across = normalize(cross(up, d));
    let x = dot(p, across);
    let a = dot(p, d);
    let ph1 = x / STREAK_WARP_L_M.x + 1.3 * sin(a / 61000.0);
    let ph2 = x / STREAK_WARP_L_M.y + 2.1 + 0.9 * sin(a / 97000.0 + 1.7);
    let w = STREAK_WARP_A_M.x * sin(ph1) + STREAK_WARP_A_M.y * sin(ph2);
    // The warp's slope across the wind: the noise is read 1 + slope times as fast there.
    let slope = STREAK_WARP_A_M.x / STREAK_WARP_L_M.x * cos(ph1) + STREAK_WARP_A_M.y / STREAK_WARP_L_M.y * cos(ph2);
    footprint_scale = max(1.0 + slope, 1.0);
    return q + across * w;
}

// Where map uv is on the plane tangent to the sea-level sphere at the region's centre (m, east
// and north of it): a flat frame for the cumulus cells, fixed to the Earth, square to a few
// per cent over a region tens of degrees across.
fn ground_xy(uv: vec2<f32>) -> vec2<f32> {
    let lat = radians(f.region_north - uv.y * (f.region_north - f.region_south));
    let lon = radians(f.region_west + uv.x * f.region_lon_span);
    let up = vec3<f32>(cos(lat) * cos(lon), cos(lat) * sin(lon), sin(lat));
    let p = up * EARTH_R - f.region_origin;
    return vec2<f32>(dot(p, f.region_east), dot(p, f.region_north_dir));
}

// A cumulus column (DESIGN §7): inside a cell of the field (render::cells) a dome on the
// column's flat base, ρ² + z³ < 1 (steeper sides than an ellipsoid's, so no wide skirt), as
// wide as the cell and as tall as the cell's own height; between the cells clear air. A
// fraction cm of the ground lies inside cells, so a broken field seen from above shows the
// ground between its clouds. The noise moves the dome's surface in and
// out (billows, lumpy outlines), and only that: where the cells stand is the field's, the same
// at every height.
// k: the layer, whose drift (f.cell_drift, east/north modulo the tile) moves the cells.
fn cumulus_carving(uv: vec2<f32>, k: i32, cm: f32, ph: f32, thick: f32) -> Carving {
    let drift = select(select(f.cell_drift_high.xy, f.cell_drift.zw, k == 1), f.cell_drift.xy, k == 0);
    let c = textureSampleLevel(cells, repeat_lin, (ground_xy(uv) - drift) / CELL_PERIOD_M, 0.0);
    // The field's rank is the area nearer the core, so 1 − (rank over the threshold, per
    // coverage) grows as the squared distance from the core: rho is about that distance over
    // the cell's radius (past 1 between cells).
    let rho2 = 1.0 - (c.r - (1.0 - cm)) / max(cm, 0.05);
    // The cell's height (m): its own share of the column, at least CELL_MIN_M (a shallower
    // dome is thinner than a fast march's stride, which then draws a field at a fraction of its
    // coverage), lower where the cells are small (scattered: their width goes as √cm).
    let tall = min(max(0.9 * c.g * thick, CELL_MIN_M), 0.9 * thick) * min(sqrt(cm / 0.4), 1.0);
    let z = ph * thick / max(tall, 50.0);
    // Distance inside the dome's surface, in the dome's own units (0 on it, 1 at its core).
    let inside = 1.0 - sqrt(max(rho2, 0.0) + z * z * z);
    // Solid from the base (60 % at once), the billows' relief on the surface.
    let gd = CELL_DENSITY * (0.6 + 0.4 * sat(2.0 * ph));
    let outside = inside * CELL_EDGE < CELL_MID - 1.0;
    cell_tall_m = tall;
    return Carving(1.0, CELL_MID - inside * CELL_EDGE, select(gd, 0.0, outside), CELL_FREQ);
}

// The height (m) of the cell cumulus_carving last looked at.
var<private> cell_tall_m: f32;

// A cumulus field seen from farther than its cells can be drawn (issue 30): their mean, a
// slab from the column's base up to the cell's height whose optical depth straight down,
// −ln(1 − cm), lets through what a fraction cm of opaque cells does, so a pixel over many cells
// is as opaque as the field's coverage (the cells are calibrated to that mean:
// examples/coverage_ramp.rs), the same value from one frame to the next. Density (the carve's
// units, before the column's scale).
fn cumulus_slab(cm: f32, ph: f32, thick: f32) -> f32 {
    let tall = max(cell_tall_m, 50.0);
    let tau = -log(max(1.0 - cm, 0.02));
    // A raised cosine over the cells' height, its integral the height: smooth at both ends, so
    // a march step that crosses the slab's top or bottom does not add or lose optical depth (a
    // flat slab with hard ends was drawn up to a step too deep: the field's edge a block wide).
    return tau / (f.extinction * tall) * raised_cosine_mean(ph * thick / tall, step_dz / tall);
}

// The mean of the raised cosine 1 − cos(2πu) on 0 ≤ u ≤ 1 (0 outside) over the window of width
// w (the profile's units) centred on u: its integral, u − sin(2πu)/2π between the window's
// clamped ends, over w. For w → 0 the profile's value at u. Samples a window apart then add up
// to the slab's whole optical depth wherever they fall, however thin the slab is against the
// step: a far march took one point of a slab thinner than its step, its optical depth then
// following where the point fell (grain over a faded cumulus field at 250 km).
fn raised_cosine_mean(u: f32, w: f32) -> f32 {
    if (w < 1e-3) {
        return select(1.0 - cos(6.2831853 * u), 0.0, u < 0.0 || u > 1.0);
    }
    let a = clamp(u - 0.5 * w, 0.0, 1.0);
    let b = clamp(u + 0.5 * w, 0.0, 1.0);
    return ((b - a) - (sin(6.2831853 * b) - sin(6.2831853 * a)) / 6.2831853) / w;
}

// Where a view ray's cone is 1.5 km wide or more a cumulonimbus cluster is drawn as its mean:
// straight down from a map pixel (the score's rays, 6-14 km on the random draws' 2.5° maps) a
// tower's trunk or anvil filled a 4×4 block of pixels or missed it, and the block's opacity
// followed where the towers happen to stand, not the forecast's coverage; the towers' places
// are Stratus' own, finer than any GFS grid. A switch, not a blend: blended as densities, the
// towers' opaque cores stayed opaque under the slab and a half-faded field came out more
// opaque than its coverage (0.53 at coverage 0.375, 5.5 km rays). From 1.5 km, not 4: on the
// 0.25° maps' 2 km map pixels the towers still decided the blocks (a random draw, 500 hPa over
// Poland, Dice 0.944; 0.978 so; docs/footprint.md). By the cone alone (cone_m), not the step: a
// 1.5 km cone is 350 km away at 480×270 and a 60° field, past the haze's cut-off at the default
// 60 km visibility, and 232 km away in the ¼ window's 320×180 march.
const TOWER_MEAN_FROM_M: f32 = 1500.0;
fn tower_fade() -> f32 {
    return select(0.0, 1.0, cone_m >= TOWER_MEAN_FROM_M);
}

// A cumulonimbus cluster's mean (tower_fade): a slab over the column's top from ANVIL_FROM,
// where the anvils and their shield spread, whose optical depth straight down, −ln(1 − cm),
// lets through what a fraction cm of opaque cloud does (as cumulus_slab). Density in the
// carve's units, before the density multiplier.
fn anvil_slab(cm: f32, ph: f32, thick: f32) -> f32 {
    let tall = (1.0 - ANVIL_FROM) * thick;
    let tau = -log(max(1.0 - cm, 0.02));
    let z = (ph - ANVIL_FROM) / (1.0 - ANVIL_FROM);
    return tau / (f.extinction * tall) * raised_cosine_mean(z, step_dz / tall);
}

// How far the cells have faded into their mean at the current sample's footprint: 0 for a
// footprint under half their spacing, 1 at the whole spacing and beyond.
fn cell_fade() -> f32 {
    return smoothstep(0.5, 1.0, footprint_m * footprint_scale / CELL_SPACING_M);
}

// Density at altitude h in the column at map uv, from the column's own base, top and genus
// (render::structure). A cumulonimbus column draws one tower through the convective cloud in
// place of the layers it spans; elsewhere the layer whose column holds h (the densest one where
// two overlap) is the only one evaluated.
fn column_density(uv: vec2<f32>, h: f32, np: vec3<f32>, detail: bool, s: Sample) -> f32 {
    let su = uv * f.st_scale + f.st_offset;
    let b = textureSampleLevel(st_base, clamp_lin, su, 0.0);
    let t = textureSampleLevel(st_top, clamp_lin, su, 0.0);
    // The genus of the nearest texel, the choice dithered over a texel by a hash of the noise
    // cell, so a boundary between genera blends instead of stepping along texel edges.
    let dims = vec2<i32>(textureDimensions(st_kind));
    let kc = clamp(vec2<i32>(floor(su * vec2<f32>(dims) + (cell_hash(np) - 0.5))), vec2<i32>(0), dims - 1);
    let kind = textureLoad(st_kind, kc, 0);
    let towers = feature(FLAG_TOWERS);
    var k = -1;
    var best = 0.0;
    // The tower's body takes the coverage of the low and middle layers it spans; its anvil,
    // under the top, that of the high layer too (GFS's high cover over deep convection is the
    // anvil's cirrus shield, far wider than the towers).
    var body_cm = 0.0;
    var anvil_cm = 0.0;
    for (var j = 0; j < 3; j++) {
        if (f.layer_scale[j] > 0.0) {
            if (towers && kind[j] == T_CUMULONIMBUS) {
                anvil_cm = max(anvil_cm, s.cm[j]);
                if (j < 2) {
                    body_cm = max(body_cm, s.cm[j]);
                }
            } else if (h >= b[j] && h <= t[j] && s.cm[j] > best) {
                k = j;
                best = s.cm[j];
            }
        }
    }
    var base = 0.0;
    var top = 0.0;
    var cm = 0.0;
    var code = 0.0;
    // How much of the sample is a tower's trunk rather than its anvil's shield (0 elsewhere).
    var trunk = 0.0;
    if (anvil_cm > 0.0 && h >= b.a && h <= t.a) {
        base = b.a;
        top = t.a;
        // The towers, and under the column's top the anvil's shield: the high layer's coverage.
        let ph_t = (h - base) / max(top - base, 1.0);
        let tc = tower_cover(uv, ph_t, body_cm);
        let sc = anvil_cm * smoothstep(ANVIL_FROM, 0.9, ph_t);
        cm = max(tc, sc);
        trunk = sat(2.0 * (tc - sc));
        code = T_CUMULONIMBUS;
    } else if (k >= 0) {
        base = b[k];
        top = t[k];
        cm = best;
        code = kind[k];
    } else {
        return 0.0;
    }
    local_count[C_DENSITY] += 1u;
    last_sample.cover = cm;
    let thick = max(top - base, 1.0);
    let ph = (h - base) / thick;
    // A column's optical depth follows its coverage, not its thickness (as for bands, frame.rs).
    var scale = mix(clamp(REFERENCE_THICKNESS_M / thick, 0.25, 4.0), TRUNK_DENSITY, trunk) * f.density_mul;
    let nq = drifted(np, max(k, 0));
    var p = nq;
    var c: Carving;
    // A cumulus field's mean where its cells are finer than the footprint (cumulus_slab).
    var fade = 0.0;
    var slab = 0.0;
    if (code < 0.5) {
        c = layer_carving(cm, ph);
    } else if (feature(FLAG_CELLS) && code == T_CUMULUS) {
        c = cumulus_carving(uv, max(k, 0), cm, ph, thick);
        // A cell's density is the cloud's own, not normalised to the column: its coverage is
        // its area.
        scale = f.density_mul;
        fade = cell_fade();
        slab = cumulus_slab(cm, ph, thick);
        if (fade >= 1.0) {
            c.gd = 0.0;
        }
    } else {
        c = genus_carving(cm, ph, code);
        if (feature(FLAG_STREAKS) && code >= T_CIRRUS && code <= T_CIRROSTRATUS) {
            // Streaks where the column's own wind blows (calm air, < 1 m/s, has none), along
            // the layer's one direction.
            let w = textureSampleLevel(st_wind, clamp_lin, su, 0.0);
            let wl = select(w.zw, w.xy, k == 2);
            let dir = select(f.streak_dir.zw, f.streak_dir.xy, k == 2);
            if (dot(wl, wl) >= 1.0 && dot(dir, dir) > 0.5) {
                p = STREAK_ROT * (streaked(uv, h, ph, dir) + (nq - np));
            }
        }
    }
    // A cumulonimbus cluster seen from farther than its towers can be told apart: its mean.
    // Only in the towers' variant (`towers` is a pipeline constant): a CPU driver runs this
    // for every sample of every map otherwise (1.2 % of a synthetic map's frame on lavapipe).
    var cb_mean = 0.0;
    if (towers && code == T_CUMULONIMBUS) {
        cb_mean = tower_fade();
        if (cb_mean >= 1.0) {
            c.gd = 0.0;
        }
    }
    var carved = mix(carve_with(p, c, cm, ph, detail), slab, fade) * scale;
    if (towers && cb_mean > 0.0) {
        carved = mix(carved, anvil_slab(max(body_cm, anvil_cm), ph, thick) * f.density_mul, cb_mean);
    }
    footprint_scale = 1.0;
    return carved;
}

// Density (unitless, DESIGN's d summed over layers) at altitude h, direction pos, noise np.
// Map uv of a sample (negative u outside the region): one lat/lon per step, shared by the
// coarse-map test and the weather lookup (on a CPU driver the step's fixed cost dominates).
fn sample_uv(pos: vec3<f32>) -> vec2<f32> {
    return region_uv(lat_lon(pos));
}

fn density(pos: vec3<f32>, h: f32, np: vec3<f32>, detail: bool) -> f32 {
    // Checked here as well as in density_uv so a light sample outside the shells costs no lat/lon.
    if (h < f.shell_base_m || h > f.shell_top_m) {
        return 0.0;
    }
    return density_uv(sample_uv(pos), h, np, detail);
}

// Whether the altitudes lo..hi meet the envelope of a drawn layer with cover in the column of
// the last density look-up (`last_sample`), or the towers' there: where a ray going on from that
// sample can find cloud. A column with no cover gives false: a stride over clear sea keeps its
// length (the next column's cover comes from the same smooth map, and at the edge of a
// clear area it is small, the cloud it hides as thin).
fn envelope_overlaps(lo: f32, hi: f32) -> bool {
    // Vector compares, not a loop over the layers: with the loop the test's code alone (never
    // binding) made a lavapipe frame 5 % slower, with this form about 2 %.
    let cover = last_sample.cm * f.layer_scale;
    let layers = any((cover > vec3<f32>(0.0)) & (vec3<f32>(lo) <= f.layer_top) & (vec3<f32>(hi) >= f.layer_base));
    let towers = feature(FLAG_STRUCTURE) && any(cover > vec3<f32>(0.0)) && lo <= f.tower_top_m && hi >= f.tower_base_m;
    return layers || towers;
}

fn density_uv(uv: vec2<f32>, h: f32, np: vec3<f32>, detail: bool) -> f32 {
    last_sample = LastSample(0.0, vec3<f32>(0.0));
    if (h < f.shell_base_m || h > f.shell_top_m) {
        return 0.0;
    }
    let s = weather_at(uv);
    last_sample.cm = s.cm;
    let cull = has_flag(FLAG_CULL);
    if (!s.inside) {
        if (cull) {
            return 0.0;
        }
        local_count[C_OUTSIDE] += 1u;
    }
    if (feature(FLAG_STRUCTURE)) {
        // Outside every cloudy layer's envelope and the towers' there is nothing to look up
        // (a column without cover has no towers either: column_density would give 0).
        if (!envelope_overlaps(h, h)) {
            return 0.0;
        }
        return column_density(uv, h, np, detail, s);
    }
    // The drawn bands are disjoint (frame.rs makes them so): one layer at most holds h, and only
    // its density is evaluated. A SIMD CPU driver (lavapipe) executes both sides of every branch,
    // so a loop carving each layer would cost three evaluations on every sample.
    var k = -1;
    for (var j = 0; j < 3; j++) {
        if (f.layer_scale[j] > 0.0 && h >= f.layer_base[j] && h <= f.layer_top[j]) {
            k = j;
        }
    }
    if (k < 0 || (cull && s.cm[k] <= 0.0)) {
        return 0.0;
    }
    local_count[C_DENSITY] += 1u;
    last_sample.cover = s.cm[k];
    let base = f.layer_base[k];
    let ph = (h - base) / max(f.layer_top[k] - base, 1.0);
    let c = layer_carving(s.cm[k], ph);
    return carve_with(drifted(np, k), c, s.cm[k], ph, detail) * f.layer_scale[k] * f.density_mul;
}
