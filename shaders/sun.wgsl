// The environment's sun lit per pixel (group 3, render/src/passes/sun.rs; the disc and its
// directions come from nodes/src/sun.rs): each direction carries an equal share of the disc's
// power and is shadowed by its own orthographic shadow map (2x2 PCF by the comparison sampler).

const MAX_SUN_DIRECTIONS: i32 = 32;

struct Sun {
    // rgb: radiance x solid angle / direction count (irradiance at normal incidence per
    // direction); w: direction count (0: no separate sun).
    irradiance: vec4<f32>,
    // x: normal offset against self-shadowing (world units); yzw unused.
    offset: vec4<f32>,
    // xyz: the disc's axis; w: cos of its angular radius.
    axis: vec4<f32>,
    // xyz: unit vector towards the sun.
    directions: array<vec4<f32>, MAX_SUN_DIRECTIONS>,
    // World to each shadow map's clip space (orthographic, depth in [0, 1]).
    view_proj: array<mat4x4<f32>, MAX_SUN_DIRECTIONS>,
};

@group(3) @binding(0) var<uniform> sun: Sun;
@group(3) @binding(1) var sun_shadow_maps: texture_depth_2d_array;
@group(3) @binding(2) var sun_shadow_sampler: sampler_comparison;

// Whether direction `k` sees the sun from `shifted` (2x2 PCF; 1 outside its map).
fn sun_visibility(k: i32, shifted: vec4<f32>) -> f32 {
    let clip = sun.view_proj[k] * shifted;
    let uv = vec2<f32>(clip.x * 0.5 + 0.5, 0.5 - clip.y * 0.5);
    if (any(uv <= vec2<f32>(0.0)) || any(uv >= vec2<f32>(1.0)) || clip.z >= 1.0) {
        return 1.0;
    }
    return textureSampleCompareLevel(sun_shadow_maps, sun_shadow_sampler, uv, k, clip.z);
}

// Light reflected towards the viewer at `p` (normal `n`) from the sun: per direction, the
// shadow test times the cosine times Lambert `kd` plus the material's Phong-equivalent lobe
// `lobe_weight cos_m^exponent` (nodes/src/brdf.rs `Brdf::eval`, exact for Phong).
fn sun_direct(p: vec3<f32>, n: vec3<f32>, kd: vec3<f32>, lobe_weight: vec3<f32>, exponent: f32, mirror: vec3<f32>, glossy: bool) -> vec3<f32> {
    let count = i32(sun.irradiance.w);
    if (count == 0) {
        return vec3<f32>(0.0);
    }
    let shifted = vec4<f32>(p + n * sun.offset.x, 1.0);
    // The last quarter of the directions (from 16 on) lie evenly round the disc's rim
    // (nodes/src/sun.rs `rim_directions`): where they all agree (all wholly lit or all wholly
    // shadowed), the disc does up to the segment between two of them, and the other maps need
    // not be read (outside penumbrae, nearly everywhere). Below 16 every direction is read.
    var probes = count;
    if (count >= 16) {
        probes = count / 4;
    }
    var probe_sum = 0.0;
    for (var j = 0; j < probes; j = j + 1) {
        probe_sum = probe_sum + sun_visibility(count - 1 - j, shifted);
    }
    if (probe_sum == 0.0) {
        return vec3<f32>(0.0);
    }
    let lit = probe_sum == f32(probes);
    // A wholly lit disc wholly above the horizon: the cap's mean cosine is exact,
    // (n . axis)(1 + cos r)/2, and only a lobe needs the directions.
    let cos_axis = dot(n, sun.axis.xyz);
    let cos_r = sun.axis.w;
    let above = cos_axis * cos_axis >= 1.0 - cos_r * cos_r && cos_axis > 0.0;
    if (lit && above && !glossy) {
        return kd * (cos_axis * (1.0 + cos_r) * 0.5 * f32(count)) * sun.irradiance.rgb;
    }
    var sum = vec3<f32>(0.0);
    for (var k = 0; k < count; k = k + 1) {
        let d = sun.directions[k].xyz;
        let cos_i = dot(n, d);
        if (cos_i <= 0.0) {
            continue;
        }
        var visible = 1.0;
        if (!lit) {
            visible = sun_visibility(k, shifted);
        }
        var f = kd;
        if (glossy) {
            f = f + lobe_weight * pow(max(dot(d, mirror), 0.0), exponent);
        }
        let reflected = f * cos_i;
        sum = sum + visible * reflected;
    }
    return sum * sun.irradiance.rgb;
}
