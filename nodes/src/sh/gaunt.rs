//! SH products through Gaunt (tripling) coefficients `C_ijk = ∫ Y_i Y_j Y_k dω`, stored
//! sparsely (Sun 2008 §2.2; the SH analogue of the wavelet tripling coefficients).
//!
//! Each coefficient factorises as `∫ N_i N_j N_k d(cos θ) · ∫ Φ_i Φ_j Φ_k dφ`. Both factors
//! are polynomials (in `cos θ` and in `e^{iφ}`), so Gauss–Legendre and the trapezoid rule
//! with enough nodes give them exactly; the selection rules (`l_k` between `|l_i - l_j|` and
//! `l_i + l_j` with even sum, `|m_k| = |m_i| ± |m_j|`) skip the zeros without evaluating them.

use super::{ShBasis, coeff_count, index};
use glam::DVec3;
use std::f64::consts::PI;

/// Sparse Gaunt tensor for products of an `a`-band and a `b`-band function projected to
/// `out` bands.
#[derive(Clone, Debug)]
pub struct GauntTable {
    pub bands_a: usize,
    pub bands_b: usize,
    pub bands_out: usize,
    /// `(i, j, k, C_ijk)`, sorted by `k`.
    entries: Vec<(u32, u32, u32, f64)>,
}

impl GauntTable {
    pub fn new(bands_a: usize, bands_b: usize, bands_out: usize) -> Self {
        let max_l = bands_a + bands_b + bands_out;
        let max_m = bands_a.max(bands_b).max(bands_out);
        // Legendre part N_l^|m|(z) (includes sin^|m| θ) at Gauss nodes.
        let n_theta = max_l / 2 + 2;
        let (zs, ws) = crate::quadrature::gauss_legendre(n_theta);
        let table_bands = bands_a.max(bands_b).max(bands_out);
        let basis = ShBasis::new(table_bands);
        let legendre: Vec<Vec<f64>> = zs
            .iter()
            .map(|z| {
                let y = basis.eval_vec(DVec3::new((1.0 - z * z).max(0.0).sqrt(), 0.0, *z));
                (0..coeff_count(table_bands))
                    .map(|i| {
                        let l = super::band_of(i);
                        let m = i as i64 - (l * (l + 1)) as i64;
                        if m == 0 { y[i] } else { y[index(l, m.abs())] / 2f64.sqrt() }
                    })
                    .collect()
            })
            .collect();
        // Azimuthal part by the trapezoid rule, exact for frequencies below `n_phi`.
        let n_phi = 3 * max_m + 1;
        let phi_fn = |m: i64, phi: f64| -> f64 {
            match m {
                0 => 1.0,
                m if m > 0 => 2f64.sqrt() * (m as f64 * phi).cos(),
                m => 2f64.sqrt() * ((-m) as f64 * phi).sin(),
            }
        };
        let phi_integral = |m1: i64, m2: i64, m3: i64| -> f64 {
            let dphi = 2.0 * PI / n_phi as f64;
            (0..n_phi)
                .map(|k| {
                    let phi = k as f64 * dphi;
                    phi_fn(m1, phi) * phi_fn(m2, phi) * phi_fn(m3, phi)
                })
                .sum::<f64>()
                * dphi
        };
        let mut entries = Vec::new();
        for l1 in 0..bands_a {
            for m1 in -(l1 as i64)..=l1 as i64 {
                let i = index(l1, m1);
                for l2 in 0..bands_b {
                    for m2 in -(l2 as i64)..=l2 as i64 {
                        let j = index(l2, m2);
                        let l3_min = l1.abs_diff(l2);
                        let l3_max = (l1 + l2).min(bands_out.saturating_sub(1));
                        let mut l3 = l3_min;
                        while l3 <= l3_max {
                            let (a1, a2) = (m1.abs(), m2.abs());
                            let mut candidates = [a1 + a2, (a1 - a2).abs(), -(a1 + a2), -(a1 - a2).abs()];
                            candidates.sort_unstable();
                            let mut last = i64::MIN;
                            for m3 in candidates {
                                if m3 == last || m3.unsigned_abs() as usize > l3 {
                                    continue;
                                }
                                last = m3;
                                let phi_part = phi_integral(m1, m2, m3);
                                if phi_part.abs() < 1e-12 {
                                    continue;
                                }
                                let k = index(l3, m3);
                                let theta_part: f64 = legendre
                                    .iter()
                                    .zip(&ws)
                                    .map(|(n, w)| w * n[index(l1, a1)] * n[index(l2, a2)] * n[index(l3, m3.abs())])
                                    .sum();
                                let value = theta_part * phi_part;
                                if value.abs() > 1e-13 {
                                    entries.push((i as u32, j as u32, k as u32, value));
                                }
                            }
                            l3 += 2;
                        }
                    }
                }
            }
        }
        entries.sort_by_key(|e| (e.2, e.0, e.1));
        Self { bands_a, bands_b, bands_out, entries }
    }

    pub fn entries(&self) -> &[(u32, u32, u32, f64)] {
        &self.entries
    }

    pub fn len(&self) -> usize {
        self.entries.len()
    }

    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// Projection of the pointwise product `f g` onto `bands_out` bands:
    /// `(fg)_k = Σ_ij C_ijk f_i g_j`.
    pub fn multiply(&self, f: &[f64], g: &[f64]) -> Vec<f64> {
        assert_eq!(f.len(), coeff_count(self.bands_a), "first factor has the wrong band count");
        assert_eq!(g.len(), coeff_count(self.bands_b), "second factor has the wrong band count");
        let mut out = vec![0.0; coeff_count(self.bands_out)];
        for &(i, j, k, c) in &self.entries {
            out[k as usize] += c * f[i as usize] * g[j as usize];
        }
        out
    }

    /// The product matrix `M_kj = Σ_i C_ijk f_i`, so that `(fg) = M g` (used when one factor
    /// is fixed and applied many times, e.g. visibility times lighting).
    pub fn product_matrix(&self, f: &[f64]) -> Vec<f64> {
        let cols = coeff_count(self.bands_b);
        let mut m = vec![0.0; coeff_count(self.bands_out) * cols];
        for &(i, j, k, c) in &self.entries {
            m[k as usize * cols + j as usize] += c * f[i as usize];
        }
        m
    }
}
