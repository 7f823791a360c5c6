// The environment's sun lit per pixel (group 3, render/src/passes/sun.rs; the disc and its
// directions come from nodes/src/sun.rs): each direction carries an equal share of the disc's
// power and is shadowed by its own orthographic shadow map (2x2 PCF by the comparison sampler).

#define_import_path lightloom::sun

#import lightloom::common::{SpecularLobe, frame_tangent}
#import lightloom::normal_map::{NDF_SINGLE_NORMAL, SurfaceNdf, WidenedLobe, ndf_mapped, ndf_direct_diffuse, ndf_widened_axes, ndf_widened_lobe, ndf_shadow_terminator}

const MAX_SUN_DIRECTIONS: i32 = 32;
const SUN_MATERIALS: i32 = 8;
const SUN_PI: f32 = 3.14159265358979;

struct Sun {
    // Radiance x solid angle / direction count: irradiance at normal incidence per direction.
    irradiance: vec3<f32>,
    // 0: no separate sun.
    direction_count: u32,
    // Offset along the normal against self-shadowing (world units).
    normal_offset: f32,
    // How many of the last directions lie evenly on the disc's rim (nodes/src/sun.rs
    // `rim_directions`; 0: none).
    rim_directions: u32,
    // The disc's axis, and the cosine of its angular radius.
    axis: vec3<f32>,
    cos_radius: f32,
    // Unit vectors towards the sun.
    directions: array<vec3<f32>, MAX_SUN_DIRECTIONS>,
    // World to each shadow map's clip space (orthographic, depth in [0, 1]).
    view_proj: array<mat4x4<f32>, MAX_SUN_DIRECTIONS>,
    // Per material, its specular lobe.
    lobes: array<SpecularLobe, SUN_MATERIALS>,
};

@group(3) @binding(0) var<uniform> sun: Sun;
@group(3) @binding(1) var sun_shadow_maps: texture_depth_2d_array;
@group(3) @binding(2) var sun_shadow_sampler: sampler_comparison;

// Whether direction `k` sees the sun from `shifted` (2x2 PCF; 1 outside its map).
fn sun_visibility(k: i32, shifted: vec4<f32>) -> f32 {
    let clip = sun.view_proj[k] * shifted;
    let uv = vec2<f32>(clip.x * 0.5 + 0.5, 0.5 - clip.y * 0.5);
    if (any(uv <= vec2<f32>(0.0)) || any(uv >= vec2<f32>(1.0)) || clip.z >= 1.0) {
        return 1.0;
    }
    return textureSampleCompareLevel(sun_shadow_maps, sun_shadow_sampler, uv, k, clip.z);
}

// Smith's Lambda for anisotropic GGX (nodes/src/brdf.rs `ggx_lambda`), `w` in the local frame.
fn sun_ggx_lambda(w: vec3<f32>, ax: f32, ay: f32) -> f32 {
    let t2 = ((ax * w.x) * (ax * w.x) + (ay * w.y) * (ay * w.y)) / max(w.z * w.z, 1e-12);
    return (-1.0 + sqrt(1.0 + t2)) * 0.5;
}

// Material `m`'s specular lobe from `wi` toward `wo`, without its colour, in the frame of the
// normal `n` and the tangent `tangent` (nodes/src/brdf.rs `Brdf::lobe_value`: normalised Phong
// and Blinn-Phong and Ward weighted by f0; GGX with height-correlated Smith masking and
// Schlick's Fresnel).
fn sun_lobe(m: u32, n: vec3<f32>, tangent: vec3<f32>, wi: vec3<f32>, wo: vec3<f32>) -> f32 {
    return sun_lobe_of(sun.lobes[m], n, tangent, wi, wo);
}

// A lobe as `Sun.lobes` holds it.
fn sun_lobe_of(lobe: SpecularLobe, n: vec3<f32>, tangent: vec3<f32>, wi: vec3<f32>, wo: vec3<f32>) -> f32 {
    let cos_i = dot(n, wi);
    let cos_o = dot(n, wo);
    if (cos_i <= 0.0 || cos_o <= 0.0) {
        return 0.0;
    }
    let model = lobe.model;
    let f0 = lobe.reflectance;
    let exponent = lobe.sharpness;
    if (model == 1u) {
        let c = max(dot(wi, reflect(-wo, n)), 0.0);
        return f0 * (exponent + 2.0) / (2.0 * SUN_PI) * pow(c, exponent);
    }
    let h_world = normalize(wi + wo);
    if (model == 2u) {
        return f0 * (exponent + 8.0) / (8.0 * SUN_PI) * pow(max(dot(n, h_world), 0.0), exponent);
    }
    // The local frame [t, n x t, n] (as the reference and the wavelet tables take it).
    let t = frame_tangent(n, tangent);
    let b = cross(n, t);
    let h = vec3<f32>(dot(h_world, t), dot(h_world, b), dot(h_world, n));
    let ax = lobe.sharpness;
    let ay = lobe.alpha_y;
    if (h.z <= 0.0) {
        return 0.0;
    }
    if (model == 3u) {
        let s = (h.x / ax) * (h.x / ax) + (h.y / ay) * (h.y / ay) + h.z * h.z;
        let d = 1.0 / (SUN_PI * ax * ay * s * s);
        let li = vec3<f32>(dot(wi, t), dot(wi, b), cos_i);
        let lo = vec3<f32>(dot(wo, t), dot(wo, b), cos_o);
        let g = 1.0 / (1.0 + sun_ggx_lambda(li, ax, ay) + sun_ggx_lambda(lo, ax, ay));
        let f = f0 + (1.0 - f0) * pow(1.0 - clamp(dot(wi, h_world), 0.0, 1.0), 5.0);
        return f * d * g / (4.0 * cos_i * cos_o);
    }
    if (model == 4u) {
        let e = ((h.x / ax) * (h.x / ax) + (h.y / ay) * (h.y / ay)) / (h.z * h.z);
        return f0 * exp(-e) / (4.0 * SUN_PI * ax * ay * sqrt(cos_i * cos_o));
    }
    return 0.0;
}

// The angular variance (per axis, about the normal) of the half vectors a lobe reflects through:
// 1/s for Blinn-Phong's exponent s, a quarter of Phong's mirror-space 1/s, α²/2 for GGX and
// Ward (along the sharper axis).
fn sun_lobe_variance(lobe: SpecularLobe) -> f32 {
    if (lobe.model == 1u) {
        return 0.25 / max(lobe.sharpness, 1e-6);
    }
    if (lobe.model == 2u) {
        return 1.0 / max(lobe.sharpness, 1e-6);
    }
    if (lobe.model == 3u || lobe.model == 4u) {
        let a = min(lobe.sharpness, lobe.alpha_y);
        return 0.5 * a * a;
    }
    return 0.0;
}

// The concentration of the normals a lobe reflects `wi` to `wo` through, about the half vector
// (the inverse of sun_lobe_variance's per-axis variance, as a vMF's κ is of its own): 2/α² for
// GGX and Ward (along the sharper axis), s for Blinn-Phong, 4s for Phong (its lobe is about the
// mirror direction, which turns twice as far as the normal).
fn sun_lobe_concentration(lobe: SpecularLobe) -> f32 {
    return 1.0 / max(sun_lobe_variance(lobe), 1e-9);
}

// Material `lobe` reflecting `wi` to `wo` through a lobe of normals about unit `mu`, without its
// colour, times the cosine: the lobe's distribution `widened` by the normals' spread
// (normal_map.wgsl ndf_widened_lobe, nodes/src/brdf.rs `Lobe::widened`; `tangent` its frame
// where it is anisotropic), about `mu`, times the rest of the BRDF (masking of the unwidened
// lobe, Fresnel, `1/(4 cos_i cos_o)`) and the cosine at the normal that does the reflecting,
// `n* ∝ κ_b h + κ mu` (the product of the lobe of normals, of concentration `kappa`, and the
// material's own lobe about the half vector, of concentration κ_b: sun_lobe_concentration).
// Evaluating those at `mu` instead loses most of the light at grazing views, where `cos_o`
// varies most across the lobe; masking by the widened lobe would count the map's spread as
// microgeometry that shadows, which a normal map is not. `g` is the surface's unperturbed
// normal, for the shadow terminator (nodes/src/reference.rs) at `n*`. `mixture`: the lobe is one of
// a fitted vMF mixture (the GGX distribution then convolved with it as below).
fn sun_lobe_through(lobe: SpecularLobe, widened: WidenedLobe, kappa: f32, mixture: bool, mu: vec3<f32>, g: vec3<f32>, tangent: vec3<f32>, wi: vec3<f32>, wo: vec3<f32>) -> f32 {
    let half = wi + wo;
    if (dot(half, half) < 1e-12) {
        return 0.0;
    }
    let h_world = normalize(half);
    // A single normal (a flat map, averaged normals) reflects through itself.
    var star = mu;
    if (kappa < NDF_SINGLE_NORMAL) {
        star = normalize(sun_lobe_concentration(lobe) * h_world + kappa * mu);
    }
    let cos_i = dot(star, wi);
    let cos_o = dot(star, wo);
    if (cos_i <= 0.0 || cos_o <= 0.0 || dot(g, wi) <= 0.0) {
        return 0.0;
    }
    let model = lobe.model;
    let f0 = lobe.reflectance;
    var value = 0.0;
    if (model == 1u) {
        let c = max(dot(wi, reflect(-wo, mu)), 0.0);
        let s = widened.lobe.sharpness;
        value = f0 * (s + 2.0) / (2.0 * SUN_PI) * pow(c, s) * cos_i;
    } else if (model == 2u) {
        let s = widened.lobe.sharpness;
        value = f0 * (s + 8.0) / (8.0 * SUN_PI) * pow(max(dot(mu, h_world), 0.0), s) * cos_i;
    } else if (model == 3u || model == 4u) {
        // The half vector in the frame of mu (any frame for isotropic lobes).
        let hz = dot(h_world, mu);
        if (hz <= 0.0) {
            return 0.0;
        }
        var h = vec3<f32>(sqrt(max(1.0 - hz * hz, 0.0)), 0.0, hz);
        if (widened.lobe.sharpness != widened.lobe.alpha_y) {
            let t = frame_tangent(mu, tangent);
            h = vec3<f32>(dot(h_world, t), dot(h_world, cross(mu, t)), hz);
        }
        let ax = widened.lobe.sharpness;
        let ay = widened.lobe.alpha_y;
        if (model == 3u) {
            let s = (h.x / ax) * (h.x / ax) + (h.y / ay) * (h.y / ay) + h.z * h.z;
            var d = 1.0 / (SUN_PI * ax * ay * s * s);
            // GGX convolved with a fitted vMF lobe of normals (`mixture`): the widened GGX where
            // the material's own roughness holds most of the slope variance, a Beckmann lobe of
            // the same widths (the Gaussian slopes a vMF lobe's are) where the normals' spread
            // does, mixed by the spread's share, which keeps GGX's own tail. The widened GGX alone
            // stretches the tail to the full width: a bright core and weak shoulders, 75% of the
            // reference's on a far dimpled floor. A single lobe standing for a whole NDF (Toksvig,
            // the SH filter's) is no Gaussian of normals, and keeps the widened GGX.
            let spread = select(0.0, clamp(1.0 - lobe.sharpness * lobe.alpha_y / (ax * ay), 0.0, 1.0), mixture);
            if (spread > 0.0) {
                let hz2 = max(h.z * h.z, 1e-8);
                let e = ((h.x / ax) * (h.x / ax) + (h.y / ay) * (h.y / ay)) / hz2;
                d = mix(d, exp(-e) / (SUN_PI * ax * ay * hz2 * hz2), spread);
            }
            // Masking by the material's own roughness, in the frame of n*.
            var li = vec3<f32>(sqrt(max(1.0 - cos_i * cos_i, 0.0)), 0.0, cos_i);
            var lo = vec3<f32>(sqrt(max(1.0 - cos_o * cos_o, 0.0)), 0.0, cos_o);
            if (lobe.sharpness != lobe.alpha_y) {
                let ts = frame_tangent(star, tangent);
                let bs = cross(star, ts);
                li = vec3<f32>(dot(wi, ts), dot(wi, bs), cos_i);
                lo = vec3<f32>(dot(wo, ts), dot(wo, bs), cos_o);
            }
            let masking = 1.0 / (1.0 + sun_ggx_lambda(li, lobe.sharpness, lobe.alpha_y) + sun_ggx_lambda(lo, lobe.sharpness, lobe.alpha_y));
            let f = f0 + (1.0 - f0) * pow(1.0 - clamp(dot(wi, h_world), 0.0, 1.0), 5.0);
            value = f * d * masking / (4.0 * cos_o);
        } else {
            let e = ((h.x / ax) * (h.x / ax) + (h.y / ay) * (h.y / ay)) / (h.z * h.z);
            value = f0 * exp(-e) / (4.0 * SUN_PI * ax * ay) * sqrt(cos_i / cos_o);
        }
    }
    return widened.factor * value * ndf_shadow_terminator(star, g, wi);
}

// Lobe `j` of the pixel's normals (normal_map.wgsl), as seen from `wo` (ndf_seen_from), lit
// from `d`, its concentration taken as `kappa`: its weight times material m's lobe through it
// (sun_lobe_through).
fn sun_ndf_lobe(ndf: ptr<function, SurfaceNdf>, j: i32, m: u32, kappa: f32, g: vec3<f32>, tangent: vec3<f32>, d: vec3<f32>, wo: vec3<f32>) -> f32 {
    let lobe = (*ndf).lobes[j];
    if (lobe.w <= 0.0) {
        return 0.0;
    }
    let material = sun.lobes[m];
    var widened = ndf_widened_lobe(material, kappa);
    var frame = tangent;
    var concentration = kappa;
    // The SH NDF's anisotropic spread widens an isotropic GGX or Ward lobe along its axes, each by
    // its own variance (Lobe::widened per axis), plus whatever `kappa` adds to the lobe's own
    // concentration (the sun disc's spread). One call below for both (two call sites of the
    // lobe's evaluation cost lavapipe a fifth of the frame, even where this branch is not taken).
    let spread = (*ndf).spread;
    if (spread.x > 0.0 && (material.model == 3u || material.model == 4u) && material.sharpness == material.alpha_y) {
        let extra = max(1.0 / kappa - 1.0 / (*ndf).kappas[j], 0.0);
        let along = spread.x + extra;
        let across = spread.y + extra;
        widened = ndf_widened_axes(material, along, across);
        concentration = 2.0 / (along + across);
        // A flipped part's axis is mirrored with it (n -> 2(n.g)g - n).
        frame = (*ndf).axis;
        if (((*ndf).flipped & (1u << u32(j))) != 0u) {
            frame = 2.0 * dot(frame, g) * g - frame;
        }
    }
    return lobe.w * sun_lobe_through(material, widened, concentration, (*ndf).fitted, lobe.xyz, g, frame, d, wo);
}

// Light reflected towards `wo` (unit, to the viewer) at `p` (normal `n`, tangent `tangent`)
// from the sun: per direction, the shadow test times the cosine times Lambert `kd` plus
// material `m`'s lobe (nodes/src/brdf.rs `Brdf::eval`).
// Through a normal map (`ndf`, normal_map.wgsl, its lobes as the view sees them: ndf_seen_from),
// Lambert over the NDF and the lobe per lobe of normals, widened.
fn sun_direct(p: vec3<f32>, n: vec3<f32>, tangent: vec3<f32>, wo: vec3<f32>, kd: vec3<f32>, m: u32, ndf: ptr<function, SurfaceNdf>) -> vec3<f32> {
    let count = i32(sun.direction_count);
    if (count == 0) {
        return vec3<f32>(0.0);
    }
    let shifted = vec4<f32>(p + n * sun.normal_offset, 1.0);
    let colour = sun.lobes[m].colour;
    // Phong, Blinn-Phong and Ward are weighted by f0; GGX's Schlick term is not zero at f0 = 0.
    let model = sun.lobes[m].model;
    let glossy = model > 0u && (model == 3u || sun.lobes[m].reflectance > 0.0) && max(colour.r, max(colour.g, colour.b)) > 0.0;
    // The rim directions first: where they all agree (all wholly lit or all wholly shadowed),
    // the disc does up to the segment between two of them, and the other maps need not be read
    // (outside penumbrae, nearly everywhere). Without rim directions every direction is read.
    var probes = i32(sun.rim_directions);
    if (probes == 0) {
        probes = count;
    }
    var probe_sum = 0.0;
    for (var j = 0; j < probes; j = j + 1) {
        probe_sum = probe_sum + sun_visibility(count - 1 - j, shifted);
    }
    if (probe_sum == 0.0) {
        return vec3<f32>(0.0);
    }
    let lit = probe_sum == f32(probes);
    // A wholly lit disc wholly above the horizon: the cap's mean cosine is exact,
    // (n . axis)(1 + cos r)/2, and only a lobe needs the directions.
    let cos_axis = dot(n, sun.axis);
    let cos_r = sun.cos_radius;
    let above = cos_axis * cos_axis >= 1.0 - cos_r * cos_r && cos_axis > 0.0;
    if (lit && above && !glossy) {
        var cosine = cos_axis;
        if (ndf_mapped(ndf)) {
            cosine = ndf_direct_diffuse(ndf, sun.axis);
        }
        return kd * (cosine * (1.0 + cos_r) * 0.5 * f32(count)) * sun.irradiance;
    }
    // Through a normal map, wholly lit: the diffuse light by the cap's closed form, and each lobe
    // of normals whose highlight spreads well past the disc (its normals' variance 1/κ and the
    // material lobe's own over four times the disc's half-vector variance r²/16) evaluated once,
    // at the axis, widened by the disc as well; sharper lobes, and a single normal (a flat map,
    // averaged normals: drawn as without a map), take every direction.
    if (lit && above && ndf_mapped(ndf)) {
        let r2 = max(1.0 - cos_r * cos_r, 0.0);
        let own = sun_lobe_variance(sun.lobes[m]);
        var lobes = 0.0;
        for (var j = 0; j < (*ndf).count; j = j + 1) {
            let kappa = (*ndf).kappas[j];
            if (kappa < NDF_SINGLE_NORMAL && 1.0 / kappa + own > r2 * 0.25) {
                let wide = 1.0 / (1.0 / kappa + r2 / 16.0);
                lobes = lobes + f32(count) * sun_ndf_lobe(ndf, j, m, wide, n, tangent, sun.axis, wo);
            } else {
                for (var k = 0; k < count; k = k + 1) {
                    let d = sun.directions[k];
                    if (dot(n, d) > 0.0) {
                        lobes = lobes + sun_ndf_lobe(ndf, j, m, kappa, n, tangent, d, wo);
                    }
                }
            }
        }
        let diffuse = kd * (ndf_direct_diffuse(ndf, sun.axis) * (1.0 + cos_r) * 0.5 * f32(count));
        return (diffuse + colour * lobes) * sun.irradiance;
    }
    var sum = vec3<f32>(0.0);
    for (var k = 0; k < count; k = k + 1) {
        let d = sun.directions[k];
        let cos_i = dot(n, d);
        if (cos_i <= 0.0) {
            continue;
        }
        var visible = 1.0;
        if (!lit) {
            visible = sun_visibility(k, shifted);
        }
        var reflected = kd * cos_i;
        if (ndf_mapped(ndf)) {
            reflected = kd * ndf_direct_diffuse(ndf, d);
            if (glossy) {
                var lobes = 0.0;
                for (var j = 0; j < (*ndf).count; j = j + 1) {
                    lobes = lobes + sun_ndf_lobe(ndf, j, m, (*ndf).kappas[j], n, tangent, d, wo);
                }
                reflected = reflected + colour * lobes;
            }
        } else if (glossy) {
            reflected = reflected + colour * sun_lobe(m, n, tangent, d, wo) * cos_i;
        }
        sum = sum + visible * reflected;
    }
    return sum * sun.irradiance;
}
