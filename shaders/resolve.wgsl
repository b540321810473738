// Resolve stage: where a march smaller than its target is enlarged (the window's render scale,
// `render --render-scale`), its jitter is resolved first, at the march's own size, as the
// present stage resolves a march at the target's size (jitter.wgsl), and lays it over its
// background; the present stage then enlarges that picture, one bilinear read a target pixel
// instead of four of the cloud and four of the background. Enlarged unresolved, the ¼
// window showed the jitter's grain as 4-px blocks; one 3×3 resolve a march pixel costs a
// sixteenth of one a target pixel (docs/footprint.md, "The ¼ window's grain").

@group(1) @binding(0) var cloud: texture_2d<f32>;
@group(1) @binding(1) var scene: texture_2d<f32>;
@group(2) @binding(0) var resolved: texture_storage_2d<rgba16float, write>;

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    load_frame();
    let dims = vec2<i32>(textureDimensions(cloud));
    let at = vec2<i32>(id.xy);
    if (all(at < dims)) {
        // The centre-weighted kernel whatever the step: `fast`'s 3×3 mean is a blur 12 window
        // pixels wide at ¼ scale, which cost more than the grain it took (the ¼ window against
        // the full march: the cruise 0.0069 against 0.0060, the synthetic above-noon 0.0083
        // against 0.0071).
        let c = jitter_resolved(at, dims, resolve_weights(0.01));
        let bg = textureLoad(scene, at, 0).rgb;
        // What the pixel shows (linear, before the exposure); the opacity rides along unread.
        textureStore(resolved, at, vec4<f32>(bg * (1.0 - c.a) + c.rgb, c.a));
    }
}
