// Area-light pass: painted area lights' diffuse light (Sun 2008 eq. 4.36, E = sum_k L_k T_k per
// vertex, computed on the CPU) and their glossy highlights toward the view (sec. 4.9, radiance
// per vertex, specular colour applied), added over the mode's surfaces: radiance out =
// albedo * E / pi + highlight, seen through the medium's extinction when there is one.

#define_import_path lightloom::mesh_area

#import lightloom::common::{MeshVertex, PI, globals}
#import lightloom::mesh_vertex::VertexOut
#import lightloom::fog::fog

struct AreaLights {
    // Diffuse albedo of each material, indexed by the vertex's material.
    albedo: array<vec3<f32>, 8>,
};

@group(2) @binding(0) var<uniform> area: AreaLights;
// Per vertex: irradiance E (rgb) from every linked area light.
@group(2) @binding(1) var<storage, read> irradiance: array<vec4<f32>>;
// Per vertex: reflected radiance (rgb) of the lights' highlights (zeros without them).
@group(2) @binding(2) var<storage, read> highlight: array<vec4<f32>>;

fn light_vertex(v: MeshVertex, index: u32, common_out: VertexOut) -> VertexOut {
    var out = common_out;
    let kd = area.albedo[v.material].rgb * v.color / PI;
    out.diffuse = kd * irradiance[index].rgb + highlight[index].rgb;
    return out;
}

fn shade(in: VertexOut, front: bool) -> vec4<f32> {
    var radiance = in.diffuse;
    if (fog.linked != 0u) {
        radiance = radiance * exp(-fog.beta * length(globals.camera_pos.xyz - in.world));
    }
    return vec4<f32>(radiance, 0.0);
}
