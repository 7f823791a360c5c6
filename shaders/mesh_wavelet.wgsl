// Mesh pass for the `wavelet_vertex` and `wavelet_pixel` modes (nodes/src/triple_product.rs,
// Ma et al. eq. 7 in top-only cell form):
//   B = albedo * E + specular * sum_c P_c S_c(w_o),   E = sum_c P_c D_c
// P_c = dOmega_c L_c V_c is lighting x visibility on the local-frame cells and E the diffuse
// transfer, both written by wavelet_relight.wgsl when the lighting changes; S is the specular
// lobe table on a (theta_o, phi_o) grid, interpolated bilinearly at the view direction
// expressed in the frame [t, n x t, n].
// Kept detail terms (nodes/src/triple_product/details.rs) add sum_k d_k T_{4n+k}(w_o) per kept
// node n to the glossy sum, T the fine lobe table on the two levels below the cells.
// Under a normal map each pixel corrects the glossy sum for its NDF (normal_map.wgsl
// ndf_vertex_glossy).
// Per vertex everywhere; in `wavelet_pixel`, meshes with a visibility texture are shaded per
// pixel from their texels instead: E and P of the four nearest texels, weighted bilinearly.

#define_import_path lightloom::mesh_wavelet

#import lightloom::common::{MeshVertex, PI, frame_tangent, globals}
#import lightloom::mesh_vertex::VertexOut
#import lightloom::normal_map::{SurfaceNdf, surface_ndf, ndf_vertex_diffuse_scale, ndf_open_fraction, ndf_vertex_glossy}
#import lightloom::fog::fog_shade

struct WaveletMaterial {
    albedo: vec3<f32>,
    // 1 with a specular lobe.
    glossy: u32,
    specular: vec3<f32>,
    // Where its fine lobe table starts in fine_specular.
    fine_offset: u32,
};

struct WaveletParams {
    cells: u32,
    // Floats of one material's specular table.
    specular_stride: u32,
    theta_steps: u32,
    phi_steps: u32,
    // 1 when per-texel data is bound.
    texels_bound: u32,
    // Texels per side.
    texel_size: u32,
    // Detail nodes kept per receiver.
    details_kept: u32,
    materials: array<WaveletMaterial, 8>,
};

@group(2) @binding(0) var<uniform> wp: WaveletParams;
// P_c per vertex and cell, RGB9E5-packed (nodes/src/triple_product/packing.rs).
@group(2) @binding(1) var<storage, read> products: array<u32>;
// E per vertex.
@group(2) @binding(2) var<storage, read> irradiance: array<vec4<f32>>;
@group(2) @binding(3) var<storage, read> specular_table: array<f32>;
// E per texel (layer-major, rows at increasing v).
@group(2) @binding(4) var<storage, read> texel_irradiance: array<vec4<f32>>;
// P_c per texel, RGB9E5-packed.
@group(2) @binding(5) var<storage, read> texel_products: array<u32>;
// Per vertex: its mesh's layer of texels, or -1.
@group(2) @binding(6) var<storage, read> vertex_layers: array<i32>;
// Per material and (theta_o, phi_o) patch: [first, count] of the cells its glossy sum reads.
@group(2) @binding(7) var<storage, read> specular_ranges: array<vec2<u32>>;
@group(2) @binding(8) var<storage, read> specular_cells: array<u32>;
// Per vertex (binding 9) and per texel (10): kept detail nodes, five words each
// (wavelet_relight.wgsl).
@group(2) @binding(9) var<storage, read> vertex_details: array<u32>;
@group(2) @binding(10) var<storage, read> texel_details: array<u32>;
// Per glossy material and (theta_o, phi_o) row: the lobe on 20 * cells fine entries, two half
// floats per word.
@group(2) @binding(11) var<storage, read> fine_specular: array<u32>;

fn rgb9e5(v: u32) -> vec3<f32> {
    let scale = exp2(f32(i32(v >> 27u) - 24));
    return vec3<f32>(f32(v & 0x1ffu), f32((v >> 9u) & 0x1ffu), f32((v >> 18u) & 0x1ffu)) * scale;
}

// Rows of material m's specular table around w_o and the bilinear fractions.
struct TableRows {
    // The four rows' offsets into specular_table: (i, j), (i, j + 1), (i + 1, j), (i + 1, j + 1).
    rows: vec4<u32>,
    fi: f32,
    fj: f32,
    // The cells that carry the lobe here: [first, count] into specular_cells.
    cells: vec2<u32>,
    // The four rows' offsets into fine_specular.
    fine: vec4<u32>,
};

fn table_rows(wo: vec3<f32>, m: u32) -> TableRows {
    let cells = wp.cells;
    let theta_steps = wp.theta_steps;
    let phi_steps = wp.phi_steps;
    let theta_max = PI / 2.0 - 1e-3;
    let theta = min(acos(clamp(wo.z, 0.0, 1.0)), theta_max);
    let ft = theta / theta_max * f32(theta_steps - 1u);
    let i = min(u32(floor(ft)), theta_steps - 2u);
    var phi = atan2(wo.y, wo.x);
    if (phi < 0.0) {
        phi = phi + 2.0 * PI;
    }
    let fp = phi / (2.0 * PI) * f32(phi_steps);
    let j = min(u32(floor(fp)), phi_steps - 1u);
    let j1 = (j + 1u) % phi_steps;
    let table = m * wp.specular_stride;
    var rows: TableRows;
    rows.rows.x = table + (i * phi_steps + j) * cells;
    rows.rows.y = table + (i * phi_steps + j1) * cells;
    rows.rows.z = table + ((i + 1u) * phi_steps + j) * cells;
    rows.rows.w = table + ((i + 1u) * phi_steps + j1) * cells;
    rows.fi = ft - f32(i);
    rows.fj = fp - f32(j);
    rows.cells = specular_ranges[(m * (theta_steps - 1u) + i) * phi_steps + j];
    let stride = 20u * cells;
    let fine = wp.materials[m].fine_offset;
    rows.fine = fine + stride * vec4<u32>(i * phi_steps + j, i * phi_steps + j1, (i + 1u) * phi_steps + j,
        (i + 1u) * phi_steps + j1);
    return rows;
}

fn specular_at(rows: TableRows, c: u32) -> f32 {
    let top = mix(specular_table[rows.rows.x + c], specular_table[rows.rows.y + c], rows.fj);
    let bottom = mix(specular_table[rows.rows.z + c], specular_table[rows.rows.w + c], rows.fj);
    return mix(top, bottom, rows.fi);
}

fn fine_value(i: u32) -> f32 {
    let pair = unpack2x16float(fine_specular[i / 2u]);
    return select(pair.x, pair.y, (i & 1u) == 1u);
}

fn fine_at(rows: TableRows, e: u32) -> f32 {
    let top = mix(fine_value(rows.fine.x + e), fine_value(rows.fine.y + e), rows.fj);
    let bottom = mix(fine_value(rows.fine.z + e), fine_value(rows.fine.w + e), rows.fj);
    return mix(top, bottom, rows.fi);
}

// One kept node's glossy term (nodes/src/triple_product/details.rs `detail_glossy`).
fn detail_glossy(w0: u32, w1: u32, w2: u32, w3: u32, w4: u32, rows: TableRows) -> vec3<f32> {
    let e = 4u * (w0 & 0xffffu);
    let b = unpack2x16float(w3);
    let d0 = vec3<f32>(unpack2x16float(w0).y, unpack2x16float(w1));
    let d1 = vec3<f32>(unpack2x16float(w2), b.x);
    let d2 = vec3<f32>(b.y, unpack2x16float(w4));
    let last = fine_at(rows, e + 3u);
    return d0 * (fine_at(rows, e) - last) + d1 * (fine_at(rows, e + 1u) - last) + d2 * (fine_at(rows, e + 2u) - last);
}

// The view direction in the frame [t, n x t, n].
fn local_view(position: vec3<f32>, normal: vec3<f32>, tangent: vec3<f32>) -> vec3<f32> {
    let n = normalize(normal);
    let t = frame_tangent(n, tangent);
    let b = cross(n, t);
    let view = normalize(globals.camera_pos.xyz - position);
    return vec3<f32>(dot(view, t), dot(view, b), dot(view, n));
}

fn light_vertex(v: MeshVertex, index: u32, common_out: VertexOut) -> VertexOut {
    var out = common_out;
    let m = v.material;
    out.layer = vertex_layers[index];
    out.albedo = wp.materials[m].albedo * v.color;
    let cells = wp.cells;
    let base = index * cells;
    out.diffuse = out.albedo * irradiance[index].rgb;
    out.open = ndf_open_fraction(PI * irradiance[index].rgb, normalize(v.normal));
    let wo = local_view(v.position, v.normal, v.tangent.xyz);
    if (wp.materials[m].glossy != 0u && wo.z > 0.0) {
        let rows = table_rows(wo, m);
        var glossy = vec3<f32>(0.0);
        for (var k = rows.cells.x; k < rows.cells.x + rows.cells.y; k = k + 1u) {
            let c = specular_cells[k];
            glossy = glossy + rgb9e5(products[base + c]) * specular_at(rows, c);
        }
        let kept = wp.details_kept;
        for (var j = 0u; j < kept; j = j + 1u) {
            let at = (index * kept + j) * 5u;
            let w0 = vertex_details[at];
            if ((w0 & 0xffffu) == 0xffffu) {
                break;
            }
            glossy = glossy + detail_glossy(w0, vertex_details[at + 1u], vertex_details[at + 2u],
                vertex_details[at + 3u], vertex_details[at + 4u], rows);
        }
        out.glossy = wp.materials[m].specular * glossy;
    }
    return out;
}

fn shade(in: VertexOut, front: bool) -> vec4<f32> {
    let n = normalize(in.normal);
    var ndf: SurfaceNdf;
    surface_ndf(&ndf, in.material, in.uv, n, in.tangent);
    let diffuse_scale = ndf_vertex_diffuse_scale(&ndf, n);
    let view = normalize(globals.camera_pos.xyz - in.world);
    let glossy = wp.materials[in.material].glossy != 0u && dot(view, n) > 0.0;
    if (wp.texels_bound == 0u || in.layer < 0) {
        var specular = in.glossy;
        if (glossy) {
            specular = ndf_vertex_glossy(&ndf, n, view, in.material, in.open, specular);
        }
        let lit = in.diffuse * diffuse_scale + specular;
        return vec4<f32>(fog_shade(lit, in.world, n, in.tangent.xyz, in.albedo / PI, in.material, &ndf), 1.0);
    }
    let m = in.material;
    // The four texels around the pixel (texel centres at (x + 0.5) / size), clamped at the
    // layer's edges.
    let size = wp.texel_size;
    let cells = wp.cells;
    let f = clamp(in.uv * f32(size) - 0.5, vec2<f32>(0.0), vec2<f32>(f32(size - 1u)));
    let x0 = u32(floor(f.x));
    let y0 = u32(floor(f.y));
    let x1 = min(x0 + 1u, size - 1u);
    let y1 = min(y0 + 1u, size - 1u);
    let w = f - floor(f);
    let layer = u32(in.layer) * size * size;
    let s00 = layer + y0 * size + x0;
    let s01 = layer + y0 * size + x1;
    let s10 = layer + y1 * size + x0;
    let s11 = layer + y1 * size + x1;
    let e_top = mix(texel_irradiance[s00].rgb, texel_irradiance[s01].rgb, w.x);
    let e_bottom = mix(texel_irradiance[s10].rgb, texel_irradiance[s11].rgb, w.x);
    let e = mix(e_top, e_bottom, w.y);
    let diffuse = in.albedo * e;
    var specular = vec3<f32>(0.0);
    let wo = local_view(in.world, in.normal, in.tangent.xyz);
    if (wp.materials[m].glossy != 0u && wo.z > 0.0) {
        let rows = table_rows(wo, m);
        let t00 = s00 * cells;
        let t01 = s01 * cells;
        let t10 = s10 * cells;
        let t11 = s11 * cells;
        for (var k = rows.cells.x; k < rows.cells.x + rows.cells.y; k = k + 1u) {
            let c = specular_cells[k];
            let top = mix(rgb9e5(texel_products[t00 + c]), rgb9e5(texel_products[t01 + c]), w.x);
            let bottom = mix(rgb9e5(texel_products[t10 + c]), rgb9e5(texel_products[t11 + c]), w.x);
            specular = specular + mix(top, bottom, w.y) * specular_at(rows, c);
        }
        let kept = wp.details_kept;
        var slots = array<u32, 4>(s00, s01, s10, s11);
        var weights = array<f32, 4>((1.0 - w.x) * (1.0 - w.y), w.x * (1.0 - w.y), (1.0 - w.x) * w.y, w.x * w.y);
        for (var t = 0u; t < 4u; t = t + 1u) {
            var sum = vec3<f32>(0.0);
            for (var j = 0u; j < kept; j = j + 1u) {
                let at = (slots[t] * kept + j) * 5u;
                let w0 = texel_details[at];
                if ((w0 & 0xffffu) == 0xffffu) {
                    break;
                }
                sum = sum + detail_glossy(w0, texel_details[at + 1u], texel_details[at + 2u], texel_details[at + 3u],
                    texel_details[at + 4u], rows);
            }
            specular = specular + weights[t] * sum;
        }
        specular = wp.materials[m].specular * specular;
    }
    if (glossy) {
        specular = ndf_vertex_glossy(&ndf, n, view, m, ndf_open_fraction(PI * e, n), specular);
    }
    let lit = diffuse * diffuse_scale + specular;
    return vec4<f32>(fog_shade(lit, in.world, n, in.tangent.xyz, in.albedo / PI, in.material, &ndf), 1.0);
}
