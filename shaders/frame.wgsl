// The frame's uniforms (`struct Frame`, common.wgsl) as the one global every stage that draws
// a view reads, and the helpers that read it. They read the global `f` itself: when they took
// it by value, the limb test's two calls a pixel cost the march 15-25 % on an NVIDIA GPU, most
// likely a copy of the whole 464-byte struct at each call (docs/performance.md, "The
// Frame passed by value"). Prepended after common.wgsl to the stages that bind it.
@group(0) @binding(0) var<storage, read> f: Frame;   // storage: see render::contract::frame

// Every entry point of a stage that binds the frame calls this first. On a GPU it does nothing:
// `f` is the storage binding. On a CPU adapter render::shader::module rewrites the binding
// above into `frame_in` and `f` into a private copy that this fills once an invocation: a read
// of a storage buffer is a load lavapipe bounds-checks and, most likely, cannot keep in a
// register across the shader's own stores, and the march reads `f` hundreds of times a step;
// a private copy's reads are not — the same pictures, the march 17-43 % faster
// (docs/performance.md, "The frame read once an invocation"). Not on a GPU, where the copy
// would hold 116 words of registers through the whole march (not measured: none was lent).
fn load_frame() {}

fn has_flag(bit: u32) -> bool {
    return (f.flags & bit) != 0u;
}

// Weather-map uv of a lat/lon, or a negative u when outside the region.
fn region_uv(ll: vec2<f32>) -> vec2<f32> {
    let dx = ll.y - f.region_west;
    let wrapped = dx - 360.0 * floor(dx / 360.0);
    let u = wrapped / f.region_lon_span;
    let v = (f.region_north - ll.x) / (f.region_north - f.region_south);
    if (u < 0.0 || u > 1.0 || v < 0.0 || v > 1.0) {
        return vec2<f32>(-1.0, -1.0);
    }
    return vec2<f32>(u, v);
}

// Clear-sky radiance seen along direction v from a point with local up `up`: a Rayleigh-blue
// dome brighter toward the horizon, Mie glow around the Sun, twilight that outlasts sunset, and
// the night's. An analytic stand-in for the atmosphere's tables (render::atmosphere), used for
// the ambient light of cloud and ground anywhere in the region (the tables are the camera's).
fn sky_radiance(v: vec3<f32>, up: vec3<f32>) -> vec3<f32> {
    let s = f.sun_dir;
    let sun_el = dot(s, up);
    let view_el = max(dot(v, up), 0.0);
    let day = smoothstep(-0.15, 0.05, sun_el);
    let zenith = vec3<f32>(0.20, 0.38, 0.80) * (0.25 + 0.75 * sat(sun_el * 3.0));
    let horizon_col = mix(vec3<f32>(0.95, 0.55, 0.30), vec3<f32>(0.60, 0.72, 0.90), sat(sun_el * 4.0 + 0.2));
    let horizon_w = pow(1.0 - view_el, 4.0);
    var c = mix(zenith, horizon_col, horizon_w) * day * 0.5;
    let cos_s = dot(v, s);
    c += f.sun_col * (hg(cos_s, 0.76) * 0.08 + hg(cos_s, 0.3) * 0.05);
    return c + night_sky(v, up);
}

// The night's sky: a faint airglow (about 1/250 of full-moon light) and the moonlit sky.
fn night_sky(v: vec3<f32>, up: vec3<f32>) -> vec3<f32> {
    let horizon_w = pow(1.0 - max(dot(v, up), 0.0), 4.0);
    let m = f.moon_dir;
    let moon_up = smoothstep(-0.05, 0.05, dot(m, up));
    var c = vec3<f32>(0.3, 0.4, 0.6) * 1e-8 * (1.0 + horizon_w);
    c += f.moon_col * moon_up * (mix(vec3<f32>(0.10, 0.19, 0.40), vec3<f32>(0.3, 0.36, 0.45), horizon_w)
        + vec3<f32>(hg(dot(v, m), 0.76) * 0.08));
    return c;
}

// The sky-view table's frame at the camera: horizontal toward the Sun, and 90° left of it.
fn sky_frame() -> array<vec3<f32>, 2> {
    let up = f.cam_up;
    let s = f.sun_dir - up * dot(f.sun_dir, up);
    var x = f.cam_right - up * dot(f.cam_right, up);
    if (dot(s, s) > 1e-8) {
        x = s;
    }
    x = normalize(x);
    return array<vec3<f32>, 2>(x, cross(up, x));
}

// Perspective view direction through pixel position px (pixel units, centre = +0.5).
fn persp_dir(px: vec2<f32>) -> vec3<f32> {
    let ndc = vec2<f32>(px.x / f.out_size.x * 2.0 - 1.0, 1.0 - px.y / f.out_size.y * 2.0);
    let tn = f.tan_half_fov;
    return normalize(f.cam_fwd + f.cam_right * (ndc.x * tn * f.aspect) + f.cam_view_up * (ndc.y * tn));
}

// The cosine to the camera's vertical of a ray grazing the Earth's limb (the sea-level horizon).
fn limb_mu() -> f32 {
    let k = EARTH_R / (EARTH_R + max(f.cam_alt_m, 0.0));
    return -sqrt(max(1.0 - k * k, 0.0));
}

// Which side of the Earth's limb the pixel at `px` lies on: 1 above, −1 below, 0 where the limb
// crosses it (its corners' rays lie on both sides of the horizon's cone). A pixel the limb
// crosses covers sky and sea, and one ray shows one of them: the march takes one ray in each
// part there (`limb_share`), and the present stage's resolve does not blend across the limb.
fn limb_side(px: vec2<f32>) -> i32 {
    let mu_h = limb_mu();
    // A pixel is at most one pixel's angle at the view's middle from its centre ray to a corner,
    // and a ray's cosine to the vertical moves no faster than its angle: most pixels are settled
    // by their centre alone.
    let off = dot(persp_dir(px), f.cam_up) - mu_h;
    if (abs(off) > 2.0 * f.tan_half_fov / f.out_size.y) {
        return select(-1, 1, off > 0.0);
    }
    var above = 0;
    for (var i = 0u; i < 4u; i++) {
        let c = px + vec2<f32>(select(-0.5, 0.5, (i & 1u) != 0u), select(-0.5, 0.5, (i & 2u) != 0u));
        above += select(0, 1, dot(persp_dir(c), f.cam_up) > mu_h);
    }
    return select(select(0, -1, above == 0), 1, above == 4);
}

// Which of the rows above, at and below the pixel at `px` lie on its side of the Earth's limb
// (1) or not (0): none where the limb crosses the pixel itself. The present stage's resolve
// blends only those. Beyond four pixels' angle from the limb (a row and its corners are less
// than two away) the centre ray settles all three, as it does for most pixels.
fn limb_rows(px: vec2<f32>) -> vec3<f32> {
    let off = dot(persp_dir(px), f.cam_up) - limb_mu();
    if (abs(off) > 4.0 * f.tan_half_fov / f.out_size.y) {
        return vec3<f32>(1.0);
    }
    let side = limb_side(px);
    var rows = vec3<f32>(0.0);
    if (side != 0) {
        rows = vec3<f32>(
            select(0.0, 1.0, limb_side(px - vec2<f32>(0.0, 1.0)) == side),
            1.0,
            select(0.0, 1.0, limb_side(px + vec2<f32>(0.0, 1.0)) == side),
        );
    }
    return rows;
}

// How far above the horizontal (the cosine to the vertical) a ray still counts as grazing.
const GRAZE_MU: f32 = 0.01;

// Whether the ray through the pixel at `px` runs between the sea's limb and just above the
// horizontal. There it meets the layers' tops and bases nearly edge-on: a deck's top or base
// crosses the pixel's row as a line thinner than the pixel, and one ray shows one side of it,
// or whichever side the step's jitter picks. The march takes more rays down such a pixel where
// its picture differs from its neighbours' (march.wgsl `needs_grazing_rays`, `rework`), and the present
// stage's resolve blends only along its row.
fn grazing(px: vec2<f32>) -> bool {
    let m = dot(persp_dir(px), f.cam_up);
    return m > limb_mu() && m < GRAZE_MU;
}

// Where the limb crosses the pixel's middle column, as the share of its height above that point
// (the ray's angle to the limb is linear in y to well under a pixel's height).
fn limb_share(px: vec2<f32>) -> f32 {
    let mu_h = limb_mu();
    let top = dot(persp_dir(px - vec2<f32>(0.0, 0.5)), f.cam_up) - mu_h;
    let bottom = dot(persp_dir(px + vec2<f32>(0.0, 0.5)), f.cam_up) - mu_h;
    return select(0.5, clamp(top / (top - bottom), 0.0, 1.0), abs(top - bottom) > 1e-9);
}

// Aerial haze transmittance over `dist` metres between altitudes h0 and h1: the haze's share of
// the visibility's extinction (3.912 / V, Koschmieder, less the clear air's, frame.rs) at sea
// level, thinning with a 1.5 km aerosol scale height (taken at the mean altitude). The clear
// air's own extinction and light are the aerial-perspective table's (scene.wgsl `aerial`).
fn haze_transmittance(h0: f32, h1: f32, dist: f32) -> f32 {
    let hm = max(0.5 * (h0 + h1), 0.0);
    let beta = f.haze_beta * exp(-hm / 1500.0);
    return exp(-beta * dist);
}
