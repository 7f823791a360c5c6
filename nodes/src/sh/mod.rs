//! Real orthonormal spherical harmonics: the one SH module every technique uses.
//!
//! # Convention
//!
//! * Index `l*(l+1)+m`, `0 <= l < bands`, `-l <= m <= l`; "`bands` = n" means `n²`
//!   coefficients (the thesis's "order n", Sun 2008 §2.2).
//! * Functions of a unit direction `(x, y, z)` given in **world coordinates** (right-handed,
//!   +Y up). The SH polar axis is world **+Z**; it is only a labelling of the basis, and
//!   every formula below is written in Cartesian form, so callers never convert angles.
//! * No Condon–Shortley phase: `Y_1,-1 = c·y`, `Y_1,0 = c·z`, `Y_1,1 = c·x` with
//!   `c = sqrt(3/4π)`. In general `Y_l,m = √2 K_l^m P_l^m(z) Re[(x+iy)^m] / sin^m θ` for `m > 0`,
//!   the imaginary part for `m < 0`, and `K_l^0 P_l(z)` for `m = 0`.
//! * Projection `f_lm = ∫ f Y_lm dω` (Sun 2008 eq. 2.12) and reconstruction `f ≈ Σ f_lm Y_lm`
//!   (eq. 2.13).

pub mod gaunt;
pub mod rotation;

pub use gaunt::GauntTable;
pub use rotation::ShRotation;

use glam::DVec3;
use std::f64::consts::PI;

// Stage value types this module owns (see `engine::value`).
crate::stage_type!(ShRgb, "SH", |v| v.coeffs.len() * 24, numbers = |v| v.coeffs.iter().flatten().copied());

/// Number of coefficients of an SH expansion with `bands` bands.
pub const fn coeff_count(bands: usize) -> usize {
    bands * bands
}

/// Linear index of `(l, m)`.
pub const fn index(l: usize, m: i64) -> usize {
    (l as i64 * (l as i64 + 1) + m) as usize
}

/// Band `l` of linear index `i`.
pub fn band_of(i: usize) -> usize {
    (i as f64).sqrt() as usize
}

/// Evaluator of all `bands²` real SH at a direction, with the recurrence factors of the
/// normalised associated Legendre functions precomputed (stable to at least 64 bands).
#[derive(Clone, Debug)]
pub struct ShBasis {
    bands: usize,
    /// `a_lm`, `b_lm` of `P̄_l^m = a_lm (z P̄_{l-1}^m - b_lm P̄_{l-2}^m)`, indexed like the SH.
    recurrence: Vec<(f64, f64)>,
}

impl ShBasis {
    pub fn new(bands: usize) -> Self {
        assert!(bands >= 1, "SH needs at least one band");
        let mut recurrence = vec![(0.0, 0.0); coeff_count(bands)];
        for l in 2..bands {
            for m in 0..l - 1 {
                let (lf, mf) = (l as f64, m as f64);
                let a = ((4.0 * lf * lf - 1.0) / (lf * lf - mf * mf)).sqrt();
                let b = (((lf - 1.0) * (lf - 1.0) - mf * mf) / (4.0 * (lf - 1.0) * (lf - 1.0) - 1.0)).sqrt();
                recurrence[index(l, m as i64)] = (a, b);
            }
        }
        Self { bands, recurrence }
    }

    pub fn bands(&self) -> usize {
        self.bands
    }

    pub fn len(&self) -> usize {
        coeff_count(self.bands)
    }

    pub fn is_empty(&self) -> bool {
        false
    }

    /// Writes `Y_lm(dir)` for all `l < bands` into `out` (`dir` must be unit length).
    pub fn eval(&self, dir: DVec3, out: &mut [f64]) {
        let bands = self.bands;
        debug_assert!(out.len() >= coeff_count(bands));
        let z = dir.z;
        // (c_m, s_m) = Re, Im of (x + i y)^m, i.e. sin^m θ (cos mφ, sin mφ).
        let (mut c, mut s) = (1.0, 0.0);
        // P̄_m^m without the sin^m θ factor (folded into c, s).
        let mut p_mm = (1.0 / (4.0 * PI)).sqrt();
        for m in 0..bands {
            let mf = m as f64;
            if m > 0 {
                p_mm *= ((2.0 * mf + 1.0) / (2.0 * mf)).sqrt();
                let (nc, ns) = (c * dir.x - s * dir.y, c * dir.y + s * dir.x);
                c = nc;
                s = ns;
            }
            let (scale_c, scale_s) = if m == 0 { (1.0, 0.0) } else { (2f64.sqrt() * c, 2f64.sqrt() * s) };
            let mut write = |l: usize, p: f64| {
                if m == 0 {
                    out[index(l, 0)] = p;
                } else {
                    out[index(l, m as i64)] = p * scale_c;
                    out[index(l, -(m as i64))] = p * scale_s;
                }
            };
            write(m, p_mm);
            if m + 1 < bands {
                let mut p_prev = p_mm;
                let mut p = (2.0 * mf + 3.0).sqrt() * z * p_mm;
                write(m + 1, p);
                for l in m + 2..bands {
                    let (a, b) = self.recurrence[index(l, m as i64)];
                    let next = a * (z * p - b * p_prev);
                    p_prev = p;
                    p = next;
                    write(l, p);
                }
            }
        }
    }

    /// `Y(dir)` as a new vector.
    pub fn eval_vec(&self, dir: DVec3) -> Vec<f64> {
        let mut out = vec![0.0; self.len()];
        self.eval(dir, &mut out);
        out
    }
}

/// Reconstructs `Σ f_lm Y_lm(dir)` for a scalar coefficient vector.
pub fn reconstruct(coeffs: &[f64], dir: DVec3) -> f64 {
    let basis = ShBasis::new(bands_of_len(coeffs.len()));
    let y = basis.eval_vec(dir);
    coeffs.iter().zip(&y).map(|(c, y)| c * y).sum()
}

/// Number of bands of a coefficient vector of length `len` (must be a square).
pub fn bands_of_len(len: usize) -> usize {
    let bands = band_of(len);
    assert_eq!(bands * bands, len, "SH vector length {len} is not a square");
    bands
}

/// Projects a scalar spherical function by an exact product quadrature: exact when `f` is
/// band-limited to `bands + extra_degree` bands.
pub fn project_fn(bands: usize, extra_degree: usize, f: impl Fn(DVec3) -> f64) -> Vec<f64> {
    let quadrature = crate::quadrature::SphereQuadrature::exact_for_degree(2 * bands + extra_degree);
    let basis = ShBasis::new(bands);
    let mut y = vec![0.0; basis.len()];
    let mut out = vec![0.0; basis.len()];
    for (d, w) in quadrature.directions.iter().zip(&quadrature.weights) {
        basis.eval(*d, &mut y);
        let fw = f(*d) * w;
        for (o, y) in out.iter_mut().zip(&y) {
            *o += fw * y;
        }
    }
    out
}

/// Projects weighted samples `(direction, solid angle, value)`: `f_lm ≈ Σ f_k Y_lm(ω_k) Δω_k`
/// (eq. 2.12 as a quadrature). Used for images, where `Δω_k` is the texel solid angle.
pub fn project_samples<'a>(bands: usize, samples: impl IntoIterator<Item = (DVec3, f64, [f64; 3])> + 'a) -> ShRgb {
    let basis = ShBasis::new(bands);
    let mut y = vec![0.0; basis.len()];
    let mut out = ShRgb::zero(bands);
    for (dir, solid_angle, value) in samples {
        basis.eval(dir, &mut y);
        for (o, y) in out.coeffs.iter_mut().zip(&y) {
            let w = y * solid_angle;
            o[0] += value[0] * w;
            o[1] += value[1] * w;
            o[2] += value[2] * w;
        }
    }
    out
}

/// Projects an equirectangular image with exact per-row texel solid angles (eq. 2.12 as a
/// quadrature over pixels), in parallel over rows.
pub fn project_equirect(image: &crate::cubemap::Equirect, bands: usize) -> ShRgb {
    use rayon::prelude::*;
    let basis = ShBasis::new(bands);
    // Per-column azimuth terms, so the inner loop has no trigonometry.
    let columns: Vec<(f64, f64)> = (0..image.width)
        .map(|x| {
            let phi = 2.0 * PI * ((x as f64 + 0.5) / image.width as f64 - 0.5);
            (phi.sin(), -phi.cos())
        })
        .collect();
    (0..image.height)
        .into_par_iter()
        .fold(
            || (ShRgb::zero(bands), vec![0.0; basis.len()]),
            |(mut acc, mut y), row| {
                let solid_angle = image.row_solid_angle(row);
                let theta = PI * (row as f64 + 0.5) / image.height as f64;
                let (sin_t, cos_t) = theta.sin_cos();
                for (x, (sin_p, neg_cos_p)) in columns.iter().enumerate() {
                    let p = image.pixels[row * image.width + x];
                    basis.eval(DVec3::new(sin_t * sin_p, cos_t, sin_t * neg_cos_p), &mut y);
                    let rgb = p.map(|v| v as f64 * solid_angle);
                    for (o, y) in acc.coeffs.iter_mut().zip(&y) {
                        o[0] += rgb[0] * y;
                        o[1] += rgb[1] * y;
                        o[2] += rgb[2] * y;
                    }
                }
                (acc, y)
            },
        )
        .map(|(acc, _)| acc)
        .reduce(
            || ShRgb::zero(bands),
            |mut a, b| {
                a.add_assign(&b);
                a
            },
        )
}

/// RGB SH coefficients (linear radiance).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ShRgb {
    pub bands: usize,
    pub coeffs: Vec<[f64; 3]>,
}

impl ShRgb {
    pub fn zero(bands: usize) -> Self {
        Self { bands, coeffs: vec![[0.0; 3]; coeff_count(bands)] }
    }

    /// Its first `bands` bands (all of it when it has no more).
    pub fn truncated(&self, bands: usize) -> Self {
        let bands = self.bands.min(bands);
        Self { bands, coeffs: self.coeffs[..coeff_count(bands)].to_vec() }
    }

    /// One colour channel as a scalar SH vector.
    pub fn channel(&self, c: usize) -> Vec<f64> {
        self.coeffs.iter().map(|v| v[c]).collect()
    }

    pub fn from_channels(channels: [&[f64]; 3]) -> Self {
        let bands = bands_of_len(channels[0].len());
        let coeffs = (0..channels[0].len()).map(|i| [channels[0][i], channels[1][i], channels[2][i]]).collect();
        Self { bands, coeffs }
    }

    pub fn add_assign(&mut self, other: &ShRgb) {
        assert_eq!(self.bands, other.bands);
        for (a, b) in self.coeffs.iter_mut().zip(&other.coeffs) {
            for c in 0..3 {
                a[c] += b[c];
            }
        }
    }

    /// Value of the expansion at `dir`.
    pub fn eval(&self, basis: &ShBasis, dir: DVec3) -> [f64; 3] {
        let y = basis.eval_vec(dir);
        let mut out = [0.0; 3];
        for (c, y) in self.coeffs.iter().zip(&y) {
            for k in 0..3 {
                out[k] += c[k] * y;
            }
        }
        out
    }

    /// Multiplies each band `l` by `factors[l]` (zonal convolution, windowing).
    pub fn scale_bands(&self, factors: &[f64]) -> Self {
        let mut out = self.clone();
        for (i, c) in out.coeffs.iter_mut().enumerate() {
            let f = factors[band_of(i)];
            for v in c.iter_mut() {
                *v *= f;
            }
        }
        out
    }

    /// Multiplies band `l` of channel `c` by `factors[l][c]` (per-channel zonal convolution);
    /// bands beyond `factors` are dropped.
    pub fn scale_bands_rgb(&self, factors: &[[f64; 3]]) -> Self {
        let mut out = self.clone();
        for (i, c) in out.coeffs.iter_mut().enumerate() {
            let f = factors.get(band_of(i)).copied().unwrap_or([0.0; 3]);
            for (v, f) in c.iter_mut().zip(f) {
                *v *= f;
            }
        }
        out
    }

    /// Irradiance coefficients `E_lm = Â_l L_lm` (Sun 2008 eqs. 2.20–2.25).
    pub fn irradiance(&self) -> Self {
        self.scale_bands(&clamped_cosine_factors(self.bands))
    }
}

/// `Â_l`, the clamped-cosine convolution factors (Sun 2008 eq. 2.24, with the typos of
/// eq. 2.22/2.25 fixed): `Â_0 = π`, `Â_1 = 2π/3`, `Â_odd>1 = 0`, and for even `l`
/// `Â_l = 2π (-1)^{l/2-1} / ((l+2)(l-1)) · l! / (2^l ((l/2)!)^2)`.
pub fn clamped_cosine_factor(l: usize) -> f64 {
    match l {
        0 => PI,
        1 => 2.0 * PI / 3.0,
        l if l % 2 == 1 => 0.0,
        l => {
            // l! / (2^l ((l/2)!)^2) = C(l, l/2) / 2^l, accumulated as a product for stability.
            let half = l / 2;
            let mut binomial_over_pow = 1.0;
            for k in 1..=half {
                binomial_over_pow *= (half + k) as f64 / (4.0 * k as f64);
            }
            let sign = if (half - 1) % 2 == 0 { 1.0 } else { -1.0 };
            2.0 * PI * sign / (((l + 2) * (l - 1)) as f64) * binomial_over_pow
        }
    }
}

pub fn clamped_cosine_factors(bands: usize) -> Vec<f64> {
    (0..bands).map(clamped_cosine_factor).collect()
}

/// Zonal harmonic coefficients `z_l` (coefficients of `Y_l0`) of a kernel `k(cos θ)`
/// about +Z, by Gauss–Legendre quadrature with `samples` nodes.
pub fn zonal_project(bands: usize, samples: usize, kernel: impl Fn(f64) -> f64) -> Vec<f64> {
    let (nodes, weights) = crate::quadrature::gauss_legendre(samples);
    let basis = ShBasis::new(bands);
    let mut y = vec![0.0; basis.len()];
    let mut out = vec![0.0; bands];
    for (z, w) in nodes.iter().zip(&weights) {
        let r = (1.0 - z * z).max(0.0).sqrt();
        basis.eval(DVec3::new(r, 0.0, *z), &mut y);
        let k = kernel(*z) * w * 2.0 * PI;
        for (l, o) in out.iter_mut().enumerate() {
            *o += k * y[index(l, 0)];
        }
    }
    out
}

/// Rotates a zonal harmonic (coefficients `z_l` about +Z) so that its axis is `dir`:
/// `f_lm = sqrt(4π/(2l+1)) z_l Y_lm(dir)`.
pub fn rotate_zonal(zonal: &[f64], dir: DVec3) -> Vec<f64> {
    let bands = zonal.len();
    let y = ShBasis::new(bands).eval_vec(dir.normalize());
    y.iter()
        .enumerate()
        .map(|(i, y)| {
            let l = band_of(i);
            (4.0 * PI / (2 * l + 1) as f64).sqrt() * zonal[l] * y
        })
        .collect()
}

/// Convolution of `f` with a radially symmetric kernel of zonal coefficients `k_l`:
/// `(k ⊛ f)_lm = sqrt(4π/(2l+1)) k_l f_lm` (the multiplier of Sun 2008 eqs. 3.34, 5.7).
pub fn zonal_convolution_factors(zonal: &[f64]) -> Vec<f64> {
    zonal.iter().enumerate().map(|(l, k)| (4.0 * PI / (2 * l + 1) as f64).sqrt() * k).collect()
}

/// Ringing-suppression windows applied per band (Sloan, "Stupid SH tricks").
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Window {
    None,
    /// `(1 + cos(π l / w)) / 2` for `l < w`, else 0.
    Hanning {
        width: f64,
    },
    /// `sinc(π l / w)` for `l < w`, else 0.
    Lanczos {
        width: f64,
    },
    /// `exp(-l (l+1) / (2 w²))`, a heat-kernel Gaussian of width `w` bands.
    Gaussian {
        width: f64,
    },
}

impl Window {
    pub fn factors(&self, bands: usize) -> Vec<f64> {
        (0..bands)
            .map(|l| {
                let lf = l as f64;
                match *self {
                    Window::None => 1.0,
                    Window::Hanning { width } if lf < width => 0.5 * (1.0 + (PI * lf / width).cos()),
                    Window::Lanczos { width } if lf < width => {
                        if l == 0 {
                            1.0
                        } else {
                            let x = PI * lf / width;
                            x.sin() / x
                        }
                    }
                    Window::Gaussian { width } => (-(lf * (lf + 1.0)) / (2.0 * width * width)).exp(),
                    _ => 0.0,
                }
            })
            .collect()
    }
}

/// Energy `Σ_m f_lm²` of each band; invariant under rotation.
pub fn band_energies(coeffs: &[f64]) -> Vec<f64> {
    let bands = bands_of_len(coeffs.len());
    (0..bands).map(|l| (0..2 * l + 1).map(|k| coeffs[l * l + k].powi(2)).sum()).collect()
}

#[cfg(test)]
mod tests;
