// Shared by every scene pass: the camera (group 0, render/src/passes/camera.rs), the vertex
// layout and the SH basis.

#define_import_path lightloom::common

struct Globals {
    view_proj: mat4x4<f32>,
    inv_view_proj: mat4x4<f32>,
    camera_pos: vec3<f32>,
    // 1 when the background is drawn
    background: u32,
};

@group(0) @binding(0) var<uniform> globals: Globals;

// The viewport's vertex layout (render/src/passes/geometry.rs `Vertex`); mesh passes take what they need.
struct MeshVertex {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) color: vec3<f32>,
    @location(3) tangent: vec4<f32>,
    @location(4) uv: vec2<f32>,
    @location(5) material: u32,
};

const PI: f32 = 3.14159265358979;

// The unit tangent of the frame [t, n x t, n] at unit normal `n`, by the rule of the Monte
// Carlo reference and the CPU shading (nodes/src/rsl/shade.rs `shading_frame`): `tangent` made
// orthogonal to `n`, or, where that leaves a zero vector (interpolated tangents that cancel),
// glam's `any_orthonormal_vector(n)` (Duff et al. 2017). Lengths beyond f32's square range
// (|t| above about 1e19 or below 1e-19) also take the fallback, where f64 would not.
fn frame_tangent(n: vec3<f32>, tangent: vec3<f32>) -> vec3<f32> {
    let t = tangent - n * dot(n, tangent);
    let length2 = dot(t, t);
    if (length2 > 0.0 && length2 < 3.0e38) {
        return t * inverseSqrt(length2);
    }
    // glam's signum: -1 for a negative z, -0 included.
    let sign = select(1.0, -1.0, (bitcast<u32>(n.z) & 0x80000000u) != 0u);
    let a = -1.0 / (sign + n.z);
    return vec3<f32>(n.x * n.y * a, sign + n.y * n.y * a, -n.y);
}

const MAX_COEFFS: i32 = 64;

// One step in l of the normalised associated-Legendre recurrence at fixed m (l > m): from
// p = P_{l-1}^m and p_prev = P_{l-2}^m (unused at l = m + 1, where p = P_m^m) to P_l^m.
fn legendre_next(l: i32, m: i32, z: f32, p: f32, p_prev: f32) -> f32 {
    let mf = f32(m);
    if (l == m + 1) {
        return sqrt(2.0 * mf + 3.0) * z * p;
    }
    let lf = f32(l);
    let a = sqrt((4.0 * lf * lf - 1.0) / (lf * lf - mf * mf));
    let b = sqrt(((lf - 1.0) * (lf - 1.0) - mf * mf) / (4.0 * (lf - 1.0) * (lf - 1.0) - 1.0));
    return a * (z * p - b * p_prev);
}

// Real orthonormal SH without the Condon-Shortley phase, by the normalised associated-Legendre
// recurrence of nodes/src/sh/mod.rs (ShBasis::eval), one (l, m) step at a time: after
// `sh_walk_next` returns true, `cos_y` is Y_{l,m} (index l(l+1)+m) and, for m > 0, `sin_y` is
// Y_{l,-m} (index l(l+1)-m). Passes sum as they walk: a basis array indexed at run time is
// spilled to memory in every fragment by software rasterisers (lavapipe).
struct ShWalk {
    dir: vec3<f32>,
    bands: i32,
    l: i32,
    m: i32,
    // cos(mφ) and sin(mφ) times sin^m θ, the sectoral P_m^m and the last two P_l^m.
    c: f32,
    s: f32,
    p_mm: f32,
    p: f32,
    p_prev: f32,
    cos_y: f32,
    sin_y: f32,
};

fn sh_walk(dir: vec3<f32>, bands: i32) -> ShWalk {
    return ShWalk(dir, bands, -1, 0, 1.0, 0.0, sqrt(1.0 / (4.0 * PI)), 0.0, 0.0, 0.0, 0.0);
}

// Steps to the next (l, m): l runs from m to bands - 1, then m moves on.
fn sh_walk_next(w: ptr<function, ShWalk>) -> bool {
    if ((*w).l < 0) {
        if ((*w).bands <= 0) {
            return false;
        }
        (*w).l = 0;
        (*w).p = (*w).p_mm;
    } else if ((*w).l + 1 < (*w).bands) {
        (*w).l = (*w).l + 1;
        let next = legendre_next((*w).l, (*w).m, (*w).dir.z, (*w).p, (*w).p_prev);
        (*w).p_prev = (*w).p;
        (*w).p = next;
    } else {
        (*w).m = (*w).m + 1;
        if ((*w).m >= (*w).bands) {
            return false;
        }
        let mf = f32((*w).m);
        (*w).p_mm = (*w).p_mm * sqrt((2.0 * mf + 1.0) / (2.0 * mf));
        let nc = (*w).c * (*w).dir.x - (*w).s * (*w).dir.y;
        let ns = (*w).c * (*w).dir.y + (*w).s * (*w).dir.x;
        (*w).c = nc;
        (*w).s = ns;
        (*w).l = (*w).m;
        (*w).p = (*w).p_mm;
        (*w).p_prev = 0.0;
    }
    if ((*w).m == 0) {
        (*w).cos_y = (*w).p;
        (*w).sin_y = 0.0;
    } else {
        (*w).cos_y = (*w).p * sqrt(2.0) * (*w).c;
        (*w).sin_y = (*w).p * sqrt(2.0) * (*w).s;
    }
    return true;
}

// The whole basis as an array (for the few passes that read it more than once).
fn sh_basis(n: vec3<f32>, bands: i32) -> array<f32, MAX_COEFFS> {
    var y: array<f32, MAX_COEFFS>;
    var walk = sh_walk(n, bands);
    while (sh_walk_next(&walk)) {
        let base = walk.l * (walk.l + 1);
        y[base + walk.m] = walk.cos_y;
        if (walk.m > 0) {
            y[base - walk.m] = walk.sin_y;
        }
    }
    return y;
}

// A material's specular lobe (nodes/src/frame `SpecularLobe`, nodes/src/brdf.rs `Lobe`):
// `model` 0 none, 1 Phong, 2 Blinn-Phong, 3 GGX, 4 Ward; `sharpness` the exponent (the Phong
// models) or the alpha along the tangent, `alpha_y` the alpha along the bitangent;
// `reflectance` the Fresnel term at normal incidence; `colour` what it reflects.
struct SpecularLobe {
    model: u32,
    sharpness: f32,
    reflectance: f32,
    alpha_y: f32,
    colour: vec3<f32>,
};
