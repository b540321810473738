// Section stage: the march's cloud (cloud.wgsl) on a vertical curtain. One invocation per pixel
// of a distance × altitude image evaluates the cloud's extinction (1/m) at that point: column x
// stands on the great-circle point `columns[x]`, row y at altitude top_m·(1 − (y + ½)/height).

struct SectionParams {
    width: u32,
    height: u32,
    top_m: f32,
    _pad: f32,
};

@group(2) @binding(0) var<uniform> sp: SectionParams;
// Unit ECEF direction of each column's ground point (xyz; w unused), formed in f64 on the CPU.
@group(2) @binding(1) var<storage, read_write> columns: array<vec4<f32>>;
@group(2) @binding(2) var<storage, read_write> sigma_out: array<f32>;

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    load_frame();
    if (id.x >= sp.width || id.y >= sp.height) {
        return;
    }
    let up = columns[id.x].xyz;
    let h = sp.top_m * (1.0 - (f32(id.y) + 0.5) / f32(sp.height));
    let pos = up * (EARTH_R + h);
    // The noise at this point as the march sees it from any camera: ECEF modulo the period.
    let np = pos - f.shape_period_m * floor(pos / f.shape_period_m);
    let sigma = density(pos, h, np, feature(FLAG_DETAIL)) * f.extinction;
    sigma_out[id.y * sp.width + id.x] = sigma;
}
