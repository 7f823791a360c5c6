//! Light scattered onto surfaces (Sun 2008 eqs. 3.22–3.29): the `G_n` tables (eq. 3.23), the
//! Phong layers, and the surface radiance with its reference by quadrature.

use super::*;

/// `G_n(T_sp, θ_s)` tabulated (eq. 3.23): the hemisphere integral of eq. 3.17's airlight shape
/// against `cos^n θ_i` (`n = 1` is the Lambertian `G_0` of eq. 3.26; `n` is the Phong
/// exponent after reparameterisation about the mirror direction). Columns: `T/(1+T)`; rows:
/// `√(θ_s/π)` over `θ_s ∈ [0, π]` (lights below the horizon still light the fog above the
/// surface; rows are dense near 0, where peaky lobes make `G_n` vary fastest). Stores
/// `(1+T)·e^T·G_n`: every scattered path is at least `D_sp` long, so `e^T G_n` stays O(1) where
/// `G_n` itself falls by orders of magnitude between columns.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GTable {
    pub exponent: f64,
    pub table: Table2,
}

/// `θ_s ∈ [0, π] ↦` the `G` tables' row coordinate.
fn to_theta_row(theta: f64) -> f64 {
    (theta / PI).clamp(0.0, 1.0).sqrt()
}

/// `∫_0^{2π} max(0, a + b cos ψ)^n dψ` (`b ≥ 0`): the azimuthal ring of `cos^n θ_i` at angle
/// `γ'` from the source, `a = cos θ_s cos γ'`, `b = sin θ_s sin γ'`. Gauss–Legendre over the
/// part of `[0, ψ_end]` where the lobe is not negligible (it falls at least as fast as a
/// Gaussian of width `σ = (π/2)·√((a+b)/(n b))`, so beyond `9σ` it is below `e^{-40}`).
pub(super) fn lobe_ring(a: f64, b: f64, n: f64, nodes: &[f64], weights: &[f64]) -> f64 {
    let peak = a + b;
    if peak <= 0.0 {
        return 0.0;
    }
    if b < 1e-12 * peak {
        return 2.0 * PI * peak.powf(n);
    }
    let end = if a >= b { PI } else { (-a / b).acos() };
    let sigma = FRAC_PI_2 * (peak / (n * b)).sqrt();
    let range = end.min(9.0 * sigma);
    let half: f64 = nodes
        .iter()
        .zip(weights)
        .map(|(x, w)| {
            let psi = (x + 1.0) * 0.5 * range;
            w * (a + b * psi.cos()).max(0.0).powf(n)
        })
        .sum();
    half * range
}

/// Polar nodes `γ' ∈ [0, π]` and the G tables' quadrature, shared by every exponent.
struct GQuadrature {
    gamma: Vec<f64>,
    weights: Vec<f64>,
    ring_nodes: (Vec<f64>, Vec<f64>),
}

impl GQuadrature {
    fn new() -> Self {
        let (nodes, weights) = gauss_legendre(512);
        Self {
            gamma: nodes.iter().map(|x| (x + 1.0) * FRAC_PI_2).collect(),
            weights: weights.iter().map(|w| w * FRAC_PI_2).collect(),
            ring_nodes: gauss_legendre(32),
        }
    }

    /// `e^T · e^{-T cos γ'} [F(T sin γ', π/2) − F(T sin γ', γ'/2)]` per polar node (eq. 3.23
    /// without `1/sin γ'`, which `dω = sin γ' dγ' dψ` cancels), for the table column `T`. As
    /// `cos γ' + sin γ' tan(γ'/2) = 1`, this is `∫_{γ'/2}^{π/2} exp(−T sin γ' (tan ξ − tan γ'/2)) dξ`,
    /// integrated directly: the difference of two `F` values cancels catastrophically at large `T`.
    fn shape(&self, t_sp: f64) -> Vec<f64> {
        self.gamma
            .iter()
            .map(|&g| {
                let (a, t0) = (t_sp * g.sin(), (g / 2.0).tan());
                let integrand = |xi: f64| {
                    let t = xi.tan();
                    if t.is_finite() { (-a * (t - t0)).exp() } else { f64::from(a == 0.0) }
                };
                // The integral is at most min(π/2, 1/a) (the integrand falls from 1 at rate ≥ a).
                let scale = (FRAC_PI_2 - g / 2.0).min(1.0 / a.max(1e-300));
                adaptive_simpson(&integrand, g / 2.0, FRAC_PI_2, 1e-10 * scale)
            })
            .collect()
    }

    /// The lobe ring per polar node for the table row `θ_s`.
    fn rings(&self, theta_s: f64, exponent: f64) -> Vec<f64> {
        let (sin_s, cos_s) = theta_s.sin_cos();
        let (nodes, weights) = &self.ring_nodes;
        self.gamma.iter().map(|&g| lobe_ring(cos_s * g.cos(), sin_s * g.sin(), exponent, nodes, weights)).collect()
    }

    /// Tables for several exponents: `G_n(T, θ) = ∫ shape(T, γ') ring_n(θ, γ') dγ'` separates,
    /// so each table is one matrix product of per-column shapes and per-row rings.
    fn tables(&self, exponents: &[f64], resolution: usize) -> Vec<GTable> {
        use rayon::prelude::*;
        let n = resolution.max(2);
        let at = |i: usize| i as f64 / (n - 1) as f64;
        let shapes: Vec<Vec<f64>> = (0..n)
            .into_par_iter()
            .map(|x| {
                // The last column (T = ∞, where e^T G_n grows like ln T) repeats the one before
                // it: everything there is extinguished by e^{-T} anyway.
                let t_sp = from_t(at(x).min(1.0 - 1.0 / (n - 1) as f64));
                self.shape(t_sp).iter().zip(&self.weights).map(|(s, w)| (1.0 + t_sp) * s * w).collect()
            })
            .collect();
        exponents
            .iter()
            .map(|&exponent| {
                let values: Vec<Vec<f32>> = (0..n)
                    .into_par_iter()
                    .map(|y| {
                        let theta = at(y) * at(y) * PI;
                        let rings = self.rings(theta, exponent);
                        shapes.iter().map(|s| s.iter().zip(&rings).map(|(a, b)| a * b).sum::<f64>() as f32).collect()
                    })
                    .collect();
                GTable { exponent, table: Table2 { width: n, height: n, values: values.concat() } }
            })
            .collect()
    }
}

impl GTable {
    pub fn new(exponent: f64, resolution: usize) -> Self {
        GQuadrature::new().tables(&[exponent], resolution).remove(0)
    }

    pub fn lookup(&self, t_sp: f64, theta_s: f64, interpolation: Interpolation) -> f64 {
        self.table.sample(to_t(t_sp), to_theta_row(theta_s), interpolation) * (-t_sp).exp() / (1.0 + t_sp)
    }
}

/// Tables per octave of Phong exponent in [`PhongGTables`] (layer `k` holds `n = 2^{k/4}`).
pub const PHONG_STEPS_PER_OCTAVE: usize = 4;
/// Layers of [`PhongGTables`]: `n` from 1 (the Lambertian `G_0`) to 4096.
pub const PHONG_LAYERS: usize = 12 * PHONG_STEPS_PER_OCTAVE + 1;

/// The Phong exponent of ladder layer `k`.
pub fn phong_layer_exponent(k: usize) -> f64 {
    (k as f64 / PHONG_STEPS_PER_OCTAVE as f64).exp2()
}

/// `G_n` for any Phong exponent: a ladder of tables at quarter-octave exponents, interpolated
/// linearly in `log₂ n` after normalising by the lobe's solid angle `∫ cos^n θ dω = 2π/(n+1)`
/// (the normalised tables converge as `n` grows, so exponents beyond the last use it).
/// Material edits never recompute a table.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PhongGTables {
    pub tables: Vec<GTable>,
}

impl PhongGTables {
    pub fn new(resolution: usize) -> Self {
        let exponents: Vec<f64> = (0..PHONG_LAYERS).map(phong_layer_exponent).collect();
        Self { tables: GQuadrature::new().tables(&exponents, resolution) }
    }

    /// The layers bracketing `exponent` and the weight of the upper one.
    pub fn bracket(&self, exponent: f64) -> (usize, usize, f64) {
        let last = self.tables.len() - 1;
        let position = (exponent.max(1.0).log2() * PHONG_STEPS_PER_OCTAVE as f64).min(last as f64);
        let lower = (position.floor() as usize).min(last);
        (lower, (lower + 1).min(last), position - lower as f64)
    }

    pub fn lookup(&self, exponent: f64, t_sp: f64, theta_s: f64, interpolation: Interpolation) -> f64 {
        let (lower, upper, w) = self.bracket(exponent);
        let normalised = |i: usize| {
            let g = &self.tables[i];
            g.lookup(t_sp, theta_s, interpolation) * (g.exponent + 1.0)
        };
        ((1.0 - w) * normalised(lower) + w * normalised(upper)) / (exponent.max(1.0) + 1.0)
    }
}

/// Reference for [`surface_scattered`]: eq. 3.22 with the airlight of each incident direction
/// from [`airlight_reference`] (rays to infinity), integrated over the hemisphere around the
/// normal `+Z` against `cos^n θ_i`; the source lies at `θ_s` in the XZ plane.
pub fn surface_scattered_reference(beta: f64, d_sp: f64, theta_s: f64, i0: f64, exponent: f64, n: usize) -> f64 {
    let phase = Phase::isotropic();
    let (nodes, weights) = gauss_legendre(n);
    let source = glam::DVec3::new(theta_s.sin(), 0.0, theta_s.cos());
    // Source-centred polar coordinates: dω = sin γ dγ dψ.
    let frame_x = source.any_orthonormal_vector();
    let frame_y = source.cross(frame_x);
    let mut total = 0.0;
    for (x, w) in nodes.iter().zip(&weights) {
        let g = (x + 1.0) * FRAC_PI_2;
        let (sin_g, cos_g) = g.sin_cos();
        let la = airlight_reference(&AirlightQuery { beta, d_sv: d_sp, d_vp: f64::INFINITY, gamma: g, i0 }, &phase);
        let mut ring = 0.0;
        let n_psi = 2 * n;
        for j in 0..n_psi {
            let psi = (j as f64 + 0.5) / n_psi as f64 * 2.0 * PI;
            let dir = source * cos_g + (frame_x * psi.cos() + frame_y * psi.sin()) * sin_g;
            if dir.z > 0.0 {
                ring += dir.z.powf(exponent);
            }
        }
        total += w * FRAC_PI_2 * la * sin_g * ring * 2.0 * PI / n_psi as f64;
    }
    total
}

/// A surface point seen through fog, lit by isotropic point lights (the CPU twin of the fog
/// shader, Fig. 3.13): `L = e^{-T_vp} L_p + Σ L_a` (eq. 3.29) with `L_p` from eqs. 3.27–3.28.
#[derive(Clone, Debug)]
pub struct FogShadingPoint {
    pub viewer: glam::DVec3,
    pub point: glam::DVec3,
    pub normal: glam::DVec3,
    /// Lambertian reflectance `k_d` (radiance per irradiance: albedo/π).
    pub k_d: f64,
    /// Phong `k_s cos^n` about the mirror direction; `k_s = 0` for none.
    pub k_s: f64,
    pub exponent: f64,
}

/// The tables a shading evaluation reads.
pub struct FogTables<'a> {
    pub f: &'a [FTable],
    pub g: &'a PhongGTables,
}

/// Single-scattered light reaching a surface point and reflected, per unit intensity and
/// reflectance (`k_d` or `k_s`): `β² G_n(T_sp, θ) / (2π T_sp)` (eqs. 3.26–3.28), `θ` from the
/// normal (Lambert, `n = 1`) or the mirror direction (Phong).
pub fn surface_scattered(beta: f64, d_sp: f64, theta: f64, exponent: f64, g: &PhongGTables) -> f64 {
    let t_sp = beta * d_sp;
    if t_sp <= 0.0 {
        return 0.0;
    }
    beta * beta * g.lookup(exponent, t_sp, theta, Interpolation::Bilinear) / (2.0 * PI * t_sp)
}

/// Radiance reaching the viewer from `p` through fog `beta` (isotropic phase), lights
/// `(position, intensity)`; visibility between lights and surfaces is not modelled (as in the
/// thesis, the medium's glow and surface terms are unshadowed).
pub fn shade(p: &FogShadingPoint, lights: &[(glam::DVec3, f64)], beta: f64, tables: &FogTables) -> f64 {
    let phase = Phase::isotropic();
    let to_viewer = p.viewer - p.point;
    let d_vp = to_viewer.length();
    let view = -to_viewer / d_vp;
    let mirror = view - 2.0 * view.dot(p.normal) * p.normal;
    let mut surface = 0.0;
    let mut air = 0.0;
    for &(position, i0) in lights {
        let to_light = position - p.point;
        let d_sp = to_light.length();
        let l = to_light / d_sp;
        let t_sp = beta * d_sp;
        let cos_s = l.dot(p.normal);
        let theta_s = cos_s.clamp(-1.0, 1.0).acos();
        let direct = (-t_sp).exp() / (d_sp * d_sp);
        surface += i0 * p.k_d * (direct * cos_s.max(0.0) + surface_scattered(beta, d_sp, theta_s, 1.0, tables.g));
        if p.k_s > 0.0 {
            let cos_m = l.dot(mirror);
            let theta_m = cos_m.clamp(-1.0, 1.0).acos();
            surface += i0
                * p.k_s
                * (direct * cos_m.max(0.0).powf(p.exponent) * f64::from(cos_s > 0.0)
                    + surface_scattered(beta, d_sp, theta_m, p.exponent, tables.g));
        }
        let to_source = position - p.viewer;
        let d_sv = to_source.length();
        let gamma = view.dot(to_source / d_sv).clamp(-1.0, 1.0).acos();
        air += airlight(&AirlightQuery { beta, d_sv, d_vp, gamma, i0 }, &phase, tables.f, Interpolation::Bilinear);
    }
    (-beta * d_vp).exp() * surface + air
}

/// [`shade`] with every scattering integral done numerically (eqs. 3.5 and 3.22).
pub fn shade_reference(p: &FogShadingPoint, lights: &[(glam::DVec3, f64)], beta: f64) -> f64 {
    let phase = Phase::isotropic();
    let to_viewer = p.viewer - p.point;
    let d_vp = to_viewer.length();
    let view = -to_viewer / d_vp;
    let mirror = view - 2.0 * view.dot(p.normal) * p.normal;
    // Rotate so the normal (or the mirror direction) is +Z for the hemisphere integrals.
    let theta = |axis: glam::DVec3, l: glam::DVec3| l.dot(axis).clamp(-1.0, 1.0).acos();
    let mut total = 0.0;
    for &(position, i0) in lights {
        let to_light = position - p.point;
        let d_sp = to_light.length();
        let l = to_light / d_sp;
        let direct = (-beta * d_sp).exp() / (d_sp * d_sp);
        let mut surface = p.k_d
            * (direct * l.dot(p.normal).max(0.0)
                + surface_scattered_reference(beta, d_sp, theta(p.normal, l), 1.0, 1.0, 48));
        if p.k_s > 0.0 {
            surface += p.k_s
                * (direct * l.dot(mirror).max(0.0).powf(p.exponent) * f64::from(l.dot(p.normal) > 0.0)
                    + surface_scattered_reference(beta, d_sp, theta(mirror, l), 1.0, p.exponent, 48));
        }
        let to_source = position - p.viewer;
        let d_sv = to_source.length();
        let gamma = view.dot(to_source / d_sv).clamp(-1.0, 1.0).acos();
        total += i0 * (-beta * d_vp).exp() * surface
            + airlight_reference(&AirlightQuery { beta, d_sv, d_vp, gamma, i0 }, &phase);
    }
    total
}
