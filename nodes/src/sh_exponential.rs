//! Soft shadows from sphere blockers by SH exponentials, SHEXP (Sun 2008 §5.2).
//!
//! - **Visibility of one sphere (Eq. 5.36).** Seen from a receiver, a sphere of centre `c` and
//!   radius `r` hides the cap of angular radius `θ = asin(r / |c − x|)` about `c − x`. The cap
//!   visibility `g = 1 − [s in cap]` is zonal with closed-form coefficients ([`cap_zonal`]).
//! - **Products (Eqs. 5.8–5.10).** `(f * g)_k = Σ_ij Γ_ijk f_i g_j`, truncated to `n²`
//!   coefficients; `M_f g = f * g` with the symmetric product matrix `M_f`.
//! - **Log space (Eq. 5.13).** The visibility of many blockers is `exp_*(Σ_i log g_i)`: the sum
//!   is O(n²) per blocker and independent of blocker order, against O(n⁵) per product.
//! - **Exponential.** [`ShExp::exp_series`] is PS-p (Eqs. 5.20–5.22);
//!   [`ShExp::exp_ps_star`] is PS*-p: the DC term isolated (Eqs. 5.24–5.25, with the notes'
//!   correction `f̂ = f − f₀/√(4π)·1`), scaling and squaring (Eq. 5.26, `p = ⌈log₂‖f̂‖ + 3⌉`)
//!   and the even/odd factored series (Eq. 5.27). [`ShExp::exp_hyb`] is HYB: the optimal
//!   linear approximation `a(‖f̂‖)·1 + b(‖f̂‖)·f̂` (OL, Ren et al. 2006) after halving, then
//!   squaring back. [`ShExp::exp_exact`] is the series summed through the eigenvectors of
//!   `M_f` (Eq. 5.31), the oracle.
//! - **Logarithm (Eqs. 5.29–5.35).** [`ShExp::log_eigen`]: `log g = Rᵀ q'(D̃) R (g − 1)` with
//!   `q'(x) = log x / (x − 1)` and eigenvalues clipped at `0.02 λ_max`. A cap's log is zonal,
//!   so [`LogCapTable`] tabulates its `n` zonal coefficients against `θ`; a blocker then costs
//!   one lookup and one zonal rotation.

use crate::sh::{self, GauntTable, ShBasis};
use glam::DVec3;
use nalgebra::{DMatrix, DVector, SymmetricEigen};
use serde::{Deserialize, Serialize};
use std::f64::consts::{FRAC_PI_2, PI};

/// `√(4π)`: the DC coefficient of the constant 1.
pub const SQRT_4PI: f64 = 3.5449077018110318;

/// The eigenvalue clip of the log, relative to the largest (Sun 2008 §5.2.2).
pub const LOG_CLIP_RELATIVE: f64 = 0.02;

/// Zonal coefficients `g_l` (of `Y_l0`) of the visibility of a cap of angular radius `θ`
/// about +Z (0 inside the cap, 1 outside), `x = cos θ`:
/// `g_0 = √(4π) − √π (1 − x)`, `g_l = −√(π/(2l+1)) [P_{l−1}(x) − P_{l+1}(x)]` (notes §3.4,
/// from `∫_x^1 P_l = (P_{l−1}(x) − P_{l+1}(x)) / (2l+1)`).
pub fn cap_zonal(bands: usize, cos_theta: f64) -> Vec<f64> {
    let x = cos_theta.clamp(-1.0, 1.0);
    // Legendre P_0 ..= P_bands by the three-term recurrence.
    let mut p = vec![1.0, x];
    for l in 1..bands {
        let lf = l as f64;
        p.push(((2.0 * lf + 1.0) * x * p[l] - lf * p[l - 1]) / (lf + 1.0));
    }
    (0..bands)
        .map(|l| {
            if l == 0 {
                SQRT_4PI - PI.sqrt() * (1.0 - x)
            } else {
                -(PI / (2 * l + 1) as f64).sqrt() * (p[l - 1] - p[l + 1])
            }
        })
        .collect()
}

/// Angular radius of a sphere seen from `receiver`; `π/2` when the receiver is inside it.
pub fn angular_radius(receiver: DVec3, centre: DVec3, radius: f64) -> f64 {
    let distance = (centre - receiver).length();
    if distance <= radius { FRAC_PI_2 } else { (radius / distance).asin() }
}

/// The exponential variants a blocker set can shade with.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum ExpMethod {
    /// PS*-p: DC isolation, scaling and squaring, factored series of this degree.
    PsStar(usize),
    /// HYB: halving to the OL table's range, OL, squaring back.
    Hyb,
}

/// SH products and the exponential and logarithm at `bands` bands.
#[derive(Clone, Debug)]
pub struct ShExp {
    bands: usize,
    gaunt: GauntTable,
    ol: Option<OlTable>,
}

impl ShExp {
    pub fn new(bands: usize) -> Self {
        Self { bands, gaunt: GauntTable::new(bands, bands, bands), ol: None }
    }

    /// With an OL table for [`Self::exp_hyb`].
    pub fn with_ol(bands: usize, ol: OlTable) -> Self {
        Self { ol: Some(ol), ..Self::new(bands) }
    }

    pub fn bands(&self) -> usize {
        self.bands
    }

    pub fn len(&self) -> usize {
        self.bands * self.bands
    }

    pub fn is_empty(&self) -> bool {
        self.bands == 0
    }

    /// The constant function 1.
    pub fn one(&self) -> Vec<f64> {
        let mut one = vec![0.0; self.len()];
        one[0] = SQRT_4PI;
        one
    }

    /// Truncated product `f * g` (Eq. 5.8).
    pub fn product(&self, f: &[f64], g: &[f64]) -> Vec<f64> {
        self.gaunt.multiply(f, g)
    }

    /// The product matrix `M_f` (Eq. 5.10), symmetric.
    pub fn matrix(&self, f: &[f64]) -> DMatrix<f64> {
        let n = self.len();
        DMatrix::from_row_slice(n, n, &self.gaunt.product_matrix(f))
    }

    /// PS-p: `1 + f + f^{2*}/2! + … + f^{p*}/p!`, powers accumulated left to right.
    pub fn exp_series(&self, f: &[f64], degree: usize) -> Vec<f64> {
        let mut out = self.one();
        let mut power = self.one();
        let mut factorial = 1.0;
        for k in 1..=degree {
            power = self.product(&power, f);
            factorial *= k as f64;
            out.iter_mut().zip(&power).for_each(|(o, p)| *o += p / factorial);
        }
        out
    }

    /// Squarings PS*-p uses for `f̂` of norm `norm`: `max(0, ⌈log₂ norm + 3⌉)` (Eq. 5.26).
    pub fn squarings(norm: f64) -> u32 {
        if norm <= 0.0 { 0 } else { (norm.log2() + 3.0).ceil().max(0.0) as u32 }
    }

    /// PS*-p (Eqs. 5.24–5.27).
    pub fn exp_ps_star(&self, f: &[f64], degree: usize) -> Vec<f64> {
        let (dc, mut hat) = split_dc(f);
        let squarings = Self::squarings(norm(&hat));
        let scale = 0.5f64.powi(squarings as i32);
        hat.iter_mut().for_each(|v| *v *= scale);
        let mut g = self.factored_series(&hat, degree);
        for _ in 0..squarings {
            g = self.product(&g, &g);
        }
        let dc_factor = (dc / SQRT_4PI).exp();
        g.iter_mut().for_each(|v| *v *= dc_factor);
        g
    }

    /// `Σ f^{k*}/k!` to `degree` as even part plus `f *` odd part (Eq. 5.27):
    /// `(h₀1 + h₂f² + h₄f⁴ + …) + f * (h₁1 + h₃f² + …)`.
    fn factored_series(&self, f: &[f64], degree: usize) -> Vec<f64> {
        let one = self.one();
        if degree == 0 {
            return one;
        }
        let square = self.product(f, f);
        let (mut even, mut odd) = (one.clone(), one.clone());
        let mut power = one; // f^{2j*}
        let mut factorial = 1.0;
        for k in 2..=degree {
            factorial *= k as f64;
            if k % 2 == 0 {
                power = self.product(&power, &square);
                even.iter_mut().zip(&power).for_each(|(e, p)| *e += p / factorial);
            } else {
                odd.iter_mut().zip(&power).for_each(|(o, p)| *o += p / factorial);
            }
        }
        let odd = self.product(f, &odd);
        even.iter().zip(&odd).map(|(e, o)| e + o).collect()
    }

    /// HYB: `f̂` halved until its norm is within the OL table, OL, then squared back; the DC
    /// term isolated as in PS*. Falls back to PS*-2 without an OL table.
    pub fn exp_hyb(&self, f: &[f64]) -> Vec<f64> {
        let Some(ol) = &self.ol else {
            return self.exp_ps_star(f, 2);
        };
        let (dc, mut hat) = split_dc(f);
        let mut squarings = 0;
        while norm(&hat) > ol.halving_threshold && squarings < 16 {
            hat.iter_mut().for_each(|v| *v *= 0.5);
            squarings += 1;
        }
        let (a, b) = ol.lookup(norm(&hat));
        let mut g: Vec<f64> = hat.iter().map(|v| b * v).collect();
        g[0] = a * SQRT_4PI;
        for _ in 0..squarings {
            g = self.product(&g, &g);
        }
        let dc_factor = (dc / SQRT_4PI).exp();
        g.iter_mut().for_each(|v| *v *= dc_factor);
        g
    }

    pub fn exp(&self, f: &[f64], method: ExpMethod) -> Vec<f64> {
        match method {
            ExpMethod::PsStar(degree) => self.exp_ps_star(f, degree),
            ExpMethod::Hyb => self.exp_hyb(f),
        }
    }

    /// The product series summed exactly: `exp(M_f) 1 = 1 + Rᵀ q(D) R f` with
    /// `q(x) = (eˣ − 1)/x` and `M_f = Rᵀ D R` (Eq. 5.31).
    pub fn exp_exact(&self, f: &[f64]) -> Vec<f64> {
        let eigen = SymmetricEigen::new(self.matrix(f));
        let q = eigen.eigenvalues.map(|x| if x.abs() < 1e-12 { 1.0 } else { x.exp_m1() / x });
        let projected = eigen.eigenvectors.transpose() * DVector::from_column_slice(f);
        let result = &eigen.eigenvectors * projected.component_mul(&q);
        let mut g = self.one();
        g.iter_mut().zip(result.iter()).for_each(|(g, r)| *g += r);
        g
    }

    /// The eigen logarithm (Eqs. 5.32–5.35): `log g = Rᵀ q'(D̃) R (g − 1)` with
    /// `q'(x) = log x / (x − 1)` and `D̃ = max(D, clip · λ_max)`.
    pub fn log_eigen(&self, g: &[f64], clip_relative: f64) -> Vec<f64> {
        let eigen = SymmetricEigen::new(self.matrix(g));
        let largest = eigen.eigenvalues.max();
        let floor = clip_relative * largest;
        let q = eigen.eigenvalues.map(|x| {
            let x = x.max(floor);
            if (x - 1.0).abs() < 1e-9 { 1.0 } else { x.ln() / (x - 1.0) }
        });
        let mut shifted = DVector::from_column_slice(g);
        shifted[0] -= SQRT_4PI;
        let projected = eigen.eigenvectors.transpose() * shifted;
        let f = &eigen.eigenvectors * projected.component_mul(&q);
        f.iter().copied().collect()
    }
}

/// `(f₀, f̂)`: the DC coefficient and `f` with it removed.
fn split_dc(f: &[f64]) -> (f64, Vec<f64>) {
    let mut hat = f.to_vec();
    hat[0] = 0.0;
    (f[0], hat)
}

fn norm(f: &[f64]) -> f64 {
    f.iter().map(|v| v * v).sum::<f64>().sqrt()
}

/// Zonal coefficients of `log g` for a cap against its angular radius `θ ∈ [0, π/2]`, at
/// `entries` evenly spaced angles (linear interpolation between them).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LogCapTable {
    pub bands: usize,
    /// `entries × bands`, row `i` at `θ = i · (π/2) / (entries − 1)`.
    pub zonal: Vec<f64>,
    pub entries: usize,
}

crate::stage_type!(LogCapTable, "log cap table", |v| v.zonal.len() * 8 + 32);

impl LogCapTable {
    pub fn new(shexp: &ShExp, entries: usize, clip_relative: f64) -> Self {
        let bands = shexp.bands();
        let mut zonal = Vec::with_capacity(entries * bands);
        for i in 0..entries {
            let theta = i as f64 * FRAC_PI_2 / (entries - 1) as f64;
            let cap = zonal_to_full(&cap_zonal(bands, theta.cos()));
            let log = shexp.log_eigen(&cap, clip_relative);
            zonal.extend((0..bands).map(|l| log[sh::index(l, 0)]));
        }
        Self { bands, zonal, entries }
    }

    /// Zonal log coefficients at angular radius `theta` (clamped to `[0, π/2]`).
    pub fn lookup(&self, theta: f64, out: &mut [f64]) {
        let t = (theta.clamp(0.0, FRAC_PI_2) / FRAC_PI_2) * (self.entries - 1) as f64;
        let i = (t.floor() as usize).min(self.entries - 2);
        let w = t - i as f64;
        for (l, o) in out.iter_mut().enumerate().take(self.bands) {
            *o = (1.0 - w) * self.zonal[i * self.bands + l] + w * self.zonal[(i + 1) * self.bands + l];
        }
    }
}

/// A zonal expansion about +Z as a full coefficient vector.
pub fn zonal_to_full(zonal: &[f64]) -> Vec<f64> {
    let bands = zonal.len();
    let mut full = vec![0.0; bands * bands];
    for (l, z) in zonal.iter().enumerate() {
        full[sh::index(l, 0)] = *z;
    }
    full
}

/// Rotates zonal coefficients to axis `dir` and adds `weight ×` them to `out`:
/// `f_lm += weight · √(4π/(2l+1)) z_l Y_lm(dir)`.
pub fn add_rotated_zonal(basis: &ShBasis, zonal: &[f64], dir: DVec3, weight: f64, y: &mut [f64], out: &mut [f64]) {
    basis.eval(dir, y);
    for (i, o) in out.iter_mut().enumerate() {
        let l = sh::band_of(i);
        *o += weight * (4.0 * PI / (2 * l + 1) as f64).sqrt() * zonal[l] * y[i];
    }
}

/// OL's `a(m)`, `b(m)` over `m = ‖f̂‖` in equal bins, fitted by least squares to the exact
/// exponential of training log vectors (`ĝ = e^{−f₀/√4π} exp(f) ≈ a·1 + b·f̂`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct OlTable {
    pub max_norm: f64,
    pub a: Vec<f64>,
    pub b: Vec<f64>,
    /// HYB halves `f̂` until its norm is at most this.
    pub halving_threshold: f64,
}

impl OlTable {
    /// Fits the table on `training` log vectors (any DC term; it is isolated).
    pub fn fit(shexp: &ShExp, training: &[Vec<f64>], bins: usize, max_norm: f64, halving_threshold: f64) -> Self {
        let mut sums = vec![(0.0, 0.0, 0.0, 0.0); bins]; // (Σ ĝ₀/√4π, count, Σ ĝ·f̂, Σ f̂·f̂)
        for f in training {
            let (dc, hat) = split_dc(f);
            let m = norm(&hat);
            if m > max_norm {
                continue;
            }
            let mut g = shexp.exp_exact(f);
            let undc = (-dc / SQRT_4PI).exp();
            g.iter_mut().for_each(|v| *v *= undc);
            let bin = ((m / max_norm * bins as f64) as usize).min(bins - 1);
            let s = &mut sums[bin];
            s.0 += g[0] / SQRT_4PI;
            s.1 += 1.0;
            s.2 += g.iter().zip(&hat).skip(1).map(|(g, h)| g * h).sum::<f64>();
            s.3 += m * m;
        }
        let a = sums.iter().map(|s| if s.1 > 0.0 { s.0 / s.1 } else { f64::NAN }).collect();
        let b = sums.iter().map(|s| if s.3 > 0.0 { s.2 / s.3 } else { f64::NAN }).collect();
        let mut table = Self { max_norm, a, b, halving_threshold };
        table.fill_gaps();
        table
    }

    /// Empty bins take their nearest filled neighbour (the first bin defaults to `a = b = 1`).
    fn fill_gaps(&mut self) {
        for values in [&mut self.a, &mut self.b] {
            let mut last = 1.0;
            for v in values.iter_mut() {
                if v.is_nan() {
                    *v = last;
                } else {
                    last = *v;
                }
            }
        }
    }

    pub fn lookup(&self, m: f64) -> (f64, f64) {
        let bins = self.a.len();
        let t = (m / self.max_norm * bins as f64 - 0.5).clamp(0.0, (bins - 1) as f64);
        let i = (t.floor() as usize).min(bins.saturating_sub(2));
        let w = (t - i as f64).min(1.0);
        let j = (i + 1).min(bins - 1);
        ((1.0 - w) * self.a[i] + w * self.a[j], (1.0 - w) * self.b[i] + w * self.b[j])
    }
}

/// A sphere blocker in world space.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Blocker {
    pub centre: [f64; 3],
    pub radius: f64,
}

/// Blockers seen under less than this angular radius are culled: each would darken a
/// receiver's irradiance by at most `sin²` of it (0.25%). The influence radius of a sphere is
/// `r / sin` of it, 20 radii.
pub const MIN_ANGULAR_RADIUS: f64 = 0.05;

impl Blocker {
    /// Whether `point` lies inside the sphere (there it hides everything).
    pub fn contains(&self, point: DVec3) -> bool {
        (DVec3::from(self.centre) - point).length_squared() <= self.radius * self.radius
    }

    /// Distance beyond which the blocker is culled.
    pub fn influence_radius(&self) -> f64 {
        self.radius / MIN_ANGULAR_RADIUS.sin()
    }

    /// Adds `weight ×` this blocker's log visibility at `receiver` to `out` (O(n²)); false
    /// when culled. A receiver inside the sphere gets the hemisphere towards its centre (the
    /// table ends at θ = π/2); [`BlockedProduct`] treats it as fully hidden instead.
    pub fn add_log(
        &self,
        receiver: DVec3,
        table: &LogCapTable,
        basis: &ShBasis,
        weight: f64,
        scratch: &mut LogScratch,
        out: &mut [f64],
    ) -> bool {
        let to = DVec3::from(self.centre) - receiver;
        let distance = to.length();
        if distance > self.influence_radius() || distance == 0.0 {
            return false;
        }
        table.lookup(angular_radius(receiver, DVec3::from(self.centre), self.radius), &mut scratch.zonal);
        add_rotated_zonal(basis, &scratch.zonal, to / distance, weight, &mut scratch.y, out);
        true
    }
}

/// Reusable buffers for [`Blocker::add_log`].
pub struct LogScratch {
    zonal: Vec<f64>,
    y: Vec<f64>,
}

impl LogScratch {
    pub fn new(bands: usize) -> Self {
        Self { zonal: vec![0.0; bands], y: vec![0.0; bands * bands] }
    }
}

/// `f = Σ_i log g_i` at each receiver (n² per receiver, receiver-major).
pub fn accumulate_logs(receivers: &[DVec3], blockers: &[Blocker], table: &LogCapTable) -> Vec<f64> {
    let n = table.bands * table.bands;
    let basis = ShBasis::new(table.bands);
    let mut scratch = LogScratch::new(table.bands);
    let mut f = vec![0.0; receivers.len() * n];
    for (x, out) in receivers.iter().zip(f.chunks_mut(n)) {
        for blocker in blockers {
            blocker.add_log(*x, table, &basis, 1.0, &mut scratch, out);
        }
    }
    f
}

/// Moves one blocker from `old` to `new`: `f += f_new − f_old` at the receivers within
/// either's influence (log space is additive, so this equals a full recompute). Returns the
/// receivers touched.
pub fn move_blocker(
    f: &mut [f64],
    receivers: &[DVec3],
    old: &Blocker,
    new: &Blocker,
    table: &LogCapTable,
) -> Vec<usize> {
    let n = table.bands * table.bands;
    let basis = ShBasis::new(table.bands);
    let mut scratch = LogScratch::new(table.bands);
    let mut touched = Vec::new();
    for (i, (x, out)) in receivers.iter().zip(f.chunks_mut(n)).enumerate() {
        let removed = old.add_log(*x, table, &basis, -1.0, &mut scratch, out);
        let added = new.add_log(*x, table, &basis, 1.0, &mut scratch, out);
        if removed || added {
            touched.push(i);
        }
    }
    touched
}

/// `count` log vectors, each the sum of 1–40 random spheres' logs (distance 1.5–6, radius
/// 0.2–1, upper hemisphere): what [`OlTable::fit`] is trained on.
pub fn training_logs(table: &LogCapTable, count: usize, seed: u64) -> Vec<Vec<f64>> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand::rngs::SmallRng::seed_from_u64(seed);
    let bands = table.bands;
    let basis = ShBasis::new(bands);
    let (mut y, mut zonal) = (vec![0.0; bands * bands], vec![0.0; bands]);
    (0..count)
        .map(|_| {
            let mut f = vec![0.0; bands * bands];
            for _ in 0..rng.random_range(1..=40) {
                let d: f64 = rng.random_range(1.5..6.0);
                let r: f64 = rng.random_range(0.2..1.0);
                let z: f64 = rng.random_range(0.05..1.0);
                let phi: f64 = rng.random_range(0.0..2.0 * PI);
                let dir = DVec3::new((1.0 - z * z).sqrt() * phi.cos(), (1.0 - z * z).sqrt() * phi.sin(), z);
                table.lookup((r / d).asin(), &mut zonal);
                add_rotated_zonal(&basis, &zonal, dir, 1.0, &mut y, &mut f);
            }
            f
        })
        .collect()
}

/// Per receiver, a transport's SH vectors (`bands_t²` each, receiver-major) times the
/// blockers' visibility `g = exp_*(strength · Σ log g_i)` at the blockers' order, by the
/// truncated product `v * g` (Eq. 5.8). Receivers no sphere reaches keep their vectors.
pub struct BlockedProduct {
    shexp: ShExp,
    gaunt: GauntTable,
    basis: ShBasis,
    bands_t: usize,
}

impl BlockedProduct {
    pub fn new(shexp: ShExp, bands_t: usize) -> Self {
        let bands_b = shexp.bands();
        Self { gaunt: GauntTable::new(bands_t, bands_b, bands_t), basis: ShBasis::new(bands_b), shexp, bands_t }
    }

    /// The visibility of `blockers` at `receiver`, `None` where none reaches it.
    pub fn visibility(
        &self,
        receiver: DVec3,
        blockers: &[Blocker],
        table: &LogCapTable,
        method: ExpMethod,
        strength: f64,
        scratch: &mut LogScratch,
    ) -> Option<Vec<f64>> {
        if strength <= 0.0 {
            return None;
        }
        // A receiver inside a sphere sees nothing (as the reference's rays do).
        if blockers.iter().any(|b| b.contains(receiver)) {
            return Some(vec![0.0; self.shexp.len()]);
        }
        let mut f = vec![0.0; self.shexp.len()];
        let mut reached = false;
        for blocker in blockers {
            reached |= blocker.add_log(receiver, table, &self.basis, strength, scratch, &mut f);
        }
        reached.then(|| self.shexp.exp(&f, method))
    }

    /// `vectors` (each `bands_t²`, several per receiver) multiplied in place by each
    /// receiver's visibility.
    pub fn apply(
        &self,
        receivers: &[DVec3],
        blockers: &[Blocker],
        table: &LogCapTable,
        method: ExpMethod,
        strength: f64,
        vectors: &mut [&mut [f32]],
    ) {
        let n = self.bands_t * self.bands_t;
        let mut scratch = LogScratch::new(table.bands);
        for (i, x) in receivers.iter().enumerate() {
            let Some(g) = self.visibility(*x, blockers, table, method, strength, &mut scratch) else {
                continue;
            };
            for v in vectors.iter_mut() {
                let slot = &mut v[i * n..(i + 1) * n];
                let before: Vec<f64> = slot.iter().map(|&x| f64::from(x)).collect();
                for (o, p) in slot.iter_mut().zip(self.gaunt.multiply(&before, &g)) {
                    *o = p as f32;
                }
            }
        }
    }
}

/// Receivers grouped for clustered culling and partial recompute: by cells of a grid over
/// their bounds (a 16th of the largest extent), at most `max` per part, in a fixed order.
pub fn receiver_parts(positions: &[DVec3], max: usize) -> Vec<Vec<usize>> {
    if positions.is_empty() {
        return Vec::new();
    }
    let lo = positions.iter().fold(DVec3::splat(f64::INFINITY), |a, p| a.min(*p));
    let hi = positions.iter().fold(DVec3::splat(f64::NEG_INFINITY), |a, p| a.max(*p));
    let cell = ((hi - lo).max_element() / 16.0).max(1e-9);
    let mut cells: std::collections::BTreeMap<[i64; 3], Vec<usize>> = Default::default();
    for (i, p) in positions.iter().enumerate() {
        let c = ((*p - lo) / cell).floor();
        cells.entry([c.x as i64, c.y as i64, c.z as i64]).or_default().push(i);
    }
    cells.into_values().flat_map(|v| v.chunks(max.max(1)).map(<[usize]>::to_vec).collect::<Vec<_>>()).collect()
}

/// The blockers that may reach any of `points` (their bounding sphere against each sphere's
/// influence radius).
pub fn blockers_in_reach(points: &[DVec3], blockers: &[Blocker]) -> Vec<Blocker> {
    spheres_in_reach(points, blockers).into_iter().map(|i| blockers[i]).collect()
}

/// Indices of [`blockers_in_reach`], in order.
pub fn spheres_in_reach(points: &[DVec3], blockers: &[Blocker]) -> Vec<usize> {
    let centre = points.iter().sum::<DVec3>() / points.len().max(1) as f64;
    let radius = points.iter().map(|p| (*p - centre).length()).fold(0.0, f64::max);
    (0..blockers.len())
        .filter(|&i| (DVec3::from(blockers[i].centre) - centre).length() <= radius + blockers[i].influence_radius())
        .collect()
}

#[cfg(test)]
mod tests;
