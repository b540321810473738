// Reproject stage: builds the full-resolution frame from this frame's subset march (one pixel
// of each n×n cell, render::reproject) and the previous full-resolution frame moved by the
// camera's motion and each pixel's distance (DESIGN §4b, as in Guerrilla's Nubis). History that
// no longer fits (off the last frame, disoccluded, a large change of distance, past the
// region's edge) is rejected and the fresh subset, upsampled, stands in for it.

@group(0) @binding(1) var<storage, read> rp: Reproject;   // storage: see render::contract::params
@group(0) @binding(2) var lin: sampler;
// This frame's subset march: one texel per cell (march.wgsl's cloud and scene).
@group(1) @binding(0) var fresh_cloud: texture_2d<f32>;
@group(1) @binding(1) var fresh_scene: texture_2d<f32>;
// The previous full-resolution frame.
@group(1) @binding(2) var hist_cloud: texture_2d<f32>;
@group(1) @binding(3) var hist_scene: texture_2d<f32>;
@group(1) @binding(4) var out_cloud: texture_storage_2d<rgba16float, write>;
@group(1) @binding(5) var out_scene: texture_storage_2d<rgba16float, write>;

// The previous frame's camera (render::reproject::ReprojectParams).
struct Reproject {
    prev_fwd: vec3<f32>,
    prev_tan_half_fov: f32,
    prev_right: vec3<f32>,
    prev_aspect: f32,
    prev_view_up: vec3<f32>,
    valid: u32,                 // 0: no usable history (first frame, a teleport, a new map)
    prev_delta: vec3<f32>,      // previous camera position − this one (ECEF m)
    max_depth_change: f32,      // relative change of a pixel's distance that rejects its history
    still: u32,                 // 0: the camera moved; k + 1: the k-th frame of a still camera
    max_age: u32,               // a still view's marched pixel older than this (frames) is not kept
    lattice_x: u32,             // the still view's lattice of young marched pixels: its offset
    lattice_y: u32,
    lattice_step: u32,          // and step (render::reproject::still_lattice)
    whole: u32,                 // 1: the still view began after a full march: every pixel is its own
    new_weight: f32,            // a still view's march this frame against its pixel's mean
                                // (render::reproject::still_mean_weight)
    _pad2: u32,
};

// Set by the pipeline (render::reproject::ReprojectPass): a still camera with a valid history
// (`rp.still` > 0, `rp.valid`), whose pixels fill from the still view's lattice; else the
// moving view's path. A constant, not the uniform's test: a CPU driver runs both paths for
// every pixel when the choice is a uniform's.
override STILL: bool = false;

// Moved by less than this (px) since the last frame, a pixel keeps its history unclamped.
const STILL_PX: f32 = 0.25;

// Fresh samples around a pixel (the moving view's bilinear footprint, the still view's
// lattice): their range bounds the history kept (no ghosts) and their bilinear mean stands in
// where there is none. Both views gather it with fill_add.
struct Fill {
    lo_c: vec4<f32>,
    hi_c: vec4<f32>,
    lo_s: vec3<f32>,
    hi_s: vec3<f32>,
    up_c: vec4<f32>,    // weighted sums: the mean is up / wsum
    up_s: vec3<f32>,
    wsum: f32,
};

fn fill_empty() -> Fill {
    return Fill(vec4<f32>(1e30), vec4<f32>(-1e30), vec3<f32>(1e30), vec3<f32>(-1e30),
        vec4<f32>(0.0), vec3<f32>(0.0), 0.0);
}

// Adds the sample (cloud c, scene s) at bilinear weight wb. Not weighed down across a change
// of opacity or distance: against the nearest sample's, on a lattice n pixels apart, that kept
// the nearest one wherever they differed and turned the fill into n-pixel blocks, and it erred
// more than bilinear against the full march (docs/footprint.md, "The enlarged march,
// bilinear").
fn fill_add(fill: ptr<function, Fill>, c: vec4<f32>, s: vec4<f32>, wb: f32) {
    (*fill).lo_c = min((*fill).lo_c, c);
    (*fill).hi_c = max((*fill).hi_c, c);
    (*fill).lo_s = min((*fill).lo_s, s.rgb);
    (*fill).hi_s = max((*fill).hi_s, s.rgb);
    let w = wb + 1e-4;
    (*fill).up_c += w * c;
    (*fill).up_s += w * s.rgb;
    (*fill).wsum += w;
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    load_frame();
    let size = vec2<u32>(f.out_size);
    if (any(id.xy >= size)) {
        return;
    }
    let n = max(u32(f.subset_n), 1u);
    let off = vec2<u32>(f.subset_offset);
    let cells = vec2<i32>(textureDimensions(fresh_cloud));
    let p = vec2<i32>(id.xy);
    let cell = p / i32(n);
    let own = min(vec2<u32>(cell) * n + off, size - 1u);
    if (all(own == id.xy)) {
        // Marched this frame: in a still view, into the mean of its marches so far (weighed
        // by render::reproject::still_mean_weight: the ¼ window at rest otherwise kept one
        // march's jitter noise, docs/footprint.md, "A still view's marches averaged").
        var c = textureLoad(fresh_cloud, cell, 0);
        var s = textureLoad(fresh_scene, cell, 0);
        if (STILL) {
            let w = rp.new_weight;
            c = mix(textureLoad(hist_cloud, p, 0), c, w);
            s = vec4<f32>(mix(textureLoad(hist_scene, p, 0).rgb, s.rgb, w), s.a);
        }
        textureStore(out_cloud, p, c);
        textureStore(out_scene, p, s);
        return;
    }
    if (STILL) {
        still_pixel(id.xy, size, n);
        return;
    }
    // Where the pixel sits among the fresh samples (sample c stands at pixel c·n + off).
    let q = (vec2<f32>(p) - vec2<f32>(off)) / f32(n);
    let c0 = vec2<i32>(floor(q));
    let fr = q - floor(q);
    let nearest = clamp(vec2<i32>(round(q)), vec2<i32>(0), cells - 1);
    let near_scene = textureLoad(fresh_scene, nearest, 0);
    // The fresh samples' bilinear footprint (Fill: where the march now finds clear air around
    // a pixel, no history keeps cloud there).
    var fill = fill_empty();
    for (var j = 0; j < 2; j++) {
        for (var i = 0; i < 2; i++) {
            let at = clamp(c0 + vec2<i32>(i, j), vec2<i32>(0), cells - 1);
            let c = textureLoad(fresh_cloud, at, 0);
            let wb = select(1.0 - fr.x, fr.x, i == 1) * select(1.0 - fr.y, fr.y, j == 1);
            let s = textureLoad(fresh_scene, at, 0);
            fill_add(&fill, c, s, wb);
        }
    }
    var out_c = fill.up_c / fill.wsum;
    var out_s = vec4<f32>(fill.up_s / fill.wsum, near_scene.a);
    if (rp.valid != 0u) {
        // The point this pixel shows, at the distance of the fresh sample nearest to it (sky:
        // a direction, infinitely far), seen from the previous camera.
        let d = persp_dir(vec2<f32>(p) + 0.5);
        var v = d;
        var expect_km = 0.0;
        if (near_scene.a > 0.0) {
            let w = d * (near_scene.a * 1000.0) - rp.prev_delta;
            expect_km = length(w) * 1e-3;
            v = normalize(w);
        }
        let z = dot(v, rp.prev_fwd);
        if (z > 1e-4) {
            let x = dot(v, rp.prev_right) / z / (rp.prev_tan_half_fov * rp.prev_aspect);
            let y = dot(v, rp.prev_view_up) / z / rp.prev_tan_half_fov;
            let uv = vec2<f32>(x + 1.0, 1.0 - y) * 0.5;
            let inside = all(uv >= vec2<f32>(0.0)) && all(uv <= vec2<f32>(1.0));
            let moved = length(uv * f.out_size - (vec2<f32>(p) + 0.5));
            if (inside && moved < STILL_PX) {
                // Where the pixel has not moved its history is its own earlier march, exact:
                // kept whole, so a still view gathers every pixel of the cell in n² frames.
                out_c = textureLoad(hist_cloud, p, 0);
                out_s = textureLoad(hist_scene, p, 0);
            } else if (inside) {
                let hp = clamp(vec2<i32>(floor(uv * f.out_size)), vec2<i32>(0), vec2<i32>(size) - 1);
                let hd = textureLoad(hist_scene, hp, 0).a;
                // The history's own point, seen from this camera: its distance now.
                var carried = 0.0;
                if (hd > 0.0) {
                    let pd = normalize(rp.prev_fwd + rp.prev_right * (x * rp.prev_tan_half_fov * rp.prev_aspect)
                        + rp.prev_view_up * (y * rp.prev_tan_half_fov));
                    carried = length(pd * (hd * 1000.0) + rp.prev_delta) * 1e-3;
                }
                // Disocclusion or a large change of distance: the history shows something else.
                let same_kind = (hd > 0.0) == (expect_km > 0.0);
                let change = abs(hd - expect_km) / max(max(hd, expect_km), 1e-3);
                // Past the region's edge there is no cloud to keep: a point the pixel shows
                // outside the map takes the fresh samples.
                var in_region = true;
                if (expect_km > 0.0) {
                    let at = f.cam_up * (EARTH_R + f.cam_alt_m) + d * (near_scene.a * 1000.0);
                    in_region = region_uv(lat_lon(at)).x >= 0.0;
                }
                if (same_kind && in_region && change <= rp.max_depth_change) {
                    let hc = textureSampleLevel(hist_cloud, lin, uv, 0.0);
                    let hs = textureSampleLevel(hist_scene, lin, uv, 0.0);
                    out_c = clamp(hc, fill.lo_c, fill.hi_c);
                    out_s = vec4<f32>(clamp(hs.rgb, fill.lo_s, fill.hi_s), carried);
                }
            }
        }
    }
    textureStore(out_cloud, p, out_c);
    textureStore(out_scene, p, out_s);
}

// Rank of a pixel of an n×n cell in the subset order (render::reproject::bayer): the Bayer
// matrix, M₂ = [0 2; 3 1] at each bit of the position, the lowest bit weighing most.
fn bayer_rank(q: vec2<u32>, n: u32) -> u32 {
    var r = 0u;
    var w = n * n / 4u;
    for (var l = 0u; (1u << l) < n; l++) {
        let x = (q.x >> l) & 1u;
        let y = (q.y >> l) & 1u;
        r += w * select(select(0u, 2u, x == 1u), select(3u, 1u, x == 1u), y == 1u);
        w /= 4u;
    }
    return r;
}

struct Px {
    c: vec4<f32>,
    s: vec4<f32>,
};

// A pixel's own march in a still view: this frame's (the fresh texel it stands at) or kept.
fn own_march(q: vec2<u32>, n: u32) -> Px {
    if (all(q % n == vec2<u32>(f.subset_offset))) {
        let cell = vec2<i32>(q / n);
        return Px(textureLoad(fresh_cloud, cell, 0), textureLoad(fresh_scene, cell, 0));
    }
    return Px(textureLoad(hist_cloud, vec2<i32>(q), 0), textureLoad(hist_scene, vec2<i32>(q), 0));
}

// A still view (the camera has not moved for k + 1 frames, rp.still): a pixel marched in the
// last max_age frames is kept whole (a still view gathers every pixel of its cell in n²
// frames). Any other pixel is made from the still lattice, the pixels around it that were
// marched recently (render::reproject::still_lattice): bilinear from them once the
// lattice is at most half a large cell (8 px or more: the last frame's picture, from the fresh
// subset or a moving view's coarse history, is no better than that then), else
// the last frame's pixel (no pop when the camera stops: it was the moving view's reprojected
// picture, at least as good as a coarse lattice), clamped to their range only where time runs
// fast enough to drift the clouds before the cell is marched whole. A still view that began
// after a full march (rp.whole) keeps every pixel.
fn still_pixel(p: vec2<u32>, size: vec2<u32>, n: u32) {
    let nn = n * n;
    let k = rp.still - 1u;
    let r = bayer_rank(p % n, n);
    let since = (k % nn + nn - r) % nn;
    if (rp.whole != 0u || (k >= r && since < rp.max_age)) {
        textureStore(out_cloud, p, textureLoad(hist_cloud, p, 0));
        textureStore(out_scene, p, textureLoad(hist_scene, p, 0));
        return;
    }
    let st = max(rp.lattice_step, 1u);
    let o = vec2<u32>(rp.lattice_x, rp.lattice_y);
    // The lattice pixel at or before p on each axis (the first one where p lies before it).
    let q0 = o + select((p - o) / st, vec2<u32>(0u), p < o) * st;
    let fr = clamp((vec2<f32>(p) - vec2<f32>(q0)) / f32(st), vec2<f32>(0.0), vec2<f32>(1.0));
    var px: array<Px, 4>;
    var wb: array<f32, 4>;
    var best = 0;
    for (var i = 0; i < 4; i++) {
        let ij = vec2<u32>(u32(i & 1), u32(i >> 1));
        // Past the picture's edge the lattice pixel before it stands in.
        let q = select(q0 + ij * st, q0, q0 + ij * st >= size);
        px[i] = own_march(q, n);
        wb[i] = select(1.0 - fr.x, fr.x, ij.x == 1u) * select(1.0 - fr.y, fr.y, ij.y == 1u);
        if (wb[i] > wb[best]) {
            best = i;
        }
    }
    let near = px[best];
    var fill = fill_empty();
    for (var i = 0; i < 4; i++) {
        fill_add(&fill, px[i].c, px[i].s, wb[i]);
    }
    if (st * 2u <= n && n >= 8u) {
        textureStore(out_cloud, p, fill.up_c / fill.wsum);
        textureStore(out_scene, p, vec4<f32>(fill.up_s / fill.wsum, near.s.a));
        return;
    }
    let hc = textureLoad(hist_cloud, p, 0);
    let hs = textureLoad(hist_scene, p, 0);
    if (rp.max_age >= nn) {
        // The scene's time stands (or crawls): nothing drifts before the cell is marched whole.
        textureStore(out_cloud, p, hc);
        textureStore(out_scene, p, hs);
        return;
    }
    textureStore(out_cloud, p, clamp(hc, fill.lo_c, fill.hi_c));
    textureStore(out_scene, p, vec4<f32>(clamp(hs.rgb, fill.lo_s, fill.hi_s), hs.a));
}
