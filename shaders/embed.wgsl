// Embedding (render::embed): the two small stages around the march when the clouds are drawn
// into a host's frame. `far_main` turns the host's depth buffer into each pixel's farthest ray
// reach (metres along the ray), which the march stops at (march.wgsl `ray_far`); the composite
// (`vs_main`, `fs_main`) lays the cloud over the host's colour by its transmittance:
// out = cloud + T·host, a premultiplied blend onto the host's target.

struct EmbedParams {
    // The host's target size (px).
    width: u32,
    height: u32,
    // 1/z = inv_a + inv_b·depth: the view-space distance z (m, along the camera's axis) of a
    // depth value, from the host's near/far and depth convention (render::embed::DepthConvention).
    inv_a: f32,
    inv_b: f32,
    // The depth of nothing drawn (1 standard, 0 reversed-Z): its pixels are not limited.
    none_depth: f32,
    // The projection's focal terms: a pixel's view ray is ((ndc.x − cx)/fx, (ndc.y − cy)/fy, −1).
    fx: f32,
    fy: f32,
    cx: f32,
    cy: f32,
    // Cloud radiance → the target's units (times the exposure stage's value when `stratus_exposure`).
    exposure_mul: f32,
    stratus_exposure: u32,
    // 1: ACES-tone-map the cloud (a display-referred target); 0: linear radiance (HDR).
    tone: u32,
    // 1: resolve the march's jitter by a 3×3 kernel over pixels at a like host depth.
    resolve: u32,
    // 1: Stratus' own sky (the march's background) where the host drew nothing.
    sky: u32,
    // The march's step growth per metre of distance: the resolve's weights (`resolve_weights`).
    step_growth: f32,
    _pad2: u32,
};

// The value of a pixel no host geometry limits (march.rs UNLIMITED_M).
const FAR_NONE: f32 = 3.0e38;

@group(0) @binding(0) var<storage, read> p: EmbedParams;

// The depth stage: the host's depth buffer in, each pixel's reach out.
@group(1) @binding(0) var host_depth: texture_depth_2d;
@group(1) @binding(1) var<storage, read_write> far_out: array<f32>;

// The composite: the march's cloud, the reach (for the edge-aware resolve), the exposure.
@group(2) @binding(0) var cloud: texture_2d<f32>;
@group(2) @binding(1) var<storage, read> far_in: array<f32>;
@group(2) @binding(2) var<storage, read> exposure: ExposureState;
// The background behind each ray (march.wgsl `out_scene`): Stratus' sky, for `sky`.
@group(2) @binding(3) var scene: texture_2d<f32>;

@compute @workgroup_size(8, 8, 1)
fn far_main(@builtin(global_invocation_id) id: vec3<u32>) {
    let size = vec2<u32>(p.width, p.height);
    if (any(id.xy >= size)) {
        return;
    }
    let d = textureLoad(host_depth, vec2<i32>(id.xy), 0);
    var reach = FAR_NONE;
    if (d != p.none_depth) {
        let inv_z = p.inv_a + p.inv_b * d;
        // The ray through the pixel's centre, as the march's (wgpu: NDC y up, pixels y down).
        let ndc = vec2<f32>(
            (f32(id.x) + 0.5) / f32(size.x) * 2.0 - 1.0,
            1.0 - (f32(id.y) + 0.5) / f32(size.y) * 2.0
        );
        let ray = vec3<f32>((ndc.x - p.cx) / p.fx, (ndc.y - p.cy) / p.fy, 1.0);
        if (inv_z > 0.0) {
            reach = length(ray) / inv_z;
        }
    }
    far_out[id.y * size.x + id.x] = reach;
}


// Whether two reaches belong to the same surface (within 5 %), so the resolve does not carry
// cloud across the edge of the host's geometry.
fn same_surface(a: f32, b: f32) -> bool {
    return abs(a - b) <= 0.05 * max(min(a, b), 1.0);
}

@fragment
fn fs_main(in: VsOut) -> @location(0) vec4<f32> {
    let at = vec2<i32>(floor(in.pos.xy));
    let dims = vec2<i32>(i32(p.width), i32(p.height));
    var c = textureLoad(cloud, at, 0);
    if (p.resolve != 0u) {
        // The march's interleaved-gradient jitter spreads evenly over each 3×3 block (resolved
        // as the present stage does), among the pixels on the same host surface.
        let here = far_in[u32(at.y) * p.width + u32(at.x)];
        let rw = resolve_weights(p.step_growth);
        var sum = vec4<f32>(0.0);
        var n = 0.0;
        for (var j = -1; j <= 1; j++) {
            for (var i = -1; i <= 1; i++) {
                let q = clamp(at + vec2<i32>(i, j), vec2<i32>(0), dims - 1);
                if (same_surface(here, far_in[u32(q.y) * p.width + u32(q.x)])) {
                    let w = resolve_weight(rw, i, j);
                    sum += w * textureLoad(cloud, q, 0);
                    n += w;
                }
            }
        }
        c = sum / max(n, 1e-6);
    }
    var scale = p.exposure_mul;
    if (p.stratus_exposure != 0u) {
        scale *= exposure.value;
    }
    if (p.sky != 0u && far_in[u32(at.y) * p.width + u32(at.x)] >= FAR_NONE) {
        // Where the host drew nothing: the cloud over Stratus' sky, replacing the host's colour.
        var sky = (c.rgb + textureLoad(scene, at, 0).rgb * (1.0 - c.a)) * scale;
        if (p.tone != 0u) {
            sky = aces(sky);
        }
        return vec4<f32>(sky, 1.0);
    }
    var rgb = c.rgb * scale;
    if (p.tone != 0u) {
        // Tone-map the cloud's own colour, then weigh it by its opacity again (premultiplied).
        rgb = aces(rgb / max(c.a, 1e-4)) * c.a;
    }
    // Blend One, OneMinusSrcAlpha: out = cloud + (1 − a)·host.
    return vec4<f32>(rgb, c.a);
}
