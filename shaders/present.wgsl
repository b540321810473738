// Present stage: a full-screen triangle that lays the cloud image over the sky, the Sun, Moon,
// stars and the hazy ground, applies exposure and a filmic tone curve; the sRGB target encodes.

@group(0) @binding(0) var<uniform> f: Frame;
@group(1) @binding(0) var cloud: texture_2d<f32>;    // the march output; lives with its size

struct VsOut {
    @builtin(position) pos: vec4<f32>,
};

@vertex
fn vs_main(@builtin(vertex_index) i: u32) -> VsOut {
    var o: VsOut;
    let uv = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    o.pos = vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
    return o;
}

fn hash2(p: vec2<f32>) -> f32 {
    return fract(sin(dot(p, vec2<f32>(127.1, 311.7))) * 43758.5453);
}

// Stars: a sparse fixed field in ECEF direction space, visible once the sky is dark enough.
fn stars(v: vec3<f32>) -> vec3<f32> {
    let ll = lat_lon(v);
    let cell = floor(vec2<f32>(ll.x * 2.0, ll.y * 2.0 * cos(radians(ll.x))));
    let h = hash2(cell);
    if (h > 0.985) {
        return vec3<f32>(1.0, 0.95, 0.9) * (h - 0.985) * 2e-7;
    }
    return vec3<f32>(0.0);
}

// Ordered so a narrow sliver of each disc does not alias: a soft edge over 10 % of the radius.
fn disc(v: vec3<f32>, dir: vec3<f32>, radius_rad: f32) -> f32 {
    let ang = acos(clamp(dot(v, dir), -1.0, 1.0));
    return 1.0 - smoothstep(radius_rad * 0.9, radius_rad * 1.1, ang);
}

fn background(v: vec3<f32>) -> vec3<f32> {
    let up = f.cam_up;
    let h = f.cam_alt_m;
    let mu = dot(v, up);
    let ground = shell_hits(h, mu, 0.0);
    if (ground.x <= ground.y && ground.y > 0.0) {
        // Ground: a dull land albedo under Sun and sky, fading into the haze with distance.
        let t = max(ground.x, 0.0);
        let n = normalize(up * (EARTH_R + h) + v * t);
        let sun = f.sun_col * max(dot(n, f.sun_dir), 0.0) * SUN_I * 0.25
            + f.moon_col * max(dot(n, f.moon_dir), 0.0) * SUN_I * 0.25;
        let albedo = vec3<f32>(0.08, 0.10, 0.07);
        let lit = albedo * (sun + sky_radiance(f, n, n));
        let fog = haze_transmittance(f, h, 0.0, t);
        return lit * fog + sky_radiance(f, v, up) * (1.0 - fog);
    }
    var c = sky_radiance(f, v, up);
    let above = smoothstep(-0.01, 0.01, mu);
    c += f.sun_col * disc(v, f.sun_dir, 0.0047) * 2e4 * above;
    c += f.moon_col * disc(v, f.moon_dir, 0.0045) * 2e4 * above;
    let dark = 1.0 - smoothstep(-0.2, 0.0, dot(f.sun_dir, up));
    c += stars(v) * dark * above;
    return c;
}

// Set by the pipeline for a non-sRGB target (a window's Bgra8Unorm, which egui prefers): the
// shader then applies the sRGB transfer curve itself.
override ENCODE_SRGB: bool = false;

fn srgb_encode(c: vec3<f32>) -> vec3<f32> {
    let lo = c * 12.92;
    let hi = 1.055 * pow(c, vec3<f32>(1.0 / 2.4)) - 0.055;
    return select(hi, lo, c <= vec3<f32>(0.0031308));
}

// Narkowicz's fitted ACES curve.
fn aces(x: vec3<f32>) -> vec3<f32> {
    return clamp((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), vec3<f32>(0.0), vec3<f32>(1.0));
}

@fragment
fn fs_main(in: VsOut) -> @location(0) vec4<f32> {
    // march_scale: march pixels per target pixel (the window may march at a lower resolution).
    let px = in.pos.xy * f.march_scale;
    let dims = vec2<i32>(textureDimensions(cloud));
    var c: vec4<f32>;
    // Resolve the march's interleaved-gradient jitter, which spreads its values evenly over
    // every 3×3 block (Jimenez 2014): a still frame has no temporal filter, and thin layers
    // otherwise show the jitter's lattice. Not for the score's top-down frames (a mask view,
    // where a blur only moves edges). One separable filter does both cases: bilinear between
    // 3×3 means over a 4×4 footprint, weights (1−f)/3, 1/3, 1/3, f/3 per axis; at 1:1 f = 0
    // and it is the plain 3×3 mean. When the window marches at a fraction of its size
    // (march_scale < 1) it is also the upsample.
    let resolve = has_flag(f, FLAG_JITTER) && !has_flag(f, FLAG_NO_SKY);
    if (resolve || f.march_scale < 0.99) {
        let q = px - 0.5;
        let i0 = vec2<i32>(floor(q));
        let fr = q - floor(q);
        let wx = vec4<f32>(1.0 - fr.x, 1.0, 1.0, fr.x) / 3.0;
        let wy = vec4<f32>(1.0 - fr.y, 1.0, 1.0, fr.y) / 3.0;
        c = vec4<f32>(0.0);
        for (var j = 0; j < 4; j++) {
            var row = vec4<f32>(0.0);
            for (var i = 0; i < 4; i++) {
                let at = clamp(i0 + vec2<i32>(i - 1, j - 1), vec2<i32>(0), dims - 1);
                row += wx[i] * textureLoad(cloud, at, 0);
            }
            c += wy[j] * row;
        }
    } else {
        c = textureLoad(cloud, clamp(vec2<i32>(px), vec2<i32>(0), dims - 1), 0);
    }
    var bg = vec3<f32>(0.0);
    if (!has_flag(f, FLAG_NO_SKY)) {
        bg = background(persp_dir(f, px));
    }
    let lin = bg * (1.0 - c.a) + c.rgb;
    var out = aces(lin * f.exposure);
    if (ENCODE_SRGB) {
        out = srgb_encode(out);
    }
    return vec4<f32>(out, 1.0);
}
