// Present stage: a full-screen triangle that lays the cloud image over the background
// (scene.wgsl: sky, Sun, Moon, stars, the ground in the clouds' shadows), applies the exposure
// stage's exposure and a filmic tone curve; the sRGB target encodes.

// The march's cloud (premultiplied radiance and opacity); where the march is enlarged, its
// picture resolved and laid over its background at its own size (the resolve stage: linear
// radiance as shown, before the exposure).
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

@fragment
fn fs_main(in: VsOut) -> @location(0) vec4<f32> {
    load_frame();
    // march_scale: march pixels per target pixel (the window may march at a lower resolution).
    let px = in.pos.xy * f.march_scale;
    let dims = vec2<i32>(textureDimensions(cloud));
    var lin: vec3<f32>;
    if (UPSAMPLE) {
        // The window marches at a fraction of its size: the resolve stage has already laid
        // the march's cloud over its background there, so one bilinear read of that picture
        // (scene.wgsl's linear, clamp-to-edge sampler, shared with the sky, the ground and
        // the shadow volume) is the four nearest march pixels as shown. Two textures read
        // four times each, weights and composite here, cost about 12 ms of a 1280×720 frame
        // on lavapipe and drew the same picture within 5/255 (docs/performance.md, "The
        // enlarged march composited at its own size"). Not edge-aware: weighting each by its
        // opacity and distance against the nearest one's drew every cloud edge as 4-px steps
        // and erred more against the full march (docs/footprint.md, "The enlarged march,
        // bilinear").
        lin = textureSampleLevel(cloud, od_sampler, px / vec2<f32>(dims), 0.0).rgb;
    } else {
        let near_at = clamp(vec2<i32>(floor(px)), vec2<i32>(0), dims - 1);
        let bg = textureLoad(scene, near_at, 0).rgb;
        let c = jitter_resolved(near_at, dims, resolve_weights(f.step_growth));
        lin = bg * (1.0 - c.a) + c.rgb;
    }
    var out = aces(lin * exposure.value);
    if (ENCODE_SRGB) {
        out = srgb_encode(out);
    }
    return vec4<f32>(out, 1.0);
}
