// Background pass: the environment's radiance cube map seen through the camera.

#import lightloom::common::globals
#import lightloom::fog::fog_background

@group(2) @binding(0) var environment: texture_cube<f32>;
@group(2) @binding(1) var environment_sampler: sampler;

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) ndc: vec2<f32>,
};

@vertex
fn vs_main(@builtin(vertex_index) index: u32) -> VertexOut {
    // One triangle covering the screen.
    let uv = vec2<f32>(f32((index << 1u) & 2u), f32(index & 2u));
    var out: VertexOut;
    out.ndc = uv * 2.0 - 1.0;
    out.clip = vec4<f32>(out.ndc, 0.0, 1.0);
    return out;
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    let far = globals.inv_view_proj * vec4<f32>(in.ndc, 1.0, 1.0);
    let dir = normalize(far.xyz / far.w - globals.camera_pos.xyz);
    var env = textureSample(environment, environment_sampler, dir).rgb;
    if (globals.background == 0u) {
        env = vec3<f32>(0.0);
    }
    return vec4<f32>(fog_background(env, dir), 1.0);
}
