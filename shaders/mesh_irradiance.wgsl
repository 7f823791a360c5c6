// Mesh pass: unshadowed diffuse lighting from the environment's irradiance SH
// (Sun 2008 eq. 2.20: E(n) = sum_lm A_l L_lm Y_lm(n); radiance out = albedo * E / pi).
// The coefficients E_lm arrive precomputed; this shader only evaluates the basis.

#define_import_path lightloom::mesh_irradiance

#import lightloom::common::{MeshVertex, PI, sh_walk, sh_walk_next}
#import lightloom::mesh_vertex::VertexOut
#import lightloom::normal_map::{SurfaceNdf, ndf_mapped, surface_ndf, ndf_sh9, ndf_band_attenuation}
#import lightloom::fog::fog_shade

struct Irradiance {
    // SH bands (0 = no environment)
    bands: u32,
    // Diffuse albedo of each material, indexed by the vertex's material.
    albedo: array<vec3<f32>, 8>,
    // Irradiance SH coefficients E_lm, index l*(l+1)+m, at most 5 bands.
    coeffs: array<vec3<f32>, 25>,
};

@group(2) @binding(0) var<uniform> sh: Irradiance;

// Only the material's albedo: the light is per pixel.
fn light_vertex(v: MeshVertex, index: u32, common_out: VertexOut) -> VertexOut {
    var out = common_out;
    out.albedo = sh.albedo[v.material].rgb * v.color;
    return out;
}

// E(n) = sum_k E_k Y_k(n), summed as the shared basis walk (common.wgsl) goes; through a normal
// map, averaged over the pixel's NDF: bands 0-2 exactly by its moments, the higher bands at its
// mean direction, attenuated (normal_map.wgsl).
fn sh_irradiance(ndf: ptr<function, SurfaceNdf>, bands: i32) -> vec3<f32> {
    var result = vec3<f32>(0.0);
    var low: array<f32, 9>;
    let mapped = ndf_mapped(ndf);
    if (mapped) {
        low = ndf_sh9(ndf);
    }
    var walk = sh_walk((*ndf).normal, bands);
    while (sh_walk_next(&walk)) {
        let base = walk.l * (walk.l + 1);
        var cos_y = walk.cos_y;
        var sin_y = walk.sin_y;
        if (mapped) {
            if (walk.l <= 2) {
                cos_y = low[base + walk.m];
                sin_y = low[base - walk.m];
            } else {
                let attenuation = ndf_band_attenuation(ndf, walk.l);
                cos_y = cos_y * attenuation;
                sin_y = sin_y * attenuation;
            }
        }
        result = result + sh.coeffs[base + walk.m].rgb * cos_y;
        if (walk.m > 0) {
            result = result + sh.coeffs[base - walk.m].rgb * sin_y;
        }
    }
    return result;
}

fn shade(in: VertexOut, front: bool) -> vec4<f32> {
    let n = select(-1.0, 1.0, front) * normalize(in.normal);
    var ndf: SurfaceNdf;
    surface_ndf(&ndf, in.material, in.uv, n, in.tangent);
    let bands = i32(sh.bands);
    var irradiance = vec3<f32>(0.0);
    if (bands > 0) {
        irradiance = max(sh_irradiance(&ndf, bands), vec3<f32>(0.0));
    }
    let kd = in.albedo / PI;
    return vec4<f32>(fog_shade(kd * irradiance, in.world, n, in.tangent.xyz, kd, in.material, &ndf), 1.0);
}
