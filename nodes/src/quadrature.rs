//! Gauss–Legendre quadrature on `[-1, 1]`, used for exact spherical integration of
//! band-limited functions (nodes in `cos θ`, uniform trapezoid in `φ`).

use std::f64::consts::PI;

/// Gauss–Legendre nodes and weights on `[-1, 1]` with `n` points (exact for
/// polynomials of degree `2n - 1`). Newton iteration on the Legendre recurrence.
pub fn gauss_legendre(n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut nodes = vec![0.0; n];
    let mut weights = vec![0.0; n];
    for i in 0..n.div_ceil(2) {
        let mut x = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut derivative = 0.0;
        for _ in 0..100 {
            let (p, dp) = legendre_with_derivative(n, x);
            derivative = dp;
            let step = p / dp;
            x -= step;
            if step.abs() < 1e-16 {
                let (_, dp) = legendre_with_derivative(n, x);
                derivative = dp;
                break;
            }
        }
        let w = 2.0 / ((1.0 - x * x) * derivative * derivative);
        nodes[i] = x;
        weights[i] = w;
        nodes[n - 1 - i] = -x;
        weights[n - 1 - i] = w;
    }
    (nodes, weights)
}

fn legendre_with_derivative(n: usize, x: f64) -> (f64, f64) {
    let (mut p0, mut p1) = (1.0, x);
    if n == 0 {
        return (1.0, 0.0);
    }
    for k in 2..=n {
        let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
        p0 = p1;
        p1 = p2;
    }
    let dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
    (p1, dp)
}

/// `∫_a^b f` by adaptive Simpson's rule to an absolute tolerance (Richardson-corrected),
/// for integrands with peaks the caller cannot place exactly (reference integrals).
pub fn adaptive_simpson(f: &dyn Fn(f64) -> f64, a: f64, b: f64, tolerance: f64) -> f64 {
    /// An interval with its end and middle values and its Simpson estimate.
    #[derive(Clone, Copy)]
    struct Segment {
        a: f64,
        b: f64,
        fa: f64,
        fm: f64,
        fb: f64,
        whole: f64,
    }
    fn recurse(f: &dyn Fn(f64) -> f64, s: Segment, tol: f64, depth: u32) -> f64 {
        let m = 0.5 * (s.a + s.b);
        let (lm, rm) = (0.5 * (s.a + m), 0.5 * (m + s.b));
        let (flm, frm) = (f(lm), f(rm));
        let left =
            Segment { a: s.a, b: m, fa: s.fa, fm: flm, fb: s.fm, whole: (m - s.a) / 6.0 * (s.fa + 4.0 * flm + s.fm) };
        let right =
            Segment { a: m, b: s.b, fa: s.fm, fm: frm, fb: s.fb, whole: (s.b - m) / 6.0 * (s.fm + 4.0 * frm + s.fb) };
        let delta = left.whole + right.whole - s.whole;
        if depth == 0 || delta.abs() <= 15.0 * tol {
            return left.whole + right.whole + delta / 15.0;
        }
        recurse(f, left, tol * 0.5, depth - 1) + recurse(f, right, tol * 0.5, depth - 1)
    }
    if b <= a {
        return 0.0;
    }
    let (fa, fm, fb) = (f(a), f(0.5 * (a + b)), f(b));
    let whole = (b - a) / 6.0 * (fa + 4.0 * fm + fb);
    recurse(f, Segment { a, b, fa, fm, fb, whole }, tolerance, 40)
}

/// A product quadrature on the unit sphere: Gauss–Legendre in `z = cos θ` times the
/// trapezoid rule in `φ`. With `n_theta` and `n_phi` points it integrates spherical
/// harmonics products exactly up to total degree `min(2 n_theta - 1, n_phi - 1)`.
pub struct SphereQuadrature {
    pub directions: Vec<glam::DVec3>,
    pub weights: Vec<f64>,
}

impl SphereQuadrature {
    /// A rule exact for polynomials on the sphere of total degree `degree`.
    pub fn exact_for_degree(degree: usize) -> Self {
        let n_theta = degree / 2 + 1;
        let n_phi = degree + 1;
        Self::new(n_theta, n_phi)
    }

    pub fn new(n_theta: usize, n_phi: usize) -> Self {
        let (zs, ws) = gauss_legendre(n_theta);
        let mut directions = Vec::with_capacity(n_theta * n_phi);
        let mut weights = Vec::with_capacity(n_theta * n_phi);
        let dphi = 2.0 * PI / n_phi as f64;
        for (z, w) in zs.iter().zip(&ws) {
            let r = (1.0 - z * z).max(0.0).sqrt();
            for j in 0..n_phi {
                let phi = (j as f64 + 0.5) * dphi;
                directions.push(glam::DVec3::new(r * phi.cos(), r * phi.sin(), *z));
                weights.push(w * dphi);
            }
        }
        Self { directions, weights }
    }

    pub fn integrate(&self, f: impl Fn(glam::DVec3) -> f64) -> f64 {
        self.directions.iter().zip(&self.weights).map(|(d, w)| f(*d) * w).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn adaptive_simpson_integrates_a_sharp_peak() {
        // ∫_{-1}^{1} ε / (x² + ε²) dx = 2 atan(1/ε): a Lorentzian of width 1e-4.
        let eps: f64 = 1e-4;
        let exact = 2.0 * (1.0 / eps).atan();
        let got = adaptive_simpson(&|x| eps / (x * x + eps * eps), -1.0, 1.0, 1e-10);
        assert!((got - exact).abs() < 1e-7, "{got} vs {exact}");
        assert!((adaptive_simpson(&f64::exp, 0.0, 1.0, 1e-12) - (1f64.exp() - 1.0)).abs() < 1e-11);
    }

    #[test]
    fn gauss_legendre_integrates_polynomials_exactly() {
        let (x, w) = gauss_legendre(8);
        for degree in 0..16 {
            let numeric: f64 = x.iter().zip(&w).map(|(x, w)| w * x.powi(degree)).sum();
            let exact = if degree % 2 == 1 { 0.0 } else { 2.0 / (degree as f64 + 1.0) };
            assert!((numeric - exact).abs() < 1e-14, "degree {degree}: {numeric} vs {exact}");
        }
    }

    #[test]
    fn sphere_rule_area_and_moments() {
        let q = SphereQuadrature::exact_for_degree(6);
        assert!((q.integrate(|_| 1.0) - 4.0 * PI).abs() < 1e-12);
        // ∫ x² dω = 4π/3, ∫ x²y²z² dω = 4π/105.
        assert!((q.integrate(|d| d.x * d.x) - 4.0 * PI / 3.0).abs() < 1e-12);
        let m = q.integrate(|d| d.x * d.x * d.y * d.y * d.z * d.z);
        assert!((m - 4.0 * PI / 105.0).abs() < 1e-12);
    }
}
