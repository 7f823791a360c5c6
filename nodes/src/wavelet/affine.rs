//! Affine double and triple product integrals of Haar functions (Sun 2008 ch. 4, §4.3–4.4,
//! with the corrections of `sun-ch4-affine-wavelet-products.md`).
//!
//! - **Basis** on `[0, 1)`: index 0 is the scaling function `φ = 1`; index `k ≥ 1` is
//!   `ψ_{l,t}(v) = 2^{l/2} ψ(2^l v − t)` with `l = ⌊log₂ k⌋`, `t = k − 2^l` (coarse to fine).
//!   In 2D the standard decomposition: the tensor product of two full 1D bases, coefficient
//!   `(i₁, i₂)` stored at `i₂·n + i₁`.
//! - **Affine coupling coefficient (ACC, Eq. 4.8):** `D_ij(s, o) = ∫ Φ_i(s v + o) Φ_j(v) dv`.
//!   It is the affine transform in coefficient space: `(F∘A)_j = Σ_i F_i D_ij(s, o)`.
//! - **Canonical coupling coefficient (Eqs. 4.21–4.22):** for two wavelets
//!   `D_ij = 2^{(l_i − l_j)/2} M(r, c)`, `r = 2^{l_j − l_i − 1}/s`,
//!   `c = (2^{l_j − l_i} t_i − 2^{l_j} o + 2^{l_j − l_i − 1})/s − t_j` (Eq. 4.23 as corrected:
//!   the printed `2^{l_i} o` is wrong), and `M(r, c) = 2Λ(c) − Λ(c − r) − Λ(c + r)` with the tent
//!   `Λ(u) = max(0, min(u, 1 − u))`, the antiderivative of `ψ` (notes §1.4).
//! - **Affine tripling coefficient (ATC, Eq. 4.10):** `D_ijk = ∫ Φ_i(s v + o) Φ_j Φ_k dv`,
//!   by Property 2 (Eq. 4.29) with the sign the thesis drops, plus the cases it omits
//!   (`j = k`, a scaling index).
//! - **Propagation (Eqs. 4.35–4.36):** a light texture's coefficients moved to a receiver's
//!   top face in two separable steps (§4.5.5), visiting only the nonzero couplings found by the
//!   breakpoint fan-out (notes §1.6: at most 3 targets per level).

use std::collections::BTreeMap;

/// Level and offset of basis index `k`, `None` for the scaling function.
pub fn level_offset(k: usize) -> Option<(u32, u32)> {
    (k > 0).then(|| {
        let l = k.ilog2();
        (l, (k - (1 << l)) as u32)
    })
}

/// `Λ(u) = max(0, min(u, 1 − u))`: the antiderivative of the mother wavelet.
pub fn tent(u: f64) -> f64 {
    u.min(1.0 - u).max(0.0)
}

/// The canonical coupling coefficient `M(r, c) = ∫ α(u) ψ(u) du` (Eq. 4.22), where `α` is
/// `+1` on `[c − r, c)` and `−1` on `[c, c + r)`: the transformed wavelet in units of the
/// target's support. Branch-free closed form.
pub fn canonical_coupling(r: f64, c: f64) -> f64 {
    2.0 * tent(c) - tent(c - r) - tent(c + r)
}

/// `M(r, c)` by the thesis's case analysis (Fig. 4.4, absolute values restored as the notes
/// give them); kept as an independent check of [`canonical_coupling`].
pub fn canonical_coupling_by_cases(r: f64, c: f64) -> f64 {
    let d = (c - 0.5).abs();
    let sum = r + 0.5;
    let diff = (r - 0.5).abs();
    let (larger, smaller) = (r.max(0.5), r.min(0.5));
    if d >= sum {
        0.0
    } else if d >= larger {
        d - sum
    } else if d >= diff.max(smaller) {
        diff - d
    } else if d >= diff.min(smaller) {
        if diff >= smaller { 0.0 } else { sum - 3.0 * d }
    } else {
        2.0 * (smaller - d)
    }
}

/// The memory-based ACC of §4.5.5 (notes §2.8): couplings taken at the nearest point of a grid
/// over the map `(s, o)` instead of at the map itself, so receivers with nearby maps share one
/// set of couplings (computed once, then looked up). The grid has `steps` points per unit of the
/// footprint's position `c = (o + s)/(1 + s)` (`c ∈ (0, 1)` where the mapped interval
/// `[o, o + s)` meets `[0, 1)`) and `steps / 2` per octave of `s`. The thesis tabulates 256²
/// points; the couplings are piecewise linear in `(s, o)`, so the error falls with the step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CouplingGrid {
    pub steps: u32,
}

impl CouplingGrid {
    /// The grid point nearest `map` (a map with no finite positive scale is left as it is).
    pub fn snap(&self, map: Affine) -> Affine {
        if !(map.s.is_finite() && map.s > 0.0 && map.o.is_finite()) {
            return map;
        }
        let steps = f64::from(self.steps.max(2));
        let per_octave = steps / 2.0;
        let s = ((map.s.log2() * per_octave).round() / per_octave).exp2();
        let c = ((map.o + map.s) / (1.0 + map.s) * steps).round() / steps;
        Affine { s, o: c * (1.0 + s) - s }
    }
}

/// An affine map `v ↦ s v + o` of the unit interval, `s > 0`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Affine {
    pub s: f64,
    pub o: f64,
}

impl Affine {
    /// `∫_α^β Φ_i(s v + o) dv`.
    pub fn integral(&self, i: usize, alpha: f64, beta: f64) -> f64 {
        let (a, b) = (self.s * alpha + self.o, self.s * beta + self.o);
        match level_offset(i) {
            // The length of [a, b] ∩ [0, 1), back in v.
            None => (b.min(1.0) - a.max(0.0)).max(0.0) / self.s,
            Some((l, t)) => {
                let scale = f64::from(1u32 << l);
                (tent(scale * b - f64::from(t)) - tent(scale * a - f64::from(t))) / (self.s * scale.sqrt())
            }
        }
    }

    /// The ACC `D_ij(s, o)` (Eq. 4.8): Eq. 4.21 for two wavelets, and the closed forms of the
    /// notes for a scaling index.
    pub fn coupling(&self, i: usize, j: usize) -> f64 {
        match (level_offset(i), level_offset(j)) {
            (_, None) => self.integral(i, 0.0, 1.0),
            (None, Some((l, t))) => {
                // φ(s v + o) is 1 on [a, b]: ∫_a^b ψ_j = 2^{−l/2} [Λ(2^l b − t) − Λ(2^l a − t)],
                // exactly 0 where ψ_j's support lies inside or outside [a, b].
                let (a, b) = ((-self.o / self.s).max(0.0), ((1.0 - self.o) / self.s).min(1.0));
                if b <= a {
                    return 0.0;
                }
                let scale = f64::from(1u32 << l);
                (tent(scale * b - f64::from(t)) - tent(scale * a - f64::from(t))) / scale.sqrt()
            }
            (Some((li, ti)), Some((lj, tj))) => {
                let ratio = 2f64.powi(lj as i32 - li as i32);
                let r = 0.5 * ratio / self.s;
                let c = (ratio * f64::from(ti) - f64::from(1u32 << lj) * self.o + 0.5 * ratio) / self.s - f64::from(tj);
                canonical_coupling(r, c) / ratio.sqrt()
            }
        }
    }

    /// The ATC `D_ijk(s, o)` (Eq. 4.10). Disjoint supports give 0; `Φ_0 Φ_k = Φ_k`;
    /// `ψ_j² = 2^{l_j} 1_{supp j}`; for overlapping wavelets at levels `l_n < l_m`,
    /// `ψ_n ψ_m = σ 2^{l_n/2} ψ_m` with `σ` the sign of `ψ_n` on `supp ψ_m`, so
    /// `D_ijk = σ 2^{l_n/2} D_im` (Property 2, Eq. 4.29, with `σ`).
    pub fn tripling(&self, i: usize, j: usize, k: usize) -> f64 {
        let (coarse, fine) = if j <= k { (j, k) } else { (k, j) };
        let Some((lm, tm)) = level_offset(fine) else {
            return self.integral(i, 0.0, 1.0); // both scaling functions
        };
        let Some((ln, tn)) = level_offset(coarse) else {
            return self.coupling(i, fine);
        };
        if coarse == fine {
            let (x0, x1) = support(lm, tm);
            return f64::from(1u32 << lm) * self.integral(i, x0, x1);
        }
        if ln == lm || (tm >> (lm - ln)) != tn {
            return 0.0; // same level and different offsets, or disjoint
        }
        // ψ_n is + on its first half: the finer support lies in its first half when the
        // next bit of the finer offset is 0.
        let sigma = if (tm >> (lm - ln - 1)) & 1 == 0 { 1.0 } else { -1.0 };
        sigma * f64::from(1u32 << ln).sqrt() * self.coupling(i, fine)
    }

    /// The targets `j < size` with possibly nonzero `D_ij`: `φ` when the transformed source
    /// meets `[0, 1)`, and at each level the wavelets whose open support holds one of the
    /// source's breakpoints (elsewhere `Φ_i(s v + o)` is constant on `supp ψ_j`, so
    /// `D_ij = 0`): at most 3 per level, `2` for a scaling source (notes §1.6).
    pub fn targets(&self, i: usize, size: usize, out: &mut Vec<usize>) {
        out.clear();
        let (breaks, count) = match level_offset(i) {
            None => ([0.0, 1.0, 1.0], 2),
            Some((l, t)) => {
                let h = 0.5 / f64::from(1u32 << l);
                let x0 = f64::from(t) * 2.0 * h;
                ([x0, x0 + h, x0 + 2.0 * h], 3)
            }
        };
        let in_v = &breaks.map(|b| (b - self.o) / self.s)[..count];
        let (lo, hi) = (in_v[0], in_v[in_v.len() - 1]);
        if hi <= 0.0 || lo >= 1.0 {
            return;
        }
        out.push(0);
        let levels = size.max(1).ilog2();
        for l in 0..levels {
            let cells = f64::from(1u32 << l);
            let first = out.len();
            for v in in_v {
                let x = v * cells;
                let t = x.floor();
                if t < 0.0 || t >= cells || x == t {
                    continue; // outside, or on a support's edge
                }
                let j = (1usize << l) + t as usize;
                if !out[first..].contains(&j) {
                    out.push(j);
                }
            }
        }
    }
}

/// `[t 2^{−l}, (t + 1) 2^{−l})`.
fn support(l: u32, t: u32) -> (f64, f64) {
    let w = 1.0 / f64::from(1u32 << l);
    (f64::from(t) * w, f64::from(t + 1) * w)
}

/// Orthonormal 1D Haar transform of `n = 2^L` cell values on `[0, 1)` (a piecewise-constant
/// function) into the basis above, in place.
pub fn haar_forward(values: &mut [f64]) {
    let n = values.len();
    assert!(n.is_power_of_two(), "Haar transform of {n} values");
    // Coefficients of the function: averages scaled to the unit interval's normalisation.
    let mut scratch = values.to_vec();
    let mut len = n;
    let norm = 1.0 / (n as f64).sqrt();
    scratch.iter_mut().for_each(|v| *v *= norm);
    while len > 1 {
        let half = len / 2;
        let (mut sums, mut diffs) = (vec![0.0; half], vec![0.0; half]);
        for k in 0..half {
            let (a, b) = (scratch[2 * k], scratch[2 * k + 1]);
            sums[k] = (a + b) * std::f64::consts::FRAC_1_SQRT_2;
            diffs[k] = (a - b) * std::f64::consts::FRAC_1_SQRT_2;
        }
        scratch[..half].copy_from_slice(&sums);
        scratch[half..len].copy_from_slice(&diffs);
        len = half;
    }
    values.copy_from_slice(&scratch);
}

/// The inverse of [`haar_forward`]: cell values from coefficients.
pub fn haar_inverse(coefficients: &mut [f64]) {
    let n = coefficients.len();
    assert!(n.is_power_of_two(), "Haar transform of {n} values");
    let mut len = 1;
    while len < n {
        let mut next = vec![0.0; 2 * len];
        for k in 0..len {
            let (a, d) = (coefficients[k], coefficients[len + k]);
            next[2 * k] = (a + d) * std::f64::consts::FRAC_1_SQRT_2;
            next[2 * k + 1] = (a - d) * std::f64::consts::FRAC_1_SQRT_2;
        }
        coefficients[..2 * len].copy_from_slice(&next);
        len *= 2;
    }
    let scale = (n as f64).sqrt();
    coefficients.iter_mut().for_each(|v| *v *= scale);
}

/// Standard-decomposition 2D Haar transform of an `n × n` image (row `y` at `y·n`): every
/// row, then every column.
pub fn haar_forward_2d(image: &mut [f64], n: usize) {
    transform_2d(image, n, haar_forward);
}

/// The inverse of [`haar_forward_2d`].
pub fn haar_inverse_2d(coefficients: &mut [f64], n: usize) {
    transform_2d(coefficients, n, haar_inverse);
}

fn transform_2d(data: &mut [f64], n: usize, transform: fn(&mut [f64])) {
    assert_eq!(data.len(), n * n, "an {n} × {n} image");
    for row in data.chunks_mut(n) {
        transform(row);
    }
    let mut column = vec![0.0; n];
    for x in 0..n {
        column.iter_mut().enumerate().for_each(|(y, c)| *c = data[y * n + x]);
        transform(&mut column);
        column.iter().enumerate().for_each(|(y, c)| data[y * n + x] = *c);
    }
}

/// `L_k = Σ_i F_i D_ik(s, o)` for `size` targets (Eq. 4.35 in 1D), over the fan-out only.
pub fn propagate_1d(source: &[(usize, f64)], map: Affine, size: usize) -> Vec<f64> {
    let mut out = vec![0.0; size];
    let mut targets = Vec::new();
    for &(i, f) in source {
        map.targets(i, size, &mut targets);
        for &k in &targets {
            out[k] += f * map.coupling(i, k);
        }
    }
    out
}

/// The 2D propagation in two separable steps (§4.5.5): `Z_{i₂k₁} = Σ_{i₁} F_{i₁i₂} D_{i₁k₁}`,
/// then `L_{k₁k₂} = Σ_{i₂} Z_{i₂k₁} D_{i₂k₂}`, each over the fan-out only. `source` holds
/// `((i₁, i₂), F)`; the result is the dense `size × size` target (`k₂·size + k₁`).
pub fn propagate_2d(source: &[((usize, usize), f64)], maps: [Affine; 2], size: usize) -> Vec<f64> {
    let mut targets = Vec::new();
    let mut step1: BTreeMap<(usize, usize), f64> = BTreeMap::new();
    for &((i1, i2), f) in source {
        maps[0].targets(i1, size, &mut targets);
        for &k1 in &targets {
            *step1.entry((i2, k1)).or_default() += f * maps[0].coupling(i1, k1);
        }
    }
    let mut out = vec![0.0; size * size];
    for (&(i2, k1), &z) in &step1 {
        maps[1].targets(i2, size, &mut targets);
        for &k2 in &targets {
            out[k2 * size + k1] += z * maps[1].coupling(i2, k2);
        }
    }
    out
}

#[cfg(test)]
mod tests;
