// March stage: one compute invocation per pixel marches the view ray through the cloud shells
// (DESIGN §2–4) and writes premultiplied linear cloud radiance + opacity to a storage texture.

// Bind groups by lifetime: 0 lives as long as the device, 1 as the map, 2 as the output size.
@group(0) @binding(0) var<uniform> f: Frame;
@group(0) @binding(1) var shape_tex: texture_3d<f32>;
@group(0) @binding(2) var detail_tex: texture_3d<f32>;
@group(0) @binding(3) var clamp_lin: sampler;
@group(0) @binding(4) var repeat_lin: sampler;
@group(0) @binding(5) var<storage, read_write> counters: array<atomic<u32>, N_COUNTERS>;
@group(0) @binding(6) var profiles: texture_2d<f32>;     // per genus row: (P, D) by height fraction
@group(1) @binding(0) var weather: texture_2d<f32>;      // R low, G middle, B high, A total
@group(1) @binding(1) var coarse: texture_2d<f32>;       // max total cover per cell, dilated
// The map's structure (render::structure): R/G/B low/middle/high, A the convective cloud.
@group(1) @binding(2) var st_base: texture_2d<f32>;      // cloud base, m
@group(1) @binding(3) var st_top: texture_2d<f32>;       // cloud top, m
@group(1) @binding(4) var st_kind: texture_2d<f32>;      // genus code, nearest texel
@group(1) @binding(5) var st_wind: texture_2d<f32>;      // (u, v) high in RG, middle in BA, m/s
@group(2) @binding(0) var out_cloud: texture_storage_2d<rgba16float, write>;
@group(2) @binding(1) var<storage, read_write> cut_mask: array<atomic<u32>>;   // 1 bit per pixel

// Genus codes (stratus_ingest::weather::CloudType) and the profile table's rows.
const T_CIRRUS: f32 = 1.0;
const T_CIRROSTRATUS: f32 = 3.0;
const T_CUMULONIMBUS: f32 = 10.0;
const PROFILE_ROWS: f32 = 11.0;
const PROFILE_WIDTH: f32 = 64.0;
// The column thickness a layer's density is normalised to (render::frame::REFERENCE_THICKNESS_M).
const REFERENCE_THICKNESS_M: f32 = 2000.0;
// Half-length of a cirrus streak along the wind (m).
const STREAK_M: f32 = 2500.0;

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
const N_COUNTERS: u32 = 9u;

var<workgroup> wg_count: array<atomic<u32>, N_COUNTERS>;
var<private> local_count: array<u32, N_COUNTERS>;

struct Sample {
    cm: vec3<f32>,   // coverage per layer
    inside: bool,    // inside the region
};

fn weather_at(uv: vec2<f32>) -> Sample {
    var s: Sample;
    s.inside = uv.x >= 0.0;
    s.cm = vec3<f32>(0.0);
    if (s.inside) {
        let w = textureSampleLevel(weather, clamp_lin, uv, 0.0);
        // Layers that are off are never looked up (density_uv picks a drawn layer).
        s.cm = clamp(w.rgb * f.coverage_mul, vec3<f32>(0.0), vec3<f32>(1.0));
    }
    return s;
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

// The shape noise's low-frequency FBM at np, remapped by its Perlin-Worley channel (eqs 11–14).
fn shape_noise(np: vec3<f32>) -> f32 {
    let sn = textureSampleLevel(shape_tex, repeat_lin, np / f.shape_period_m, 0.0);
    let fbm = sn.g * 0.625 + sn.b * 0.25 + sn.a * 0.125;
    return remap(sn.r, fbm - 1.0, 1.0, 0.0, 1.0);
}

// Carve the noise: what survives the threshold `lo` (after scaling the noise by `ns_scale`),
// eroded by detail noise at the edges, times the density profile gd (DESIGN §2 eqs 15–18).
// `streak`: a half-length vector along the wind, or zero: the union of the noise shifted both
// ways along it draws the streaks of cirrus (a union of shifted blobs is a streak; stretching
// the coordinates instead would jump where the noise origin wraps by a period).
fn carve(np: vec3<f32>, ns_scale: f32, lo: f32, gd: f32, cm: f32, ph: f32, detail: bool, streak: vec3<f32>) -> f32 {
    var ns_tex = shape_noise(np);
    if (any(streak != vec3<f32>(0.0))) {
        ns_tex = max(ns_tex, max(shape_noise(np + streak), shape_noise(np - streak)));
    }
    let ns = sat(remap(ns_tex * ns_scale, lo, 1.0, 0.0, 1.0));
    if (ns <= 0.0) {
        return 0.0;
    }
    var nd_mod = 0.0;
    if (detail) {
        local_count[C_DETAIL] += 1u;
        let dn = textureSampleLevel(detail_tex, repeat_lin, np / f.detail_period_m, 0.0);
        let nd_fbm = dn.r * 0.625 + dn.g * 0.25 + dn.b * 0.125;
        nd_mod = 0.35 * exp(-0.75 * cm) * mix(nd_fbm, 1.0 - nd_fbm, sat(5.0 * ph));
    }
    return sat(remap(ns, nd_mod, 1.0, 0.0, 1.0)) * gd;
}

// DESIGN §2, eqs 5–18, for one layer band: coverage cm, height fraction ph, noise position np.
fn layer_density(np: vec3<f32>, cm: f32, ph: f32, detail: bool) -> f32 {
    let gs = sat(remap(ph, 0.0, 0.07, 0.0, 1.0)) * sat(remap(ph, 0.2 * cm, cm, 1.0, 0.0));
    let gd = ph * sat(remap(ph, 0.0, 0.15, 0.0, 1.0)) * sat(remap(ph, 0.9, 1.0, 1.0, 0.0)) * cm * 2.0;
    if (gs <= 0.0 || gd <= 0.0) {
        return 0.0;
    }
    return carve(np, gs, 1.0 - cm, gd, cm, ph, detail, vec3<f32>(0.0));
}

// DESIGN §7, one column of a genus: the threshold 1 − cm·P(h) from the genus' profile row, so
// the base is solid and flat and only the noise's peaks reach the top.
fn genus_density(np: vec3<f32>, cm: f32, ph: f32, code: f32, detail: bool, streak: vec3<f32>) -> f32 {
    let x = (ph * (PROFILE_WIDTH - 1.0) + 0.5) / PROFILE_WIDTH;
    let pd = textureSampleLevel(profiles, clamp_lin, vec2<f32>(x, (code + 0.5) / PROFILE_ROWS), 0.0);
    let gd = pd.g * cm * 2.0;
    if (pd.r <= 0.0 || gd <= 0.0) {
        return 0.0;
    }
    // The threshold sees coverage^γ (render::profile::Shape::gamma): opacity follows coverage.
    return carve(np, 1.0, 1.0 - pow(cm, pd.b) * pd.r, gd, cm, ph, detail, streak);
}

// A cheap hash of a 200 m cell of noise space, in 0..1.
fn cell_hash(np: vec3<f32>) -> f32 {
    let c = vec3<u32>(vec3<i32>(floor(np / 200.0)));
    var x = c.x * 73856093u ^ c.y * 19349663u ^ c.z * 83492791u;
    x = (x ^ (x >> 16u)) * 0x45d9f3bu;
    x = x ^ (x >> 16u);
    return f32(x & 0xffffu) / 65535.0;
}

// Unit vector toward the wind (u east, v north) at map uv, or zero in calm air.
fn wind_dir(uv: vec2<f32>, w: vec2<f32>) -> vec3<f32> {
    if (dot(w, w) < 1.0) {
        return vec3<f32>(0.0);
    }
    let lat = radians(f.region_north - uv.y * (f.region_north - f.region_south));
    let lon = radians(f.region_west + uv.x * f.region_lon_span);
    let east = vec3<f32>(-sin(lon), cos(lon), 0.0);
    let north = vec3<f32>(-sin(lat) * cos(lon), -sin(lat) * sin(lon), cos(lat));
    return normalize(w.x * east + w.y * north);
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
    let towers = has_flag(f, FLAG_TOWERS);
    var k = -1;
    var best = 0.0;
    var tower_cm = 0.0;
    for (var j = 0; j < 3; j++) {
        if (f.layer_scale[j] > 0.0) {
            if (towers && kind[j] == T_CUMULONIMBUS) {
                tower_cm = max(tower_cm, s.cm[j]);
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
    if (tower_cm > 0.0 && h >= b.a && h <= t.a) {
        base = b.a;
        top = t.a;
        cm = tower_cm;
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
    let thick = max(top - base, 1.0);
    let ph = (h - base) / thick;
    // A column's optical depth follows its coverage, not its thickness (as for bands, frame.rs).
    let scale = clamp(REFERENCE_THICKNESS_M / thick, 0.25, 4.0) * f.density_mul;
    if (code < 0.5) {
        return layer_density(np, cm, ph, detail) * scale;
    }
    var streak = vec3<f32>(0.0);
    if (has_flag(f, FLAG_STREAKS) && code >= T_CIRRUS && code <= T_CIRROSTRATUS) {
        // Streaks along the layer's wind, sheared downwind with height (fall streaks trail).
        let w = textureSampleLevel(st_wind, clamp_lin, su, 0.0);
        let dir = wind_dir(uv, select(w.zw, w.xy, k == 2));
        streak = dir * STREAK_M;
        return genus_density(np + dir * (ph * STREAK_M), cm, ph, code, detail, streak) * scale;
    }
    return genus_density(np, cm, ph, code, detail, streak) * scale;
}

// Density (unitless, DESIGN's d summed over layers) at altitude h, direction pos, noise np.
// Map uv of a sample (negative u outside the region): one lat/lon per step, shared by the
// coarse-map test and the weather lookup (on a CPU driver the step's fixed cost dominates).
fn sample_uv(pos: vec3<f32>) -> vec2<f32> {
    return region_uv(f, lat_lon(pos));
}

fn density(pos: vec3<f32>, h: f32, np: vec3<f32>, detail: bool) -> f32 {
    // Checked here as well as in density_uv so a light sample outside the shells costs no lat/lon.
    if (h < f.shell_base_m || h > f.shell_top_m) {
        return 0.0;
    }
    return density_uv(sample_uv(pos), h, np, detail);
}

fn density_uv(uv: vec2<f32>, h: f32, np: vec3<f32>, detail: bool) -> f32 {
    if (h < f.shell_base_m || h > f.shell_top_m) {
        return 0.0;
    }
    let s = weather_at(uv);
    let cull = has_flag(f, FLAG_CULL);
    if (!s.inside) {
        if (cull) {
            return 0.0;
        }
        local_count[C_OUTSIDE] += 1u;
    }
    if (has_flag(f, FLAG_STRUCTURE)) {
        // Outside every layer's envelope and the towers' there is nothing to look up.
        let in_tower = h >= f.tower_base_m && h <= f.tower_top_m;
        var in_layer = false;
        for (var j = 0; j < 3; j++) {
            in_layer = in_layer || (f.layer_scale[j] > 0.0 && h >= f.layer_base[j] && h <= f.layer_top[j] && s.cm[j] > 0.0);
        }
        if (!in_tower && !in_layer) {
            return 0.0;
        }
        return column_density(uv, h, np, detail, s);
    }
    // The drawn bands are disjoint (frame.rs makes them so): one layer at most holds h, and only
    // its density is evaluated. A SIMD CPU driver (lavapipe) executes both sides of every branch,
    // so a loop calling layer_density per layer would cost three evaluations on every sample.
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
    let base = f.layer_base[k];
    let ph = (h - base) / max(f.layer_top[k] - base, 1.0);
    return layer_density(np, s.cm[k], ph, detail) * f.layer_scale[k] * f.density_mul;
}

struct Ray {
    h: f32,          // origin altitude (m)
    up: vec3<f32>,   // local up at the origin
    d: vec3<f32>,    // direction
    np: vec3<f32>,   // noise-space origin (m)
};

fn make_ray(px: vec2<f32>) -> Ray {
    var r: Ray;
    let size = f.out_size;
    if (has_flag(f, FLAG_NO_SKY)) {
        // Top-down: one nadir ray per map pixel centre (DESIGN §1.2 pixel convention).
        let lat = radians(f.region_north - px.y / size.y * (f.region_north - f.region_south));
        let lon = radians(f.region_west + px.x / size.x * f.region_lon_span);
        r.up = vec3<f32>(cos(lat) * cos(lon), cos(lat) * sin(lon), sin(lat));
        r.h = f.cam_alt_m;
        r.d = -r.up;
        let o = r.up * (EARTH_R + r.h);
        r.np = o - f.shape_period_m * floor(o / f.shape_period_m);
    } else {
        r.d = persp_dir(f, px);
        r.up = f.cam_up;
        r.h = f.cam_alt_m;
        r.np = f.noise_origin;
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
        tau += density(pl, hl, np + key * sm, false) * f.extinction * ds;
    }
    return tau;
}

const MIN_SEG_STEPS: f32 = 16.0;
// Clear-air stride: normal steps taken after the last cloud sample before striding again.
const FINE_AFTER_CLOUD: u32 = 8u;

// Where a segment's march starts and its longest step: at least MIN_SEG_STEPS samples per
// crossing of the layer shells, so a steep ray through a thin layer (400 hPa is ~700 m) does not
// take one or two jittered samples and show the jitter pattern instead of the cloud.
fn seg_start(seg: vec2<f32>, jitter: f32) -> vec2<f32> {
    let seg_dt = max((seg.y - seg.x) / MIN_SEG_STEPS, 1.0);
    let t = seg.x + jitter * min(clamp(f.step_min_m + f.step_growth * seg.x, f.step_min_m, f.step_max_m), seg_dt);
    return vec2<f32>(t, seg_dt);
}

fn march(r: Ray, jitter: f32) -> vec4<f32> {
    let mu = dot(r.d, r.up);
    let outer = shell_hits(r.h, mu, f.shell_top_m);
    if (outer.y < 0.0 || outer.x > outer.y) {
        return vec4<f32>(0.0);
    }
    // Beyond five visibility lengths the haze hides everything (haze_cutoff_m). Haze lives in the low
    // atmosphere, so the length counts from where the ray enters the cloud shells: a camera in
    // orbit still sees the deck below it.
    var end_all = min(outer.y, max(outer.x, 0.0) + f.haze_cutoff_m);
    let ground = shell_hits(r.h, mu, 0.0);
    if (ground.x <= ground.y && ground.y > 0.0) {
        end_all = min(end_all, max(ground.x, 0.0));
    }
    // At most two segments: above and below the innermost shell's bottom.
    let inner = shell_hits(r.h, mu, f.shell_base_m);
    var seg = vec2<f32>(max(outer.x, 0.0), end_all);
    var seg2 = vec2<f32>(1.0, 0.0);
    if (inner.x <= inner.y && inner.y > 0.0) {
        seg = vec2<f32>(max(outer.x, 0.0), min(end_all, inner.x));
        seg2 = vec2<f32>(max(max(outer.x, 0.0), inner.y), end_all);
    }

    let no_sky = has_flag(f, FLAG_NO_SKY);
    let skip = has_flag(f, FLAG_SKIP);
    let lod = has_flag(f, FLAG_LIGHT_LOD);
    let may_stride = has_flag(f, FLAG_STRIDE);
    // The score's top-down columns stride at most 2×: there a wisp jumped over is a mask pixel
    // lost (at 4× the top-down RGB error against reference rose from 0.006 to 0.023).
    let max_mult = select(4.0, 2.0, no_sky);
    let detail = has_flag(f, FLAG_DETAIL);
    let sun_key = f.sun_is_key != 0u;
    let cos_t = dot(r.d, select(f.moon_dir, f.sun_dir, sun_key));
    let g = f.hg_g;
    let ph_fn = phase(cos_t, g);
    let powder_w = remap(cos_t, -1.0, 1.0, 0.0, 1.0);
    let max_steps = f.max_steps;
    let early = f.early_exit;
    let n_light = f.light_steps;
    let origin = r.up * (EARTH_R + r.h);

    var tr = 1.0;
    var col = vec3<f32>(0.0);
    var depth_w = 0.0;
    var steps = 0u;
    var second = false;
    var st = seg_start(seg, jitter);
    var t = st.x;
    var seg_dt = st.y;
    var stride = false;
    var mult = 1.0;
    var fine_left = 0u;
    var finished = false;
    // Whether the last sample was clear: a cloud met after clear air has its edge refined.
    var prev_clear = true;
    // Two nested loops: the inner one walks to the next sample with cloud, looking up density
    // only; the outer one lights that sample. On a GPU this is the same march as one loop. On a
    // SIMD CPU driver, where every branch is executed under a mask, it keeps the light march
    // and shading out of clear-air steps (measured: docs/performance.md).
    loop {
        var sigma = 0.0;
        var dt = 0.0;
        var uv = vec2<f32>(0.0);
        var h = 0.0;
        var found = false;
        loop {
            if (t >= seg.y) {
                if (second) {
                    finished = true;
                    break;
                }
                second = true;
                seg = seg2;
                st = seg_start(seg, jitter);
                t = st.x;
                seg_dt = st.y;
                stride = false;
                mult = 1.0;
                fine_left = 0u;
                continue;
            }
            if (steps >= max_steps) {
                finished = true;
                break;
            }
            steps += 1u;
            dt = min(clamp(f.step_min_m + f.step_growth * t, f.step_min_m, f.step_max_m), seg_dt);
            uv = sample_uv(origin + r.d * t);
            if (skip && coarse_empty(uv)) {
                local_count[C_SKIPPED] += 1u;
                t += max(dt, f.skip_m);
                continue;
            }
            h = altitude_at(r.h, mu, t);
            sigma = density_uv(uv, h, r.np + r.d * t, detail) * f.extinction;
            if (sigma > 0.0 && stride) {
                // Met cloud on a long step: back up to the last clear sample and go on at the
                // normal step, so the cloud's near edge is found at full resolution.
                stride = false;
                fine_left = FINE_AFTER_CLOUD;
                t = max(t - dt * mult, seg.x);
                mult = 1.0;
                continue;
            }
            if (sigma > 0.0) {
                if (prev_clear && t - dt > seg.x) {
                    // Entering cloud from clear air: bisect the step for the edge. A dense
                    // cloud is opaque within one step, so its colour is that of the sample;
                    // at a fixed step that sample's depth inside the edge (and so its light)
                    // would follow the step's phase, drawing contour rings over the relief.
                    var lo_t = t - dt;
                    for (var i = 0; i < 4; i++) {
                        let mid = 0.5 * (lo_t + t);
                        let uv_m = sample_uv(origin + r.d * mid);
                        let s_m = density_uv(uv_m, altitude_at(r.h, mu, mid), r.np + r.d * mid, detail) * f.extinction;
                        if (s_m > 0.0) {
                            t = mid;
                            sigma = s_m;
                            uv = uv_m;
                        } else {
                            lo_t = mid;
                        }
                    }
                    h = altitude_at(r.h, mu, t);
                }
                prev_clear = false;
                fine_left = FINE_AFTER_CLOUD;
                found = true;
                break;
            }
            prev_clear = true;
            if (fine_left > 0u) {
                fine_left -= 1u;
            } else if (may_stride) {
                stride = true;
                mult = min(mult * 2.0, max_mult);
            }
            t += select(dt, mult * dt, stride);
        }
        if (!found) {
            break;
        }
        let pos = origin + r.d * t;
        let np = r.np + r.d * t;
        let up = normalize(pos);
        var key = select(f.moon_dir, f.sun_dir, sun_key);
        var key_col = select(f.moon_col, f.sun_col, sun_key);
        var ambient = sky_radiance(f, up, up);
        if (no_sky) {
            key = up;
            key_col = vec3<f32>(1.0);
            ambient = vec3<f32>(0.3);
        }
        var nl = n_light;
        if (lod && tr < 0.3) {
            nl = max(1u, n_light / 2u);
        }
        let tau = light_depth(pos, h, np, key, nl);
        // Eq. 22's clamp as a floor under Beer (ac·exp(-τ/4)) so deep cloud does not go
        // black, plus two octaves of Hillaire's multiple-scattering approximation
        // (extinction, phase g and energy each halved per octave).
        let powder = 1.0 - exp(-2.0 * tau);
        var ms = max(exp(-tau), f.beer_clamp * exp(-0.25 * tau)) * ph_fn;
        ms += 0.5 * exp(-0.5 * tau) * phase(cos_t, 0.5 * g);
        ms += 0.25 * exp(-0.25 * tau) * phase(cos_t, 0.25 * g);
        let lit = key_col * SUN_I * ms * mix(2.0 * powder, 1.0, powder_w);
        let ph_amb = sat((h - f.shell_base_m) / max(f.shell_top_m - f.shell_base_m, 1.0));
        let l_in = lit + ambient * (0.5 + 0.5 * ph_amb);
        // Energy-conserving step (Hillaire 2016) with albedo 1: C += T (1 - a) L.
        let a = exp(-sigma * dt);
        col += tr * (1.0 - a) * l_in;
        depth_w += tr * (1.0 - a) * t;
        tr *= a;
        if (tr < early) {
            // Opaque enough: call it opaque, and give the cut-off remainder to what was seen
            // (renormalise) rather than to the background.
            local_count[C_EARLY] += 1u;
            col /= max(1.0 - tr, 1e-6);
            depth_w /= max(1.0 - tr, 1e-6);
            tr = 0.0;
            finished = true;
            break;
        }
        t += dt;
    }
    if (!finished) {
        local_count[C_CUT] += 1u;
    }
    local_count[C_STEPS] += steps;
    let alpha = 1.0 - tr;
    if (alpha <= 0.0) {
        return vec4<f32>(0.0);
    }
    if (!no_sky) {
        // Aerial haze (Koschmieder) toward the opacity-weighted cloud distance.
        let dist = depth_w / alpha;
        let fog = haze_transmittance(f, r.h, altitude_at(r.h, mu, dist), dist);
        let haze = sky_radiance(f, r.d, r.up);
        col = col * fog + haze * alpha * (1.0 - fog);
    }
    return vec4<f32>(col, alpha);
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) id: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    if (li < N_COUNTERS) {
        atomicStore(&wg_count[li], 0u);
    }
    workgroupBarrier();
    let size = vec2<u32>(f.out_size);
    if (all(id.xy < size)) {
        let px = vec2<f32>(id.xy) + 0.5;
        var jitter = 0.5;
        if (has_flag(f, FLAG_JITTER)) {
            // Interleaved gradient noise (Jimenez 2014), shifted per frame.
            let q = px + vec2<f32>(5.588238 * f.frame_index);
            jitter = fract(52.9829189 * fract(dot(q, vec2<f32>(0.06711056, 0.00583715))));
        }
        local_count[C_RAYS] = 1u;
        let c = march(make_ray(px), jitter);
        textureStore(out_cloud, vec2<i32>(id.xy), c);
        if (local_count[C_CUT] != 0u) {
            let i = id.y * size.x + id.x;
            atomicOr(&cut_mask[i >> 5u], 1u << (i & 31u));
        }
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
