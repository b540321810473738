// The window's panel and HUD as a layer of their own (app::overlay; prepended with
// fullscreen.wgsl). egui draws them into a texture the window's size, premultiplied, and this
// stage lays that texture over each frame: out = ui + (1 − α_ui)·frame, the blend egui itself
// draws with, so the frame shows what drawing egui onto it would. `fs_clear` empties a
// rectangle of the layer (the pass's scissor) before egui redraws what stands there.

@group(0) @binding(0) var ui_layer: texture_2d<f32>;

@fragment
fn fs_over(in: VsOut) -> @location(0) vec4<f32> {
    return textureLoad(ui_layer, vec2<i32>(in.pos.xy), 0);
}

@fragment
fn fs_clear(in: VsOut) -> @location(0) vec4<f32> {
    return vec4<f32>(0.0);
}
