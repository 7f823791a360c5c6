// Shared by every scene pass: the camera (group 0, render/src/passes/camera.rs), the vertex
// layout and the SH basis.

struct Globals {
    view_proj: mat4x4<f32>,
    inv_view_proj: mat4x4<f32>,
    camera_pos: vec4<f32>,
    // y: draw background (0/1); x, z, w unused
    flags: vec4<f32>,
};

@group(0) @binding(0) var<uniform> globals: Globals;

// The viewport's vertex layout (render/src/passes/geometry.rs `Vertex`); mesh passes take what they need.
struct MeshVertex {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) color: vec3<f32>,
    @location(3) tangent: vec3<f32>,
    @location(4) uv: vec2<f32>,
    @location(5) material: u32,
};

const PI: f32 = 3.14159265358979;
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
// recurrence of nodes/src/sh/mod.rs (ShBasis::eval).
fn sh_basis(n: vec3<f32>, bands: i32) -> array<f32, MAX_COEFFS> {
    var y: array<f32, MAX_COEFFS>;
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
                y[base] = p;
            } else {
                y[base + m] = p * sqrt(2.0) * c;
                y[base - m] = p * sqrt(2.0) * s;
            }
        }
    }
    return y;
}
