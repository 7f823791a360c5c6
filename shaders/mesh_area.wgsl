// Area-light pass: painted area lights' diffuse light (Sun 2008 eq. 4.36, E = sum_k L_k T_k per
// vertex, or per texel on meshes with a visibility texture, computed on the CPU) and their
// glossy highlights toward the view (sec. 4.9, radiance per vertex, specular colour applied),
// added over the mode's surfaces: radiance out = albedo * E / pi + highlight, seen through the
// medium's extinction when there is one.

#define_import_path lightloom::mesh_area

#import lightloom::common::{MeshVertex, PI, globals}
#import lightloom::mesh_vertex::VertexOut
#import lightloom::fog::fog

struct AreaLights {
    // Diffuse albedo of each material, indexed by the vertex's material.
    albedo: array<vec3<f32>, 8>,
    // 1 when per-texel irradiance is bound, and its layers' side.
    texels_bound: u32,
    texel_size: u32,
};

@group(2) @binding(0) var<uniform> area: AreaLights;
// Per vertex: irradiance E (rgb) from every linked area light.
@group(2) @binding(1) var<storage, read> irradiance: array<vec4<f32>>;
// Per vertex: reflected radiance (rgb) of the lights' highlights (zeros without them).
@group(2) @binding(2) var<storage, read> highlight: array<vec4<f32>>;
// Per texel of the meshes with a visibility texture: E (rgb), layer-major, rows at increasing v.
@group(2) @binding(3) var<storage, read> texel_irradiance: array<vec4<f32>>;
// Per vertex: its mesh's texel layer, or -1.
@group(2) @binding(4) var<storage, read> vertex_layers: array<i32>;

fn light_vertex(v: MeshVertex, index: u32, common_out: VertexOut) -> VertexOut {
    var out = common_out;
    let kd = area.albedo[v.material].rgb * v.color / PI;
    // Lambert's factor (the albedo over pi), which the per-texel irradiance multiplies.
    out.albedo = kd;
    out.diffuse = kd * irradiance[index].rgb;
    out.glossy = highlight[index].rgb;
    if (area.texels_bound != 0u) {
        out.layer = vertex_layers[index];
    }
    return out;
}

// E at the pixel from the four texels around it (texel centres at (x + 0.5) / size), clamped
// at the layer's edges.
fn texel_e(uv: vec2<f32>, layer: u32) -> vec3<f32> {
    let size = area.texel_size;
    let f = clamp(uv * f32(size) - 0.5, vec2<f32>(0.0), vec2<f32>(f32(size - 1u)));
    let x0 = u32(floor(f.x));
    let y0 = u32(floor(f.y));
    let x1 = min(x0 + 1u, size - 1u);
    let y1 = min(y0 + 1u, size - 1u);
    let w = f - floor(f);
    let base = layer * size * size;
    let top = mix(texel_irradiance[base + y0 * size + x0].rgb, texel_irradiance[base + y0 * size + x1].rgb, w.x);
    let bottom = mix(texel_irradiance[base + y1 * size + x0].rgb, texel_irradiance[base + y1 * size + x1].rgb, w.x);
    return mix(top, bottom, w.y);
}

fn shade(in: VertexOut, front: bool) -> vec4<f32> {
    var diffuse = in.diffuse;
    if (area.texels_bound != 0u && in.layer >= 0) {
        diffuse = in.albedo * texel_e(in.uv, u32(in.layer));
    }
    var radiance = diffuse + in.glossy;
    if (fog.linked != 0u) {
        radiance = radiance * exp(-fog.beta * length(globals.camera_pos.xyz - in.world));
    }
    return vec4<f32>(radiance, 0.0);
}
