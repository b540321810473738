// The jitter resolve: a march pixel's picture from it and its 3×3 neighbours, shared by the
// present stage (a march at the target's size) and the resolve stage (a smaller march, resolved
// at its own size before the present stage enlarges it). Each includer binds the march's
// `cloud` and `scene` textures.

// The cloud of the march pixel at `near_at` (of `dims`), its jitter resolved under the 3×3
// kernel weights `rw` (common.wgsl `resolve_weights`) where the frame has jitter; as marched
// elsewhere.
fn jitter_resolved(near_at: vec2<i32>, dims: vec2<i32>, rw: vec3<f32>) -> vec4<f32> {
    if (!has_flag(FLAG_JITTER) || has_flag(FLAG_NO_SKY)) {
        return textureLoad(cloud, near_at, 0);
    }
    let own = textureLoad(scene, near_at, 0);
    // Resolve the march's interleaved-gradient jitter, which spreads its values evenly
    // over every 3×3 block (Jimenez 2014): a still frame has no temporal filter, and
    // thin layers otherwise show the jitter's lattice: a 3×3 kernel as wide as the
    // step's grain asks (`rw`). Not for the score's top-down
    // frames (a mask view, where a blur only moves edges).
    // Not across the Earth's limb: a pixel the limb crosses is the mean of its own rays
    // (march.wgsl `first_ray`, `rework`), and the rows beside it show other things (sky, sea).
    // Nor across ground's silhouette (a mountain's edge against the cloud or sky past
    // it): there the blend drew the far deck a pixel down over the rock. A pixel shows
    // ground where its cloud is under half opaque and its distance (the scene texture's
    // w, the ground's there) is not 0 (sky); a neighbour past that ground, or sky, is
    // not blended with it, either way round.
    // Along its row only where the pixel grazes (frame.wgsl `grazing`): its rays down
    // the pixel resolve the deck's edge, and a blend with the rows above and below
    // drew the edge's bright line across three rows.
    let mid = vec2<f32>(near_at) + 0.5;
    let rows = select(limb_rows(mid), vec3<f32>(0.0, 1.0, 0.0), has_flag(FLAG_GRAZE) && grazing(mid));
    let own_ground = textureLoad(cloud, near_at, 0).a < 0.5 && own.a > 0.0;
    var c = vec4<f32>(0.0);
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
    return c / wsum;
}
