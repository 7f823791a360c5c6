// Lights the wavelet modes' receivers (Ma et al. eq. 7 in top-only cell form; the CPU twins
// are nodes/src/triple_product.rs `local_products` and `diffuse_transfer`). Per receiver with
// frame M and cell c:
//   P_c = V_c * sum_s w_s L(R^-1 M d_s)     (the cell's sub-cell directions d_s, solid angles w_s)
//   E   = sum_c P_c D_c                      (the view-independent diffuse transfer)
// L is the environment prefiltered to the sub-cell size, sampled bilinearly within a cube face.
// It runs when the lighting or the visibility change; a rotation changes only R^-1.

struct RelightParams {
    // Rows of R^-1.
    inverse_rotation: array<vec4<f32>, 3>,
    // x: receivers, y: cells, z: samples per cell, w: environment face size
    counts: vec4<u32>,
    // x: receivers per row of workgroups
    dispatch: vec4<u32>,
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
@group(0) @binding(5) var<storage, read> diffuse_table: array<f32>;
// P_c per receiver and cell, RGB9E5 (render/src/packing.rs).
@group(0) @binding(6) var<storage, read_write> products: array<u32>;
// E per receiver.
@group(0) @binding(7) var<storage, read_write> irradiance: array<vec4<f32>>;

fn environment_texel(face: u32, x: u32, y: u32) -> vec3<f32> {
    let size = params.counts.w;
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
    let size = params.counts.w;
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

// render/src/packing.rs `rgb9e5`: shared exponent from the largest channel's float bits.
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
    let i = id.y * params.dispatch.x + id.x;
    if (id.x >= params.dispatch.x || i >= params.counts.x) {
        return;
    }
    let t = frames[2u * i].xyz;
    let n = frames[2u * i + 1u].xyz;
    let b = cross(n, t);
    // The columns of R^-1 M.
    let r = params.inverse_rotation;
    let rt = vec3<f32>(dot(r[0].xyz, t), dot(r[1].xyz, t), dot(r[2].xyz, t));
    let rb = vec3<f32>(dot(r[0].xyz, b), dot(r[1].xyz, b), dot(r[2].xyz, b));
    let rn = vec3<f32>(dot(r[0].xyz, n), dot(r[1].xyz, n), dot(r[2].xyz, n));
    let cells = params.counts.y;
    let per_cell = params.counts.z;
    var e = vec3<f32>(0.0);
    for (var c = 0u; c < cells; c = c + 1u) {
        let pair = unpack2x16float(visibility[(i * cells + c) / 2u]);
        let v = select(pair.x, pair.y, (c & 1u) == 1u);
        var p = vec3<f32>(0.0);
        // Cells the receiver cannot see (below its horizon, or blocked) need no lighting.
        if (v > 0.0) {
            for (var s = 0u; s < per_cell; s = s + 1u) {
                let sample = cell_samples[c * per_cell + s];
                p = p + sample_environment(rt * sample.x + rb * sample.y + rn * sample.z) * sample.w;
            }
            p = p * v;
        }
        products[i * cells + c] = pack_rgb9e5(p);
        e = e + p * diffuse_table[c];
    }
    irradiance[i] = vec4<f32>(e, 0.0);
}
