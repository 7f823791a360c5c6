// Mesh pass for the `wavelet_vertex` and `wavelet_pixel` modes (nodes/src/triple_product.rs,
// Ma et al. eq. 7 in top-only cell form), per vertex:
//   B = albedo * sum_c P_c D_c + specular * sum_c P_c S_c(w_o)
// P_c = dOmega_c L_c V_c is the vertex's lighting x visibility on the local-frame cells, D the
// diffuse cosine table, S the specular lobe table on a (theta_o, phi_o) grid, interpolated
// bilinearly at the view direction expressed in the vertex frame [t, n x t, n].
// In `wavelet_pixel`, meshes with a visibility texture take the diffuse sum per pixel from the
// per-texel transfer E = sum_c P_c D_c (bilinear), keeping the per-vertex specular.

const PI: f32 = 3.14159265358979;

struct WaveletParams {
    // x: cells, y: floats per material's specular table, z: theta steps, w: phi steps
    counts: vec4<u32>,
    // Per material: diffuse albedo; specular colour (w = 1 when it has a specular lobe).
    albedo: array<vec4<f32>, 8>,
    specular: array<vec4<f32>, 8>,
    // x: 1 when a per-texel diffuse texture is bound
    texels: vec4<u32>,
};

@group(1) @binding(0) var<uniform> wp: WaveletParams;
// P_c per vertex and cell, RGB9E5-packed (render/src/packing.rs).
@group(1) @binding(1) var<storage, read> products: array<u32>;
@group(1) @binding(2) var<storage, read> diffuse_table: array<f32>;
@group(1) @binding(3) var<storage, read> specular_table: array<f32>;
@group(1) @binding(4) var texel_diffuse: texture_2d_array<f32>;
@group(1) @binding(5) var texel_sampler: sampler;

fn rgb9e5(v: u32) -> vec3<f32> {
    let scale = exp2(f32(i32(v >> 27u) - 24));
    return vec3<f32>(f32(v & 0x1ffu), f32((v >> 9u) & 0x1ffu), f32((v >> 18u) & 0x1ffu)) * scale;
}

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) color: vec3<f32>,
    @location(3) tangent: vec3<f32>,
    @location(4) uv: vec2<f32>,
    @location(5) layer: f32,
    @location(6) material: u32,
};

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) diffuse: vec3<f32>,
    @location(1) specular: vec3<f32>,
    @location(2) albedo: vec3<f32>,
    @location(3) uv: vec2<f32>,
    @location(4) @interpolate(flat) layer: i32,
};

@vertex
fn vs_main(v: VertexIn, @builtin(vertex_index) index: u32) -> VertexOut {
    var out: VertexOut;
    out.clip = globals.view_proj * vec4<f32>(v.position, 1.0);
    let cells = wp.counts.x;
    let base = index * cells;
    var diffuse = vec3<f32>(0.0);
    for (var c = 0u; c < cells; c = c + 1u) {
        diffuse = diffuse + rgb9e5(products[base + c]) * diffuse_table[c];
    }
    let m = v.material;
    out.albedo = wp.albedo[m].rgb * v.color;
    out.diffuse = out.albedo * diffuse;
    out.specular = vec3<f32>(0.0);
    out.uv = v.uv;
    out.layer = i32(round(v.layer));
    let n = normalize(v.normal);
    let t = normalize(v.tangent - n * dot(n, v.tangent));
    let b = cross(n, t);
    let view = normalize(globals.camera_pos.xyz - v.position);
    let wo = vec3<f32>(dot(view, t), dot(view, b), dot(view, n));
    if (wp.specular[m].w > 0.0 && wo.z > 0.0) {
        let theta_steps = wp.counts.z;
        let phi_steps = wp.counts.w;
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
        let fi = ft - f32(i);
        let fj = fp - f32(j);
        let j1 = (j + 1u) % phi_steps;
        let table = m * wp.counts.y;
        let r00 = table + (i * phi_steps + j) * cells;
        let r01 = table + (i * phi_steps + j1) * cells;
        let r10 = table + ((i + 1u) * phi_steps + j) * cells;
        let r11 = table + ((i + 1u) * phi_steps + j1) * cells;
        var glossy = vec3<f32>(0.0);
        for (var c = 0u; c < cells; c = c + 1u) {
            let top = mix(specular_table[r00 + c], specular_table[r01 + c], fj);
            let bottom = mix(specular_table[r10 + c], specular_table[r11 + c], fj);
            let s = mix(top, bottom, fi);
            glossy = glossy + rgb9e5(products[base + c]) * s;
        }
        out.specular = wp.specular[m].rgb * glossy;
    }
    return out;
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    var diffuse = in.diffuse;
    if (wp.texels.x == 1u && in.layer >= 0) {
        diffuse = in.albedo * textureSample(texel_diffuse, texel_sampler, in.uv, in.layer).rgb;
    }
    return vec4<f32>(diffuse + in.specular, 1.0);
}
