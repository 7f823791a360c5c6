// Shared uniforms of the viewport passes.

struct Globals {
    view_proj: mat4x4<f32>,
    inv_view_proj: mat4x4<f32>,
    camera_pos: vec4<f32>,
    // x: SH bands used (0 = no environment), y: draw background (0/1), z: unused, w: unused
    flags: vec4<f32>,
    // Diffuse albedo (rgb) of each material, indexed by the vertex's material.
    albedo: array<vec4<f32>, 8>,
    // Irradiance SH coefficients E_lm (rgb), index l*(l+1)+m, at most 5 bands.
    irradiance: array<vec4<f32>, 25>,
};

@group(0) @binding(0) var<uniform> globals: Globals;
