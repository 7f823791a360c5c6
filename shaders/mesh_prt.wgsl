// Mesh pass for the `sh_prt` mode (nodes/src/prt.rs), per vertex:
//   diffuse  B_d = albedo/pi * sum_k T_k L_k          (shadowed cosine transfer T)
//   glossy   B_s = w * max(n.r, 0) * sum_lm f_l R_lm Y_lm(r)
// with R = L*V the shadowed incident radiance (Gaunt product, precomputed per vertex), r the
// mirror direction of the view, f_l the per-band factors of the material's Phong lobe. Under a
// normal map each pixel corrects B_s for its NDF (normal_map.wgsl ndf_vertex_glossy).

#define_import_path lightloom::mesh_prt

#import lightloom::common::{MeshVertex, PI, globals, sh_walk, sh_walk_next}
#import lightloom::mesh_vertex::VertexOut
#import lightloom::normal_map::{SurfaceNdf, surface_ndf, ndf_vertex_diffuse_scale, ndf_open_fraction, ndf_vertex_glossy}
#import lightloom::fog::fog_shade

struct PrtParams {
    // x: diffuse bands (<= 12), y: transfer floats per vertex, z: incident floats per vertex,
    // w: bands of the incident radiance R (0 when none is bound; <= 12)
    counts: vec4<u32>,
    // Per material: diffuse albedo; glossy lobe weight (rgb, w = 1 when glossy); per-band
    // lobe factors f_l, four per vector (material m: lobe[3m .. 3m + 2]).
    albedo: array<vec4<f32>, 8>,
    specular: array<vec4<f32>, 8>,
    lobe: array<vec4<f32>, 24>,
    // Lighting L_k (rgb), index l*(l+1)+m.
    light: array<vec4<f32>, 144>,
};

@group(2) @binding(0) var<uniform> prt: PrtParams;
@group(2) @binding(1) var<storage, read> transfer: array<f32>;
@group(2) @binding(2) var<storage, read> incident: array<f32>;

fn incident_rgb(ib: u32, k: i32) -> vec3<f32> {
    let o = ib + u32(k) * 3u;
    return vec3<f32>(incident[o], incident[o + 1u], incident[o + 2u]);
}

// sum_lm f_l R_lm Y_lm(r) over `bands`, summed as the shared basis walk (common.wgsl) goes (no
// basis array, so high orders fit in registers).
fn glossy_sum(r: vec3<f32>, bands: i32, ib: u32, material: u32) -> vec3<f32> {
    var sum = vec3<f32>(0.0);
    var walk = sh_walk(r, bands);
    while (sh_walk_next(&walk)) {
        let l = walk.l;
        let f = prt.lobe[3u * material + u32(l / 4)][l % 4];
        let base = l * (l + 1);
        sum = sum + f * walk.cos_y * incident_rgb(ib, base + walk.m);
        if (walk.m > 0) {
            sum = sum + f * walk.sin_y * incident_rgb(ib, base - walk.m);
        }
    }
    return sum;
}

fn light_vertex(v: MeshVertex, index: u32, common_out: VertexOut) -> VertexOut {
    var out = common_out;
    let bands = i32(prt.counts.x);
    let coeffs = u32(bands * bands);
    var diffuse = vec3<f32>(0.0);
    let tb = index * prt.counts.y;
    for (var k = 0u; k < coeffs; k = k + 1u) {
        diffuse = diffuse + prt.light[k].rgb * transfer[tb + k];
    }
    let m = v.material;
    out.albedo = prt.albedo[m].rgb * v.color;
    out.diffuse = out.albedo * max(diffuse, vec3<f32>(0.0)) / PI;
    out.open = ndf_open_fraction(diffuse, normalize(v.normal));
    if (prt.counts.w > 0u && prt.specular[m].w > 0.0) {
        let n = normalize(v.normal);
        let view = normalize(globals.camera_pos.xyz - v.position);
        let r = reflect(-view, n);
        let glossy = glossy_sum(r, i32(prt.counts.w), index * prt.counts.z, m);
        out.glossy = prt.specular[m].rgb * max(glossy, vec3<f32>(0.0)) * max(dot(n, r), 0.0);
    }
    return out;
}

fn shade(in: VertexOut, front: bool) -> vec4<f32> {
    let n = normalize(in.normal);
    var ndf: SurfaceNdf;
    surface_ndf(&ndf, in.material, in.uv, n, in.tangent);
    var glossy = in.glossy;
    if (prt.counts.w > 0u && prt.specular[in.material].w > 0.0) {
        let view = normalize(globals.camera_pos.xyz - in.world);
        glossy = ndf_vertex_glossy(&ndf, n, view, in.material, in.open, glossy);
    }
    let lit = in.diffuse * ndf_vertex_diffuse_scale(&ndf, n) + glossy;
    return vec4<f32>(fog_shade(lit, in.world, n, in.tangent.xyz, in.albedo / PI, in.material, &ndf), 1.0);
}
