// Atmosphere stage: the precomputed sky (Hillaire, "A Scalable and Production Ready Sky and
// Atmosphere Rendering Technique", EGSR 2020; DESIGN §8). Three entry points, three tables:
// `transmittance` (once per device) the air's transmittance from any altitude along any
// zenith angle; `multiscatter` (once) the light scattered more than once, per altitude and Sun
// zenith angle; `sky_view` (when the Sun or the camera's altitude moves) the sky's radiance
// around the camera, per azimuth from the Sun and elevation; `aerial` (with it) the same rays cut
// at 32 distances, the aerial perspective of ground and cloud. Earth's shadow comes out of the
// transmittance: a point of air the Earth hides from the Sun scatters none of its light.

@group(1) @binding(0) var lut_out: texture_storage_2d<rgba16float, write>;
@group(2) @binding(0) var trans_lut: texture_2d<f32>;
@group(2) @binding(1) var ms_lut: texture_2d<f32>;
@group(2) @binding(2) var lut_sampler: sampler;
// The aerial-perspective table (the `aerial` entry only).
@group(3) @binding(0) var ap_out: texture_storage_3d<rgba16float, write>;

const ATMO_TOP_M: f32 = 100000.0;
// Rayleigh and Mie scattering at sea level (1/m) and scale heights (m); ozone absorption. The
// green Rayleigh and the Mie extinction are the clear air the haze leaves out (Rust:
// frame::CLEAR_AIR_EXTINCTION; shared through render::contract).
const RAYLEIGH_GREEN: f32 = 13.558e-6;
const RAYLEIGH: vec3<f32> = vec3<f32>(5.802e-6, RAYLEIGH_GREEN, 33.1e-6);
const RAYLEIGH_H: f32 = 8000.0;
const MIE_SCATTER: f32 = 3.996e-6;
const MIE_EXTINCT: f32 = 4.40e-6;
const MIE_H: f32 = 1200.0;
const MIE_G: f32 = 0.8;
const OZONE: vec3<f32> = vec3<f32>(0.650e-6, 1.881e-6, 0.085e-6);
// Light the ground sends back into the air (the multiple-scattering table's ground).
const GROUND_ALBEDO: f32 = 0.3;

struct Medium {
    scatter_r: vec3<f32>,
    scatter_m: f32,
    extinct: vec3<f32>,
};

fn medium(h: f32) -> Medium {
    var m: Medium;
    let hh = max(h, 0.0);
    let dr = exp(-hh / RAYLEIGH_H);
    let dm = exp(-hh / MIE_H);
    let oz = max(0.0, 1.0 - abs(hh - 25000.0) / 15000.0);
    m.scatter_r = RAYLEIGH * dr;
    m.scatter_m = MIE_SCATTER * dm;
    m.extinct = m.scatter_r + vec3<f32>(MIE_EXTINCT * dm) + OZONE * oz;
    return m;
}

fn rayleigh_phase(c: f32) -> f32 {
    return 3.0 / (16.0 * PI) * (1.0 + c * c);
}

// Cornette–Shanks, the Mie phase Hillaire uses.
fn mie_phase(c: f32) -> f32 {
    let g = MIE_G;
    let k = 3.0 / (8.0 * PI) * (1.0 - g * g) / (2.0 + g * g);
    return k * (1.0 + c * c) / pow(max(1.0 + g * g - 2.0 * g * c, 1e-4), 1.5);
}

// Distance from altitude h along zenith cosine mu to the top of the air (shell_hits' far root).
fn to_top(h: f32, mu: f32) -> f32 {
    return max(shell_hits(h, mu, ATMO_TOP_M).y, 0.0);
}

fn hits_ground(h: f32, mu: f32) -> bool {
    let g = shell_hits(h, mu, 0.0);
    return mu < 0.0 && g.x <= g.y && g.y > 0.0;
}

// The transmittance table's (altitude, zenith cosine) ↔ uv (Bruneton's mapping, which puts
// texels where the transmittance changes: near the horizon).
fn trans_uv(h: f32, mu: f32) -> vec2<f32> {
    let rg = EARTH_R;
    let rt = EARTH_R + ATMO_TOP_M;
    let r = EARTH_R + clamp(h, 0.0, ATMO_TOP_M);
    let big_h = sqrt(rt * rt - rg * rg);
    let rho = sqrt(max(r * r - rg * rg, 0.0));
    let d = to_top(r - EARTH_R, mu);
    let d_min = rt - r;
    let d_max = rho + big_h;
    return vec2<f32>((d - d_min) / max(d_max - d_min, 1.0), rho / big_h);
}

fn trans_from_uv(uv: vec2<f32>) -> vec2<f32> {
    let rg = EARTH_R;
    let rt = EARTH_R + ATMO_TOP_M;
    let big_h = sqrt(rt * rt - rg * rg);
    let rho = big_h * uv.y;
    let r = sqrt(rho * rho + rg * rg);
    let d_min = rt - r;
    let d_max = rho + big_h;
    let d = d_min + uv.x * (d_max - d_min);
    var mu = 1.0;
    if (d > 0.0) {
        mu = clamp((big_h * big_h - rho * rho - d * d) / (2.0 * r * d), -1.0, 1.0);
    }
    return vec2<f32>(r - EARTH_R, mu);
}

// Transmittance of the air from altitude h toward zenith cosine mu; 0 where the Earth is in
// the way.
fn air_transmittance(h: f32, mu: f32) -> vec3<f32> {
    if (hits_ground(h, mu)) {
        return vec3<f32>(0.0);
    }
    return textureSampleLevel(trans_lut, lut_sampler, trans_uv(h, mu), 0.0).rgb;
}

fn ms_uv(h: f32, mu_s: f32) -> vec2<f32> {
    return vec2<f32>(mu_s * 0.5 + 0.5, sat(h / ATMO_TOP_M));
}

@compute @workgroup_size(8, 8, 1)
fn transmittance(@builtin(global_invocation_id) id: vec3<u32>) {
    load_frame();
    let dims = textureDimensions(lut_out);
    if (any(id.xy >= dims)) {
        return;
    }
    let hm = trans_from_uv((vec2<f32>(id.xy) + 0.5) / vec2<f32>(dims));
    let d = to_top(hm.x, hm.y);
    let n = 40u;
    var od = vec3<f32>(0.0);
    for (var i = 0u; i < n; i++) {
        let t = (f32(i) + 0.5) / f32(n) * d;
        od += medium(altitude_at(hm.x, hm.y, t)).extinct * (d / f32(n));
    }
    textureStore(lut_out, id.xy, vec4<f32>(exp(-od), 1.0));
}

// Hillaire's Ψ_ms: the second-order light at a point over a unit illuminance, summed to all
// orders as a geometric series 1/(1 − f_ms), isotropic; 8×8 directions, 20 steps each.
@compute @workgroup_size(8, 8, 1)
fn multiscatter(@builtin(global_invocation_id) id: vec3<u32>) {
    load_frame();
    let dims = textureDimensions(lut_out);
    if (any(id.xy >= dims)) {
        return;
    }
    let uv = (vec2<f32>(id.xy) + 0.5) / vec2<f32>(dims);
    let mu_s = uv.x * 2.0 - 1.0;
    let h = uv.y * ATMO_TOP_M;
    let up = vec3<f32>(0.0, 0.0, 1.0);
    let sun = vec3<f32>(sqrt(max(1.0 - mu_s * mu_s, 0.0)), 0.0, mu_s);
    var l2 = vec3<f32>(0.0);
    var fms = vec3<f32>(0.0);
    let nd = 8u;
    for (var a = 0u; a < nd; a++) {
        for (var b = 0u; b < nd; b++) {
            // Even in cos θ and φ: equal solid angles.
            let ct = 1.0 - 2.0 * (f32(a) + 0.5) / f32(nd);
            let ph = 2.0 * PI * (f32(b) + 0.5) / f32(nd);
            let st = sqrt(max(1.0 - ct * ct, 0.0));
            let v = vec3<f32>(st * cos(ph), st * sin(ph), ct);
            let ground = hits_ground(h, ct);
            var d = to_top(h, ct);
            if (ground) {
                d = shell_hits(h, ct, 0.0).x;
            }
            let n = 20u;
            let dt = d / f32(n);
            var tr = vec3<f32>(1.0);
            for (var i = 0u; i < n; i++) {
                let t = (f32(i) + 0.5) * dt;
                let hs = altitude_at(h, ct, t);
                let m = medium(hs);
                let p = up * (EARTH_R + h) + v * t;
                let mus = dot(normalize(p), sun);
                let ts = air_transmittance(hs, mus);
                let s = m.scatter_r + vec3<f32>(m.scatter_m);
                let step_tr = exp(-m.extinct * dt);
                // ∫ over the step of the transmittance: (1 − e^{-σΔt})/σ.
                let w = tr * (vec3<f32>(1.0) - step_tr) / max(m.extinct, vec3<f32>(1e-12));
                l2 += w * s * ts / (4.0 * PI);
                fms += w * s / (4.0 * PI);
                tr *= step_tr;
            }
            if (ground) {
                let p = up * EARTH_R + v * d;
                let n_g = normalize(p);
                let ts = air_transmittance(0.0, dot(n_g, sun));
                l2 += tr * ts * max(dot(n_g, sun), 0.0) * GROUND_ALBEDO / PI;
            }
        }
    }
    // Each direction stands for 4π/N of the sphere; the light arriving along it is scattered
    // on isotropically (p_u = 1/4π, the paper's eq. 5), while f_ms (eq. 6) already carries its
    // p_u inside the sum.
    let k = 4.0 * PI / f32(nd * nd);
    l2 *= k / (4.0 * PI);
    fms *= k;
    let psi = l2 / max(vec3<f32>(1.0) - fms, vec3<f32>(1e-3));
    textureStore(lut_out, id.xy, vec4<f32>(psi, 1.0));
}

// The sky-view table's elevation coordinate: half the rows above the camera's horizon, half
// below, square-root spaced so texels crowd at the horizon (scene.wgsl's sky_view_uv inverts it).
fn sky_elev_from_v(v: f32, h: f32) -> f32 {
    let eh = horizon_elev(h);
    if (v >= 0.5) {
        let x = (v - 0.5) * 2.0;
        return eh + x * x * (0.5 * PI - eh);
    }
    let x = (0.5 - v) * 2.0;
    return eh - x * x * (eh + 0.5 * PI);
}

// A ray of the sky-view and aerial-perspective tables: texel uv → direction and zenith cosine
// at the camera, and where it leaves the air or meets the (sea-level) ground.
struct SkyRay {
    v: vec3<f32>,
    mu: f32,
    h: f32,
    end: f32,
};

fn sky_ray(uv: vec2<f32>) -> SkyRay {
    var r: SkyRay;
    r.h = clamp(f.cam_alt_m, 0.0, ATMO_TOP_M - 1.0);
    let frame = sky_frame();
    let az = (uv.x - 0.5) * 2.0 * PI;
    let el = sky_elev_from_v(uv.y, r.h);
    r.v = normalize(f.cam_up * sin(el) + (frame[0] * cos(az) + frame[1] * sin(az)) * cos(el));
    r.mu = sin(el);
    r.end = to_top(r.h, r.mu);
    if (hits_ground(r.h, r.mu)) {
        r.end = shell_hits(r.h, r.mu, 0.0).x;
    }
    return r;
}

// The Sun's light scattered toward the camera by the air between t0 and t1 along r, per unit
// transmittance at t0 (single scattering through the transmittance table plus Ψ_ms), and the
// transmittance over the segment.
struct Segment {
    light: vec3<f32>,
    tr: vec3<f32>,
};

fn air_segment(r: SkyRay, t0: f32, t1: f32) -> Segment {
    var out: Segment;
    let c = dot(r.v, f.sun_dir);
    let pr = rayleigh_phase(c);
    let pm = mie_phase(c);
    let dt = t1 - t0;
    let t = 0.5 * (t0 + t1);
    let hs = altitude_at(r.h, r.mu, t);
    let m = medium(hs);
    let p = f.cam_up * (EARTH_R + r.h) + r.v * t;
    let mus = dot(normalize(p), f.sun_dir);
    let ts = air_transmittance(hs, mus);
    let psi = textureSampleLevel(ms_lut, lut_sampler, ms_uv(hs, mus), 0.0).rgb;
    let sc = m.scatter_r * (pr * ts + psi) + m.scatter_m * (pm * ts + psi);
    out.tr = exp(-m.extinct * dt);
    // ∫ over the segment of the transmittance: (1 − e^{-σΔt})/σ.
    out.light = sc * (vec3<f32>(1.0) - out.tr) / max(m.extinct, vec3<f32>(1e-12));
    return out;
}

@compute @workgroup_size(8, 8, 1)
fn sky_view(@builtin(global_invocation_id) id: vec3<u32>) {
    load_frame();
    let dims = textureDimensions(lut_out);
    if (any(id.xy >= dims)) {
        return;
    }
    let r = sky_ray((vec2<f32>(id.xy) + 0.5) / vec2<f32>(dims));
    let n = 32u;
    var tr = vec3<f32>(1.0);
    var l = vec3<f32>(0.0);
    var t0 = 0.0;
    for (var i = 0u; i < n; i++) {
        // Quadratic spacing: short steps near the camera where the air is densest.
        let x1 = (f32(i) + 1.0) / f32(n);
        let t1 = r.end * x1 * x1;
        let seg = air_segment(r, t0, t1);
        l += tr * seg.light;
        tr *= seg.tr;
        t0 = t1;
    }
    textureStore(lut_out, id.xy, vec4<f32>(l * SUN_I, 1.0));
}

// Slice k of the aerial-perspective table holds, along its texel's ray, the light the air
// scatters toward the camera from 0 to AP_MAX_M·((k + 1)/n)² (rgb) and the mean of the
// transmittance over that distance (a); two steps per slice, none past the ground or the top.
@compute @workgroup_size(8, 8, 1)
fn aerial(@builtin(global_invocation_id) id: vec3<u32>) {
    load_frame();
    let dims = textureDimensions(ap_out);
    if (any(id.xy >= dims.xy)) {
        return;
    }
    let r = sky_ray((vec2<f32>(id.xy) + 0.5) / vec2<f32>(dims.xy));
    var tr = vec3<f32>(1.0);
    var l = vec3<f32>(0.0);
    var t0 = 0.0;
    for (var k = 0u; k < dims.z; k++) {
        let x = (f32(k) + 1.0) / f32(dims.z);
        let t_end = min(AP_MAX_M * x * x, r.end);
        let half = 0.5 * max(t_end - t0, 0.0);
        for (var j = 0u; j < 2u; j++) {
            let seg = air_segment(r, t0, t0 + half);
            l += tr * seg.light;
            tr *= seg.tr;
            t0 += half;
        }
        textureStore(ap_out, vec3<u32>(id.xy, k), vec4<f32>(l * SUN_I, dot(tr, vec3<f32>(1.0 / 3.0))));
    }
}
