// Mesh pass: unshadowed diffuse lighting from the environment's irradiance SH
// (Sun 2008 eq. 2.20: E(n) = sum_lm A_l L_lm Y_lm(n); radiance out = albedo * E / pi).
// The coefficients E_lm arrive precomputed; this shader only evaluates the basis.

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) color: vec3<f32>,
    @location(6) material: u32,
};

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) normal: vec3<f32>,
    @location(1) color: vec3<f32>,
    @location(2) @interpolate(flat) material: u32,
};

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    var out: VertexOut;
    out.clip = globals.view_proj * vec4<f32>(v.position, 1.0);
    out.normal = v.normal;
    out.color = v.color;
    out.material = v.material;
    return out;
}

const PI: f32 = 3.14159265358979;

// Real orthonormal SH without the Condon-Shortley phase, by the same normalised
// associated-Legendre recurrence as nodes/src/sh/mod.rs (ShBasis::eval).
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
        var scale_c = 1.0;
        var scale_s = 0.0;
        if (m > 0) {
            scale_c = sqrt(2.0) * c;
            scale_s = sqrt(2.0) * s;
        }
        var p_prev = 0.0;
        var p = p_mm;
        for (var l = m; l < bands; l = l + 1) {
            if (l == m + 1) {
                p_prev = p;
                p = sqrt(2.0 * mf + 3.0) * n.z * p_mm;
            } else if (l > m + 1) {
                let lf = f32(l);
                let a = sqrt((4.0 * lf * lf - 1.0) / (lf * lf - mf * mf));
                let b = sqrt(((lf - 1.0) * (lf - 1.0) - mf * mf) / (4.0 * (lf - 1.0) * (lf - 1.0) - 1.0));
                let next = a * (n.z * p - b * p_prev);
                p_prev = p;
                p = next;
            }
            let base = l * (l + 1);
            if (m == 0) {
                result = result + globals.irradiance[base].rgb * p;
            } else {
                result = result + globals.irradiance[base + m].rgb * (p * scale_c);
                result = result + globals.irradiance[base - m].rgb * (p * scale_s);
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
    let bands = i32(globals.flags.x);
    var irradiance = vec3<f32>(0.0);
    if (bands > 0) {
        irradiance = max(sh_irradiance(n, bands), vec3<f32>(0.0));
    }
    let radiance = globals.albedo[in.material].rgb * in.color * irradiance / PI;
    return vec4<f32>(radiance, 1.0);
}
