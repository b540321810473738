// March stage: one compute invocation per pixel marches the view ray through the cloud shells
// (DESIGN §2–4) and writes premultiplied linear cloud radiance + opacity to a storage texture.

// Bind groups by lifetime: 0 lives as long as the device, 1 as the map (both in cloud.wgsl),
// 2 as the output size, 3 (scene.wgsl) as the key light's direction.
@group(2) @binding(0) var out_cloud: texture_storage_2d<rgba16float, write>;
@group(2) @binding(1) var<storage, read_write> cut_mask: array<atomic<u32>>;   // 1 bit per pixel
// What lies behind the cloud (linear radiance of sky or ground, scene.wgsl's background) and
// the pixel's representative distance in km (the cloud's opacity-weighted distance where it is
// at least half opaque, else the ground's; 0 for sky): what reprojection moves pixels by.
@group(2) @binding(2) var out_scene: texture_storage_2d<rgba16float, write>;
// The farthest each pixel's ray may go (m), row-major at the output size: where a host's own
// geometry hides what lies behind (render::embed, shaders/embed.wgsl); one huge value otherwise.
@group(2) @binding(3) var<storage, read> ray_far: array<f32>;
// The exposure the present stage last used (exposure.wgsl; 0 before the first frame): the limb's
// rays are averaged as they will be seen (`as_shown`).
@group(2) @binding(4) var<storage, read> shown_exposure: ExposureState;

// This invocation's pixel's entry of ray_far.
var<private> far_m: f32;

// The opacity-weighted distance (m) of the cloud the last march() saw (0 where none).
var<private> cloud_dist: f32;
// Where the last march() first read the cloud's noise (m; `NO_NOISE` where it never did): before
// that its samples were clear by the map alone (below, above or between the drawn layers,
// outside their cover), not by the noise, and a ray a fraction of a pixel beside it is clear
// there too (`extra_ray`).
const NO_NOISE: f32 = 1e9;
var<private> noise_first: f32 = NO_NOISE;
// Where the next march() starts along its ray (m): 0, or a grazing pixel's extra ray's start.
var<private> march_from: f32 = 0.0;

var<workgroup> wg_count: array<atomic<u32>, N_COUNTERS>;

struct Ray {
    h: f32,          // origin altitude (m)
    up: vec3<f32>,   // local up at the origin
    d: vec3<f32>,    // direction
    np: vec3<f32>,   // noise-space origin (m)
    // The width (m) a sample at distance t stands for: cone0 + cone·t (issue 30).
    cone0: f32,
    cone: f32,
};

fn make_ray(px: vec2<f32>) -> Ray {
    var r: Ray;
    let size = f.out_size;
    if (feature(FLAG_NO_SKY)) {
        // Top-down: one nadir ray per map pixel centre (DESIGN §1.2 pixel convention).
        let lat = radians(f.region_north - px.y / size.y * (f.region_north - f.region_south));
        let lon = radians(f.region_west + px.x / size.x * f.region_lon_span);
        r.up = vec3<f32>(cos(lat) * cos(lon), cos(lat) * sin(lon), sin(lat));
        r.h = f.cam_alt_m;
        r.d = -r.up;
        let o = r.up * (EARTH_R + r.h);
        r.np = o - f.shape_period_m * floor(o / f.shape_period_m);
        // Parallel rays, each a map pixel wide (its north-south side).
        r.cone0 = (f.region_north - f.region_south) / size.y * 111195.0;
        r.cone = 0.0;
    } else {
        r.d = persp_dir(px);
        r.up = f.cam_up;
        r.h = f.cam_alt_m;
        r.np = f.noise_origin;
        // A pixel's angle: the march's rows span the vertical field of view.
        r.cone0 = 0.0;
        r.cone = 2.0 * f.tan_half_fov / size.y;
    }
    return r;
}

// Optical depth toward the key light from a sample: short march, the last step 6× longer.
fn light_depth(pos: vec3<f32>, h: f32, np: vec3<f32>, key: vec3<f32>, n: u32) -> f32 {
    let up = normalize(pos);
    let mu = dot(key, up);
    let step0 = f.light_step0_m;
    var s = 0.0;
    var tau = 0.0;
    for (var i = 0u; i < n; i++) {
        var ds = step0;
        if (i + 1u == n) {
            ds = step0 * 6.0;
        }
        let sm = s + 0.5 * ds;
        s += ds;
        let hl = altitude_at(h, mu, sm);
        let pl = pos + key * sm;
        local_count[C_LIGHT] += 1u;
        step_dz = abs(mu) * ds;
        tau += density(pl, hl, np + key * sm, false) * f.extinction * ds;
    }
    return tau;
}

const MIN_SEG_STEPS: f32 = 16.0;
// A ray entering cloud from clear air bisects the step for the edge until the edge is known
// to within EDGE_M (m): fast's shortest step over 16, what four halvings gave there. A fixed
// count left the far field's 1–3 km steps a 60–190 m bracket, so a dense edge's depth (and
// light) followed the step's phase: grain, and a picture darker than `high` (the start view at
// noon, fast against high: RMSE 0.057 → 0.037, luminance 0.91 → 0.97; docs/footprint.md).
const EDGE_M: f32 = 6.25;
const MIN_REFINE: f32 = 2.0;
const MAX_REFINE: f32 = 6.0;

// Halvings of a step of `dt` m that bring the edge within EDGE_M.
fn refine_halvings(dt: f32) -> u32 {
    return u32(clamp(ceil(log2(dt / EDGE_M)), MIN_REFINE, MAX_REFINE));
}
// Clear-air stride: normal steps taken after the last cloud sample before striding again.
const FINE_AFTER_CLOUD: u32 = 8u;
// No stride where the column's coverage is at least this: there the carve leaves cloud in most
// of the column, the clear gaps are a few hundred metres and a 2–12 km stride jumps streaks by
// its phase, drawing rings of equal distance; sparser columns, where the stride saves most of
// the march, keep it (docs/footprint.md: the start view at noon 0.029 → 0.017 against its 4×4
// twin for at most 5 % more density samples on the bench's scenes).
const STRIDE_COVER_MAX: f32 = 0.5;

// The most altitude (m) one step or stride may span in or into the envelope of a layer with
// cover, on a map with cumulus or cumulonimbus. Less than the thinnest slab drawn there (a
// scattered cumulus field's mean, some 350 m at 5 % cover), so a stride cannot hop it: 4–6 km
// strides down a slant through a far field 0.6 km thick let through 40 % of its opacity
// (tests/genera.rs, far cumulus at a slant: 0.097 against 0.261). And a layer is crossed in
// several samples, not one or two: the far field's normal steps of 1–1.5 km fell 0.8–1.2 km
// down a steep view, so a thin genus layer was met at one jittered height of its profile or
// not at all (the 250 km view against `reference`: 0.106 → 0.051, docs/footprint.md).
const ENVELOPE_DZ_M: f32 = 300.0;

// A step of `dt` m from altitude h, where the altitude changes by `slope` per metre of the ray:
// dt where it stays out of every cloudy envelope or spans little altitude (a grazing far ray
// keeps its length), else shortened to span ENVELOPE_DZ_M.
fn envelope_step(dt: f32, h: f32, slope: f32) -> f32 {
    // Only maps with cumulus or cumulonimbus: elsewhere the code is compiled out (the bench's
    // maps: unchanged, picture for picture). The map's, not the view's (render::reach).
    if (!feature(FLAG_ENVELOPE)) {
        return dt;
    }
    let dh = slope * dt;
    if (abs(dh) <= ENVELOPE_DZ_M || !envelope_overlaps(min(h, h + dh), max(h, h + dh))) {
        return dt;
    }
    return max(ENVELOPE_DZ_M / abs(slope), f.step_min_m);
}

// The march's step at distance t in a segment whose longest step is seg_dt (variable step: it
// grows with the distance), before envelope_step shortens it.
fn natural_step(t: f32, seg_dt: f32) -> f32 {
    return min(clamp(f.step_min_m + f.step_growth * t, f.step_min_m, f.step_max_m), seg_dt);
}

// The stride multiple `m` of a clear sample's step `dt` at altitude h: m, or less where the
// stride would span too much of an envelope (envelope_step); 1 (no stride) below 2.
fn stride_mult(m: f32, dt: f32, h: f32, slope: f32) -> f32 {
    let span = envelope_step(m * dt, h, slope);
    // m itself where nothing was cut (not m·dt / dt, which is m only to a rounding).
    if (span >= m * dt) {
        return m;
    }
    let capped = span / dt;
    return select(1.0, capped, capped >= 2.0);
}

// Where a segment's march starts and its longest step: at least MIN_SEG_STEPS samples per
// crossing of the layer shells, so a steep ray through a thin layer (400 hPa is ~700 m) does not
// take one or two jittered samples and show the jitter pattern instead of the cloud.
fn seg_start(seg: vec2<f32>, jitter: f32) -> vec2<f32> {
    let seg_dt = max((seg.y - seg.x) / MIN_SEG_STEPS, 1.0);
    let t = seg.x + jitter * min(clamp(f.step_min_m + f.step_growth * seg.x, f.step_min_m, f.step_max_m), seg_dt);
    return vec2<f32>(t, seg_dt);
}

// Where a view ray is marched (the march's first step): `seg` from where it enters the cloud
// shells to the innermost shell's bottom (or to its end), `seg2` below that bottom (empty: x > y),
// both ending where the haze, the sea or the terrain hides what lies behind; `hit` is false
// when the ray misses the shells.
struct Segments {
    hit: bool,
    seg: vec2<f32>,
    seg2: vec2<f32>,
};

fn segments(r: Ray, mu: f32, ground_t: f32) -> Segments {
    var s: Segments;
    let outer = shell_hits(r.h, mu, f.shell_top_m);
    if (outer.y < 0.0 || outer.x > outer.y) {
        s.hit = false;
        return s;
    }
    // Beyond five visibility lengths the haze hides everything (haze_cutoff_m). Haze lives in the low
    // atmosphere, so the length counts from where the ray enters the cloud shells: a camera in
    // orbit still sees the deck below it.
    var end_all = min(min(outer.y, max(outer.x, 0.0) + f.haze_cutoff_m), far_m);
    if (end_all <= max(outer.x, 0.0)) {
        s.hit = false;
        return s;
    }
    let ground = shell_hits(r.h, mu, 0.0);
    if (ground.x <= ground.y && ground.y > 0.0) {
        end_all = min(end_all, max(ground.x, 0.0));
    }
    // The terrain hides what lies behind it (the score's nadir rays see the cloud above it):
    // where the ray's reach (`ground_reach`, the one its background shows) meets it, so the
    // cloud ends where the picture's rock begins and the height field is marched once a ray,
    // not twice (docs/performance.md).
    if (!feature(FLAG_NO_SKY) && ground_t >= 0.0) {
        end_all = min(end_all, ground_t);
    }
    // At most two segments: above and below the innermost shell's bottom.
    let inner = shell_hits(r.h, mu, f.shell_base_m);
    s.hit = true;
    s.seg = vec2<f32>(max(outer.x, 0.0), end_all);
    s.seg2 = vec2<f32>(1.0, 0.0);
    if (inner.x <= inner.y && inner.y > 0.0) {
        s.seg = vec2<f32>(max(outer.x, 0.0), min(end_all, inner.x));
        s.seg2 = vec2<f32>(max(max(outer.x, 0.0), inner.y), end_all);
    }
    return s;
}

// A view ray's walk through clear air from one cloud sample to the next (the march's second
// step): where it is, how it steps, and the sample it stopped at.
struct Walk {
    seg: vec2<f32>,     // the segment being walked
    seg2: vec2<f32>,    // the one after it (empty: x > y)
    second: bool,       // walking seg2
    t: f32,
    seg_dt: f32,        // the segment's longest step (seg_start)
    steps: u32,
    stride: bool,
    mult: f32,
    fine_left: u32,
    // Whether the last sample was clear: a cloud met after clear air has its edge refined, by
    // `refine` more halvings of [lo_t, t].
    prev_clear: bool,
    refine: u32,
    lo_t: f32,
    finished: bool,     // the march is over: the ray's end, max_steps, or opaque
    // The cloud sample found: extinction (1/m), step, map uv, altitude.
    sigma: f32,
    dt: f32,
    uv: vec2<f32>,
    h: f32,
    // The step before envelope_step shortened it (kept through a bisection, which moves t):
    // what the noise's level of detail follows.
    dt0: f32,
};

fn start_walk(span: Segments, jitter: f32) -> Walk {
    let st = seg_start(span.seg, jitter);
    return Walk(span.seg, span.seg2, false, st.x, st.y, 0u, false, 1.0, 0u, true, 0u, 0.0, false,
                0.0, 0.0, vec2<f32>(0.0), 0.0, 0.0);
}

// Walk on to the ray's next sample with cloud, looking up density only: true with the sample
// in the walk's sigma, dt, uv and h; false when the march is over (`finished`: it ended).
fn next_cloud(walk: ptr<function, Walk>, r: Ray, mu: f32, origin: vec3<f32>, jitter: f32) -> bool {
    let skip = has_flag(FLAG_SKIP);
    let may_stride = has_flag(FLAG_STRIDE);
    // The score's top-down columns stride at most 2×: there a wisp jumped over is a mask pixel
    // lost (at 4× the top-down RGB error against reference rose from 0.006 to 0.023).
    let max_mult = select(4.0, 2.0, feature(FLAG_NO_SKY));
    let detail = feature(FLAG_DETAIL);
    let max_steps = f.max_steps;
    var w = *walk;
    w.sigma = 0.0;
    w.dt = 0.0;
    w.uv = vec2<f32>(0.0);
    w.h = 0.0;
    var found = false;
    loop {
        if (w.t >= w.seg.y) {
            if (w.second) {
                w.finished = true;
                break;
            }
            w.second = true;
            w.seg = w.seg2;
            let st = seg_start(w.seg, jitter);
            w.t = st.x;
            w.seg_dt = st.y;
            w.stride = false;
            w.mult = 1.0;
            w.fine_left = 0u;
            continue;
        }
        // While refining, the point half-way between the last clear point and t (cloudy).
        let te = select(w.t, 0.5 * (w.lo_t + w.t), w.refine > 0u);
        let h_e = altitude_at(r.h, mu, te);
        // d(altitude)/dt along the ray there.
        let slope = (te + (EARTH_R + r.h) * mu) / (EARTH_R + h_e);
        if (w.refine == 0u) {
            if (w.steps >= max_steps) {
                w.finished = true;
                break;
            }
            w.steps += 1u;
            w.dt0 = natural_step(w.t, w.seg_dt);
            w.dt = envelope_step(w.dt0, h_e, slope);
        }
        let uv_e = sample_uv(origin + r.d * te);
        if (w.refine == 0u && skip && coarse_empty(uv_e)) {
            local_count[C_SKIPPED] += 1u;
            w.t += max(w.dt, f.skip_m);
            continue;
        }
        // What the sample stands for: the ray's cone across, the step along it. Samples a
        // step apart resolve detail no finer than two steps (Nyquist), so the noise is read at
        // the level of the cone or of two steps, whichever is coarser: finer detail is averaged
        // rather than aliased into per-pixel noise by the step's jitter (docs/footprint.md).
        // A step envelope_step shortened samples the altitude more finely, not the noise: read
        // at its level the far field's thresholded noise turned to pixel-sized specks (the 250
        // km view 0.019 → 0.041 against its 4×4 twin; at the natural step's level 0.017).
        cone_m = r.cone0 + r.cone * te;
        footprint_m = max(cone_m, 2.0 * w.dt0);
        step_dz = abs(slope * w.dt);
        // The one density call of the loop (a second call site, as a bisection loop of its
        // own, doubled the march's time on lavapipe, which runs every call site for all lanes).
        let noised_before = local_count[C_DENSITY];
        let s_e = density_uv(uv_e, h_e, r.np + r.d * te, detail) * f.extinction;
        if (local_count[C_DENSITY] != noised_before) {
            noise_first = min(noise_first, te);
        }
        if (w.refine > 0u) {
            w.refine -= 1u;
            if (s_e > 0.0) {
                w.t = te;
                w.sigma = s_e;
                w.uv = uv_e;
                w.h = h_e;
            } else {
                w.lo_t = te;
            }
            if (w.refine == 0u) {
                w.prev_clear = false;
                w.fine_left = FINE_AFTER_CLOUD;
                found = true;
                break;
            }
            continue;
        }
        w.uv = uv_e;
        w.h = h_e;
        w.sigma = s_e;
        if (w.sigma > 0.0 && w.stride) {
            // Met cloud on a long step: back up to the last clear sample and go on at the
            // normal step, so the cloud's near edge is found at full resolution.
            w.stride = false;
            w.fine_left = FINE_AFTER_CLOUD;
            w.t = max(w.t - w.dt * w.mult, w.seg.x);
            w.mult = 1.0;
            continue;
        }
        if (w.sigma > 0.0) {
            if (w.prev_clear && w.t - w.dt > w.seg.x) {
                // Entering cloud from clear air: bisect the step for the edge
                // (refine_halvings). A dense cloud is opaque within one step, so its colour is that
                // of the sample; at a fixed step that sample's depth inside the edge (and
                // so its light) would follow the step's phase, drawing contour rings over
                // the relief.
                w.refine = refine_halvings(w.dt);
                w.lo_t = w.t - w.dt;
                continue;
            }
            w.prev_clear = false;
            w.fine_left = FINE_AFTER_CLOUD;
            found = true;
            break;
        }
        w.prev_clear = true;
        if (w.fine_left > 0u) {
            w.fine_left -= 1u;
        } else if (may_stride && last_sample.cover >= STRIDE_COVER_MAX) {
            // Clear air inside a mostly cloudy column: its gaps are narrow and a stride would
            // hop the next streak by the step's phase (rings of equal distance).
            w.stride = false;
            w.mult = 1.0;
        } else if (may_stride) {
            w.mult = stride_mult(min(w.mult * 2.0, max_mult), w.dt, h_e, slope);
            w.stride = w.mult > 1.0;
        }
        w.t += select(w.dt, w.mult * w.dt, w.stride);
    }
    *walk = w;
    return found;
}

// The view ray's terms of the phase function, the same for each of its samples.
struct ViewPhase {
    cos_t: f32,      // cosine to the key light
    ph_fn: f32,      // the dual-lobe phase at it
    powder_w: f32,   // how much the powder effect is spared (toward the light)
};

// The light a cloud sample at distance t receives, toward the eye (the march's third step;
// DESIGN §8). `tr`: the view ray's transmittance so far (fewer light steps behind opaque cloud).
fn light_in(r: Ray, origin: vec3<f32>, t: f32, h: f32, uv: vec2<f32>, tr: f32, view: ViewPhase) -> vec3<f32> {
    let no_sky = feature(FLAG_NO_SKY);
    let lod = has_flag(FLAG_LIGHT_LOD);
    let sun_key = f.sun_is_key != 0u;
    let n_light = f.light_steps;
    let g = f.hg_g;
    let pos = origin + r.d * t;
    let np = r.np + r.d * t;
    let up = normalize(pos);
    var key = select(f.moon_dir, f.sun_dir, sun_key);
    var key_col = select(f.moon_col, f.sun_col, sun_key);
    var ambient = sky_radiance(up, up);
    if (no_sky) {
        key = up;
        key_col = vec3<f32>(1.0);
        ambient = vec3<f32>(0.3);
    }
    var nl = n_light;
    if (lod && tr < 0.3) {
        nl = max(1u, n_light / 2u);
    }
    // Toward the key light: the short march through the detailed cloud near the sample,
    // then the whole column beyond it from the shadow stage's smooth volume (DESIGN §8).
    var tau = light_depth(pos, h, np, key, nl);
    var od_up = 0.0;
    var bounce = vec3<f32>(0.0);
    if (!no_sky) {
        let reach = f.light_step0_m * (f32(nl) + 5.0);
        let far = pos + key * reach;
        tau += column_od(far, altitude_at(h, dot(key, up), reach)).x;
        od_up = column_od(pos, h).y;
        // Light the ground below sends back up, for the bases (its albedo, in its shadows).
        let gr = ground_at(uv);
        bounce = gr.yzw * ground_irradiance(up * (EARTH_R + gr.x), up, gr.x, ambient);
    }
    // Eq. 22's clamp as a floor under Beer (ac·exp(-τ/4)) so deep cloud does not go
    // black, plus two octaves of Hillaire's multiple-scattering approximation
    // (extinction, phase g and energy each halved per octave); deeper than those reach, the
    // diffuse light a deck lets through (two-stream), leaving it as from a Lambertian base.
    let powder = 1.0 - exp(-2.0 * tau);
    var ms = max(exp(-tau), f.beer_clamp * exp(-0.25 * tau)) * view.ph_fn;
    ms += 0.5 * exp(-0.5 * tau) * phase(view.cos_t, 0.5 * g);
    ms += 0.25 * exp(-0.25 * tau) * phase(view.cos_t, 0.25 * g);
    let mu0 = max(dot(key, up), 0.1);
    // The octaves hold the first few optical depths (the relief's light and shade); the
    // two-stream takes over by τ ≈ 10, where they have faded.
    ms = max(ms, diffuse_t(tau * mu0) * mu0 / PI * sat(tau / 10.0));
    let lit = key_col * SUN_I * ms * mix(2.0 * powder, 1.0, view.powder_w);
    // Ambient: the sky through the column above (the volume's mean, smooth, never one noise
    // look-up), and the ground's light from below.
    return lit + ambient * diffuse_t(od_up) + 0.5 * bounce;
}

// The cloud's premultiplied radiance `col` (opacity `alpha`, opacity-weighted distance `dist`)
// seen through the air in front of it (the march's last step): the clear air (the
// aerial-perspective table) and the haze (Koschmieder) toward the cloud's distance.
fn through_air(r: Ray, mu: f32, cloud: vec3<f32>, alpha: f32, dist: f32) -> vec3<f32> {
    var col = cloud;
    // The air's light is the table's for a clear sky: dimmed, as the haze's, under cloud.
    let air = haze_light();
    let ap = aerial(r.d, dist);
    col = col * ap.a + ap.rgb * air * alpha;
    let fog = haze_transmittance(r.h, altitude_at(r.h, mu, dist), dist);
    let haze = sky_seen(r.d) * air;
    col = col * fog + haze * alpha * (1.0 - fog);
    return col;
}

// The view ray's cloud: premultiplied radiance and opacity. In steps: its segments, then a
// walk to each cloud sample (`next_cloud`), lit (`light_in`) and added, then the air in front.
fn march(r: Ray, jitter: f32, ground_t: f32) -> vec4<f32> {
    cloud_dist = 0.0;
    let mu = dot(r.d, r.up);
    var span = segments(r, mu, ground_t);
    noise_first = NO_NOISE;
    if (!span.hit) {
        return vec4<f32>(0.0);
    }
    span.seg.x = max(span.seg.x, march_from);
    span.seg2.x = max(span.seg2.x, march_from);
    let sun_key = f.sun_is_key != 0u;
    let cos_t = dot(r.d, select(f.moon_dir, f.sun_dir, sun_key));
    let view = ViewPhase(cos_t, phase(cos_t, f.hg_g), remap(cos_t, -1.0, 1.0, 0.0, 1.0));
    let early = f.early_exit;
    let origin = r.up * (EARTH_R + r.h);

    var tr = 1.0;
    var col = vec3<f32>(0.0);
    var depth_w = 0.0;
    var w = start_walk(span, jitter);
    // Two nested loops: the inner one (next_cloud) walks to the next sample with cloud, looking
    // up density only; this one lights that sample. On a GPU this is the same march as one
    // loop. On a SIMD CPU driver, where every branch is executed under a mask, it keeps the
    // light march and shading out of clear-air steps (measured: docs/performance.md).
    loop {
        if (!next_cloud(&w, r, mu, origin, jitter)) {
            break;
        }
        let l_in = light_in(r, origin, w.t, w.h, w.uv, tr, view);
        // Energy-conserving step (Hillaire 2016) with albedo 1: C += T (1 - a) L.
        let a = exp(-w.sigma * w.dt);
        col += tr * (1.0 - a) * l_in;
        depth_w += tr * (1.0 - a) * w.t;
        tr *= a;
        if (tr < early) {
            // Opaque enough: call it opaque, and give the cut-off remainder to what was seen
            // (renormalise) rather than to the background.
            local_count[C_EARLY] += 1u;
            col /= max(1.0 - tr, 1e-6);
            depth_w /= max(1.0 - tr, 1e-6);
            tr = 0.0;
            w.finished = true;
            break;
        }
        w.t += w.dt;
    }
    if (!w.finished) {
        local_count[C_CUT] += 1u;
    }
    local_count[C_STEPS] += w.steps;
    let alpha = 1.0 - tr;
    if (alpha <= 0.0) {
        return vec4<f32>(0.0);
    }
    let dist = depth_w / alpha;
    cloud_dist = dist;
    if (!feature(FLAG_NO_SKY)) {
        col = through_air(r, mu, col, alpha, dist);
    }
    return vec4<f32>(col, alpha);
}

// Where a mountain's silhouette crosses the pixel at px, the share of its height above the
// crossing; 1 where none does (its top and bottom rays both meet the terrain or both pass).
// Found by bisecting the pixel's middle column three times; the first probe is the centre,
// whose ray the caller has already followed (`centre_meets`), so one edge is tested: the top
// where the centre meets the terrain, the bottom where it passes.
fn terrain_share(px: vec2<f32>, centre_meets: bool) -> f32 {
    if (sh.terrain_on == 0u) {
        return 1.0;
    }
    // Where the centre meets the terrain every probe is above it, and so above the terrain as
    // far as the centre was (`terrain_clear_to`): marched from there, a probe meets the rock
    // in a few steps, not the centre's whole way.
    let past = select(0.0, terrain_clear_to, centre_meets);
    var lo = 0.0;
    var hi = 1.0;
    if (centre_meets) {
        if (meets_terrain(persp_dir(px - vec2<f32>(0.0, 0.5)), past)) {
            return 1.0;
        }
        hi = 0.5;
    } else {
        if (!meets_terrain(persp_dir(px + vec2<f32>(0.0, 0.5)), past)) {
            return 1.0;
        }
        lo = 0.5;
    }
    for (var k = 0; k < 2; k++) {
        let m = 0.5 * (lo + hi);
        if (meets_terrain(persp_dir(px + vec2<f32>(0.0, m - 0.5)), past)) {
            hi = m;
        } else {
            lo = m;
        }
    }
    return 0.5 * (lo + hi);
}

// A grazing pixel (frame.wgsl `grazing`) whose picture stands out from its neighbours' on
// screen (`differs_from_neighbours`, by the preset's `graze_apart`) takes `GRAZE_EXTRA` more
// rays down its height (`needs_grazing_rays`, `extra_ray`): a far deck's top seen edge-on is a
// line thinner than a pixel, which one ray hits or misses as the step's jitter picks, a dashed
// line along the row.
const GRAZE_EXTRA: u32 = 4u;

// What a pixel's first ray shows: its cloud (premultiplied, opacity), what lies behind it
// (`out_scene`: radiance, distance) and the picture on screen (`seen`). Where the Earth's limb or
// a mountain's silhouette crosses the pixel (`one_ray` false) the ray is the upper part's, in
// its middle, and `share` that part's share of the pixel's height; `rework` adds the lower
// part's ray. `reach`: the centre ray's `ground_reach` where one ray makes the pixel.
struct Shaded {
    cloud: vec4<f32>,
    scene: vec4<f32>,
    seen: vec3<f32>,
    one_ray: bool,
    reach: vec2<f32>,
    share: f32,
};

// The exposure the rays will be shown at: a fixed one, else the last frame's adapted one
// (before any frame, and for every single picture, which clears it: the Sun's-height exposure
// adaptation starts from).
fn shown_at() -> f32 {
    let adapted = !has_flag(FLAG_FIXED_EXPOSURE) && shown_exposure.value > 0.0;
    return max(select(f.exposure, shown_exposure.value, adapted), 1e-12);
}

// What several rays show, averaged as shown (after the tone curve, as a supersampled picture
// is), back in radiance: the cloud keeps its mean and the background takes the rest, so the
// present stage's bg·(1 − a) + c gives it. Averaged in radiance, a bright rim beside a dark sea
// came out brighter than its rays' mean on screen; and each ray's own background counts, not
// the mean background under the mean cloud, or a sky behind the rim's cloud shows through the
// sea's clear rays. `c`, `bg` and `shown` are the rays' weighted means.
fn as_shown(c: vec4<f32>, bg: vec3<f32>, shown: vec3<f32>, dist: f32, e: f32) -> Shaded {
    let want = aces_inverse(shown) / e;
    let cloud = vec4<f32>(min(c.rgb, want), c.a);
    let back = select(bg, max(want - cloud.rgb, vec3<f32>(0.0)) / (1.0 - cloud.a), cloud.a < 0.9999);
    return Shaded(cloud, vec4<f32>(back, dist), shown, false, vec2<f32>(-1.0), 1.0);
}

// One ray of a pixel through `px` (offset down its height): its cloud, its background, what
// they show at exposure `e`, and its distance (km; the cloud's where at least half opaque).
struct OneRay {
    c: vec4<f32>,
    bg: vec3<f32>,
    seen: vec3<f32>,
    dist: f32,
};

fn one_ray(px: vec2<f32>, phase: f32, reach_in: vec2<f32>, own_reach: bool, e: f32) -> OneRay {
    let r = make_ray(px);
    // An `if`, not a select: a GPU skips the terrain march where the caller gave the reach (a
    // CPU driver runs it masked either way, docs/performance.md).
    var reach = reach_in;
    if (own_reach && !feature(FLAG_NO_SKY)) {
        reach = ground_reach(r.d);
    }
    let ck = march(r, phase, reach.y);
    var o = OneRay(ck, vec3<f32>(0.0), vec3<f32>(0.0), 0.0);
    if (!feature(FLAG_NO_SKY)) {
        let b = background_at(r.d, reach);
        o.bg = b.rgb;
        o.dist = select(b.a, cloud_dist, ck.a >= 0.5) * 1e-3;
    }
    o.seen = aces((ck.rgb + o.bg * (1.0 - ck.a)) * e);
    return o;
}

// A pixel's first ray (`Shaded`): through its centre, or where the limb or a silhouette crosses
// it, through the middle of the part above the crossing.
fn first_ray(px: vec2<f32>, jitter: f32) -> Shaded {
    let limb = !feature(FLAG_NO_SKY) && limb_side(px) == 0;
    // The part above the limb's or a silhouette's crossing is `share` of the pixel's height,
    // the other the rest.
    var share = select(1.0, limb_share(px), limb);
    // The centre ray's reach to the terrain or the sea: the silhouette's first probe, and the
    // background of a pixel marched with that one ray.
    var centre = vec2<f32>(-1.0);
    if (!limb && !feature(FLAG_NO_SKY)) {
        centre = ground_reach(persp_dir(px));
        share = terrain_share(px, centre.y >= 0.0);
    }
    let split = limb || share < 1.0;
    let y = select(0.0, 0.5 * share - 0.5, split);
    let o = one_ray(px + vec2<f32>(0.0, y), jitter, centre, split, shown_at());
    return Shaded(o.c, vec4<f32>(o.bg, o.dist), o.seen, !split, centre, share);
}

// Pixels whose picture takes more rays than their first, left by `main` for `rework`: a split
// pixel's second (the part below the crossing), a grazing pixel's `GRAZE_EXTRA` at other
// heights. A second dispatch, sized by their count, marches them: a CPU driver runs every lane
// through every call of the march in a dispatch, taken or not (docs/performance.md), so `main`
// keeps one.
struct ReworkEntry {
    // The first ray's `Shaded` fields.
    c: vec4<f32>,
    back: vec4<f32>,
    seen: vec3<f32>,
    // A split pixel's upper part's share; a grazing pixel's (whose share is 1) its centre
    // ray's `noise_first`, where its extra rays start from (`extra_ray`).
    share_or_from: f32,
    reach: vec2<f32>,
    // The invocation's subset cell, x | y << 16.
    cell: u32,
    // The extra rays: 1 (split) or GRAZE_EXTRA (grazing).
    rays: u32,
};

struct ReworkList {
    // `rework`'s workgroups: copied into its indirect dispatch (render::march).
    groups: atomic<u32>,
    // Entries taken; past the list's length a pixel keeps its first ray.
    count: atomic<u32>,
    // Of them the grazing pixels', from the list's start, `GRAZE_EXTRA` invocations each, and
    // the split pixels', from its end, one invocation each: a split pixel's one extra ray does
    // not hold three idle lanes beside it.
    grazes: atomic<u32>,
    splits: atomic<u32>,
    entries: array<ReworkEntry>,
};

@group(2) @binding(5) var<storage, read_write> rework_list: ReworkList;

// `rework`'s workgroup: a multiple of `GRAZE_EXTRA`, so a pixel's jobs share one.
const REWORK_GROUP: u32 = 64u;

// Appends the invocation's pixel (its cell, its first ray) to the list: a grazing pixel's at
// the next slot from the start, a split pixel's from the end; and a workgroup to `rework`'s
// dispatch at every `REWORK_GROUP / GRAZE_EXTRA`-th grazing entry and every `REWORK_GROUP`-th
// split one (its grazing workgroups first, then its split ones).
fn leave_for_rework(cell: vec2<u32>, s: Shaded) {
    let len = arrayLength(&rework_list.entries);
    if (atomicAdd(&rework_list.count, 1u) >= len) {
        return;
    }
    let split = !s.one_ray;
    let rays = select(GRAZE_EXTRA, 1u, split);
    // `noise_first` is still the centre ray's: nothing has marched since.
    let share_or_from = select(noise_first, s.share, split);
    let en = ReworkEntry(s.cloud, s.scene, s.seen, share_or_from, s.reach, cell.x | (cell.y << 16u), rays);
    if (split) {
        let j = atomicAdd(&rework_list.splits, 1u);
        rework_list.entries[len - 1u - j] = en;
        if (j % REWORK_GROUP == 0u) {
            atomicAdd(&rework_list.groups, 1u);
        }
    } else {
        let j = atomicAdd(&rework_list.grazes, 1u);
        rework_list.entries[j] = en;
        if (j % (REWORK_GROUP / GRAZE_EXTRA) == 0u) {
            atomicAdd(&rework_list.groups, 1u);
        }
    }
}

// The `k`-th extra ray of a pixel whose first ray is `en`: a split pixel's lower part's middle
// at the step's other half phase; a grazing pixel's at evenly spaced heights (±1/5, ±2/5 of it
// from the centre, whose ray it has), each its own phase of the step. No limb or silhouette
// crosses a grazing pixel (it would have been split), so its rays all meet the terrain or all
// pass it: past it, the centre's reach is theirs. A grazing pixel's extra rays start past the
// air its centre ray found clear by the map alone (`f.graze_from`): along the horizon under an
// overcast that is most of their way, and they cost twice a first ray (docs/footprint.md).
fn extra_ray(px: vec2<f32>, jitter: f32, k: u32, en: ReworkEntry, e: f32) -> OneRay {
    let split = en.rays == 1u;
    let n = f32(GRAZE_EXTRA + 1u);
    let graze_y = select(-1.0, 1.0, (k & 1u) == 1u) * f32((k >> 1u) + 1u) / n;
    let y = select(graze_y, 0.5 * en.share_or_from, split);
    let phase = select(fract(jitter + f32(k + 1u) / n), fract(jitter + 0.5), split);
    // A grazing pixel's extra rays skip the air its centre ray found clear by the map alone, where
    // that is more than a longest step (a shorter skip saves nothing and moves their samples).
    // `balanced` and `high` ask 0.5 (`f.graze_from`; `reference` 0): a ray a fifth of a pixel
    // higher enters a layer's band earlier than the centre, at a grazing angle by as much as
    // tens of per cent; at half the distance none enters before it starts.
    let from_t = f.graze_from * en.share_or_from;
    let read = en.share_or_from < NO_NOISE;
    march_from = select(0.0, from_t, !split && read && from_t >= f.step_max_m);
    return one_ray(px + vec2<f32>(0.0, y), phase, en.reach, split || en.reach.y >= 0.0, e);
}

// The extra rays of a workgroup's pixels, by job (`rework`): cloud, and background with the
// distance in w.
var<workgroup> wg_ray_c: array<vec4<f32>, REWORK_GROUP>;
var<workgroup> wg_ray_b: array<vec4<f32>, REWORK_GROUP>;

// A pixel's rays averaged as shown (`as_shown`): its first (`en`) and its extra rays, from the
// workgroup's jobs `first`..: a split pixel's two weighted by their parts' shares, a grazing
// pixel's five equally.
fn reworked(en: ReworkEntry, first: u32) -> Shaded {
    let e = shown_at();
    let split = en.rays == 1u;
    let w0 = select(1.0, en.share_or_from, split);
    let wk = select(1.0, 1.0 - en.share_or_from, split);
    var c = w0 * en.c;
    var bg = w0 * en.back.rgb;
    var shown = w0 * en.seen;
    var dist = w0 * en.back.a;
    for (var k = 0u; k < en.rays; k++) {
        let ck = wg_ray_c[first + k];
        let b = wg_ray_b[first + k];
        c += wk * ck;
        bg += wk * b.rgb;
        shown += wk * aces((ck.rgb + b.rgb * (1.0 - ck.a)) * e);
        dist += wk * b.a;
    }
    let n = select(1.0 / f32(GRAZE_EXTRA + 1u), 1.0, split);
    return as_shown(c * n, bg * n, shown * n, dist * n, e);
}

// Each invocation's picture on screen for its neighbours' grazing test (w: 1 where one ray
// made it).
var<workgroup> wg_seen: array<vec4<f32>, 64>;

// Whether the pixel `li` of the 8×8 workgroup stands out on screen (after the tone curve, 0..1)
// from its one-ray neighbours by more than `f.graze_apart`: from either neighbour in its row,
// or down its column from their mean (with one of them, half its distance to it), or, as far
// as `f.graze_column` says, from either neighbour in its column. A far deck's edge crossing
// the row is a line thinner than the pixel: the columns that hit it differ from those that
// missed it along the row, and it stands out from both sides down the column. The horizon's
// haze is a steep gradient down the column, which the centre ray already shows as its mean.
fn differs_from_neighbours(li: u32, seen: vec3<f32>) -> bool {
    var most = 0.0;
    let x = i32(li & 7u);
    let y = i32(li >> 3u);
    var sum = vec3<f32>(0.0);
    var n = 0.0;
    for (var k = 0; k < 4; k++) {
        let side = select(-1, 1, (k & 1) == 1);
        let in_row = k < 2;
        let nx = x + select(0, side, in_row);
        let ny = y + select(side, 0, in_row);
        if (nx >= 0 && nx < 8 && ny >= 0 && ny < 8) {
            let o = wg_seen[u32(ny * 8 + nx)];
            if (o.w > 0.0) {
                let d = abs(o.rgb - seen) * select(f.graze_column, 1.0, in_row);
                most = max(most, max(d.x, max(d.y, d.z)));
                if (!in_row) {
                    sum += o.rgb;
                    n += 1.0;
                }
            }
        }
    }
    if (n > 0.0) {
        let d = abs(seen - sum / n) * select(0.5, 1.0, n > 1.5);
        most = max(most, max(d.x, max(d.y, d.z)));
    }
    return most > f.graze_apart;
}

// Whether this invocation's one-ray pixel is a grazing pixel whose picture differs from a
// neighbour's (`differs_from_neighbours`), and so takes `GRAZE_EXTRA` more rays. Called by
// every invocation (it holds a barrier). A split pixel's first ray shows only part of it: it is
// no one's neighbour here.
fn needs_grazing_rays(li: u32, marched: bool, px: vec2<f32>, s: Shaded) -> bool {
    let one = marched && s.one_ray;
    wg_seen[li] = vec4<f32>(s.seen, select(0.0, 1.0, one));
    workgroupBarrier();
    return one && grazing(px) && differs_from_neighbours(li, s.seen);
}

// The subset cell's side (px; 1 when every pixel is marched) and the cells across the output.
fn subset_n() -> u32 {
    return max(u32(f.subset_n), 1u);
}

fn subset_cells() -> vec2<u32> {
    return (vec2<u32>(f.out_size) + vec2<u32>(subset_n() - 1u)) / subset_n();
}

// The march pixel of the invocation at `id` (its subset cell's pixel this frame).
fn pixel_of(id: vec2<u32>) -> vec2<u32> {
    return min(id * subset_n() + vec2<u32>(f.subset_offset), vec2<u32>(f.out_size) - 1u);
}

// The step's phase at a pixel: interleaved gradient noise (Jimenez 2014), shifted per frame.
fn pixel_jitter(px: vec2<f32>) -> f32 {
    if (!has_flag(FLAG_JITTER)) {
        return 0.5;
    }
    let q = px + vec2<f32>(5.588238 * f.frame_index);
    return fract(52.9829189 * fract(dot(q, vec2<f32>(0.06711056, 0.00583715))));
}

// Where the march aims in pixel `pix`: its centre, or in a still view's later marches of it the
// frame's point of the pixel (render::reproject::still_sample_offset), so the mean of its
// marches covers the pixel, not its centre alone.
fn ray_point(pix: vec2<u32>) -> vec2<f32> {
    return vec2<f32>(pix) + 0.5 + vec2<f32>(f.sample_dx, f.sample_dy);
}

// The reach limit of the pixel `pix` (`far_m`).
fn set_far(pix: vec2<u32>) {
    let full = vec2<u32>(f.out_size);
    far_m = ray_far[min(pix.y * full.x + pix.x, arrayLength(&ray_far) - 1u)];
}

// Marks the subset cell `cell` cut short where this invocation's rays were.
fn mark_cut(cell: vec2<u32>) {
    if (local_count[C_CUT] != 0u) {
        let i = cell.y * subset_cells().x + cell.x;
        atomicOr(&cut_mask[i >> 5u], 1u << (i & 31u));
    }
}

@compute @workgroup_size(8, 8, 1)
fn main(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(local_invocation_index) li: u32,
) {
    load_frame();
    if (li < N_COUNTERS) {
        atomicStore(&wg_count[li], 0u);
    }
    workgroupBarrier();
    // One invocation per subset cell: the cell's pixel this frame (every pixel when n is 1).
    // Every pixel with its first ray; the pixels that take more are left for `rework`.
    let marched = all(id.xy < subset_cells());
    let px = ray_point(pixel_of(id.xy));
    var s = Shaded(vec4<f32>(0.0), vec4<f32>(0.0), vec3<f32>(0.0), false, vec2<f32>(-1.0), 1.0);
    if (marched) {
        local_count[C_RAYS] = 1u;
        set_far(pixel_of(id.xy));
        s = first_ray(px, pixel_jitter(px));
    }
    var more = marched && !s.one_ray;
    // Only where the frame asks for it, compiled out elsewhere (`feature`).
    if (feature(FLAG_GRAZE) && !feature(FLAG_NO_SKY)) {
        let graze = needs_grazing_rays(li, marched, px, s);
        more = more || graze;
    }
    if (marched) {
        // The first ray's picture; a reworked pixel's is written over by `rework`.
        textureStore(out_cloud, vec2<i32>(id.xy), s.cloud);
        textureStore(out_scene, vec2<i32>(id.xy), s.scene);
        if (more) {
            leave_for_rework(id.xy, s);
        }
        mark_cut(id.xy);
        for (var k = 0u; k < N_COUNTERS; k++) {
            if (local_count[k] != 0u) {
                atomicAdd(&wg_count[k], local_count[k]);
            }
        }
    }
    workgroupBarrier();
    if (li < N_COUNTERS) {
        let v = atomicLoad(&wg_count[li]);
        if (v != 0u) {
            atomicAdd(&counters[li], v);
        }
    }
}

// The pixels `main` left (`ReworkList`), one invocation a ray: a grazing pixel's
// `GRAZE_EXTRA` side by side in the first workgroups (a SIMD lane group then marches
// neighbouring rays of two pixels, not one ray each of pixels far apart, whose step counts
// differ more), a split pixel's one in those after them. The pixel's first invocation averages
// them.
@compute @workgroup_size(REWORK_GROUP, 1, 1)
fn rework(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(local_invocation_index) li: u32,
) {
    load_frame();
    let len = arrayLength(&rework_list.entries);
    let grazes = atomicLoad(&rework_list.grazes);
    let per_group = REWORK_GROUP / GRAZE_EXTRA;
    let graze_lanes = (grazes + per_group - 1u) / per_group * REWORK_GROUP;
    let on_grazes = id.x < graze_lanes;
    let j = id.x - graze_lanes;
    let slot = select(len - 1u - min(j, len - 1u), id.x / GRAZE_EXTRA, on_grazes);
    let k = select(0u, id.x % GRAZE_EXTRA, on_grazes);
    let live = select(j < atomicLoad(&rework_list.splits), slot < grazes, on_grazes);
    var en = ReworkEntry(vec4<f32>(0.0), vec4<f32>(0.0), vec3<f32>(0.0), 0.0, vec2<f32>(0.0), 0u, 0u);
    if (live) {
        en = rework_list.entries[slot];
    }
    let cell = vec2<u32>(en.cell & 0xffffu, en.cell >> 16u);
    let pix = pixel_of(cell);
    let px = ray_point(pix);
    if (k < en.rays) {
        set_far(pix);
        let o = extra_ray(px, pixel_jitter(px), k, en, shown_at());
        wg_ray_c[li] = o.c;
        wg_ray_b[li] = vec4<f32>(o.bg, o.dist);
    }
    workgroupBarrier();
    if (live && k == 0u) {
        local_count[C_REWORK] = 1u;
        let s = reworked(en, li);
        textureStore(out_cloud, vec2<i32>(cell), s.cloud);
        textureStore(out_scene, vec2<i32>(cell), s.scene);
    }
    mark_cut(cell);
    for (var c = 0u; c < N_COUNTERS; c++) {
        if (local_count[c] != 0u) {
            atomicAdd(&counters[c], local_count[c]);
        }
    }
}
