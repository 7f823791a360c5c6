// Point lights and analytic single scattering in homogeneous fog (Sun 2008 ch. 3; the CPU twin
// is nodes/src/single_scattering.rs `shade`): L = e^{-T_vp} L_p + sum L_a (eq. 3.29), L_p from
// eqs. 3.27-3.28 (Lambert: direct e^{-T_sp}/D^2 cos + beta^2 G_0/(2 pi T_sp); Phong: the same
// about the mirror direction with cos^n and G_n), L_a from eq. 3.16.
// Tables are R32Float, read with textureLoad and interpolated here (no float filtering needed).

#define_import_path lightloom::fog

#import lightloom::common::{PI, SpecularLobe, globals, sh_walk, sh_walk_next}
#import lightloom::normal_map::{SurfaceNdf, ndf_mapped, ndf_direct_diffuse, ndf_widened_lobe, ndf_seen_from}
#import lightloom::sun::sun_direct

// A point light as the fog and surfaces shade it.
struct FogLight {
    position: vec3<f32>,
    // 1 when it has an angular profile (nodes/src/light.rs `AngularProfile`), else isotropic.
    profiled: u32,
    intensity: vec3<f32>,
    // The profile's axis and its phi = 0 direction.
    axis: vec3<f32>,
    x_axis: vec3<f32>,
};

// A material's Phong-equivalent lobe (eq. 3.28): weight per channel and exponent (0: none).
struct SurfaceLobe {
    weight: vec3<f32>,
    exponent: f32,
};

struct Fog {
    // beta per channel (1/m); `linked` is 1 when a medium is linked.
    beta: vec3<f32>,
    linked: u32,
    // Phase polynomial weights W_0..W_2 (eq. 3.18, normalised), and how many there are.
    phase: vec3<f32>,
    phase_terms: u32,
    light_count: u32,
    // The G ladder's layers, and its layers per octave of exponent.
    g_layers: u32,
    g_layers_per_octave: f32,
    // 1 when surfaces get the scattered environment's irradiance here (wavelet modes).
    scatter_onto_surfaces: u32,
    // The environment's attenuation e^{-beta D} (eq. 3.37), and the bands of the next field.
    attenuation: vec3<f32>,
    scattered_bands: u32,
    // SH coefficients of the light the fog scatters from the environment (eq. 3.35).
    environment_scattered: array<vec3<f32>, 64>,
    // Per material.
    lobes: array<SurfaceLobe, 8>,
    lights: array<FogLight, 8>,
};

@group(1) @binding(0) var<uniform> fog: Fog;
@group(1) @binding(1) var f_tables: texture_2d_array<f32>;
@group(1) @binding(2) var g_table: texture_2d_array<f32>;
// One layer per light: the profile over (phi, theta), theta from 0 to pi over the rows.
@group(1) @binding(3) var light_profiles: texture_2d_array<f32>;

// Light `i`'s angular profile towards the unit vector `dir` leaving it (1 when isotropic),
// bilinear in theta and phi as nodes/src/light.rs `AngularProfile::toward` reads it.
fn light_profile(i: i32, dir: vec3<f32>) -> f32 {
    if (fog.lights[i].profiled == 0u) {
        return 1.0;
    }
    let z = fog.lights[i].axis;
    let x = fog.lights[i].x_axis;
    let y = cross(z, x);
    let dims = textureDimensions(light_profiles);
    let cols = i32(dims.x);
    let rows = i32(dims.y);
    let theta = acos(clamp(dot(dir, z), -1.0, 1.0));
    var phi = atan2(dot(dir, y), dot(dir, x));
    if (phi < 0.0) {
        phi = phi + 2.0 * PI;
    }
    let fy = clamp(theta / PI, 0.0, 1.0) * f32(rows - 1);
    let fx = phi / (2.0 * PI) * f32(cols);
    let y0 = min(i32(floor(fy)), rows - 1);
    let y1 = min(y0 + 1, rows - 1);
    let x0 = i32(floor(fx)) % cols;
    let x1 = (x0 + 1) % cols;
    let ty = fy - floor(fy);
    let tx = fx - floor(fx);
    let top = mix(textureLoad(light_profiles, vec2<i32>(x0, y0), i, 0).x, textureLoad(light_profiles, vec2<i32>(x1, y0), i, 0).x, tx);
    let bottom = mix(textureLoad(light_profiles, vec2<i32>(x0, y1), i, 0).x, textureLoad(light_profiles, vec2<i32>(x1, y1), i, 0).x, tx);
    return mix(top, bottom, ty);
}

// The unit vector from light `i` to `p` (nearly zero when `p` is at the light).
fn light_direction(i: i32, p: vec3<f32>) -> vec3<f32> {
    let d = p - fog.lights[i].position;
    return d / max(length(d), 1e-4);
}

const FOG_U_MAX: f32 = 64.0;
const FOG_U_WARP: f32 = 4.0;
const FOG_MIN_GAMMA: f32 = 1e-4;

// A table at (s, t) in [0, 1]^2, bilinear between its samples (layer `k`).
fn fog_table(table: texture_2d_array<f32>, k: i32, s: f32, t: f32) -> f32 {
    let n = i32(textureDimensions(table).x);
    let x = clamp(s, 0.0, 1.0) * f32(n - 1);
    let y = clamp(t, 0.0, 1.0) * f32(n - 1);
    let x0 = i32(floor(x));
    let y0 = i32(floor(y));
    let x1 = min(x0 + 1, n - 1);
    let y1 = min(y0 + 1, n - 1);
    let fx = x - f32(x0);
    let fy = y - f32(y0);
    let a = mix(textureLoad(table, vec2<i32>(x0, y0), k, 0).r, textureLoad(table, vec2<i32>(x1, y0), k, 0).r, fx);
    let b = mix(textureLoad(table, vec2<i32>(x0, y1), k, 0).r, textureLoad(table, vec2<i32>(x1, y1), k, 0).r, fx);
    return mix(a, b, fy);
}

// F^k(u, v) (eqs. 3.15, 3.19) from its table; the asymptotic series beyond u = 64.
fn fog_f(k: i32, u: f32, v: f32) -> f32 {
    if (u > FOG_U_MAX) {
        let t = tan(min(v, 1.5707));
        let e = exp(-u * t);
        return (1.0 - e) / u - (2.0 - e * (u * u * t * t + 2.0 * u * t + 2.0)) / (u * u * u);
    }
    let s = sqrt(u / (u + FOG_U_WARP) / (FOG_U_MAX / (FOG_U_MAX + FOG_U_WARP)));
    let r = acos(clamp(1.0 - 4.0 * v / PI, -1.0, 1.0)) / PI;
    return fog_table(f_tables, k, s, r) / (1.0 + u);
}

// The angle between unit vectors, accurate near 0 (acos loses it in f32, and the glow peaks there).
fn fog_angle(a: vec3<f32>, b: vec3<f32>) -> f32 {
    return atan2(length(cross(a, b)), dot(a, b));
}

fn fog_phase(cos_alpha: f32) -> f32 {
    return fog.phase.x + cos_alpha * (fog.phase.y + cos_alpha * fog.phase.z);
}

// Airlight of one light along a view ray (eq. 3.16), `d_vp < 0` for a ray to infinity. Where
// the table difference is ill-conditioned, eq. 3.14 by 6-point Gauss-Legendre (exponent folded).
fn fog_airlight(beta: f32, d_sv: f32, d_vp: f32, gamma_in: f32, i0: f32) -> f32 {
    if (beta <= 0.0) {
        return 0.0;
    }
    let gamma = clamp(gamma_in, FOG_MIN_GAMMA, PI);
    let t_sv = beta * d_sv;
    let s = max(sin(gamma), FOG_MIN_GAMMA);
    let c = cos(gamma);
    let a1 = t_sv * s;
    var v_far = PI / 2.0;
    if (d_vp >= 0.0) {
        v_far = PI / 4.0 + 0.5 * atan((beta * d_vp - t_sv * c) / a1);
    }
    let v_near = gamma / 2.0;
    let scale = beta * beta * i0 / (2.0 * PI * t_sv * s);
    let terms = i32(fog.phase_terms);
    var table_ok = v_far - v_near >= 0.05;
    var sum = 0.0;
    if (table_ok) {
        for (var k = 0; k < terms; k = k + 1) {
            let far = fog_f(k, a1, v_far);
            let near = fog_f(k, a1, v_near);
            if (abs(far - near) < 1e-2 * max(abs(far), abs(near))) {
                table_ok = false;
            }
            sum = sum + 4.0 * PI * fog.phase[k] * (far - near);
        }
    }
    if (table_ok) {
        return scale * exp(-t_sv * c) * sum;
    }
    var x = array<f32, 6>(-0.9324695, -0.6612094, -0.2386192, 0.2386192, 0.6612094, 0.9324695);
    var w = array<f32, 6>(0.1713245, 0.3607616, 0.4679139, 0.4679139, 0.3607616, 0.1713245);
    let mid = 0.5 * (v_far + v_near);
    let radius = 0.5 * (v_far - v_near);
    var direct = 0.0;
    for (var i = 0; i < 6; i = i + 1) {
        let xi = mid + radius * x[i];
        direct = direct + w[i] * 4.0 * PI * fog_phase(cos(2.0 * xi)) * exp(-t_sv * c - a1 * tan(xi));
    }
    return scale * radius * direct;
}

// G_n(T_sp, theta_s) (eq. 3.23) from the ladder of exponents (layer k: n = 2^{k/steps}, layer 0
// the Lambertian G_0): T over T/(1+T), theta over sqrt(theta/pi), tables hold (1+T) e^T G_n;
// linear in log2 n between layers after normalising by the lobe's solid angle 2 pi/(n+1)
// (PhongGTables::lookup).
fn fog_g(exponent: f32, t_sp: f32, theta_s: f32) -> f32 {
    let n = max(exponent, 1.0);
    let last = f32(fog.g_layers) - 1.0;
    let steps = fog.g_layers_per_octave;
    let position = min(steps * log2(n), last);
    let lower = floor(position);
    let upper = min(lower + 1.0, last);
    let s = t_sp / (1.0 + t_sp);
    let r = sqrt(clamp(theta_s / PI, 0.0, 1.0));
    let g_lower = fog_table(g_table, i32(lower), s, r) * (exp2(lower / steps) + 1.0);
    let g_upper = fog_table(g_table, i32(upper), s, r) * (exp2(upper / steps) + 1.0);
    return mix(g_lower, g_upper, position - lower) * exp(-t_sp) / ((n + 1.0) * (1.0 + t_sp));
}

// sum_lm w_l c_lm Y_lm(dir) over the environment's scattered light c_lm, with w_l = 1 (radiance)
// or A_l (irradiance, Sun 2008 eq. 2.24; bands above 4 are negligible), summed as the shared
// basis walk (common.wgsl) goes.
fn fog_environment_sum(dir: vec3<f32>, irradiance: bool) -> vec3<f32> {
    var bands = i32(fog.scattered_bands);
    if (irradiance) {
        bands = min(bands, 5);
    }
    var sum = vec3<f32>(0.0);
    var walk = sh_walk(dir, bands);
    while (sh_walk_next(&walk)) {
        let l = walk.l;
        var w = 1.0;
        if (irradiance) {
            w = select(select(select(select(-PI / 24.0, 0.0, l == 3), PI / 4.0, l == 2), 2.0 * PI / 3.0, l == 1), PI, l == 0);
        }
        let base = l * (l + 1);
        sum = sum + w * walk.cos_y * fog.environment_scattered[base + walk.m];
        if (walk.m > 0) {
            sum = sum + w * walk.sin_y * fog.environment_scattered[base - walk.m];
        }
    }
    return max(sum, vec3<f32>(0.0));
}

// The environment's glow in direction `dir`: its scattered light (eq. 3.35), band-limited.
fn fog_environment_glow(dir: vec3<f32>) -> vec3<f32> {
    return fog_environment_sum(dir, false);
}

// Irradiance at normal `n` from the environment's scattered light.
fn fog_environment_glow_irradiance(n: vec3<f32>) -> vec3<f32> {
    return fog_environment_sum(n, true);
}

// What the viewer sees of a surface point `p` (normal `n`, diffuse reflectance `kd` = albedo/pi,
// material slot `material`) whose environment-lit radiance is `lit`: point lights added
// (Lambert plus the material's Phong-equivalent lobe, k_s = weight (n+2)/(2 pi) cos theta_o as
// in the SH mode), then fog applied: the surface attenuated over the view path, the lights'
// airlight, and the environment's glow in the view direction scattered in along the path
// (the glow per unit length is about constant along the ray, so the path's share of the
// infinite ray's glow is 1 - e^{-beta d}).
fn fog_shade(lit_in: vec3<f32>, p: vec3<f32>, n: vec3<f32>, tangent: vec3<f32>, kd: vec3<f32>, material: u32, ndf: ptr<function, SurfaceNdf>) -> vec3<f32> {
    let fogged = fog.linked != 0u;
    let viewer = globals.camera_pos.xyz;
    let d_vp = length(viewer - p);
    let view = (p - viewer) / max(d_vp, 1e-6);
    let lobe = fog.lobes[material];
    let exponent = max(lobe.exponent, 1.0);
    let mirror = reflect(view, n);
    let ks = lobe.weight * (exponent + 2.0) / (2.0 * PI) * max(dot(mirror, n), 0.0);
    let glossy = lobe.exponent > 0.0 && max(ks.r, max(ks.g, ks.b)) > 0.0;
    // Through a normal map, the lights see the pixel's lobes of normals as the view does: the
    // part of each it lies below flipped, as the reference shades such normals.
    if (ndf_mapped(ndf)) {
        ndf_seen_from(ndf, n, -view);
    }
    // The environment's sun, when lit apart from the mode's transport (sun.wgsl).
    var lit = lit_in + sun_direct(p, n, tangent, -view, kd, material, ndf);
    var glow = vec3<f32>(0.0);
    if (fogged) {
        glow = fog_environment_glow(view);
        if (fog.scatter_onto_surfaces != 0u) {
            lit = lit * fog.attenuation + kd * fog_environment_glow_irradiance(n);
        }
    }
    // Each light's profile towards this point and towards the viewer, once for all channels.
    var toward_point: array<f32, 8>;
    var toward_viewer: array<f32, 8>;
    for (var i = 0; i < i32(fog.light_count); i = i + 1) {
        toward_point[i] = light_profile(i, light_direction(i, p));
        toward_viewer[i] = light_profile(i, light_direction(i, viewer));
    }
    var out = vec3<f32>(0.0);
    for (var c = 0; c < 3; c = c + 1) {
        let beta = select(0.0, fog.beta[c], fogged);
        var surface = lit[c];
        var air = 0.0;
        for (var i = 0; i < i32(fog.light_count); i = i + 1) {
            let to_light = fog.lights[i].position - p;
            let d_sp = max(length(to_light), 1e-4);
            // A profiled light: its intensity towards this point lights the surface; its airlight
            // (eq. 3.16 holds for isotropic lights) takes its intensity towards the viewer.
            let i0 = fog.lights[i].intensity[c] * toward_point[i];
            let cos_s = dot(to_light / d_sp, n);
            let t_sp = beta * d_sp;
            let direct = exp(-t_sp) / (d_sp * d_sp);
            var reflected = direct * max(cos_s, 0.0);
            var specular = 0.0;
            let cos_m = dot(to_light / d_sp, mirror);
            if (glossy) {
                specular = direct * pow(max(cos_m, 0.0), exponent) * select(0.0, 1.0, cos_s > 0.0);
            }
            // Through a normal map: Lambert over the NDF, and the lobe per lobe of normals,
            // widened (normal_map.wgsl), relative to ks's normalisation and cosine.
            if (ndf_mapped(ndf) && cos_s > 0.0) {
                reflected = direct * ndf_direct_diffuse(ndf, to_light / d_sp);
                if (glossy) {
                    var sum = 0.0;
                    for (var j = 0; j < (*ndf).count; j = j + 1) {
                        let mu = (*ndf).lobes[j].xyz;
                        let phong = SpecularLobe(1u, exponent, 1.0, 0.0, vec3<f32>(1.0));
                        let widened = ndf_widened_lobe(phong, (*ndf).kappas[j]);
                        let s = widened.lobe.sharpness;
                        let mirror_j = reflect(view, mu);
                        sum = sum + (*ndf).lobes[j].w * widened.factor * (s + 2.0) * max(dot(mirror_j, mu), 0.0)
                            * pow(max(dot(to_light / d_sp, mirror_j), 0.0), s);
                    }
                    specular = direct * sum / ((exponent + 2.0) * max(dot(mirror, n), 1e-4));
                }
            }
            if (beta > 0.0) {
                reflected = reflected + beta * beta * fog_g(1.0, t_sp, acos(clamp(cos_s, -1.0, 1.0))) / (2.0 * PI * t_sp);
                if (glossy) {
                    let theta_m = acos(clamp(cos_m, -1.0, 1.0));
                    specular = specular + beta * beta * fog_g(exponent, t_sp, theta_m) / (2.0 * PI * t_sp);
                }
                let to_source = fog.lights[i].position - viewer;
                let d_sv = max(length(to_source), 1e-4);
                let gamma = fog_angle(view, to_source / d_sv);
                let i_air = fog.lights[i].intensity[c] * toward_viewer[i];
                air = air + fog_airlight(beta, d_sv, d_vp, gamma, i_air);
            }
            surface = surface + i0 * (kd[c] * reflected + ks[c] * specular);
        }
        let transmitted = exp(-beta * d_vp);
        out[c] = transmitted * surface + air + glow[c] * (1.0 - transmitted);
    }
    return out;
}

// The background seen through fog (eq. 3.36): the environment attenuated (eq. 3.37) plus its
// glow (eq. 3.35, hidden with the background), plus the lights' glows.
fn fog_background(env: vec3<f32>, dir: vec3<f32>) -> vec3<f32> {
    if (fog.linked == 0u) {
        return env;
    }
    let viewer = globals.camera_pos.xyz;
    var out = env * fog.attenuation + fog_environment_glow(dir) * f32(globals.background);
    var toward_viewer: array<f32, 8>;
    for (var i = 0; i < i32(fog.light_count); i = i + 1) {
        toward_viewer[i] = light_profile(i, light_direction(i, viewer));
    }
    for (var c = 0; c < 3; c = c + 1) {
        var air = 0.0;
        for (var i = 0; i < i32(fog.light_count); i = i + 1) {
            let to_source = fog.lights[i].position - viewer;
            let d_sv = max(length(to_source), 1e-4);
            let gamma = fog_angle(dir, to_source / d_sv);
            // A profiled light glows as bright as it shines back at the viewer.
            let i0 = fog.lights[i].intensity[c] * toward_viewer[i];
            air = air + fog_airlight(fog.beta[c], d_sv, -1.0, gamma, i0);
        }
        out[c] = out[c] + air;
    }
    return out;
}
