// Exposure stage: meters the frame as the present stage will show it (cloud over background,
// before the tone curve) on a 64×64 grid, and adapts the exposure toward a mid-grey key for the
// log-mean luminance, from ½ EV under to 3 EV over the Sun's-height exposure the CPU gives
// (Frame.exposure): an eye under an overcast opens up, a bright deck from above stays bright
// (as snow does), and dusk and night stay dark (no opening up once the Sun is down; DESIGN §8).
// One workgroup.

@group(1) @binding(0) var cloud: texture_2d<f32>;
@group(1) @binding(1) var scene: texture_2d<f32>;    // the background behind it (march.wgsl)
@group(2) @binding(0) var<storage, read_write> exposure: ExposureState;
@group(2) @binding(1) var<uniform> ep: ExposureParams;

// Meter grid side, and the samples each of the 256 invocations takes.
const METER: u32 = 64u;
const PER_LANE: u32 = 16u;
// The luminance the log-mean is exposed to, and how far adaptation may go from the anchor.
const KEY: f32 = 0.18;
const DARKER: f32 = 1.5;
const BRIGHTER: f32 = 8.0;

var<workgroup> sums: array<f32, 256>;

@compute @workgroup_size(256, 1, 1)
fn main(@builtin(local_invocation_index) li: u32) {
    load_frame();
    let dims = vec2<i32>(textureDimensions(cloud));
    var s = 0.0;
    for (var k = 0u; k < PER_LANE; k++) {
        let i = li * PER_LANE + k;
        let uv = (vec2<f32>(f32(i % METER), f32(i / METER)) + 0.5) / f32(METER);
        let at = clamp(vec2<i32>(uv * vec2<f32>(dims)), vec2<i32>(0), dims - 1);
        let c = textureLoad(cloud, at, 0);
        let bg = textureLoad(scene, at, 0).rgb;
        s += log(max(luminance(bg * (1.0 - c.a) + c.rgb), 1e-12));
    }
    sums[li] = s;
    workgroupBarrier();
    for (var w = 128u; w > 0u; w = w >> 1u) {
        if (li < w) {
            sums[li] += sums[li + w];
        }
        workgroupBarrier();
    }
    if (li == 0u) {
        let log_mean = sums[0] / f32(METER * METER);
        exposure.metered = log_mean;
        if (ep.auto_on == 0u || has_flag(FLAG_NO_SKY)) {
            exposure.value = f.exposure;
            exposure.adapted = f.exposure / ep.ev_mul;
            return;
        }
        let anchor = f.exposure / ep.ev_mul;
        // Opening up only by day, so dusk and night stay dark; stopping down always.
        let day = smoothstep(-0.02, 0.1, dot(f.sun_dir, f.cam_up));
        let want = clamp(KEY / exp(log_mean), anchor / DARKER, anchor * mix(1.0, BRIGHTER, day));
        var e = want;
        if (ep.rate < 1.0 && exposure.adapted > 0.0) {
            // Adapt in stops, as the eye does.
            e = exp(mix(log(exposure.adapted), log(want), ep.rate));
        }
        exposure.adapted = e;
        exposure.value = e * ep.ev_mul;
    }
}
