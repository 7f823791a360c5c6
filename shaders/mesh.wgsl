// Mesh pass: unshadowed diffuse lighting from the environment's irradiance SH
// (Sun 2008 eq. 2.20: E(n) = sum_lm A_l L_lm Y_lm(n); radiance out = albedo * E / pi).
// The coefficients E_lm arrive precomputed; this shader only evaluates the basis.

struct Irradiance {
    // x: SH bands (0 = no environment)
    bands: vec4<u32>,
    // Diffuse albedo (rgb) of each material, indexed by the vertex's material.
    albedo: array<vec4<f32>, 8>,
    // Irradiance SH coefficients E_lm (rgb), index l*(l+1)+m, at most 5 bands.
    coeffs: array<vec4<f32>, 25>,
};

@group(2) @binding(0) var<uniform> sh: Irradiance;

struct VertexOut {
    @builtin(position) @invariant clip: vec4<f32>,
    @location(0) normal: vec3<f32>,
    @location(1) color: vec3<f32>,
    @location(2) @interpolate(flat) material: u32,
    @location(3) world: vec3<f32>,
    @location(4) tangent: vec4<f32>,
    @location(5) uv: vec2<f32>,
};

@vertex
fn vs_main(v: MeshVertex) -> VertexOut {
    var out: VertexOut;
    out.clip = globals.view_proj * vec4<f32>(v.position, 1.0);
    out.normal = v.normal;
    out.color = v.color;
    out.material = v.material;
    out.world = v.position;
    out.tangent = v.tangent;
    out.uv = v.uv;
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

@fragment
fn fs_main(in: VertexOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    let n = select(-1.0, 1.0, front) * normalize(in.normal);
    var ndf: SurfaceNdf;
    surface_ndf(&ndf, in.material, in.uv, n, in.tangent);
    let bands = i32(sh.bands.x);
    var irradiance = vec3<f32>(0.0);
    if (bands > 0) {
        irradiance = max(sh_irradiance(&ndf, bands), vec3<f32>(0.0));
    }
    let kd = sh.albedo[in.material].rgb * in.color / PI;
    return vec4<f32>(fog_shade(kd * irradiance, in.world, n, in.tangent.xyz, kd, in.material, &ndf), 1.0);
}
