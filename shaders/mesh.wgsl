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
};

@vertex
fn vs_main(v: MeshVertex) -> VertexOut {
    var out: VertexOut;
    out.clip = globals.view_proj * vec4<f32>(v.position, 1.0);
    out.normal = v.normal;
    out.color = v.color;
    out.material = v.material;
    out.world = v.position;
    return out;
}

// E(n) = sum_k E_k Y_k(n): the recurrence of `sh_basis` (common.wgsl), each basis value added
// in as it is made. No array of basis values: a CPU Vulkan (lavapipe) spills a dynamically
// indexed private array to memory per pixel, which made this pass slower than per-vertex PRT.
fn sh_irradiance(n: vec3<f32>, bands: i32) -> vec3<f32> {
    var result = vec3<f32>(0.0);
    var c = 1.0;
    var s = 0.0;
    var p_mm = sqrt(1.0 / (4.0 * PI));
    for (var m = 0; m < bands; m = m + 1) {
        let mf = f32(m);
        if (m > 0) {
            p_mm = p_mm * sqrt((2.0 * mf + 1.0) / (2.0 * mf));
            let nc = c * n.x - s * n.y;
            let ns = c * n.y + s * n.x;
            c = nc;
            s = ns;
        }
        var p_prev = 0.0;
        var p = p_mm;
        for (var l = m; l < bands; l = l + 1) {
            if (l > m) {
                let next = legendre_next(l, m, n.z, p, p_prev);
                p_prev = p;
                p = next;
            }
            let base = l * (l + 1);
            if (m == 0) {
                result = result + sh.coeffs[base].rgb * p;
            } else {
                let q = p * sqrt(2.0);
                result = result + sh.coeffs[base + m].rgb * (q * c) + sh.coeffs[base - m].rgb * (q * s);
            }
        }
    }
    return result;
}

@fragment
fn fs_main(in: VertexOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    var n = normalize(in.normal);
    if (!front) {
        n = -n;
    }
    let bands = i32(sh.bands.x);
    var irradiance = vec3<f32>(0.0);
    if (bands > 0) {
        irradiance = max(sh_irradiance(n, bands), vec3<f32>(0.0));
    }
    let kd = sh.albedo[in.material].rgb * in.color / PI;
    return vec4<f32>(fog_shade(kd * irradiance, in.world, n, kd, in.material), 1.0);
}
