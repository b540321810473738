// Present stage: a full-screen triangle that lays the cloud image over the background
// (scene.wgsl: sky, Sun, Moon, stars, the ground in the clouds' shadows), applies the exposure
// stage's exposure and a filmic tone curve; the sRGB target encodes.

// The march's cloud (premultiplied radiance and opacity); where the march is enlarged, its
// picture resolved at its own size (the resolve stage, jitter.wgsl).
@group(1) @binding(0) var cloud: texture_2d<f32>;
// The background behind it and each pixel's distance in km (march.wgsl `out_scene`).
@group(1) @binding(1) var scene: texture_2d<f32>;
// The exposure stage's result for this frame (render::exposure).
@group(2) @binding(0) var<storage, read> exposure: ExposureState;

// Set by the pipeline (render::present::Resample): whether the march is smaller than the
// target (frame.wgsl `march_scale` under 0.99) and is enlarged. A constant, not the uniform's
// test: a CPU driver runs both sides of a branch for every pixel.
override UPSAMPLE: bool = true;

// Set by the pipeline for a non-sRGB target (a window's Bgra8Unorm, which egui prefers): the
// shader then applies the sRGB transfer curve itself.
override ENCODE_SRGB: bool = false;

fn srgb_encode(c: vec3<f32>) -> vec3<f32> {
    let lo = c * 12.92;
    let hi = 1.055 * pow(c, vec3<f32>(1.0 / 2.4)) - 0.055;
    return select(hi, lo, c <= vec3<f32>(0.0031308));
}

// How much a march pixel counts in the upsample beside the nearest one: less as its opacity
// (da) and its distance (km, 0 for sky) differ.
fn edge_weight(da: f32, d: f32, near_d: f32) -> f32 {
    let far = max(max(d, near_d), 1e-3);
    let dd = select(abs(d - near_d) / far, 1.0, (d > 0.0) != (near_d > 0.0));
    return 1.0 / (1.0 + 16.0 * abs(da) + 8.0 * dd);
}

// The upsample's running sums: cloud and its weight, background and its weight.
struct Upsample {
    c: vec4<f32>,
    wsum: f32,
    b: vec3<f32>,
    bw: f32,
};

// One march pixel into the upsample at base weight w, lowered for the cloud by how far its
// opacity and distance are from the nearest march pixel's (near), for the background by how
// far its distance is.
fn upsample_tap(acc: ptr<function, Upsample>, p: vec2<i32>, dims: vec2<i32>, w: f32, near: vec2<f32>) {
    let at = clamp(p, vec2<i32>(0), dims - 1);
    let t = textureLoad(cloud, at, 0);
    let sc = textureLoad(scene, at, 0);
    let wc = (w + 1e-4) * edge_weight(t.a - near.x, sc.a, near.y);
    (*acc).c += wc * t;
    (*acc).wsum += wc;
    let wbg = w * edge_weight(0.0, sc.a, near.y);
    (*acc).b += wbg * sc.rgb;
    (*acc).bw += wbg;
}

@fragment
fn fs_main(in: VsOut) -> @location(0) vec4<f32> {
    load_frame();
    // march_scale: march pixels per target pixel (the window may march at a lower resolution).
    let px = in.pos.xy * f.march_scale;
    let dims = vec2<i32>(textureDimensions(cloud));
    var c: vec4<f32>;
    let near_at = clamp(vec2<i32>(floor(px)), vec2<i32>(0), dims - 1);
    var bg: vec3<f32>;
    if (UPSAMPLE) {
        // The window marches at a fraction of its size: an edge-aware upsample (a joint
        // bilateral filter on the march's own opacity and depth) of the four march pixels
        // around (bilinear weights), whose jitter the resolve stage has already resolved: a
        // march pixel counts less the more its opacity and distance differ from the nearest
        // one's, so a cloud's edge stays as sharp as the march found it instead of softening.
        // A 4×4 footprint over the unresolved march here (bilinear between 3×3 means) drew the
        // same picture at four times the texture reads over every window pixel, about 17 ms
        // of a 1280×720 frame on lavapipe (docs/performance.md, "The window's frame").
        let q = px - 0.5;
        let fr = q - floor(q);
        let i0 = vec2<i32>(floor(q));
        let near = vec2<f32>(textureLoad(cloud, near_at, 0).a, textureLoad(scene, near_at, 0).a);
        var acc = Upsample(vec4<f32>(0.0), 0.0, vec3<f32>(0.0), 0.0);
        for (var j = 0; j < 2; j++) {
            for (var i = 0; i < 2; i++) {
                let w = select(1.0 - fr.x, fr.x, i == 1) * select(1.0 - fr.y, fr.y, j == 1);
                upsample_tap(&acc, i0 + vec2<i32>(i, j), dims, w, near);
            }
        }
        c = acc.c / max(acc.wsum, 1e-6);
        bg = acc.b / max(acc.bw, 1e-6);
    } else {
        bg = textureLoad(scene, near_at, 0).rgb;
        c = jitter_resolved(near_at, dims, resolve_weights(f.step_growth));
    }
    let lin = bg * (1.0 - c.a) + c.rgb;
    var out = aces(lin * exposure.value);
    if (ENCODE_SRGB) {
        out = srgb_encode(out);
    }
    return vec4<f32>(out, 1.0);
}
