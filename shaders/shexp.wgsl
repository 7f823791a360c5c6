// Blocker-sphere visibility per receiver (Sun 2008 §5.2), one invocation per receiver,
// importing common.wgsl's SH basis. The CPU twin is nodes/src/sh_exponential.rs
// (BlockedProduct); render/src/shexp.rs packs the inputs.
//
// `visibility`, one invocation per receiver:
// 1. Log sum (Eq. 5.13): f = Σ_i strength · rotate(log-cap table(θ_i), direction_i) over the
//    spheres listed for the receiver's part that reach it.
// 2. Exponential: PS*-p (DC isolation, scaling and squaring, factored series; Eqs. 5.24–5.27)
//    or HYB (halving, OL, squaring back).
// `multiply`, one invocation per receiver and transport vector: the vector v becomes the
// truncated product v * g (Eq. 5.8).

#import lightloom::common::{PI, sh_basis}

const MAX_B: i32 = 36; // visibility coefficients: up to 6 bands
const MAX_T: i32 = 196; // transport coefficients: up to 14 bands
const SQRT_4PI: f32 = 3.5449077018110318;

struct ShexpParams {
    receivers: u32,
    bands_b: u32,
    bands_t: u32,
    vectors_per_receiver: u32,
    // 0: HYB; p > 0: PS*-p.
    series_degree: u32,
    table_entries: u32,
    ol_bins: u32,
    gaunt_bb_count: u32,
    gaunt_tb_count: u32,
    offset_blockers: u32,
    offset_parts: u32,
    offset_log: u32,
    offset_ol: u32,
    offset_gaunt_bb: u32,
    offset_gaunt_tb: u32,
    // Invocations per row of workgroups (dispatches wider than 65535 groups wrap to y).
    row_stride: u32,
    strength: f32,
    ol_max_norm: f32,
    ol_halving: f32,
    // sin of the smallest angular radius a sphere is kept at (its influence radius r / sin).
    min_sin: f32,
};

@group(0) @binding(0) var<uniform> params: ShexpParams;
// xyz: position; w: the receiver's part (bitcast u32).
@group(0) @binding(1) var<storage, read> receivers: array<vec4<f32>>;
// Packed words: spheres (centre, radius as f32 bits), part ranges (start, count) into the
// sphere index lists, the lists, the log table, OL's a and b, and the two Gaunt tables as
// (i | j << 10 | k << 20, coefficient bits) pairs.
@group(0) @binding(2) var<storage, read> words: array<u32>;
// Per receiver, VISIBILITY_STRIDE words: whether any sphere reaches it (0 none, 1 some), then g.
@group(0) @binding(3) var<storage, read_write> visibility: array<f32>;
// vectors_per_receiver arrays one after another, each bands_t² coefficients per receiver,
// multiplied in place.
@group(0) @binding(4) var<storage, read_write> vectors: array<f32>;

const VISIBILITY_STRIDE: u32 = 37u; // 1 + MAX_B

fn word_f32(i: u32) -> f32 {
    return bitcast<f32>(words[i]);
}

fn n_b() -> i32 {
    return i32(params.bands_b * params.bands_b);
}

// The truncated product a * b at the visibility's order (Eq. 5.8).
fn product(a: ptr<function, array<f32, MAX_B>>, b: ptr<function, array<f32, MAX_B>>) -> array<f32, MAX_B> {
    var out: array<f32, MAX_B>;
    for (var e = 0u; e < params.gaunt_bb_count; e = e + 1u) {
        let at = params.offset_gaunt_bb + 2u * e;
        let ijk = words[at];
        let c = word_f32(at + 1u);
        out[(ijk >> 20u) & 1023u] += c * (*a)[ijk & 1023u] * (*b)[(ijk >> 10u) & 1023u];
    }
    return out;
}

fn norm_b(f: ptr<function, array<f32, MAX_B>>) -> f32 {
    var sum = 0.0;
    for (var i = 0; i < n_b(); i = i + 1) {
        sum += (*f)[i] * (*f)[i];
    }
    return sqrt(sum);
}

fn one_b() -> array<f32, MAX_B> {
    var one: array<f32, MAX_B>;
    one[0] = SQRT_4PI;
    return one;
}

// Σ f^{k*}/k! to the series degree as even part plus f * odd part (Eq. 5.27).
fn factored_series(f: ptr<function, array<f32, MAX_B>>) -> array<f32, MAX_B> {
    var even = one_b();
    var odd = one_b();
    var power = one_b();
    var square = product(f, f);
    var factorial = 1.0;
    for (var k = 2u; k <= params.series_degree; k = k + 1u) {
        factorial *= f32(k);
        if (k % 2u == 0u) {
            power = product(&power, &square);
            for (var i = 0; i < n_b(); i = i + 1) {
                even[i] += power[i] / factorial;
            }
        } else {
            for (var i = 0; i < n_b(); i = i + 1) {
                odd[i] += power[i] / factorial;
            }
        }
    }
    var odd_times_f = product(f, &odd);
    for (var i = 0; i < n_b(); i = i + 1) {
        even[i] += odd_times_f[i];
    }
    return even;
}

// OL's (a, b) at norm m, linear between bin centres.
fn ol_lookup(m: f32) -> vec2<f32> {
    let bins = params.ol_bins;
    let t = clamp(m / params.ol_max_norm * f32(bins) - 0.5, 0.0, f32(bins - 1u));
    let i = min(u32(floor(t)), max(bins, 2u) - 2u);
    let w = min(t - f32(i), 1.0);
    let j = min(i + 1u, bins - 1u);
    let a = mix(word_f32(params.offset_ol + i), word_f32(params.offset_ol + j), w);
    let b = mix(word_f32(params.offset_ol + bins + i), word_f32(params.offset_ol + bins + j), w);
    return vec2<f32>(a, b);
}

// exp_*(f) by PS*-p or HYB.
fn exponential(f: ptr<function, array<f32, MAX_B>>) -> array<f32, MAX_B> {
    let dc = (*f)[0];
    var hat = *f;
    hat[0] = 0.0;
    var squarings = 0u;
    var g: array<f32, MAX_B>;
    if (params.series_degree > 0u) {
        let m = norm_b(&hat);
        if (m > 0.0) {
            squarings = u32(max(ceil(log2(m) + 3.0), 0.0));
        }
        let scale = exp2(-f32(squarings));
        for (var i = 0; i < n_b(); i = i + 1) {
            hat[i] *= scale;
        }
        g = factored_series(&hat);
    } else {
        while (norm_b(&hat) > params.ol_halving && squarings < 16u) {
            for (var i = 0; i < n_b(); i = i + 1) {
                hat[i] *= 0.5;
            }
            squarings += 1u;
        }
        let ab = ol_lookup(norm_b(&hat));
        for (var i = 0; i < n_b(); i = i + 1) {
            g[i] = ab.y * hat[i];
        }
        g[0] = ab.x * SQRT_4PI;
    }
    for (var s = 0u; s < squarings; s = s + 1u) {
        g = product(&g, &g);
    }
    let dc_factor = exp(dc / SQRT_4PI);
    for (var i = 0; i < n_b(); i = i + 1) {
        g[i] *= dc_factor;
    }
    return g;
}

fn invocation(id: vec3<u32>) -> u32 {
    return id.x + id.y * params.row_stride;
}

@compute @workgroup_size(64)
fn visibility_main(@builtin(global_invocation_id) id: vec3<u32>) {
    let r = invocation(id);
    if (r >= params.receivers) {
        return;
    }
    let receiver = receivers[r];
    let x = receiver.xyz;
    let part = bitcast<u32>(receiver.w);
    let first = words[params.offset_parts + 2u * part];
    let count = words[params.offset_parts + 2u * part + 1u];
    let bands_b = i32(params.bands_b);
    let entries = params.table_entries;

    var f: array<f32, MAX_B>;
    var reached = false;
    var inside = false;
    for (var s = 0u; s < count; s = s + 1u) {
        let sphere = words[first + s];
        let at = params.offset_blockers + 4u * sphere;
        let centre = vec3<f32>(word_f32(at), word_f32(at + 1u), word_f32(at + 2u));
        let radius = word_f32(at + 3u);
        let to = centre - x;
        let distance = length(to);
        if (distance <= radius) {
            inside = true;
            break;
        }
        if (distance > radius / params.min_sin) {
            continue;
        }
        reached = true;
        // The log-cap table at θ = asin(r / d), linear between entries over [0, π/2].
        let theta = asin(radius / distance);
        let t = theta / (0.5 * PI) * f32(entries - 1u);
        let i = min(u32(floor(t)), entries - 2u);
        let w = t - f32(i);
        let y = sh_basis(to / distance, bands_b);
        for (var l = 0; l < bands_b; l = l + 1) {
            let row0 = params.offset_log + i * params.bands_b + u32(l);
            let zonal = mix(word_f32(row0), word_f32(row0 + params.bands_b), w);
            let weight = params.strength * sqrt(4.0 * PI / f32(2 * l + 1)) * zonal;
            for (var m = l * l; m < (l + 1) * (l + 1); m = m + 1) {
                f[m] += weight * y[m];
            }
        }
    }
    let slot = r * VISIBILITY_STRIDE;
    if (!inside && !reached) {
        visibility[slot] = 0.0;
        return;
    }
    // A receiver inside a sphere sees nothing.
    var g: array<f32, MAX_B>;
    if (!inside) {
        g = exponential(&f);
    }
    visibility[slot] = 1.0;
    for (var i = 0; i < n_b(); i = i + 1) {
        visibility[slot + 1u + u32(i)] = g[i];
    }
}

@compute @workgroup_size(64)
fn multiply_main(@builtin(global_invocation_id) id: vec3<u32>) {
    let index = invocation(id);
    if (index >= params.receivers * params.vectors_per_receiver) {
        return;
    }
    let r = index % params.receivers;
    let slot = r * VISIBILITY_STRIDE;
    if (visibility[slot] == 0.0) {
        return;
    }
    let n_t = params.bands_t * params.bands_t;
    let base = index * n_t;
    var after: array<f32, MAX_T>;
    for (var e = 0u; e < params.gaunt_tb_count; e = e + 1u) {
        let at = params.offset_gaunt_tb + 2u * e;
        let ijk = words[at];
        let g = visibility[slot + 1u + ((ijk >> 10u) & 1023u)];
        after[(ijk >> 20u) & 1023u] += word_f32(at + 1u) * vectors[base + (ijk & 1023u)] * g;
    }
    for (var k = 0u; k < n_t; k = k + 1u) {
        vectors[base + k] = after[k];
    }
}
