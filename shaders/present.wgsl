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
        // The window marches at a fraction of its size: the four march pixels around,
        // bilinear, from the picture the resolve stage has already resolved. Not edge-aware:
        // weighting each by its opacity and distance against the nearest one's kept the
        // nearest pixel wherever they differed, which drew every cloud edge as 4-px steps and
        // the far deck's rim on the haze line as 4-px blocks, and erred more than bilinear
        // against the full march (docs/footprint.md, "The enlarged march, bilinear"). A 4×4
        // footprint over the unresolved march here drew the picture of a resolve at four
        // times the texture reads over every window pixel, about 17 ms of a 1280×720 frame
        // on lavapipe (docs/performance.md, "The window's frame").
        let q = px - 0.5;
        let fr = q - floor(q);
        let i0 = vec2<i32>(floor(q));
        c = vec4<f32>(0.0);
        bg = vec3<f32>(0.0);
        for (var j = 0; j < 2; j++) {
            for (var i = 0; i < 2; i++) {
                let w = select(1.0 - fr.x, fr.x, i == 1) * select(1.0 - fr.y, fr.y, j == 1);
                let at = clamp(i0 + vec2<i32>(i, j), vec2<i32>(0), dims - 1);
                c += w * textureLoad(cloud, at, 0);
                bg += w * textureLoad(scene, at, 0).rgb;
            }
        }
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
