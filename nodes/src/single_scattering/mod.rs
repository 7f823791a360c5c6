//! Analytic single scattering from point lights in a homogeneous medium (Sun et al. 2005;
//! Sun 2008 thesis, chapter 3): airlight along a view ray (eq. 3.16) through the special
//! functions `F^k(u, v)` (eqs. 3.15, 3.19), and light scattered onto surfaces (eqs. 3.22–3.28)
//! through the tables `G_n(T_sp, θ_s)` (eq. 3.23). Each table is a pure function of its
//! resolution; light and medium parameters only enter the closed-form factors `A_0`, `A_1`.
//!
//! Tables are stored over `s = u/(1+u)` (all of `u ∈ [0, ∞)`, denser near 0) and store
//! `(1+u)·F`, which stays O(1) where `F ~ 1/u`. References integrate eq. 3.5 directly.

use crate::quadrature::{adaptive_simpson, gauss_legendre};
use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};

// Stage value types this module owns (see `engine::value`).
crate::stage_type!(Vec<FTable>, "single scattering F tables", encoding = 1, |v| v
    .iter()
    .map(|t| t.table.values.len() * 4)
    .sum());
crate::stage_type!(PhongGTables, "single scattering G tables", encoding = 1, |v| v
    .tables
    .iter()
    .map(|t| t.table.values.len() * 4)
    .sum());

/// The `F` and `G` table resolution the fog node uses unless told otherwise.
pub const DEFAULT_RESOLUTION: usize = 512;

/// Smallest angle to the source used (at 0 the ray hits the point source itself).
const MIN_GAMMA: f64 = 1e-5;

/// The integrand of `F^k`: `cos^k(2ξ) exp(-u tan ξ)`.
fn f_integrand(u: f64, k: u32, xi: f64) -> f64 {
    let t = xi.tan();
    let decay = if t.is_finite() {
        (-u * t).exp()
    } else if u > 0.0 {
        0.0
    } else {
        1.0
    };
    (2.0 * xi).cos().powi(k as i32) * decay
}

/// `F^k(u, v) = ∫_0^v cos^k(2ξ) exp(-u tan ξ) dξ` (eqs. 3.15 and 3.19), by adaptive
/// quadrature to ~1e-13.
pub fn special_f(u: f64, v: f64, k: u32) -> f64 {
    adaptive_simpson(&|xi| f_integrand(u, k, xi), 0.0, v.clamp(0.0, FRAC_PI_2), 1e-13)
}

/// How tables are read between their samples.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interpolation {
    Nearest,
    Bilinear,
}

/// A 2D table over `(s, t) ∈ [0, 1]²`, row-major in `t` (rows) × `s` (columns).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Table2 {
    pub width: usize,
    pub height: usize,
    pub values: Vec<f32>,
}

impl Table2 {
    /// The value at `(s, t) ∈ [0, 1]²` (clamped), as a GPU sampler would return it.
    pub fn sample(&self, s: f64, t: f64, interpolation: Interpolation) -> f64 {
        let x = s.clamp(0.0, 1.0) * (self.width - 1) as f64;
        let y = t.clamp(0.0, 1.0) * (self.height - 1) as f64;
        let at = |x: usize, y: usize| f64::from(self.values[y * self.width + x]);
        match interpolation {
            Interpolation::Nearest => at(x.round() as usize, y.round() as usize),
            Interpolation::Bilinear => {
                let (x0, y0) = (x.floor() as usize, y.floor() as usize);
                let (x1, y1) = ((x0 + 1).min(self.width - 1), (y0 + 1).min(self.height - 1));
                let (fx, fy) = (x - x0 as f64, y - y0 as f64);
                (at(x0, y0) * (1.0 - fx) + at(x1, y0) * fx) * (1.0 - fy)
                    + (at(x0, y1) * (1.0 - fx) + at(x1, y1) * fx) * fy
            }
        }
    }
}

/// Largest `u` the `F` tables hold; beyond it the asymptotic series is good to ~1e-6 relative.
const U_MAX: f64 = 64.0;
/// Scale of the `u` warp (denser samples at small `u`, where `F` changes fastest).
const U_WARP: f64 = 4.0;

/// `u ∈ [0, U_MAX] ↦ s ∈ [0, 1]`, the `F` tables' first coordinate: `√(u/(u+c))`, dense at
/// small `u` where `F(u, π/2) ≈ π/2 + u ln u` is not smooth in `u`.
fn to_s(u: f64) -> f64 {
    (u / (u + U_WARP) / (U_MAX / (U_MAX + U_WARP))).sqrt()
}

fn from_s(s: f64) -> f64 {
    let w = s * s * U_MAX / (U_MAX + U_WARP);
    U_WARP * w / (1.0 - w)
}

/// `v ∈ [0, π/2] ↦ r ∈ [0, 1]`, the second coordinate: cosine spacing, dense at both ends
/// (near 0 `F` turns over within `1/u`; near π/2 within `u`).
fn to_r(v: f64) -> f64 {
    (1.0 - 4.0 * v / PI).clamp(-1.0, 1.0).acos() / PI
}

fn from_r(r: f64) -> f64 {
    FRAC_PI_4 * (1.0 - (PI * r).cos())
}

/// `F^0(u, v)` for large `u`: with `t = tan ξ`, `F = ∫_0^{tan v} e^{-ut} (1 − t² + …) dt`.
fn f_asymptotic(u: f64, v: f64) -> f64 {
    let big_t = v.min(FRAC_PI_2 - 1e-9).tan();
    let e = (-u * big_t).exp();
    (1.0 - e) / u - (2.0 - e * (u * u * big_t * big_t + 2.0 * u * big_t + 2.0)) / (u * u * u)
}

/// The `G` tables' first coordinate: `T ∈ [0, ∞) ↦ T/(1+T)`.
fn to_t(t: f64) -> f64 {
    t / (1.0 + t)
}

fn from_t(s: f64) -> f64 {
    if s >= 1.0 { f64::INFINITY } else { s / (1.0 - s) }
}

/// `F^k` tabulated (eq. 3.19; `k = 0` is eq. 3.15).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FTable {
    pub k: u32,
    /// `(1+u)·F^k(u, v)` over `s(u)` (columns, [`to_s`]) and `r(v)` (rows, [`to_r`]).
    pub table: Table2,
}

impl FTable {
    /// Each column (one `u`) is one running integral over `v`, row to row.
    pub fn new(k: u32, resolution: usize) -> Self {
        use rayon::prelude::*;
        let n = resolution.max(2);
        let columns: Vec<Vec<f32>> = (0..n)
            .into_par_iter()
            .map(|x| {
                let u = from_s(x as f64 / (n - 1) as f64);
                let mut running = 0.0;
                let mut previous = 0.0;
                (0..n)
                    .map(|y| {
                        let v = from_r(y as f64 / (n - 1) as f64);
                        running += adaptive_simpson(&|xi| f_integrand(u, k, xi), previous, v, 1e-14);
                        previous = v;
                        ((1.0 + u) * running) as f32
                    })
                    .collect()
            })
            .collect();
        let values = (0..n * n).map(|i| columns[i % n][i / n]).collect();
        Self { k, table: Table2 { width: n, height: n, values } }
    }

    pub fn lookup(&self, u: f64, v: f64, interpolation: Interpolation) -> f64 {
        if u > U_MAX {
            // cos^k(2ξ) ≈ 1 where the integrand lives (ξ ≲ 1/u).
            return f_asymptotic(u, v);
        }
        self.table.sample(to_s(u), to_r(v), interpolation) / (1.0 + u)
    }
}

/// A phase function `k(α) = Σ W_k cos^k α` (eq. 3.18), normalised to `∫ k dω = 1`.
#[derive(Clone, Debug, PartialEq)]
pub struct Phase {
    pub weights: Vec<f64>,
}

impl Phase {
    pub fn isotropic() -> Self {
        Self { weights: vec![1.0 / (4.0 * PI)] }
    }

    /// From unnormalised coefficients `a_0 + a_1 cos α + a_2 cos² α + …`; `None` when the
    /// polynomial is negative somewhere or integrates to zero.
    pub fn polynomial(coefficients: &[f64]) -> Option<Self> {
        // ∫ cos^k α dω = 2π ∫_{-1}^{1} μ^k dμ = 4π/(k+1) for even k, 0 for odd.
        let total: f64 = coefficients
            .iter()
            .enumerate()
            .map(|(k, a)| if k % 2 == 0 { a * 4.0 * PI / (k + 1) as f64 } else { 0.0 })
            .sum();
        let negative = (0..=200).any(|i| {
            let mu = -1.0 + i as f64 / 100.0;
            coefficients.iter().rev().fold(0.0, |acc, a| acc * mu + a) < -1e-12
        });
        (total > 0.0 && !negative).then(|| Self { weights: coefficients.iter().map(|a| a / total).collect() })
    }

    pub fn eval(&self, cos_alpha: f64) -> f64 {
        self.weights.iter().rev().fold(0.0, |acc, w| acc * cos_alpha + w)
    }
}

/// The airlight of one view ray: an isotropic point source of intensity `i0` at distance
/// `d_sv` and angle `gamma` from the ray, the ray ending at `d_vp` (∞ for the sky), medium `beta`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AirlightQuery {
    pub beta: f64,
    pub d_sv: f64,
    pub d_vp: f64,
    pub gamma: f64,
    pub i0: f64,
}

/// The closed-form factors of eq. 3.16: `A_0` (eq. 3.7), `A_1` (eq. 3.8) and the two `v`
/// arguments of `F`.
pub fn airlight_factors(q: &AirlightQuery) -> (f64, f64, f64, f64) {
    let gamma = q.gamma.clamp(MIN_GAMMA, PI);
    let (t_sv, t_vp) = (q.beta * q.d_sv, q.beta * q.d_vp);
    let (sin, cos) = gamma.sin_cos();
    let sin = sin.max(MIN_GAMMA);
    let a0 = q.beta * q.beta * q.i0 * (-t_sv * cos).exp() / (2.0 * PI * t_sv * sin);
    let a1 = t_sv * sin;
    let v_far =
        if t_vp.is_infinite() { FRAC_PI_2 } else { FRAC_PI_4 + 0.5 * ((t_vp - t_sv * cos) / (t_sv * sin)).atan() };
    (a0, a1, v_far, gamma / 2.0)
}

/// Airlight by eq. 3.16 (isotropic, `tables[0]` = `F^0`) or, for a polynomial phase, the sum
/// over its terms `4π W_k A_0 [F^k(A_1, v_far) − F^k(A_1, γ/2)]` (scattering angle
/// `cos α = cos 2ξ` in eq. 3.14's variable; `tables[k]` = `F^k`).
pub fn airlight(q: &AirlightQuery, phase: &Phase, tables: &[FTable], interpolation: Interpolation) -> f64 {
    if q.beta <= 0.0 || q.d_sv <= 0.0 || q.d_vp <= 0.0 {
        return 0.0;
    }
    let (a0, a1, v_far, v_near) = airlight_factors(q);
    if v_far - v_near < NARROW {
        return airlight_narrow(q, phase, a1, v_far, v_near);
    }
    let mut total = 0.0;
    for (w, table) in phase.weights.iter().zip(tables) {
        let (far, near) = (table.lookup(a1, v_far, interpolation), table.lookup(a1, v_near, interpolation));
        // A difference far below the values it comes from is table noise: integrate directly.
        if (far - near).abs() < 1e-2 * far.abs().max(near.abs()) {
            return airlight_narrow(q, phase, a1, v_far, v_near);
        }
        total += 4.0 * PI * w * (far - near);
    }
    total * a0
}

/// Below this width of `[γ/2, v_far]` the table difference cancels badly (short view rays,
/// sources behind the viewer where `A_0` is huge): integrate eq. 3.14 directly instead.
pub const NARROW: f64 = 0.05;

/// Eq. 3.14 integrated directly over `[γ/2, v_far]` by 6-point Gauss–Legendre, with `A_0`'s
/// exponential folded into the integrand's (no overflow where `e^{-T cos γ}` is huge). Where
/// `e^{-A_1 tan ξ}` falls steeply, in `y = e^{-A_1 (tan ξ − tan ξ_0)}` instead: with
/// `t = tan ξ` the integrand `e^{-A_1 t}/(1+t²)` becomes the smooth `1/(A_1 (1+t²))` in `y`.
fn airlight_narrow(q: &AirlightQuery, phase: &Phase, a1: f64, v_far: f64, v_near: f64) -> f64 {
    const X: [f64; 6] = [
        -0.932_469_514_203_152,
        -0.661_209_386_466_265,
        -0.238_619_186_083_197,
        0.238_619_186_083_197,
        0.661_209_386_466_265,
        0.932_469_514_203_152,
    ];
    const W: [f64; 6] = [
        0.171_324_492_379_170,
        0.360_761_573_048_139,
        0.467_913_934_572_691,
        0.467_913_934_572_691,
        0.360_761_573_048_139,
        0.171_324_492_379_170,
    ];
    let gamma = q.gamma.clamp(MIN_GAMMA, PI);
    let t_sv = q.beta * q.d_sv;
    let (sin, cos) = gamma.sin_cos();
    let scale = q.beta * q.beta * q.i0 / (2.0 * PI * t_sv * sin.max(MIN_GAMMA));
    let phase_at = |t: f64| 4.0 * PI * phase.eval((1.0 - t * t) / (1.0 + t * t));
    let (t0, t1) = (v_near.tan(), v_far.min(FRAC_PI_2 - 1e-12).tan());
    let drop = a1 * (t1 - t0);
    if drop > 1.0 && a1 > 1.0 {
        let y_end = (-drop).exp();
        let (mid, half) = (0.5 * (1.0 + y_end), 0.5 * (1.0 - y_end));
        let sum: f64 = X
            .iter()
            .zip(W)
            .map(|(x, w)| {
                let t = t0 - (mid + half * x).ln() / a1;
                w * phase_at(t) / (1.0 + t * t)
            })
            .sum();
        return scale * (-t_sv * cos - a1 * t0).exp() / a1 * half * sum;
    }
    let (mid, half) = (0.5 * (v_far + v_near), 0.5 * (v_far - v_near));
    let sum: f64 = X
        .iter()
        .zip(W)
        .map(|(x, w)| {
            let xi = mid + half * x;
            let t = xi.tan();
            w * phase_at(t) * (-t_sv * cos - a1 * t).exp()
        })
        .sum();
    scale * half * sum
}

/// Airlight by numerical integration of eq. 3.5 (with `k(α)` in place of `1/4π`), the
/// independent reference. `d_vp = ∞` integrates to where the transmittance is below 1e-12.
pub fn airlight_reference(q: &AirlightQuery, phase: &Phase) -> f64 {
    let gamma = q.gamma.clamp(MIN_GAMMA, PI);
    let (sin, cos) = gamma.sin_cos();
    let end = if q.d_vp.is_finite() { q.d_vp } else { (q.d_sv + 40.0 / q.beta.max(1e-9)).max(q.d_sv * 2.0) };
    let f = |x: f64| {
        let d2 = (q.d_sv * q.d_sv + x * x - 2.0 * x * q.d_sv * cos).max(1e-300);
        let d = d2.sqrt();
        let cos_alpha = (q.d_sv * cos - x) / d;
        q.beta * q.i0 * phase.eval(cos_alpha) * (-q.beta * (d + x)).exp() / d2
    };
    // Split at the closest approach to the source, with the peak's width resolved.
    let closest = q.d_sv * cos;
    let width = q.d_sv * sin;
    let mut cuts = vec![0.0, end];
    for c in [closest - 10.0 * width, closest - width, closest, closest + width, closest + 10.0 * width] {
        if c > 0.0 && c < end {
            cuts.push(c);
        }
    }
    cuts.sort_by(f64::total_cmp);
    let scale = f(closest.clamp(0.0, end)).abs().max(f(0.0).abs()).max(1e-300);
    cuts.windows(2).map(|w| adaptive_simpson(&f, w[0], w[1], scale * width.max(1e-9) * 1e-9)).sum()
}

mod environment;
mod errors;
mod surface;

pub use environment::*;
pub use errors::*;
pub use surface::*;

#[cfg(test)]
mod tests;
