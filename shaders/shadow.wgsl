// Shadow stage: the full-column light (DESIGN §8). One invocation per texel of a volume over the
// region (map uv × altitude) integrates the cloud's mean extinction from the texel's point to
// the top of the cloud: toward the key light (R) and straight up (G). The march lights its
// samples with it beyond its short light march, and the ground takes the clouds' shadows from
// it. Made when the key light, the map or the look changes, not per frame, a slice of rows per
// dispatch when the key light moved (render::shadow).

@group(2) @binding(0) var od_out: texture_storage_3d<rgba16float, write>;
@group(2) @binding(1) var<storage, read> sh: ShadowParams;   // storage: see render::contract::params

// Optical depth given to a point the Earth hides from the key light; f16 holds it.
const SHADOW_BLOCKED: f32 = 1000.0;

// Mean optical depth from p0 (altitude h0) along the unit direction d to the volume's top.
fn path_od(p0: vec3<f32>, h0: f32, d: vec3<f32>) -> f32 {
    let mu = dot(d, normalize(p0));
    let earth = shell_hits(h0, mu, 0.0);
    if (mu < 0.0 && earth.x <= earth.y && earth.y > 0.0) {
        return SHADOW_BLOCKED;
    }
    let exit = min(shell_hits(h0, mu, sh.top_m).y, sh.max_path_m);
    if (exit <= 0.0) {
        return 0.0;
    }
    let n = sh.steps;
    var tau = 0.0;
    var t0 = 0.0;
    for (var i = 0u; i < n; i++) {
        var t1: f32;
        if (mu > 0.05) {
            // Evenly in altitude: a thin layer gets its samples however slanted the path.
            let ha = h0 + (sh.top_m - h0) * (f32(i) + 1.0) / f32(n);
            t1 = min(shell_hits(h0, mu, ha).y, exit);
        } else {
            t1 = exit * (f32(i) + 1.0) / f32(n);
        }
        let tm = 0.5 * (t0 + t1);
        let pos = p0 + d * tm;
        let uv = sample_uv(pos);
        if (uv.x < 0.0) {
            // Beyond the region there is no cloud.
            break;
        }
        tau += density_uv(uv, altitude_at(h0, mu, tm), pos, false) * (t1 - t0);
        t0 = t1;
    }
    return tau * f.extinction;
}

// One invocation per column of texels: straight up is one integral down the column, shared by
// its levels (a running sum from the top, two samples between level centres).
@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    load_frame();
    let dims = textureDimensions(od_out);
    // This dispatch's slice of rows (a volume may be made over several frames).
    let id = vec2<u32>(gid.x, gid.y + sh.row0);
    if (id.x >= dims.x || id.y >= min(dims.y, sh.row_end)) {
        return;
    }
    let uv = (vec2<f32>(id) + 0.5) / vec2<f32>(dims.xy);
    let lat = radians(f.region_north - uv.y * (f.region_north - f.region_south));
    let lon = radians(f.region_west + uv.x * f.region_lon_span);
    let up = vec3<f32>(cos(lat) * cos(lon), cos(lat) * sin(lon), sin(lat));
    let span = sh.top_m - sh.bottom_m;
    var tau_up = 0.0;
    var above = sh.top_m;
    for (var k = i32(dims.z) - 1; k >= 0; k--) {
        let h0 = sh.bottom_m + (f32(k) + 0.5) / f32(dims.z) * span;
        let dz = (above - h0) * 0.5;
        for (var j = 0; j < 2; j++) {
            let h = h0 + (f32(j) + 0.5) * dz;
            tau_up += density_uv(uv, h, up * (EARTH_R + h), false) * dz;
        }
        above = h0;
        let p0 = up * (EARTH_R + h0);
        let od = min(vec2<f32>(path_od(p0, h0, sh.key_dir), tau_up * f.extinction), vec2<f32>(6.0e4));
        textureStore(od_out, vec3<u32>(id, u32(k)), vec4<f32>(od, 0.0, 0.0));
    }
}
