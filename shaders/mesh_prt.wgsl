// Mesh pass for the `sh_prt` and `sh_adaptive` modes (nodes/src/prt.rs), per vertex:
//   diffuse  B_d = albedo/pi * sum_k T_k L_k          (shadowed cosine transfer T)
//   glossy   B_s = w * max(n.r, 0) * sum_lm f_l R_lm Y_lm(r)
// with R = L*V the shadowed incident radiance (Gaunt product, precomputed per vertex), r the
// mirror direction of the view, f_l the per-band factors of the material's Phong lobe. Once the
// prefiltered light is bound (normal_map.wgsl ndf_prefiltered_highlight), each pixel draws the
// material's true lobe from it instead, times how open the vertex is to it (highlight_open,
// from the transfer T): the Phong lobe to a few bands spreads bright lights into dark
// reflections. Under a normal map each pixel corrects the highlight for its NDF
// (ndf_vertex_glossy).

#define_import_path lightloom::mesh_prt

#import lightloom::common::{MeshVertex, PI, globals, sh_walk, sh_walk_next}
#import lightloom::mesh_vertex::VertexOut
#import lightloom::normal_map::{SurfaceNdf, surface_ndf, ndf_vertex_diffuse_scale, ndf_open_fraction, ndf_vertex_glossy, ndf_prefiltered_highlight, ndf_prefiltered_vertex_highlight}
#import lightloom::fog::fog_shade

struct PrtMaterial {
    albedo: vec3<f32>,
    // 1 with a glossy lobe.
    glossy: u32,
    // The lobe's weight.
    weight: vec3<f32>,
    // Per-band lobe factors f_l, l at [l / 4][l % 4].
    factors: array<vec4<f32>, 3>,
};

struct PrtParams {
    // Diffuse bands (<= 12).
    diffuse_bands: u32,
    // Floats per vertex of the transfer and of the incident radiance.
    transfer_stride: u32,
    incident_stride: u32,
    // Bands of the incident radiance R (0 when none is bound; <= 12).
    incident_bands: u32,
    materials: array<PrtMaterial, 8>,
    // Lighting L_k, index l*(l+1)+m.
    light: array<vec3<f32>, 144>,
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
        let f = prt.materials[material].factors[l / 4][l % 4];
        let base = l * (l + 1);
        sum = sum + f * walk.cos_y * incident_rgb(ib, base + walk.m);
        if (walk.m > 0) {
            sum = sum + f * walk.sin_y * incident_rgb(ib, base - walk.m);
        }
    }
    return sum;
}

// How open a vertex is to its highlight about the mirror direction `r`: its cosine-weighted
// visibility (the diffuse transfer T, over `bands`) seen through material m's Phong lobe,
// sum_lm f_l T_lm Y_lm(r), over the same of the unoccluded clamped cosine about the normal `n`,
// sum_l f_l c_l P_l(n.r) with c_l = (2l+1)/2 a_l, a_l = int_0^1 t P_l(t) dt (1/2, 1/3, 1/8, then
// 0 for odd l and a_(l+2) = -a_l (l-1)/(l+4) for even l): the same truncation in both, so an
// unoccluded vertex is open 1 whatever the bands ring. In [0, 1]; 1 where the lobe looks below
// the horizon.
fn highlight_open(r: vec3<f32>, n: vec3<f32>, tb: u32, bands: i32, m: u32) -> f32 {
    var occluded = 0.0;
    var walk = sh_walk(r, bands);
    while (sh_walk_next(&walk)) {
        let l = walk.l;
        let f = prt.materials[m].factors[l / 4][l % 4];
        let base = l * (l + 1);
        occluded = occluded + f * walk.cos_y * transfer[tb + u32(base + walk.m)];
        if (walk.m > 0) {
            occluded = occluded + f * walk.sin_y * transfer[tb + u32(base - walk.m)];
        }
    }
    // The unoccluded sum by the Legendre recurrence; a_l = int_0^1 t P_l(t) dt.
    let x = clamp(dot(n, r), -1.0, 1.0);
    var p_prev = 1.0;
    var p = x;
    var even = 0.125;
    var open = prt.materials[m].factors[0].x * 0.5 * 0.5;
    if (bands > 1) {
        open = open + prt.materials[m].factors[0].y * 1.5 / 3.0 * x;
    }
    for (var l = 2; l < bands; l = l + 1) {
        let next = (f32(2 * l - 1) * x * p - f32(l - 1) * p_prev) / f32(l);
        p_prev = p;
        p = next;
        if (l % 2 == 0) {
            open = open + prt.materials[m].factors[l / 4][l % 4] * (f32(2 * l + 1) / 2.0) * even * p;
            even = -even * f32(l - 1) / f32(l + 4);
        }
    }
    if (open <= 1e-4 * prt.materials[m].factors[0].x) {
        return 1.0;
    }
    return clamp(occluded / open, 0.0, 1.0);
}

fn light_vertex(v: MeshVertex, index: u32, common_out: VertexOut) -> VertexOut {
    var out = common_out;
    let bands = i32(prt.diffuse_bands);
    let coeffs = u32(bands * bands);
    var diffuse = vec3<f32>(0.0);
    let tb = index * prt.transfer_stride;
    for (var k = 0u; k < coeffs; k = k + 1u) {
        diffuse = diffuse + prt.light[k] * transfer[tb + k];
    }
    let m = v.material;
    out.albedo = prt.materials[m].albedo * v.color;
    out.diffuse = out.albedo * max(diffuse, vec3<f32>(0.0)) / PI;
    out.open = ndf_open_fraction(diffuse, normalize(v.normal));
    if (prt.incident_bands > 0u && prt.materials[m].glossy != 0u) {
        let n = normalize(v.normal);
        let view = normalize(globals.camera_pos.xyz - v.position);
        let r = reflect(-view, n);
        let ib = index * prt.incident_stride;
        if (ndf_prefiltered_highlight()) {
            out.highlight_open = vec3<f32>(highlight_open(r, n, tb, bands, m));
        } else {
            let glossy = glossy_sum(r, i32(prt.incident_bands), ib, m);
            out.glossy = prt.materials[m].weight * max(glossy, vec3<f32>(0.0)) * max(dot(n, r), 0.0);
        }
    }
    return out;
}

fn shade(in: VertexOut, front: bool) -> vec4<f32> {
    let n = normalize(in.normal);
    var ndf: SurfaceNdf;
    surface_ndf(&ndf, in.material, in.uv, n, in.tangent);
    var glossy = in.glossy;
    if (prt.incident_bands > 0u && prt.materials[in.material].glossy != 0u) {
        let view = normalize(globals.camera_pos.xyz - in.world);
        if (ndf_prefiltered_highlight()) {
            glossy = ndf_prefiltered_vertex_highlight(n, view, in.material, in.highlight_open);
        }
        glossy = ndf_vertex_glossy(&ndf, n, view, in.material, in.open, glossy);
    }
    let lit = in.diffuse * ndf_vertex_diffuse_scale(&ndf, n) + glossy;
    return vec4<f32>(fog_shade(lit, in.world, n, in.tangent.xyz, in.albedo / PI, in.material, &ndf), 1.0);
}
