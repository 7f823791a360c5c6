// Lights the wavelet modes' receivers (Ma et al. eq. 7 in top-only cell form; the CPU twins
// are nodes/src/triple_product.rs `local_products` and `diffuse_transfer`). Per receiver with
// frame M and cell c:
//   P_c = V_c * sum_s w_s L(R^-1 M d_s)     (the cell's sub-cell directions d_s, solid angles w_s)
//   E   = sum_c P_c D_c                      (the view-independent diffuse transfer)
// L is the environment prefiltered to the sub-cell size, sampled bilinearly within a cube face.
// It runs when the lighting or the visibility change; a rotation changes only R^-1.
// Each receiver also keeps its K best detail nodes (nodes/src/triple_product/details.rs): node
// n < cells is cell n split into its four children (four samples each), node cells + 4c + k the
// child k of cell c split into its four samples. A node's children products p_k (solid angles
// a_k) give the details d_k = p_k - P a_k / A, scored by sum |d_k|^2 / a_k times the materials'
// lobe weight W_n^2; the K best are kept (ties keep the first offered), and their first three
// details written as half floats.

struct RelightParams {
    // R^-1.
    inverse_rotation: mat3x3<f32>,
    receivers: u32,
    cells: u32,
    samples_per_cell: u32,
    // Texels per side of the environment's faces.
    face_size: u32,
    // Receivers per row of workgroups.
    row_width: u32,
    // Detail nodes kept per receiver.
    details_kept: u32,
};

@group(0) @binding(0) var<uniform> params: RelightParams;
// Per receiver [t, 0] then [n, 0]: the frame [t, n x t, n].
@group(0) @binding(1) var<storage, read> frames: array<vec4<f32>>;
// V_c per receiver and cell, two half floats per word.
@group(0) @binding(2) var<storage, read> visibility: array<u32>;
// The prefiltered environment, face * size^2 + y * size + x.
@group(0) @binding(3) var<storage, read> environment: array<vec4<f32>>;
// Per cell its samples: direction in the local frame, solid angle.
@group(0) @binding(4) var<storage, read> cell_samples: array<vec4<f32>>;
// D_c per cell, then W_n^2 per detail node (5 cells).
@group(0) @binding(5) var<storage, read> cell_tables: array<f32>;
// P_c per receiver and cell, RGB9E5 (nodes/src/triple_product/packing.rs).
@group(0) @binding(6) var<storage, read_write> products: array<u32>;
// E per receiver.
@group(0) @binding(7) var<storage, read_write> irradiance: array<vec4<f32>>;
// Per receiver and kept slot, five words: node | d0.r << 16, then d0.g, d0.b, d1.rgb, d2.rgb as
// half floats (node 0xffff: unused).
@group(0) @binding(8) var<storage, read_write> details: array<u32>;

const MAX_DETAILS: u32 = 64u;
const NO_NODE: u32 = 0xffffu;
var<private> kept_scores: array<f32, 64>;
var<private> kept_nodes: array<u32, 64>;
// The current cell's samples w_s L_s.
var<private> samples: array<vec3<f32>, 16>;

struct Node {
    d: array<vec3<f32>, 4>,
    energy: f32,
};

fn node_details(p: array<vec3<f32>, 4>, a: vec4<f32>) -> Node {
    let area = a.x + a.y + a.z + a.w;
    let total = p[0] + p[1] + p[2] + p[3];
    var node: Node;
    node.energy = 0.0;
    for (var k = 0u; k < 4u; k = k + 1u) {
        let d = p[k] - total * (a[k] / area);
        node.d[k] = d;
        node.energy = node.energy + dot(d, d) / a[k];
    }
    return node;
}

// Node j (0: the cell, 1 + k: its child k) of cell c from the samples times v.
fn cell_node(c: u32, j: u32, v: f32) -> Node {
    var p: array<vec3<f32>, 4>;
    var a: vec4<f32>;
    let base = c * 16u;
    for (var i = 0u; i < 4u; i = i + 1u) {
        if (j == 0u) {
            let s = 4u * i;
            p[i] = samples[s] * v + samples[s + 1u] * v + samples[s + 2u] * v + samples[s + 3u] * v;
            a[i] = cell_samples[base + s].w + cell_samples[base + s + 1u].w + cell_samples[base + s + 2u].w
                + cell_samples[base + s + 3u].w;
        } else {
            let s = 4u * (j - 1u) + i;
            p[i] = samples[s] * v;
            a[i] = cell_samples[base + s].w;
        }
    }
    return node_details(p, a);
}

fn node_id(c: u32, j: u32, cells: u32) -> u32 {
    return select(cells + 4u * c + j - 1u, c, j == 0u);
}

fn offer(score: f32, node: u32, kept: u32) {
    if (kept == 0u || !(score > kept_scores[kept - 1u])) {
        return;
    }
    var j = kept - 1u;
    while (j > 0u && kept_scores[j - 1u] < score) {
        kept_scores[j] = kept_scores[j - 1u];
        kept_nodes[j] = kept_nodes[j - 1u];
        j = j - 1u;
    }
    kept_scores[j] = score;
    kept_nodes[j] = node;
}

fn half_bits(x: f32) -> u32 {
    return pack2x16float(vec2<f32>(clamp(x, -65504.0, 65504.0), 0.0)) & 0xffffu;
}

fn environment_texel(face: u32, x: u32, y: u32) -> vec3<f32> {
    let size = params.face_size;
    return environment[(face * size + y) * size + x].xyz;
}

// nodes/src/cubemap.rs `dir_to_face_uv` then `CubeMap::sample`: bilinear, clamped at the
// face's edges.
fn sample_environment(d: vec3<f32>) -> vec3<f32> {
    let a = abs(d);
    var face: u32;
    var sc: f32;
    var tc: f32;
    var ma: f32;
    if (a.x >= a.y && a.x >= a.z) {
        ma = a.x;
        tc = -d.y;
        if (d.x >= 0.0) {
            face = 0u;
            sc = -d.z;
        } else {
            face = 1u;
            sc = d.z;
        }
    } else if (a.y >= a.z) {
        ma = a.y;
        sc = d.x;
        if (d.y >= 0.0) {
            face = 2u;
            tc = d.z;
        } else {
            face = 3u;
            tc = -d.z;
        }
    } else {
        ma = a.z;
        tc = -d.y;
        if (d.z >= 0.0) {
            face = 4u;
            sc = d.x;
        } else {
            face = 5u;
            sc = -d.x;
        }
    }
    let size = params.face_size;
    let last = f32(size - 1u);
    let uv = 0.5 * (vec2<f32>(sc, tc) / ma + 1.0);
    let f = clamp(uv * f32(size) - 0.5, vec2<f32>(0.0), vec2<f32>(last));
    let x0 = u32(floor(f.x));
    let y0 = u32(floor(f.y));
    let x1 = min(x0 + 1u, size - 1u);
    let y1 = min(y0 + 1u, size - 1u);
    let t = f - floor(f);
    let top = mix(environment_texel(face, x0, y0), environment_texel(face, x1, y0), t.x);
    let bottom = mix(environment_texel(face, x0, y1), environment_texel(face, x1, y1), t.x);
    return mix(top, bottom, t.y);
}

// nodes/src/triple_product/packing.rs `rgb9e5`: shared exponent from the largest channel's float bits.
fn pack_rgb9e5(rgb: vec3<f32>) -> u32 {
    let c = clamp(rgb, vec3<f32>(0.0), vec3<f32>(65408.0));
    let m = max(c.x, max(c.y, c.z));
    if (!(m > 0.0)) {
        return 0u;
    }
    var exponent = max(i32((bitcast<u32>(m) >> 23u) & 0xffu) - 127, -16) + 16;
    var scale = exp2(f32(exponent - 24));
    if (floor(m / scale + 0.5) >= 512.0) {
        exponent = exponent + 1;
        scale = scale * 2.0;
    }
    let q = min(vec3<u32>(floor(c / scale + 0.5)), vec3<u32>(511u));
    return q.x | (q.y << 9u) | (q.z << 18u) | (u32(clamp(exponent, 0, 31)) << 27u);
}

@compute @workgroup_size(64)
fn relight(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.y * params.row_width + id.x;
    if (id.x >= params.row_width || i >= params.receivers) {
        return;
    }
    let t = frames[2u * i].xyz;
    let n = frames[2u * i + 1u].xyz;
    let b = cross(n, t);
    // The columns of R^-1 M.
    let r = params.inverse_rotation;
    let rt = r * t;
    let rb = r * b;
    let rn = r * n;
    let cells = params.cells;
    let per_cell = params.samples_per_cell;
    // Details need 16 samples per cell (nodes/src/triple_product.rs SUBLEVELS = 2).
    let kept = select(0u, min(params.details_kept, MAX_DETAILS), per_cell == 16u);
    for (var j = 0u; j < kept; j = j + 1u) {
        kept_scores[j] = 0.0;
        kept_nodes[j] = NO_NODE;
    }
    var e = vec3<f32>(0.0);
    for (var c = 0u; c < cells; c = c + 1u) {
        let v = visibility_of(i, c, cells);
        var p = vec3<f32>(0.0);
        // Cells the receiver cannot see (below its horizon, or blocked) need no lighting.
        if (v > 0.0) {
            for (var s = 0u; s < per_cell; s = s + 1u) {
                let sample = cell_samples[c * per_cell + s];
                let l = sample_environment(rt * sample.x + rb * sample.y + rn * sample.z) * sample.w;
                if (kept > 0u) {
                    samples[s] = l;
                }
                p = p + l;
            }
            p = p * v;
            for (var j = 0u; j < 5u * u32(kept > 0u); j = j + 1u) {
                let node = node_id(c, j, cells);
                let w = cell_tables[cells + node];
                if (w > 0.0) {
                    offer(cell_node(c, j, v).energy * w, node, kept);
                }
            }
        }
        products[i * cells + c] = pack_rgb9e5(p);
        e = e + p * cell_tables[c];
    }
    irradiance[i] = vec4<f32>(e, 0.0);
    // The kept nodes' details, their cells' samples taken again.
    for (var j = 0u; j < kept; j = j + 1u) {
        let node = kept_nodes[j];
        let at = (i * kept + j) * 5u;
        if (node == NO_NODE) {
            details[at] = NO_NODE;
            details[at + 1u] = 0u;
            details[at + 2u] = 0u;
            details[at + 3u] = 0u;
            details[at + 4u] = 0u;
            continue;
        }
        let c = select((node - cells) / 4u, node, node < cells);
        for (var s = 0u; s < 16u; s = s + 1u) {
            let sample = cell_samples[c * 16u + s];
            samples[s] = sample_environment(rt * sample.x + rb * sample.y + rn * sample.z) * sample.w;
        }
        let d = cell_node(c, select(node - cells - 4u * c + 1u, 0u, node < cells), visibility_of(i, c, cells)).d;
        details[at] = node | (half_bits(d[0].x) << 16u);
        details[at + 1u] = pack2x16float(vec2<f32>(clamp(d[0].yz, vec2<f32>(-65504.0), vec2<f32>(65504.0))));
        details[at + 2u] = pack2x16float(clamp(d[1].xy, vec2<f32>(-65504.0), vec2<f32>(65504.0)));
        details[at + 3u] = pack2x16float(clamp(vec2<f32>(d[1].z, d[2].x), vec2<f32>(-65504.0), vec2<f32>(65504.0)));
        details[at + 4u] = pack2x16float(clamp(d[2].yz, vec2<f32>(-65504.0), vec2<f32>(65504.0)));
    }
}

fn visibility_of(i: u32, c: u32, cells: u32) -> f32 {
    let pair = unpack2x16float(visibility[(i * cells + c) / 2u]);
    return select(pair.x, pair.y, (c & 1u) == 1u);
}
