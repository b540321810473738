// The scene around the cloud, shared by the stages that light it or show it (march, present,
// exposure; prepended after common.wgsl): the full-column optical-depth volume the shadow stage
// made (render::shadow), the light that comes through it, and the background a view ray meets
// where there is no cloud (sky, Sun, Moon, stars, ground in the clouds' shadows).
@group(3) @binding(0) var od_tex: texture_3d<f32>;
@group(3) @binding(1) var od_sampler: sampler;
@group(3) @binding(2) var<storage, read> sh: ShadowParams;   // storage: see render::contract::params
// The sky around the camera (render::atmosphere's sky-view table).
@group(3) @binding(3) var sky_tex: texture_2d<f32>;
// The map's ground (render::ground): terrain height (m) and surface albedo (RGB).
@group(3) @binding(4) var ground_tex: texture_2d<f32>;
// The clear air's light and transmittance along view rays (render::atmosphere's aerial table).
@group(3) @binding(5) var ap_tex: texture_3d<f32>;

// Asymmetry of cloud droplets' scattering, for the diffuse (two-stream) light (DESIGN §8).
const G_CLOUD: f32 = 0.85;

// Optical depth of the cloud column from a point at altitude h: x toward the key light, y
// straight up (the volume's mean, smooth). Zero outside the region and above the volume.
fn column_od(pos: vec3<f32>, h: f32) -> vec2<f32> {
    if (sh.enabled == 0u) {
        return vec2<f32>(0.0);
    }
    let uv = region_uv(lat_lon(pos));
    let w = (h - sh.bottom_m) / max(sh.top_m - sh.bottom_m, 1.0);
    if (uv.x < 0.0 || w >= 1.0) {
        return vec2<f32>(0.0);
    }
    return textureSampleLevel(od_tex, od_sampler, vec3<f32>(uv, max(w, 0.0)), 0.0).rg;
}

// Two-stream diffuse transmittance of a cloud of optical depth tau (DESIGN §8): the share of
// the light that comes through a deck by multiple scattering, 1/(1 + ¾(1 − g)τ).
fn diffuse_t(tau: f32) -> f32 {
    return 1.0 / (1.0 + 0.75 * (1.0 - G_CLOUD) * tau);
}

// The key light's irradiance factor through a column of optical depth tau along its path, at a
// cosine mu0 to the local vertical: the direct beam (Beer) or, under thick cloud, the diffuse
// light a plane-parallel deck of vertical depth tau·mu0 lets through, whichever is more.
fn key_through(tau: f32, mu0: f32) -> f32 {
    return max(exp(-tau), diffuse_t(tau * max(mu0, 0.1)));
}

// Ground albedo where the map has no ground (a dull land; render::ground's stand-in texel too,
// shared through render::contract).
const DEFAULT_ALBEDO: vec3<f32> = vec3<f32>(0.08, 0.10, 0.07);

// The ground at region uv: (terrain height m, albedo rgb); sea level and the default outside
// the region or without a ground.
fn ground_at(uv: vec2<f32>) -> vec4<f32> {
    if (sh.ground_on == 0u || uv.x < 0.0) {
        return vec4<f32>(0.0, DEFAULT_ALBEDO);
    }
    let g = textureSampleLevel(ground_tex, od_sampler, uv * sh.ground_uv.xy + sh.ground_uv.zw, 0.0);
    return vec4<f32>(max(g.r, 0.0), g.gba);
}

// Terrain samples along a ray and the halvings that refine the hit.
const TERRAIN_STEPS: u32 = 48u;
const TERRAIN_REFINE: u32 = 6u;

// Where the last `terrain_hit` that met the terrain was last above it: the distance its
// bisection left below the hit. A ray above that one, from the same camera, is above the
// terrain there too (march.wgsl `terrain_share`).
var<private> terrain_clear_to: f32 = 0.0;

// Distance along the ray from altitude h (zenith cosine mu to the local up, direction d from
// origin o) to the terrain, or -1 where it meets none between `t_min` and `t_max`. Marched as a
// height field below the highest terrain, in steps growing with distance, then bisected
// (`refine`; a caller that asks only whether it meets the terrain needs no bisection).
fn terrain_hit(o: vec3<f32>, h: f32, mu: f32, d: vec3<f32>, t_min: f32, t_max: f32, refine: bool) -> f32 {
    if (sh.terrain_on == 0u) {
        return -1.0;
    }
    let top = shell_hits(h, mu, sh.ground_top_m + 1.0);
    var t0 = t_min;
    if (h > sh.ground_top_m + 1.0) {
        if (top.x > top.y || top.y < 0.0) {
            return -1.0;
        }
        t0 = max(top.x, t_min);
    }
    // Below the top the ray leaves the terrain's shell at top.y (or runs on to t_max).
    var t1 = t_max;
    if (top.x <= top.y && top.y > t0) {
        t1 = min(t1, top.y);
    }
    if (t1 <= t0) {
        return -1.0;
    }
    var lo = t0;
    var prev = t0;
    var hit = -1.0;
    for (var i = 0u; i < TERRAIN_STEPS; i++) {
        let x = (f32(i) + 1.0) / f32(TERRAIN_STEPS);
        let t = t0 + (t1 - t0) * x * x;
        let p = o + d * t;
        if (altitude_at(h, mu, t) <= ground_at(region_uv(lat_lon(p))).x) {
            lo = prev;
            hit = t;
            break;
        }
        prev = t;
    }
    if (hit < 0.0 || !refine) {
        return hit;
    }
    for (var k = 0u; k < TERRAIN_REFINE; k++) {
        let t = 0.5 * (lo + hit);
        let p = o + d * t;
        if (altitude_at(h, mu, t) <= ground_at(region_uv(lat_lon(p))).x) {
            hit = t;
        } else {
            lo = t;
        }
    }
    terrain_clear_to = lo;
    return hit;
}

// Along v from the camera: x the distance to sea level (-1 where the ray misses the Earth), y
// to the terrain before it (-1 where it meets none).
fn ground_reach(v: vec3<f32>) -> vec2<f32> {
    return reach_along(v, 0.0, true);
}

// `ground_reach`, the terrain looked for past `t_min` only, its hit bisected or not.
fn reach_along(v: vec3<f32>, t_min: f32, refine: bool) -> vec2<f32> {
    let up = f.cam_up;
    let h = f.cam_alt_m;
    let mu = dot(v, up);
    let ground = shell_hits(h, mu, 0.0);
    var t_sea = -1.0;
    if (ground.x <= ground.y && ground.y > 0.0) {
        t_sea = max(ground.x, 0.0);
    }
    let t_far = select(2.0e6, t_sea, t_sea >= 0.0);
    return vec2<f32>(t_sea, terrain_hit(up * (EARTH_R + h), h, mu, v, t_min, t_far, refine));
}

// Whether the camera's ray along v meets the terrain before the sea, past `t_min` (where the
// caller knows it is above it): which side of a mountain's silhouette it passes (march.wgsl
// `terrain_share`).
fn meets_terrain(v: vec3<f32>, t_min: f32) -> bool {
    return reach_along(v, t_min, false).y >= 0.0;
}

// The terrain's normal at p from the height field's slope over about a kilometre.
fn terrain_normal(p: vec3<f32>) -> vec3<f32> {
    let n = normalize(p);
    if (sh.ground_on == 0u) {
        return n;
    }
    let east = normalize(vec3<f32>(-n.y, n.x, 0.0) + vec3<f32>(1e-9, 0.0, 0.0));
    let north = cross(n, east);
    let step = 2000.0;
    let h0 = ground_at(region_uv(lat_lon(p))).x;
    let he = ground_at(region_uv(lat_lon(p + east * step))).x;
    let hn = ground_at(region_uv(lat_lon(p + north * step))).x;
    return normalize(n * step - east * (he - h0) - north * (hn - h0));
}

// Irradiance on level ground at p (unit up n, altitude hg) over π: the Sun or Moon through the
// clouds' column, and the sky through the column above.
fn ground_irradiance(p: vec3<f32>, n: vec3<f32>, hg: f32, sky: vec3<f32>) -> vec3<f32> {
    let od = column_od(p, hg);
    let sun_mu = max(dot(n, f.sun_dir), 0.0);
    let moon_mu = max(dot(n, f.moon_dir), 0.0);
    let key = select(key_through(od.x, moon_mu), key_through(od.x, sun_mu), f.sun_is_key != 0u);
    let other = diffuse_t(od.y);
    let sun_t = select(other, key, f.sun_is_key != 0u);
    let moon_t = select(key, other, f.sun_is_key != 0u);
    let direct = f.sun_col * sun_mu * SUN_I * 0.25 * sun_t + f.moon_col * moon_mu * SUN_I * 0.25 * moon_t;
    return direct + sky * diffuse_t(od.y);
}

fn hash2(p: vec2<f32>) -> f32 {
    return fract(sin(dot(p, vec2<f32>(127.1, 311.7))) * 43758.5453);
}

// Stars: a sparse fixed field in ECEF direction space, one in about 70 cells of 0.5°, about
// 2 500 over the whole sky as for the naked eye. Magnitudes 0.5–6.5 with the counts growing
// 10^(0.5 m) as real ones do; a star's light is its illuminance (magnitude 0 is 2e-11 of the
// Sun's, SUN_I) spread over a small disc about a pixel wide at 60° field of view, so against a
// moonlit sky only the brightest show and on a moonless night many do.
const STAR_R: f32 = 0.002;
fn stars(v: vec3<f32>) -> vec3<f32> {
    let ll = lat_lon(v);
    let c = vec2<f32>(ll.x * 2.0, ll.y * 2.0 * cos(radians(ll.x)));
    let cell = floor(c);
    let h = hash2(cell);
    if (h <= 0.985) {
        return vec3<f32>(0.0);
    }
    let at = vec2<f32>(hash2(cell + 17.0), hash2(cell + 31.0)) * 0.6 + 0.2;
    let d = radians(0.5 * length(c - cell - at));
    let m = 6.5 + 2.0 * log2(max((h - 0.985) / 0.015, 1e-3)) * 0.30103;
    let e = SUN_I * 2e-11 * exp2(-1.3287712 * m);
    let w = 1.0 - smoothstep(0.6 * STAR_R, 1.2 * STAR_R, d);
    return vec3<f32>(1.0, 0.95, 0.9) * e / (3.14159265 * STAR_R * STAR_R) * w;
}

// Ordered so a narrow sliver of each disc does not alias: a soft edge over 10 % of the radius.
fn disc(v: vec3<f32>, dir: vec3<f32>, radius_rad: f32) -> f32 {
    let ang = acos(clamp(dot(v, dir), -1.0, 1.0));
    return 1.0 - smoothstep(radius_rad * 0.9, radius_rad * 1.1, ang);
}

// Where direction v falls in the sky-view table.
fn sky_view_uv(v: vec3<f32>) -> vec2<f32> {
    let up = f.cam_up;
    let fr = sky_frame();
    let el = asin(clamp(dot(v, up), -1.0, 1.0));
    let eh = horizon_elev(f.cam_alt_m);
    var y = 0.0;
    if (el >= eh) {
        y = 0.5 + 0.5 * sqrt(sat((el - eh) / (0.5 * PI - eh)));
    } else {
        y = 0.5 - 0.5 * sqrt(sat((eh - el) / (eh + 0.5 * PI)));
    }
    let x = atan2(dot(v, fr[1]), dot(v, fr[0])) / (2.0 * PI) + 0.5;
    return vec2<f32>(x, y);
}

// The clear air between the camera and the point at distance d along v (the aerial-perspective
// table, Hillaire 2020): the light it scatters toward the camera (rgb) and its mean
// transmittance (a). Nearer than the first slice, a share of it.
fn aerial(v: vec3<f32>, d: f32) -> vec4<f32> {
    if (sh.aerial_on == 0u) {
        return vec4<f32>(0.0, 0.0, 0.0, 1.0);
    }
    let n = f32(textureDimensions(ap_tex).z);
    let s = sqrt(sat(d / AP_MAX_M)) * n;
    let a = textureSampleLevel(ap_tex, od_sampler, vec3<f32>(sky_view_uv(v), (max(s, 1.0) - 0.5) / n), 0.0);
    if (s < 1.0) {
        return vec4<f32>(a.rgb * s, mix(1.0, a.a, s));
    }
    return a;
}

// The clear sky's light on level ground near the camera: the sky-view table's radiance
// averaged over the hemisphere, cosine-weighted (the zenith and four directions 30° up), so
// twilight's sky lights the ground as brightly as it is drawn.
fn sky_ambient() -> vec3<f32> {
    let up = f.cam_up;
    let fr = sky_frame();
    var l = sky_seen(up);
    for (var k = 0u; k < 4u; k++) {
        let a = f32(k) * 0.5 * PI + 0.25 * PI;
        l += 0.5 * sky_seen(normalize(up * 0.5 + (fr[0] * cos(a) + fr[1] * sin(a)) * 0.8660254));
    }
    return l / 3.0;
}

// The sky seen from the camera along v: the atmosphere's table by day and twilight (Earth's
// shadow and all), the night's moonlit sky and airglow over it.
fn sky_seen(v: vec3<f32>) -> vec3<f32> {
    let day = textureSampleLevel(sky_tex, od_sampler, sky_view_uv(v), 0.0).rgb;
    return day + night_sky(v, f.cam_up);
}

// How much of the clear sky's light the haze around the camera gets: the key light and the sky
// through the cloud column above the camera (under an overcast the haze is grey and dim).
fn haze_light() -> f32 {
    let o = f.cam_up * (EARTH_R + f.cam_alt_m);
    let od = column_od(o, f.cam_alt_m);
    let key = select(f.moon_dir, f.sun_dir, f.sun_is_key != 0u);
    return key_through(od.x, max(dot(key, f.cam_up), 0.0));
}

// The Moon's disc lit by the Sun: its phase is the lit part of a sphere whose visible face
// looks back at the camera.
fn moon_disc(v: vec3<f32>) -> vec3<f32> {
    let m = f.moon_dir;
    let radius = 0.0045;
    let inside = disc(v, m, radius);
    if (inside <= 0.0) {
        return vec3<f32>(0.0);
    }
    let off = (v - m * dot(v, m)) / radius;
    let n = normalize(off - m * sqrt(max(1.0 - dot(off, off), 0.0)));
    let lit = max(dot(n, f.sun_dir), 0.0);
    // moon_col is the Moon's light at the ground, in proportion to its lit fraction.
    let phase = max(0.5 * (1.0 - dot(f.sun_dir, m)), 0.02);
    return f.moon_col / phase * (0.02 + lit) * inside * 2e4;
}

// What a view ray from the camera meets where there is no cloud.
// The background along v (linear radiance) and the distance to the ground it shows (m; 0 for
// sky), given the ray's `ground_reach`.
fn background_at(v: vec3<f32>, reach: vec2<f32>) -> vec4<f32> {
    let up = f.cam_up;
    let h = f.cam_alt_m;
    let mu = dot(v, up);
    let o = up * (EARTH_R + h);
    let t_ground = select(reach.x, reach.y, reach.y >= 0.0);
    if (t_ground >= 0.0) {
        // Ground: its albedo under Sun and sky through the clouds, fading into the haze.
        let t = t_ground;
        let p = o + v * t;
        let g = ground_at(region_uv(lat_lon(p)));
        let n = terrain_normal(p);
        // The air's light (the table's, for a clear sky) and the haze's, both dimmed under cloud.
        let air = haze_light();
        let ap = aerial(v, t);
        let lit = g.yzw * ground_irradiance(p, n, g.x, sky_ambient()) * ap.a + ap.rgb * air;
        let fog = haze_transmittance(h, g.x, t);
        return vec4<f32>(lit * fog + sky_seen(v) * air * (1.0 - fog), t);
    }
    var c = sky_seen(v);
    let above = smoothstep(-0.01, 0.01, mu);
    c += f.sun_col * disc(v, f.sun_dir, 0.0047) * 2e4 * above;
    c += moon_disc(v) * above;
    let dark = 1.0 - smoothstep(-0.2, 0.0, dot(f.sun_dir, up));
    c += stars(v) * dark * above;
    return vec4<f32>(c, 0.0);
}
