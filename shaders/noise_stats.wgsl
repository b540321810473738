// Noise statistics stage: once at start-up, after the noise stage, the mip chain of what the
// cloud carve reads from each noise texture (render::noise): per texel the mean and the variance
// of the carved noise value over the texels it covers. A sample whose pixel covers many texels
// reads the level of its footprint and carves the value's spread, not one point of it (its
// least and greatest value bound the spread: the noise's tails are short)
// (cloud.wgsl `carve`): footprint-aware sampling, issue 30.
//
// Mode 0 reads the noise stage's packed RGBA8 texels and writes level 0 (variance 0); mode 1
// averages 2×2×2 texels of a level into the next (min of mins, max of maxes). Every level is
// packed half floats (mean, variance, min, max: the texel layout of an Rgba16Float texture), two
// u32s a texel, rows padded to the copy alignment. Packed by hand:
// naga asks a capability for pack2x16float that not every adapter grants.

struct StatsParams {
    size: u32,        // texels per side of the level written
    mode: u32,        // 0: level 0 from the RGBA8 noise; 1: the next level from the previous
    kind: u32,        // 0 shape, 1 detail (mode 0 only)
    row_words: u32,   // u32s per texel row in `dst`
    src_row_words: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
};

@group(0) @binding(0) var<uniform> params: StatsParams;
@group(0) @binding(1) var<storage, read> src: array<u32>;
@group(0) @binding(2) var<storage, read_write> dst: array<u32>;

// The carved noise value of one texel, as cloud.wgsl used to compute it from the filtered
// channels: shape, the Perlin-Worley remapped by the Worley FBM (DESIGN §2 eqs 11–14); detail,
// its Worley FBM.
fn carved_value(t: vec4<f32>) -> f32 {
    if (params.kind == 0u) {
        let fbm = t.g * 0.625 + t.b * 0.25 + t.a * 0.125;
        return remap(t.r, fbm - 1.0, 1.0, 0.0, 1.0);
    }
    return t.r * 0.625 + t.g * 0.25 + t.b * 0.125;
}

// Half-float bits of a non-negative x (rounded; under 2⁻¹⁴, 6e-5, flushed to zero).
fn half_bits(x: f32) -> u32 {
    let b = bitcast<u32>(max(x, 0.0)) + 0x1000u;
    let e = i32((b >> 23u) & 0xffu) - 112;
    if (e <= 0) {
        return 0u;
    }
    return min((u32(e) << 10u) | ((b >> 13u) & 0x3ffu), 0x7bffu);
}

fn half_value(h: u32) -> f32 {
    let e = (h >> 10u) & 0x1fu;
    if (e == 0u) {
        return 0.0;
    }
    return bitcast<f32>(((e + 112u) << 23u) | ((h & 0x3ffu) << 13u));
}

fn pack_pair(v: vec2<f32>) -> u32 {
    return half_bits(v.x) | (half_bits(v.y) << 16u);
}

fn unpack_pair(w: u32) -> vec2<f32> {
    return vec2<f32>(half_value(w & 0xffffu), half_value(w >> 16u));
}

fn noise_at(c: vec3<u32>, side: u32) -> u32 {
    return src[(c.z * side + c.y) * params.src_row_words + c.x];
}

fn stats_at(c: vec3<u32>, side: u32) -> vec4<f32> {
    let i = (c.z * side + c.y) * params.src_row_words + 2u * c.x;
    return vec4<f32>(unpack_pair(src[i]), unpack_pair(src[i + 1u]));
}

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let n = params.size;
    if (any(id >= vec3<u32>(n))) {
        return;
    }
    var out: vec4<f32>;
    if (params.mode == 0u) {
        let v = carved_value(unpack4x8unorm(noise_at(id, n)));
        out = vec4<f32>(v, 0.0, v, v);
    } else {
        // The parent's mean is the children's; its variance the children's variance plus the
        // spread of their means: E[v²] − E[v]², with E[v²] = var + mean² per child.
        var m = 0.0;
        var m2 = 0.0;
        var lo = 1e9;
        var hi = -1e9;
        for (var k = 0u; k < 8u; k++) {
            let o = vec3<u32>(k & 1u, (k >> 1u) & 1u, (k >> 2u) & 1u);
            let c = stats_at(id * 2u + o, 2u * n);
            m += c.x;
            m2 += c.y + c.x * c.x;
            lo = min(lo, c.z);
            hi = max(hi, c.w);
        }
        m *= 0.125;
        m2 *= 0.125;
        out = vec4<f32>(m, max(m2 - m * m, 0.0), lo, hi);
    }
    let i = (id.z * n + id.y) * params.row_words + 2u * id.x;
    dst[i] = pack_pair(out.xy);
    dst[i + 1u] = pack_pair(out.zw);
}
