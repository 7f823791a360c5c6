// Depth of the scene seen from one direction over the sun's disc (render/src/passes/sun.rs):
// the instance index picks the shadow map's matrix.

@group(0) @binding(0) var<uniform> view_proj: array<mat4x4<f32>, 32>;

@vertex
fn vs_main(@location(0) position: vec3<f32>, @builtin(instance_index) layer: u32) -> @builtin(position) vec4<f32> {
    return view_proj[layer] * vec4<f32>(position, 1.0);
}
