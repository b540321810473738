// Present stage: a full-screen triangle that lays the cloud image over the background
// (scene.wgsl: sky, Sun, Moon, stars, the ground in the clouds' shadows), applies the exposure
// stage's exposure and a filmic tone curve; the sRGB target encodes.

@group(1) @binding(0) var cloud: texture_2d<f32>;    // the march output; lives with its size
// The background behind it and each pixel's distance in km (march.wgsl `out_scene`).
@group(1) @binding(1) var scene: texture_2d<f32>;
// The exposure stage's result for this frame (render::exposure).
@group(2) @binding(0) var<storage, read> exposure: ExposureState;


// Set by the pipeline (render::present::Resample): whether the march is smaller than the
// target (frame.wgsl `march_scale` under 0.99) and is enlarged; if so, from the preset
// (render::preset::MarchParams::wide_upsample), over a 4×4 footprint that also resolves the
// march's jitter, else the four nearest. Constants, not the uniform's test: a CPU driver runs
// both sides of a branch for every pixel.
override UPSAMPLE: bool = true;
override WIDE_UPSAMPLE: bool = true;

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

// One march pixel into the upsample, at base weights w (cloud) and wb (background), each
// lowered by how far its opacity and distance are from the nearest march pixel's (near).
fn upsample_tap(acc: ptr<function, Upsample>, p: vec2<i32>, dims: vec2<i32>, w: f32, wb: f32, near: vec2<f32>) {
    let at = clamp(p, vec2<i32>(0), dims - 1);
    let t = textureLoad(cloud, at, 0);
    let sc = textureLoad(scene, at, 0);
    let wc = (w + 1e-4) * edge_weight(t.a - near.x, sc.a, near.y);
    (*acc).c += wc * t;
    (*acc).wsum += wc;
    let wbg = wb * edge_weight(0.0, sc.a, near.y);
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
        // bilateral filter on the march's own opacity and depth): a march pixel counts less the
        // more its opacity and distance differ from the nearest one's, so a cloud's edge stays
        // as sharp as the march found it instead of softening. Over the four march pixels
        // around (bilinear weights), or with WIDE_UPSAMPLE over a 4×4 footprint that also
        // resolves the march's jitter: bilinear between 3×3 means, weights (1−f)/3, 1/3, 1/3,
        // f/3 per axis. On a CPU driver, the one that upsamples, this pass runs over every
        // window pixel: the 4×4 footprint costs about 17 ms a frame more than the four at
        // 1280×720 on lavapipe (docs/performance.md, "The window's frame").
        let q = px - 0.5;
        let fr = q - floor(q);
        let i0 = vec2<i32>(floor(q));
        let near = vec2<f32>(textureLoad(cloud, near_at, 0).a, textureLoad(scene, near_at, 0).a);
        var acc = Upsample(vec4<f32>(0.0), 0.0, vec3<f32>(0.0), 0.0);
        if (WIDE_UPSAMPLE) {
            let wx = vec4<f32>(1.0 - fr.x, 1.0, 1.0, fr.x) / 3.0;
            let wy = vec4<f32>(1.0 - fr.y, 1.0, 1.0, fr.y) / 3.0;
            for (var j = 0; j < 4; j++) {
                for (var i = 0; i < 4; i++) {
                    let at = clamp(i0 + vec2<i32>(i - 1, j - 1), vec2<i32>(0), dims - 1);
                    let t = textureLoad(cloud, at, 0);
                    let wc = (wx[i] * wy[j] + 1e-4) * edge_weight(t.a - near.x, textureLoad(scene, at, 0).a, near.y);
                    acc.c += wc * t;
                    acc.wsum += wc;
                }
            }
            // The background has no jitter to resolve: its own bilinear taps, the middle four.
            for (var j = 0; j < 2; j++) {
                for (var i = 0; i < 2; i++) {
                    let at = clamp(i0 + vec2<i32>(i, j), vec2<i32>(0), dims - 1);
                    let sc = textureLoad(scene, at, 0);
                    let wbg = select(1.0 - fr.x, fr.x, i == 1) * select(1.0 - fr.y, fr.y, j == 1) * edge_weight(0.0, sc.a, near.y);
                    acc.b += wbg * sc.rgb;
                    acc.bw += wbg;
                }
            }
        } else {
            for (var j = 0; j < 2; j++) {
                for (var i = 0; i < 2; i++) {
                    let w = select(1.0 - fr.x, fr.x, i == 1) * select(1.0 - fr.y, fr.y, j == 1);
                    upsample_tap(&acc, i0 + vec2<i32>(i, j), dims, w, w, near);
                }
            }
        }
        c = acc.c / max(acc.wsum, 1e-6);
        bg = acc.b / max(acc.bw, 1e-6);
    } else {
        let own = textureLoad(scene, near_at, 0);
        bg = own.rgb;
        if (has_flag(FLAG_JITTER) && !has_flag(FLAG_NO_SKY)) {
            // Resolve the march's interleaved-gradient jitter, which spreads its values evenly
            // over every 3×3 block (Jimenez 2014): a still frame has no temporal filter, and
            // thin layers otherwise show the jitter's lattice: a 3×3 kernel as wide as the
            // step's grain asks (common.wgsl `resolve_weights`). Not for the score's top-down
            // frames (a mask view, where a blur only moves edges).
            // Not across the Earth's limb: a pixel the limb crosses is the mean of its own rays
            // (march.wgsl `first_ray`, `rework`), and the rows beside it show other things (sky, sea).
            // Nor across ground's silhouette (a mountain's edge against the cloud or sky past
            // it): there the blend drew the far deck a pixel down over the rock. A pixel shows
            // ground where its cloud is under half opaque and its distance (the scene texture's
            // w, the ground's there) is not 0 (sky); a neighbour past that ground, or sky, is
            // not blended with it, either way round.
            let rw = resolve_weights(f.step_growth);
            // Along its row only where the pixel grazes (frame.wgsl `grazing`): its rays down
            // the pixel resolve the deck's edge, and a blend with the rows above and below
            // drew the edge's bright line across three rows.
            let mid = vec2<f32>(near_at) + 0.5;
            let rows = select(limb_rows(mid), vec3<f32>(0.0, 1.0, 0.0), has_flag(FLAG_GRAZE) && grazing(mid));
            let own_ground = textureLoad(cloud, near_at, 0).a < 0.5 && own.a > 0.0;
            c = vec4<f32>(0.0);
            var wsum = 0.0;
            for (var j = -1; j <= 1; j++) {
                // Picked by select, not indexed: a vector indexed by a loop variable can go
                // through memory on a GPU.
                let row = select(select(rows.z, rows.y, j == 0), rows.x, j < 0);
                for (var i = -1; i <= 1; i++) {
                    let at = clamp(near_at + vec2<i32>(i, j), vec2<i32>(0), dims - 1);
                    let t = textureLoad(cloud, at, 0);
                    let d = textureLoad(scene, at, 0).a;
                    let past_own = own_ground && (d <= 0.0 || d > 1.25 * own.a);
                    let past_it = t.a < 0.5 && d > 0.0 && (own.a <= 0.0 || own.a > 1.25 * d);
                    let across = past_own || past_it;
                    let w = resolve_weight(rw, i, j) * select(row, 1.0, i == 0 && j == 0) * select(1.0, 0.0, across);
                    c += w * t;
                    wsum += w;
                }
            }
            c /= wsum;
        } else {
            c = textureLoad(cloud, near_at, 0);
        }
    }
    let lin = bg * (1.0 - c.a) + c.rgb;
    var out = aces(lin * exposure.value);
    if (ENCODE_SRGB) {
        out = srgb_encode(out);
    }
    return vec4<f32>(out, 1.0);
}
