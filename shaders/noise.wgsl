// Noise stage: fills the tileable 3D noise textures once at start-up (DESIGN §2).
// shape 128³ RGBA: R Perlin-Worley, G/B/A Worley FBM at rising frequency.
// detail 32³ RGB: Worley FBM at rising frequency.
// Every octave's lattice wraps at the texture edge, so the textures tile seamlessly.

struct NoiseParams {
    size: u32,      // texels per side
    kind: u32,      // 0 shape, 1 detail
    seed: u32,
    row_words: u32, // u32s per texel row in `out_texels` (rows padded for the texture copy)
};

// RGBA8 texels, packed, row by row and slice by slice; the Rust side copies them into the 3D
// texture. (Not a 3D storage texture: wgpu's GL backend binds those one slice deep, and the
// other slices stayed empty.)
@group(0) @binding(0) var<uniform> params: NoiseParams;
@group(0) @binding(1) var<storage, read_write> out_texels: array<u32>;

fn hash_u(x: u32) -> u32 {
    // PCG-style integer hash.
    var v = x * 747796405u + 2891336453u;
    v = ((v >> ((v >> 28u) + 4u)) ^ v) * 277803737u;
    return (v >> 22u) ^ v;
}

fn hash3(c: vec3<u32>, salt: u32) -> u32 {
    return hash_u(c.x ^ hash_u(c.y ^ hash_u(c.z ^ hash_u(salt ^ params.seed))));
}

fn unit3(h: u32) -> vec3<f32> {
    let a = hash_u(h);
    let b = hash_u(a);
    let c = hash_u(b);
    return vec3<f32>(f32(a & 0xffffu), f32(b & 0xffffu), f32(c & 0xffffu)) / 65535.0;
}

fn wrap_cell(c: vec3<i32>, period: i32) -> vec3<u32> {
    return vec3<u32>(((c % period) + period) % period);
}

// Worley: 1 − distance to the nearest feature point, one point per cell, `period` cells.
fn worley(p: vec3<f32>, period: i32, salt: u32) -> f32 {
    let x = p * f32(period);
    let base = vec3<i32>(floor(x));
    var best = 1e9;
    for (var dz = -1; dz <= 1; dz++) {
        for (var dy = -1; dy <= 1; dy++) {
            for (var dx = -1; dx <= 1; dx++) {
                let c = base + vec3<i32>(dx, dy, dz);
                let fp = vec3<f32>(c) + unit3(hash3(wrap_cell(c, period), salt));
                best = min(best, distance(x, fp));
            }
        }
    }
    return 1.0 - clamp(best, 0.0, 1.0);
}

fn worley_fbm(p: vec3<f32>, period: i32, salt: u32) -> f32 {
    return worley(p, period, salt) * 0.625
        + worley(p, period * 2, salt + 1u) * 0.25
        + worley(p, period * 4, salt + 2u) * 0.125;
}

fn grad(c: vec3<i32>, period: i32, salt: u32) -> vec3<f32> {
    return normalize(unit3(hash3(wrap_cell(c, period), salt)) * 2.0 - 1.0 + vec3<f32>(1e-4));
}

fn fade(t: vec3<f32>) -> vec3<f32> {
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
}

// Tileable Perlin gradient noise in about [-1, 1].
fn perlin(p: vec3<f32>, period: i32, salt: u32) -> f32 {
    let x = p * f32(period);
    let i = vec3<i32>(floor(x));
    let fr = x - floor(x);
    let u = fade(fr);
    var acc = array<f32, 8>();
    for (var k = 0; k < 8; k++) {
        let o = vec3<i32>(k & 1, (k >> 1) & 1, (k >> 2) & 1);
        acc[k] = dot(grad(i + o, period, salt), fr - vec3<f32>(o));
    }
    let x00 = mix(acc[0], acc[1], u.x);
    let x10 = mix(acc[2], acc[3], u.x);
    let x01 = mix(acc[4], acc[5], u.x);
    let x11 = mix(acc[6], acc[7], u.x);
    return mix(mix(x00, x10, u.y), mix(x01, x11, u.y), u.z);
}

fn perlin_fbm(p: vec3<f32>, period: i32, salt: u32) -> f32 {
    var sum = 0.0;
    var amp = 1.0;
    var norm = 0.0;
    var per = period;
    for (var o = 0u; o < 4u; o++) {
        sum += perlin(p, per, salt + o) * amp;
        norm += amp;
        amp *= 0.5;
        per *= 2;
    }
    return sum / norm;
}

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if (any(id >= vec3<u32>(params.size))) {
        return;
    }
    let p = (vec3<f32>(id) + 0.5) / f32(params.size);
    var v: vec4<f32>;
    if (params.kind == 0u) {
        let pn = sat(perlin_fbm(p, 4, 10u) * 0.7 + 0.5);
        let w = worley_fbm(p, 4, 20u);
        // Perlin-Worley: Perlin billows carved by Worley cells (remap(perlin, 0, 1, worley, 1)).
        let pw = sat(remap(pn, 0.0, 1.0, w, 1.0));
        v = vec4<f32>(pw, worley_fbm(p, 4, 30u), worley_fbm(p, 8, 40u), worley_fbm(p, 16, 50u));
    } else {
        v = vec4<f32>(worley_fbm(p, 2, 60u), worley_fbm(p, 4, 70u), worley_fbm(p, 8, 80u), 1.0);
    }
    out_texels[(id.z * params.size + id.y) * params.row_words + id.x] = pack4x8unorm(v);
}
