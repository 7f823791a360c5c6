// Mesh pass for the `rsl` mode (nodes/src/rsl/shade.rs, Xu et al. 2006 eq. 5):
//   B = sum_i I_i Omega_i Vbar_i (albedo * mean(cos/pi) + specular * mean(lobe cos))
// The means are over the light's square in the equal-area plane of the vertex's frame
// [t, n x t, n] (nodes/src/rsl/plane.rs), four bilinear lookups of a corner-stored
// summed-area table each (nodes/src/rsl/brdf_sat.rs); Vbar per vertex and light comes from
// the CPU (the rsl_visibility stage). Per vertex, Gouraud between vertices as in the paper.

#define_import_path lightloom::mesh_rsl

#import lightloom::common::{MeshVertex, PI, frame_tangent, globals}
#import lightloom::mesh_vertex::VertexOut
#import lightloom::normal_map::{SurfaceNdf, surface_ndf, ndf_vertex_diffuse_scale, ndf_open_fraction, ndf_vertex_glossy}
#import lightloom::fog::fog_shade

// Where a material's tables start and how they are sliced.
struct RslLayout {
    // Its first float in `tables` (aligned so that an array of layouts fits a uniform).
    @align(16) first: u32,
    // 0 no lobe, 1 isotropic, 2 anisotropic.
    view_grid: u32,
    // theta_0 slices, or view slices per side.
    slices: u32,
};

struct RslParams {
    lights: u32,
    // Texels per side of every table.
    table_size: u32,
    // Per material: diffuse albedo; specular colour.
    albedo: array<vec3<f32>, 8>,
    specular: array<vec3<f32>, 8>,
    layouts: array<RslLayout, 8>,
};

@group(2) @binding(0) var<uniform> rp: RslParams;
// Per light: (direction, solid angle), (intensity, 0), world frame.
@group(2) @binding(1) var<storage, read> lights: array<vec4<f32>>;
// Vbar per vertex and light, vertex-major.
@group(2) @binding(2) var<storage, read> visibility: array<f32>;
@group(2) @binding(3) var<storage, read> tables: array<f32>;

// The largest tabulated view polar angle (brdf_sat.rs MAX_VIEW_ANGLE).
const MAX_VIEW_ANGLE: f32 = 1.5620696;

fn to_plane(d: vec3<f32>) -> vec2<f32> {
    let s = 1.0 + d.z;
    if (s <= 1e-6) {
        return vec2<f32>(1.4142135, 0.0);
    }
    return d.xy / sqrt(s);
}

// The SAT at fractional corner coordinates (bilinear; exact for piecewise-constant texels).
fn sat_at(base: u32, x: f32, y: f32) -> f32 {
    let n = rp.table_size;
    let nf = f32(n);
    let cx = clamp(x, 0.0, nf);
    let cy = clamp(y, 0.0, nf);
    let ix = min(u32(floor(cx)), n - 1u);
    let iy = min(u32(floor(cy)), n - 1u);
    let tx = cx - f32(ix);
    let ty = cy - f32(iy);
    let stride = n + 1u;
    let r0 = base + iy * stride + ix;
    let r1 = r0 + stride;
    let top = mix(tables[r0], tables[r0 + 1u], tx);
    let bottom = mix(tables[r1], tables[r1 + 1u], tx);
    return mix(top, bottom, ty);
}

// Mean over the square of half-edge `half_edge` centred on `p`, clipped to the table but divided by
// its full area.
fn square_mean(base: u32, p: vec2<f32>, half_edge: f32) -> f32 {
    let n = f32(rp.table_size);
    let lo = (p - vec2<f32>(half_edge) + 1.0) * 0.5 * n;
    let hi = (p + vec2<f32>(half_edge) + 1.0) * 0.5 * n;
    let area = (hi.x - lo.x) * (hi.y - lo.y);
    if (area <= 0.0) {
        return 0.0;
    }
    let sum = sat_at(base, hi.x, hi.y) - sat_at(base, lo.x, hi.y) - sat_at(base, hi.x, lo.y) + sat_at(base, lo.x, lo.y);
    return sum / area;
}

fn table_base(m: u32, slice: u32) -> u32 {
    let n = rp.table_size + 1u;
    return rp.layouts[m].first + (1u + slice) * n * n;
}

// Mean of lobe * cos over the square for view `wo` (local frame).
fn lobe_mean(m: u32, c: vec3<f32>, half_edge: f32, wo: vec3<f32>) -> f32 {
    let grid = rp.layouts[m];
    if (grid.view_grid == 0u || wo.z <= 0.0) {
        return 0.0;
    }
    if (grid.view_grid == 1u) {
        let slices = grid.slices;
        let phi = atan2(wo.y, wo.x);
        let s = sin(phi);
        let k = cos(phi);
        let turned = vec3<f32>(c.x * k + c.y * s, -c.x * s + c.y * k, c.z);
        let p = to_plane(turned);
        let t = min(acos(clamp(wo.z, -1.0, 1.0)) / MAX_VIEW_ANGLE, 1.0) * f32(slices - 1u);
        let j = min(u32(floor(t)), slices - 2u);
        let f = t - f32(j);
        let a = square_mean(table_base(m, j), p, half_edge);
        let b = square_mean(table_base(m, j + 1u), p, half_edge);
        return mix(a, b, f);
    }
    let size = grid.slices;
    let p = to_plane(c);
    let v = to_plane(wo);
    let last = f32(size - 1u);
    let coord = clamp((v + 1.0) * 0.5 * f32(size) - 0.5, vec2<f32>(0.0), vec2<f32>(last));
    let i = min(u32(floor(coord.x)), size - 2u);
    let j = min(u32(floor(coord.y)), size - 2u);
    let f = coord - vec2<f32>(f32(i), f32(j));
    let s00 = square_mean(table_base(m, j * size + i), p, half_edge);
    let s10 = square_mean(table_base(m, j * size + i + 1u), p, half_edge);
    let s01 = square_mean(table_base(m, (j + 1u) * size + i), p, half_edge);
    let s11 = square_mean(table_base(m, (j + 1u) * size + i + 1u), p, half_edge);
    return mix(mix(s00, s10, f.x), mix(s01, s11, f.x), f.y);
}

fn light_vertex(v: MeshVertex, index: u32, common_out: VertexOut) -> VertexOut {
    var out = common_out;
    let m = v.material;
    out.albedo = rp.albedo[m].rgb * v.color;
    let n = normalize(v.normal);
    let t = frame_tangent(n, v.tangent.xyz);
    let b = cross(n, t);
    let view = normalize(globals.camera_pos.xyz - v.position);
    let wo = vec3<f32>(dot(view, t), dot(view, b), dot(view, n));
    let count = rp.lights;
    var diffuse = vec3<f32>(0.0);
    var glossy = vec3<f32>(0.0);
    for (var i = 0u; i < count; i = i + 1u) {
        let vis = visibility[index * count + i];
        if (vis <= 0.0) {
            continue;
        }
        let d = lights[2u * i];
        let energy = lights[2u * i + 1u].rgb * d.w * vis;
        let c = vec3<f32>(dot(d.xyz, t), dot(d.xyz, b), dot(d.xyz, n));
        let half_edge = sqrt(d.w * 0.5) * 0.5;
        diffuse = diffuse + energy * square_mean(rp.layouts[m].first, to_plane(c), half_edge);
        glossy = glossy + energy * lobe_mean(m, c, half_edge, wo);
    }
    out.diffuse = out.albedo * diffuse;
    out.glossy = rp.specular[m].rgb * glossy;
    out.open = ndf_open_fraction(PI * diffuse, n);
    return out;
}

fn shade(in: VertexOut, front: bool) -> vec4<f32> {
    let n = normalize(in.normal);
    // The square lights' shading is per vertex; under a normal map each pixel scales its diffuse
    // light and corrects its highlight for the NDF (normal_map.wgsl), as the SH and wavelet modes do.
    var ndf: SurfaceNdf;
    surface_ndf(&ndf, in.material, in.uv, n, in.tangent);
    let view = normalize(globals.camera_pos.xyz - in.world);
    let glossy = ndf_vertex_glossy(&ndf, n, view, in.material, in.open, in.glossy);
    let lit = in.diffuse * ndf_vertex_diffuse_scale(&ndf, n) + glossy;
    return vec4<f32>(fog_shade(lit, in.world, n, in.tangent.xyz, in.albedo / PI, in.material, &ndf), 1.0);
}
