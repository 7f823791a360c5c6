// Normal maps filtered by their texels' normal distribution (group 4, render/src/passes/
// normal_map.rs; Sun 2008 §5.1, Han et al. 2007). The GPU twins of nodes/src/normal_filtering
// (moments.rs) and nodes/src/brdf.rs `Lobe::widened`: each pixel samples its footprint's NDF
// moments E[n], E[n n^T] trilinearly and anisotropically (averages of NDFs are NDFs), turns them
// into the world by the surface frame, and shades diffuse light with them and highlights
// through one or more vMF lobes of normals.

#define_import_path lightloom::normal_map

#import lightloom::common::{SpecularLobe, frame_tangent, sh_walk, sh_walk_next}

// Whether pixels shade through normal maps at all: each pipeline is composed with it set
// (render/src/shaders.rs), false for frames without a mapped material.
const NORMAL_MAPS: bool = #{NORMAL_MAPS};

// The lobe budget of a pixel's NDF: the up to 48 lobes of two vMF levels' four texels each are
// merged by moment matching into at most this many (ndf_insert_lobe).
const NDF_MAX_LOBES: i32 = 12;
const NDF_MATERIALS: i32 = 8;
const NDF_LEVELS: i32 = 12;
const NDF_MAX_KAPPA: f32 = 1.0e6;
// Lobes of normals at least this concentrated (within about 0.2°) are a single normal.
const NDF_SINGLE_NORMAL: f32 = 1.0e5;

// A material's normal map.
struct NormalMapMaterial {
    // 0 no map, 1 SH NDF, 2 vMF mixture, 3 Toksvig, 4 averaged normals.
    filter_kind: u32,
    // Repeats per unit of UV.
    tiling: f32,
    // How many vMF levels were fitted.
    fitted_levels: u32,
    // Its texture layer.
    layer: u32,
};

// One fitted vMF level of a material's map: its first lobe, its texels across and down, the
// map texels per texel side and its lobes per texel.
struct VmfLevel {
    first: u32,
    width: u32,
    height: u32,
    texel_span: u32,
    // Lobes per texel: 6, or up to 12 at a coarse level whose fits pay for more (nodes
    // normal_filtering::vmf_pyramid).
    count: u32,
    // A uniform array's elements are 16-byte aligned.
    pad_a: u32,
    pad_b: u32,
    pad_c: u32,
};

// A material's equivalent Phong lobe for the per-vertex environment highlight.
struct HighlightLobe {
    weight: vec3<f32>,
    // 0 without a glossy lobe, else 1 + its shape in `reflected_lobe` (0 GGX, 1 Blinn-Phong, 2 Phong).
    glossy: u32,
    // The GGX α of its equivalent Phong exponent.
    alpha: f32,
};

struct NormalMaps {
    materials: array<NormalMapMaterial, 8>,
    // 1 when the mode's per-vertex diffuse light is scaled per pixel by `irradiance` filtered
    // over unfiltered.
    scale_vertex_diffuse: u32,
    // 1 when the mode's per-vertex environment highlight is corrected per pixel (the fields
    // `highlight_*`).
    vertex_highlights: u32,
    // E_lm to band 2 of the light the mode's diffuse transport carries.
    irradiance: array<vec3<f32>, 9>,
    // Per material and vMF level (material * 12 + level).
    vmf_levels: array<VmfLevel, 96>,
    // L_lm to band 7 of the unshadowed light the mode's per-vertex environment highlight
    // carries; per material its equivalent Phong lobe's factors f_l (four per vector, material
    // m: [2m, 2m + 1]) and weight.
    highlight_radiance: array<vec3<f32>, 64>,
    highlight_factors: array<vec4<f32>, 16>,
    highlight_lobes: array<HighlightLobe, 8>,
    // Roughness levels of `highlight_light` (0: none bound, H from the SH).
    highlight_cube_levels: u32,
    // The reflected lobe (nodes reflected_lobe::table): per shape (GGX, Blinn-Phong, Phong) and α row
    // of NDF_REFLECTED_MU view cosines, the directional albedo E, the turn t of the rays' mean
    // from the mirror direction towards the normal and their broadening b over normal incidence.
    reflected_lobe: array<vec4<f32>, 384>,
};

// The reflected-lobe table's view cosines μ = (i / 15)² and roughnesses α = (j / 7)².
const NDF_REFLECTED_MU: u32 = 16u;
const NDF_REFLECTED_ALPHA: u32 = 8u;

const NDF_HIGHLIGHT_BANDS: i32 = 8;

@group(4) @binding(0) var<uniform> normal_maps: NormalMaps;
@group(4) @binding(1) var normal_moments_a: texture_2d_array<f32>;
@group(4) @binding(2) var normal_moments_b: texture_2d_array<f32>;
@group(4) @binding(3) var normal_sampler: sampler;
// The vMF lobes, `NDF_LOBE_ROW` to a row (a texture, not a storage buffer: the wavelet pass's
// fragment stage has none to spare).
@group(4) @binding(4) var normal_lobes: texture_2d<f32>;
// The same unshadowed light as `highlight_radiance`, GGX-prefiltered (nodes specular_cube): mip
// m of M holds perceptual roughness m / (M - 1), GGX α its square.
@group(4) @binding(5) var highlight_light: texture_cube<f32>;
// Trilinear, no anisotropy: the levels are read at an explicit level of detail.
@group(4) @binding(6) var highlight_sampler: sampler;

const NDF_LOBE_ROW: u32 = 4096u;

fn ndf_lobe_at(i: u32) -> vec4<f32> {
    return textureLoad(normal_lobes, vec2<u32>(i % NDF_LOBE_ROW, i / NDF_LOBE_ROW), 0);
}

// What a pixel shades with: its NDF in the world frame.
struct SurfaceNdf {
    // The filter (as NormalMaps.materials.x; 0: no map, the geometric normal alone).
    method: i32,
    // Unit shading normal: the NDF's mean direction.
    normal: vec3<f32>,
    // E[n] and E[n n^T].
    mean: vec3<f32>,
    second: mat3x3<f32>,
    // Toksvig's concentration from |E[n]|.
    kappa: f32,
    // The SH NDF's spread about its mean direction, from its band 2 (the second moments): the
    // variances of the normals' tangential components along `axis` (the wider) and across it
    // (0 for the other filters, which take the lobes' concentrations alone).
    spread: vec2<f32>,
    axis: vec3<f32>,
    // Bit j set where lobe j is a flipped part (ndf_seen_from): its spread axis is mirrored too.
    flipped: u32,
    // Whether the lobes are as the view sees them already (ndf_seen_from ran).
    seen: bool,
    // Whether the lobes are a fitted vMF mixture's (method 2 with its levels fitted; until they
    // are, Toksvig's single lobe stands in).
    fitted: bool,
    // The highlight's lobes of normals: xyz unit mean, w weight; and their concentrations.
    count: i32,
    lobes: array<vec4<f32>, 12>,
    kappas: array<f32, 12>,
};

// Whether the pixel shades through a normal map. `NORMAL_MAPS` is a shader def each pipeline
// is composed with (render/src/shaders.rs): frames without a mapped material draw with it false, and
// every normal-map path folds away (the pixel's lobes are then never read, nor initialised).
fn ndf_mapped(ndf: ptr<function, SurfaceNdf>) -> bool {
    return NORMAL_MAPS && (*ndf).method != 0;
}

// Banerjee et al.'s κ for a mean resultant length r (nodes Vmf::kappa_from_mean_length).
fn ndf_kappa(r: f32) -> f32 {
    let c = clamp(r, 0.0, 1.0);
    if (c >= 0.999999) {
        return NDF_MAX_KAPPA;
    }
    return min((3.0 * c - c * c * c) / (1.0 - c * c), NDF_MAX_KAPPA);
}

// Sets `ndf` to the NDF of a flat surface: a delta at `n` (its lobe arrays past the first
// are left as they are: `count` says how many hold lobes).
fn ndf_set_flat(ndf: ptr<function, SurfaceNdf>, n: vec3<f32>) {
    (*ndf).method = 0;
    (*ndf).normal = n;
    (*ndf).mean = n;
    (*ndf).second = mat3x3<f32>(n * n.x, n * n.y, n * n.z);
    (*ndf).kappa = NDF_MAX_KAPPA;
    (*ndf).spread = vec2<f32>(0.0);
    (*ndf).axis = vec3<f32>(0.0);
    (*ndf).flipped = 0u;
    (*ndf).seen = false;
    (*ndf).fitted = false;
    (*ndf).count = 1;
    (*ndf).lobes[0] = vec4<f32>(n, 1.0);
    (*ndf).kappas[0] = NDF_MAX_KAPPA;
}

// The vMF lobes of material m's fitted level `level` about `uv`, bilinear between the four
// nearest texels' sets (the map repeating), turned by `frame`, weighted by `share`, appended to
// `ndf` (lobes under 0.1% of the pixel's NDF are dropped).
fn ndf_add_level(ndf: ptr<function, SurfaceNdf>, m: u32, level: i32, uv: vec2<f32>, map_size: vec2<f32>, frame: mat3x3<f32>, share: f32) {
    let info = normal_maps.vmf_levels[i32(m) * NDF_LEVELS + level];
    let size = vec2<i32>(i32(info.width), i32(info.height));
    let at = fract(uv) * map_size / f32(info.texel_span) - 0.5;
    let corner = vec2<i32>(floor(at));
    let f = at - floor(at);
    for (var k = 0; k < 4; k = k + 1) {
        let offset = vec2<i32>(k & 1, k >> 1u);
        let texel = ((corner + offset) % size + size) % size;
        let bilinear = select(1.0 - f.x, f.x, offset.x == 1) * select(1.0 - f.y, f.y, offset.y == 1);
        let first = info.first + u32(texel.y * size.x + texel.x) * info.count;
        for (var j = 0u; j < info.count; j = j + 1u) {
            let lobe = ndf_lobe_at(first + j);
            let weight = lobe.w * bilinear * share;
            let kappa = length(lobe.xyz);
            if (weight <= 1e-3 || kappa <= 0.0) {
                continue;
            }
            ndf_insert_lobe(ndf, normalize(frame * (lobe.xyz / kappa)), weight, kappa);
        }
    }
}

// The mean resultant length A(κ) = coth κ - 1/κ of a vMF lobe of concentration κ.
fn ndf_mean_length(kappa: f32) -> f32 {
    if (kappa < 1e-3) {
        return kappa / 3.0;
    }
    if (kappa > 20.0) {
        return 1.0 - 1.0 / kappa;
    }
    return 1.0 / tanh(kappa) - 1.0 / kappa;
}

// Adds a vMF lobe (unit mean `mu`, weight, κ) to the pixel's mixture. Where it lies within the
// spread of the nearest lobe (squared angle under the sum of their variances 1/κ), or the
// budget is spent, the two merge by moment matching: the weighted mean of their mean resultant
// vectors A(κ) μ gives the direction, and its length, through Banerjee's κ, the concentration
// (two equal lobes merge into themselves).
fn ndf_insert_lobe(ndf: ptr<function, SurfaceNdf>, mu: vec3<f32>, weight: f32, kappa: f32) {
    var nearest = -1;
    var best = -2.0;
    for (var i = 0; i < (*ndf).count; i = i + 1) {
        let c = dot((*ndf).lobes[i].xyz, mu);
        if (c > best) {
            best = c;
            nearest = i;
        }
    }
    let close = nearest >= 0 && 2.0 * (1.0 - best) < 1.0 / (*ndf).kappas[nearest] + 1.0 / kappa;
    if (nearest < 0 || (!close && (*ndf).count < NDF_MAX_LOBES)) {
        (*ndf).lobes[(*ndf).count] = vec4<f32>(mu, weight);
        (*ndf).kappas[(*ndf).count] = kappa;
        (*ndf).count = (*ndf).count + 1;
        return;
    }
    let held = (*ndf).lobes[nearest];
    let total = held.w + weight;
    let resultant = (held.w * ndf_mean_length((*ndf).kappas[nearest]) * held.xyz + weight * ndf_mean_length(kappa) * mu) / total;
    let r = length(resultant);
    (*ndf).lobes[nearest] = vec4<f32>(select(held.xyz, resultant / r, r > 1e-12), total);
    (*ndf).kappas[nearest] = ndf_kappa(r);
}

// Sets `ndf` to the NDF of material m's normal map over this pixel's footprint at `uv`, on
// the surface of unit normal `n` and tangent `tangent.xyz` (the frame [t, w n x t, n]: the
// tangent of common.wgsl, and the bitangent on the side the sign of `tangent.w`, the vertex's
// handedness, says); without a map, a delta at `n`. Call it where control flow is uniform: it takes
// the UV's screen derivatives (the maps are then read only where a material has one).
fn surface_ndf(ndf: ptr<function, SurfaceNdf>, m: u32, uv_in: vec2<f32>, n: vec3<f32>, tangent: vec4<f32>) {
    let settings = normal_maps.materials[m];
    let uv = uv_in * settings.tiling;
    let du = dpdx(uv);
    let dv = dpdy(uv);
    let method = i32(settings.filter_kind);
    ndf_set_flat(ndf, n);
    // A mesh without texture coordinates has 2 as its handedness (nodes
    // mesh::NO_TEXTURE_COORDINATES; interpolated signs stay within ±1): no map applies to it.
    if (!NORMAL_MAPS || method == 0 || tangent.w > 1.5) {
        return;
    }
    let layer = i32(settings.layer);
    let a = textureSampleGrad(normal_moments_a, normal_sampler, uv, layer, du, dv);
    let b = textureSampleGrad(normal_moments_b, normal_sampler, uv, layer, du, dv);
    let t = frame_tangent(n, tangent.xyz);
    let frame = mat3x3<f32>(t, cross(n, t) * select(1.0, -1.0, tangent.w < 0.0), n);
    let mean = frame * a.xyz;
    let zz = 1.0 - a.w - b.x;
    let second_t = mat3x3<f32>(vec3<f32>(a.w, b.y, b.z), vec3<f32>(b.y, b.x, b.w), vec3<f32>(b.z, b.w, zz));
    ndf_set_flat(ndf, normalize(select(n, mean, dot(mean, mean) > 1e-12)));
    (*ndf).method = method;
    if (method == 4) {
        return;
    }
    (*ndf).mean = mean;
    (*ndf).second = frame * second_t * transpose(frame);
    (*ndf).kappa = ndf_kappa(length(a.xyz));
    (*ndf).kappas[0] = (*ndf).kappa;
    if (method == 1) {
        ndf_set_spread(ndf, t);
    }
    let levels = i32(settings.fitted_levels);
    if (method != 2 || levels == 0) {
        return;
    }
    // vMF lobes: the two fitted levels about the footprint's (the side of its area), each
    // bilinear between texels, blended.
    let map_size = vec2<f32>(textureDimensions(normal_moments_a).xy);
    let footprint = sqrt(length(du * map_size) * length(dv * map_size));
    let lod = clamp(log2(max(footprint, 1e-6)), 0.0, f32(levels - 1));
    let low = i32(floor(lod));
    let share = lod - f32(low);
    (*ndf).count = 0;
    (*ndf).fitted = true;
    ndf_add_level(ndf, m, low, uv, map_size, frame, 1.0 - share);
    if (low + 1 < levels && share > 0.0) {
        ndf_add_level(ndf, m, low + 1, uv, map_size, frame, share);
    }
}

// The SH NDF's own lobe (method 1): its band 2, the second moments E[n n^T], give the covariance
// of the normals' components across the mean direction, whose eigenvalues are the variances
// along its principal axes (LEAN mapping's anisotropic lobe, Olano and Baker 2010, on unit
// normals). Toksvig's single concentration sees only their sum, from |E[n]|: a ribbed map
// spreads its normals along one axis alone, which one concentration widens both ways. The
// lobe's concentration for what takes one is 2 over their sum (a vMF's κ has 1/κ per axis).
// `t` is a unit tangent.
fn ndf_set_spread(ndf: ptr<function, SurfaceNdf>, t_in: vec3<f32>) {
    let mu = (*ndf).normal;
    let t = normalize(t_in - mu * dot(mu, t_in));
    let b = cross(mu, t);
    let s = (*ndf).second;
    let a = dot(t, s * t);
    let c = dot(b, s * b);
    let ab = dot(t, s * b);
    let half_gap = sqrt(max(0.25 * (a - c) * (a - c) + ab * ab, 0.0));
    let wide = max(0.5 * (a + c) + half_gap, 0.0);
    let narrow = max(0.5 * (a + c) - half_gap, 0.0);
    if (wide <= 1e-7) {
        return;
    }
    var along = select(vec2<f32>(0.0, 1.0), vec2<f32>(1.0, 0.0), a >= c);
    if (abs(ab) > 1e-9) {
        along = normalize(vec2<f32>(wide - c, ab));
    }
    (*ndf).spread = vec2<f32>(wide, narrow);
    (*ndf).axis = along.x * t + along.y * b;
    (*ndf).kappas[0] = min(2.0 / (wide + narrow), NDF_MAX_KAPPA);
}

// E[Y_lm(n)] for l <= 2 (nodes NdfMoments::sh; Toksvig: Y_lm at the mean direction attenuated
// by e^{-l(l+1)/2κ}), in the order of common.wgsl's basis.
fn ndf_sh9(ndf: ptr<function, SurfaceNdf>) -> array<f32, 9> {
    if ((*ndf).method == 3) {
        return ndf_sh9_about((*ndf).normal, exp(-1.0 / (*ndf).kappa), exp(-3.0 / (*ndf).kappa));
    }
    var y: array<f32, 9>;
    let m = (*ndf).mean;
    let s = (*ndf).second;
    y[0] = 0.2820948;
    y[1] = 0.4886025 * m.y;
    y[2] = 0.4886025 * m.z;
    y[3] = 0.4886025 * m.x;
    y[4] = 1.0925484 * s[1].x;
    y[5] = 1.0925484 * s[2].y;
    y[6] = 0.3153916 * (2.0 * s[2].z - s[0].x - s[1].y);
    y[7] = 1.0925484 * s[2].x;
    y[8] = 0.5462742 * (s[0].x - s[1].y);
    return y;
}

// Y_lm(d) for l <= 2, band 1 scaled by a1 and band 2 by a2 (1 and 1: a delta at unit d).
fn ndf_sh9_about(d: vec3<f32>, a1: f32, a2: f32) -> array<f32, 9> {
    return array<f32, 9>(
        0.2820948,
        0.4886025 * d.y * a1,
        0.4886025 * d.z * a1,
        0.4886025 * d.x * a1,
        1.0925484 * d.x * d.y * a2,
        1.0925484 * d.y * d.z * a2,
        0.3153916 * (3.0 * d.z * d.z - 1.0) * a2,
        1.0925484 * d.x * d.z * a2,
        0.5462742 * (d.x * d.x - d.y * d.y) * a2);
}

// The attenuation of SH band l > 2 under the NDF (Toksvig's lobe; 1 without a map).
fn ndf_band_attenuation(ndf: ptr<function, SurfaceNdf>, l: i32) -> f32 {
    if ((*ndf).method == 0 || (*ndf).kappa >= NDF_MAX_KAPPA) {
        return 1.0;
    }
    return exp(-f32(l * (l + 1)) / (2.0 * (*ndf).kappa));
}

// E[max(0, n.l)] over the NDF (nodes NdfMoments::direct_diffuse): n.l taken as Gaussian of the
// moments' mean and variance; the averaged normal alone for Toksvig and averaged normals.
fn ndf_direct_diffuse(ndf: ptr<function, SurfaceNdf>, l: vec3<f32>) -> f32 {
    if ((*ndf).method == 0 || (*ndf).method == 4) {
        return max(dot((*ndf).normal, l), 0.0);
    }
    let mu = dot((*ndf).mean, l);
    if ((*ndf).method == 3) {
        return max(mu, 0.0);
    }
    let sigma = sqrt(max(dot(l, (*ndf).second * l) - mu * mu, 0.0));
    if (sigma < 1e-6) {
        return max(mu, 0.0);
    }
    let t = mu / sigma;
    return mu * ndf_normal_cdf(t) + sigma * exp(-0.5 * t * t) * 0.39894228;
}

// Φ(t), the standard normal distribution, by Abramowitz-Stegun 7.1.26 (nodes normal_cdf).
fn ndf_normal_cdf(t: f32) -> f32 {
    let x = abs(t) * 0.70710678;
    let k = 1.0 / (1.0 + 0.3275911 * x);
    let erfc = k * (0.254829592 + k * (-0.284496736 + k * (1.421413741 + k * (-1.453152027 + k * 1.061405429)))) * exp(-x * x);
    return select(0.5 * erfc, 1.0 - 0.5 * erfc, t >= 0.0);
}

// The two parts of a lobe of normals (unit mean `mu`, concentration `kappa`) on a surface of
// unperturbed normal `g`, seen from `wo`, as the reference shades it (nodes/src/reference.rs,
// after Mitsuba 3's `normalmap`): `above`, the normals the view lies above, and `below`, those it
// lies below, flipped (their tangential part mirrored: n -> 2(n.g)g - n). Each holds the part's
// mean (xyz) and its share of the lobe (w; 0 for none). `n.wo` over the lobe is taken as
// Gaussian, of mean `mu.wo` and variance `(1 - (mu.wo)^2)/kappa`; each part's mean is the lobe's
// moved towards or away from `wo` to the truncated Gaussian's mean. At grazing views much of a
// bumpy map lies below the view: drawing those normals black loses its light.
struct SeenParts {
    above: vec4<f32>,
    below: vec4<f32>,
};

fn ndf_seen_parts(mu: vec3<f32>, kappa: f32, g: vec3<f32>, wo: vec3<f32>) -> SeenParts {
    let m = dot(mu, wo);
    let across = sqrt(max(1.0 - m * m, 0.0));
    let sigma = across / sqrt(max(kappa, 1e-9));
    let flip = 2.0 * dot(mu, g) * g - mu;
    if (sigma <= 1e-6 || across <= 1e-6 || kappa >= NDF_SINGLE_NORMAL) {
        // A single normal: wholly above the view or wholly below it.
        return SeenParts(vec4<f32>(mu, select(0.0, 1.0, m > 0.0)), vec4<f32>(flip, select(0.0, 1.0, m <= 0.0)));
    }
    let z = m / sigma;
    let below = 1.0 - ndf_normal_cdf(z);
    // The truncated Gaussian's means of n.wo, as angles towards wo.
    let density = sigma * exp(-0.5 * z * z) * 0.39894228;
    let towards = wo - m * mu;
    var parts = SeenParts(vec4<f32>(mu, 0.0), vec4<f32>(flip, 0.0));
    if (1.0 - below >= 1e-4) {
        parts.above = vec4<f32>(normalize(mu + towards / across * (density / (1.0 - below) / across)), 1.0 - below);
    }
    if (below >= 1e-4) {
        let mean = normalize(mu - towards / across * (density / below / across));
        parts.below = vec4<f32>(2.0 * dot(mean, g) * g - mean, below);
    }
    return parts;
}

// Rewrites the pixel's lobes of normals as the view from `wo` sees them on a surface of
// unperturbed normal `g` (ndf_seen_parts): each lobe becomes its part above the view (or, wholly
// below it, its flipped self), and the flipped parts of lobes the view splits are then added as
// lobes of their own, merged into the nearest (ndf_insert_lobe) only once the budget is spent.
// Once a pixel, before lights loop over the lobes (later calls do nothing).
fn ndf_seen_from(ndf: ptr<function, SurfaceNdf>, g: vec3<f32>, wo: vec3<f32>) {
    if ((*ndf).seen) {
        return;
    }
    (*ndf).seen = true;
    let count = (*ndf).count;
    var flipped: array<vec4<f32>, 12>;
    var flipped_kappa: array<f32, 12>;
    for (var j = 0; j < count; j = j + 1) {
        let lobe = (*ndf).lobes[j];
        let kappa = (*ndf).kappas[j];
        let parts = ndf_seen_parts(lobe.xyz, kappa, g, wo);
        let above = parts.above;
        let below = parts.below;
        flipped[j] = vec4<f32>(below.xyz, 0.0);
        flipped_kappa[j] = kappa;
        if (above.w <= 0.0) {
            (*ndf).lobes[j] = vec4<f32>(below.xyz, lobe.w * below.w);
            (*ndf).flipped = (*ndf).flipped | (1u << u32(j));
        } else {
            (*ndf).lobes[j] = vec4<f32>(above.xyz, lobe.w * above.w);
            flipped[j].w = lobe.w * below.w;
        }
    }
    // Added only once every lobe is split, so no flipped part merges into a lobe still to split;
    // as lobes of their own while the budget lasts (merging a part into the lobe it was split
    // from wherever they overlap would switch the picture between the two at some distance).
    for (var j = 0; j < count; j = j + 1) {
        if (flipped[j].w <= 0.0) {
            continue;
        }
        let slot = (*ndf).count;
        if (slot < NDF_MAX_LOBES) {
            (*ndf).lobes[slot] = flipped[j];
            (*ndf).kappas[slot] = flipped_kappa[j];
            (*ndf).flipped = (*ndf).flipped | (1u << u32(slot));
            (*ndf).count = slot + 1;
        } else {
            ndf_insert_lobe(ndf, flipped[j].xyz, flipped[j].w, flipped_kappa[j]);
        }
    }
}

// The shadow terminator's weight (nodes/src/reference.rs `Hit::shadow_terminator`, after Estevez
// et al. 2019) for light along `wi` on a surface of unperturbed normal `g` shading with the
// perturbed normal `n`: 2/(1 + sqrt(1 + α² tan²θ_i)), θ_i from g, α² = min(tan²θ_n/8, 1).
fn ndf_shadow_terminator(n: vec3<f32>, g: vec3<f32>, wi: vec3<f32>) -> f32 {
    let c = dot(n, g);
    let c2 = max(c * c, 1e-12);
    let a2 = min((1.0 - c2) / c2 / 8.0, 1.0);
    if (a2 <= 0.0) {
        return 1.0;
    }
    let ci = dot(g, wi);
    let ci2 = max(ci * ci, 1e-12);
    return 2.0 / (1.0 + sqrt(1.0 + a2 * max((1.0 - ci2) / ci2, 0.0)));
}

// A specular lobe seen through a vMF lobe of normals of concentration kappa, and the factor its
// values take (nodes Lobe::widened).
struct WidenedLobe {
    lobe: SpecularLobe,
    factor: f32,
};

fn ndf_widened_lobe(lobe: SpecularLobe, kappa: f32) -> WidenedLobe {
    var out = WidenedLobe(lobe, 1.0);
    if (kappa >= NDF_MAX_KAPPA) {
        return out;
    }
    let k = max(kappa, 1e-9);
    if (lobe.model == 1u || lobe.model == 2u) {
        let seen = select(k, k / 4.0, lobe.model == 1u);
        let c = select(8.0, 2.0, lobe.model == 1u);
        let s = lobe.sharpness;
        let w = seen * s / (seen + s);
        out.lobe.sharpness = w;
        out.factor = (s + c) * (w + 1.0) / ((s + 1.0) * (w + c));
    } else if (lobe.model == 3u || lobe.model == 4u) {
        out = ndf_widened_axes(lobe, 1.0 / k, 1.0 / k);
    }
    return out;
}

// A GGX or Ward lobe seen through normals whose tangential components vary by `along` along its
// tangent and `across` along its bitangent: each α² grows by twice its axis's variance (a vMF
// lobe of κ has 1/κ on both; the SH NDF's own lobe, ndf_set_spread, its principal variances).
fn ndf_widened_axes(lobe: SpecularLobe, along: f32, across: f32) -> WidenedLobe {
    var out = WidenedLobe(lobe, 1.0);
    out.lobe.sharpness = sqrt(lobe.sharpness * lobe.sharpness + 2.0 * along);
    out.lobe.alpha_y = sqrt(lobe.alpha_y * lobe.alpha_y + 2.0 * across);
    return out;
}

// The per-pixel factor on a mode's per-vertex diffuse light: the transported light's irradiance
// averaged over the NDF over the same at the geometric normal `n` (1 without a map).
fn ndf_vertex_diffuse_scale(ndf: ptr<function, SurfaceNdf>, n: vec3<f32>) -> vec3<f32> {
    if (!ndf_mapped(ndf) || normal_maps.scale_vertex_diffuse == 0u) {
        return vec3<f32>(1.0);
    }
    let filtered_basis = ndf_sh9(ndf);
    let flat_basis = ndf_sh9_about(n, 1.0, 1.0);
    var filtered = vec3<f32>(0.0);
    var unfiltered = vec3<f32>(0.0);
    for (var k = 0; k < 9; k = k + 1) {
        filtered = filtered + normal_maps.irradiance[k] * filtered_basis[k];
        unfiltered = unfiltered + normal_maps.irradiance[k] * flat_basis[k];
    }
    let floor_value = 1e-4 * max(normal_maps.irradiance[0].r, max(normal_maps.irradiance[0].g, normal_maps.irradiance[0].b));
    return select(vec3<f32>(1.0), max(filtered, vec3<f32>(0.0)) / max(unfiltered, vec3<f32>(floor_value)), unfiltered > vec3<f32>(floor_value));
}

// How open a vertex is to the light its mode transports: its irradiance `e` over the
// unshadowed irradiance at its unit normal `n`, per channel in [0, 1] (1 where that is dark,
// and without maps).
fn ndf_open_fraction(e: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    if (!NORMAL_MAPS || normal_maps.vertex_highlights == 0u) {
        return vec3<f32>(1.0);
    }
    let basis = ndf_sh9_about(n, 1.0, 1.0);
    var open = vec3<f32>(0.0);
    for (var k = 0; k < 9; k = k + 1) {
        open = open + normal_maps.irradiance[k] * basis[k];
    }
    let floor_value = 1e-4 * max(normal_maps.irradiance[0].r, max(normal_maps.irradiance[0].g, normal_maps.irradiance[0].b));
    return select(vec3<f32>(1.0), clamp(e / max(open, vec3<f32>(floor_value)), vec3<f32>(0.0), vec3<f32>(1.0)), open > vec3<f32>(floor_value));
}

// sum_lm f_l e^{-2 l(l+1)/kappa} L_lm Y_lm(r): material m's lobe about the mirror direction `r`
// seen through a vMF lobe of normals of concentration kappa (the mirror direction spreads as a
// vMF of kappa/4, whose band-l factor is e^{-l(l+1)/(2 kappa/4)}), on the highlight's light.
fn ndf_highlight_sum(r: vec3<f32>, m: u32, kappa: f32) -> vec3<f32> {
    var sum = vec3<f32>(0.0);
    var walk = sh_walk(r, NDF_HIGHLIGHT_BANDS);
    while (sh_walk_next(&walk)) {
        let l = walk.l;
        let f = normal_maps.highlight_factors[2u * m + u32(l / 4)][l % 4] * exp(-2.0 * f32(l * (l + 1)) / kappa);
        let base = l * (l + 1);
        sum = sum + f * walk.cos_y * normal_maps.highlight_radiance[base + walk.m];
        if (walk.m > 0) {
            sum = sum + f * walk.sin_y * normal_maps.highlight_radiance[base - walk.m];
        }
    }
    return sum;
}

// H of material m's lobe about the direction `r` through a vMF lobe of normals of concentration
// kappa, the lobe's weighted mean of the light (the albedo is E's, ndf_view_highlight): from the
// prefiltered light where it is bound, the lobe as the GGX lobe of α `widened` (the material's,
// widened by the normals' spread); else the SH sum to band 7, through kappa, over the lobe's
// band-0 factor (its integral, (s + 2)/(s + 1) for Phong's cosˢ lobe: a uniform light's sum).
fn ndf_highlight(r: vec3<f32>, m: u32, kappa: f32, widened: f32) -> vec3<f32> {
    let levels = normal_maps.highlight_cube_levels;
    if (levels == 0u) {
        return ndf_highlight_sum(r, m, kappa) / max(normal_maps.highlight_factors[2u * m].x, 1e-6);
    }
    let lod = clamp(sqrt(widened) * f32(levels - 1u), 0.0, f32(levels - 1u));
    return textureSampleLevel(highlight_light, highlight_sampler, r, lod).rgb;
}

// (E, t, b) of the reflected lobe of `shape` (0 GGX, 1 Blinn-Phong, 2 Phong) at view cosine `mu` and
// roughness `alpha` (nodes reflected_lobe.rs), bilinear in √μ and √α.
fn ndf_reflected_lobe(shape: u32, mu: f32, alpha: f32) -> vec3<f32> {
    let x = clamp(sqrt(max(mu, 0.0)), 0.0, 1.0) * f32(NDF_REFLECTED_MU - 1u);
    let y = clamp(sqrt(max(alpha, 0.0)), 0.0, 1.0) * f32(NDF_REFLECTED_ALPHA - 1u);
    let i = min(u32(x), NDF_REFLECTED_MU - 2u);
    let j = min(u32(y), NDF_REFLECTED_ALPHA - 2u);
    let row = (shape * NDF_REFLECTED_ALPHA + j) * NDF_REFLECTED_MU + i;
    let low = mix(ndf_reflected_entry(row), ndf_reflected_entry(row + 1u), x - f32(i));
    let high = mix(ndf_reflected_entry(row + NDF_REFLECTED_MU), ndf_reflected_entry(row + NDF_REFLECTED_MU + 1u), x - f32(i));
    return mix(low, high, y - f32(j));
}

fn ndf_reflected_entry(k: u32) -> vec3<f32> {
    return normal_maps.reflected_lobe[k].xyz;
}

// The unshadowed light material m's lobe reflects towards `wo` off normals about `s` (spread
// by κ) on a surface of unperturbed normal `g`, as the reference shades it: E(μ_o) times H at
// the mean direction of the reflected rays (ndf_reflected_lobe: at grazing views the rays turn
// far above the mirror direction, where the split sum's lookup would read the horizon), through
// the lobe as wide as head-on (widening it by the rays' broadening, the table's b, made a
// grazing leaning map's far bands 2-5 points brighter against the reference), less the
// part of the lobe below g's horizon, which the reference draws black (the part below s's is E's
// already): the rays about the mirror direction taken as Gaussian in elevation, of deviation 2α.
fn ndf_view_highlight(s: vec3<f32>, g: vec3<f32>, wo: vec3<f32>, m: u32, kappa: f32) -> vec3<f32> {
    let alpha = normal_maps.highlight_lobes[m].alpha;
    let widened = sqrt(alpha * alpha + select(2.0 / max(kappa, 1e-6), 0.0, kappa >= NDF_MAX_KAPPA));
    let mu = clamp(dot(s, wo), 1e-4, 1.0);
    let r = 2.0 * mu * s - wo;
    let shape = min(max(normal_maps.highlight_lobes[m].glossy, 1u), 3u) - 1u;
    // Where the rays go, through the lobe widened by the normals' spread; their
    // albedo (masking) through the material's own roughness: the spread is no microgeometry.
    let lobe = ndf_reflected_lobe(shape, mu, widened);
    let albedo = ndf_reflected_lobe(shape, mu, alpha).x;
    // Only GGX's lookup turns: its long tail carries the light far above the mirror direction.
    // A short lobe's mean turns only where the horizon cuts it, and turning the lookup there
    // read a window's light off its edge.
    let toward = select(lobe.y, 0.0, shape != 0u);
    let across = r - dot(r, s) * s;
    let len = length(across);
    var d = s;
    if (len > 1e-6) {
        let turn = acos(clamp(dot(r, s), -1.0, 1.0)) * (1.0 - toward);
        d = s * cos(turn) + across / len * sin(turn);
    }
    let sigma = 2.0 * max(widened, 1e-3);
    let seen = ndf_normal_cdf(asin(clamp(dot(r, g), -1.0, 1.0)) / sigma) / max(ndf_normal_cdf(asin(mu) / sigma), 1e-6);
    return albedo * min(seen, 1.0) * ndf_highlight(d, m, kappa, widened);
}

// A per-vertex mode's environment highlight `glossy` (interpolated from the vertices) corrected
// for the pixel's NDF (nodes frame::VertexHighlight) as the view from `view` (unit, towards the
// eye) sees it (ndf_seen_from: the normals it lies below flipped), through the light each lobe
// reflects (ndf_view_highlight: prefiltered, or the SH to band 7): light the NDF turns away
// scales `glossy` by the lobes' sum over the same at the geometric normal `n`; light it turns
// in is added, material m's glossy weight times `open` (ndf_open_fraction at the vertices)
// times the difference. Never negative; `glossy` itself without a map or for a flat one. The
// lobes' light is in the material's own albedo (ndf_view_highlight), the true BRDF's, as the
// wavelet modes' vertices carry it; the SH modes' and `rsl`'s carry Phong's lobe and cosine, so
// there what a map turns in is added in the true BRDF's terms to a highlight in Phong's.
fn ndf_vertex_glossy(ndf: ptr<function, SurfaceNdf>, n: vec3<f32>, view: vec3<f32>, m: u32, open: vec3<f32>, glossy: vec3<f32>) -> vec3<f32> {
    let weight = normal_maps.highlight_lobes[m];
    if (!ndf_mapped(ndf) || normal_maps.vertex_highlights == 0u || weight.glossy == 0u) {
        return glossy;
    }
    ndf_seen_from(ndf, n, view);
    let unmapped = max(ndf_view_highlight(n, n, view, m, NDF_MAX_KAPPA), vec3<f32>(0.0));
    var mapped = vec3<f32>(0.0);
    for (var j = 0; j < (*ndf).count; j = j + 1) {
        let lobe = (*ndf).lobes[j];
        mapped = mapped + lobe.w * ndf_view_highlight(lobe.xyz, n, view, m, (*ndf).kappas[j]);
    }
    mapped = max(mapped, vec3<f32>(0.0));
    let kept = select(vec3<f32>(1.0), min(mapped / unmapped, vec3<f32>(1.0)), unmapped > vec3<f32>(1e-12));
    return max(glossy, vec3<f32>(0.0)) * kept + weight.weight * open * max(mapped - unmapped, vec3<f32>(0.0));
}

// Whether the SH modes draw their environment highlight from the prefiltered light (nodes
// frame::VertexHighlight, Mode::prefilters_highlight): it is bound and current.
fn ndf_prefiltered_highlight() -> bool {
    return NORMAL_MAPS && normal_maps.vertex_highlights != 0u && normal_maps.highlight_cube_levels > 0u;
}

// The environment highlight of material m at a pixel of unit normal `n` seen from `view`, as
// the reference shades it unshadowed (ndf_view_highlight: the lobe's albedo at the view, the
// prefiltered light where its rays go), times `open` (how open the vertices are to it: mesh_prt.wgsl highlight_open).
fn ndf_prefiltered_vertex_highlight(n: vec3<f32>, view: vec3<f32>, m: u32, open: vec3<f32>) -> vec3<f32> {
    let lobe = max(ndf_view_highlight(n, n, view, m, NDF_MAX_KAPPA), vec3<f32>(0.0));
    return normal_maps.highlight_lobes[m].weight * open * lobe;
}
