// Tone mapping: linear HDR radiance -> display (the target format applies the sRGB curve).

struct ToneParams {
    // 2^EV
    exposure_scale: f32,
    // 0 ACES, 1 Reinhard, 2 linear clamp
    curve: u32,
};

@group(0) @binding(0) var hdr: texture_2d<f32>;
@group(0) @binding(1) var<uniform> tone: ToneParams;

@vertex
fn vs_main(@builtin(vertex_index) index: u32) -> @builtin(position) vec4<f32> {
    let uv = vec2<f32>(f32((index << 1u) & 2u), f32(index & 2u));
    return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
}

// Narkowicz's fit of the ACES filmic curve.
fn aces(x: vec3<f32>) -> vec3<f32> {
    return clamp((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), vec3<f32>(0.0), vec3<f32>(1.0));
}

@fragment
fn fs_main(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    let x = textureLoad(hdr, vec2<i32>(pos.xy), 0).rgb * tone.exposure_scale;
    var y: vec3<f32>;
    if (tone.curve == 0u) {
        y = aces(x);
    } else if (tone.curve == 1u) {
        y = x / (1.0 + x);
    } else {
        y = clamp(x, vec3<f32>(0.0), vec3<f32>(1.0));
    }
    return vec4<f32>(y, 1.0);
}
