//! SH precomputed radiance transfer (thesis ch. 2; Sloan et al. 2002; Lee 2014 ch. 3–4).
//!
//! * Diffuse, shadowed: exit radiance `B = (albedo/π) Σ_k T_k L_k` with the per-receiver
//!   shadowed cosine transfer `T_k = ∫ V max(n·ω, 0) Y_k dω` (Sun 2008 eq. 2.24).
//! * Glossy, shadowed: the incident radiance `R = L·V` is projected to SH per receiver with
//!   the Gaunt tensor, `R_k = Σ_ij C_ijk L_i V_j` (Lee 2014 eq. 3.6, "product projection"); a
//!   lobe symmetric about the mirror direction `r` (zonal `z_l`) then gives
//!   `B_spec = Σ_lm sqrt(4π/(2l+1)) z_l R_lm Y_lm(r)` (Funk–Hecke, Sun 2008 eq. 2.20's
//!   convolution) times `max(n·r, 0)` for the cosine. `R` depends on lighting and geometry only,
//!   so BRDF and camera edits reuse it (Lee's cache, notes §C3).
//!
//! The renderer evaluates both sums per vertex in WGSL (`shaders/mesh_prt.wgsl`); the CPU
//! versions here are the reference for its tests.

use crate::engine::{CancelToken, StageError};
use crate::sh::{self, GauntTable, ShBasis, ShRgb};
use crate::transport::ShTransport;
use glam::DVec3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

// Stage value types this module owns (see `engine::value`).
crate::stage_type!(
    IncidentSh,
    "incident radiance SH",
    |v| v.coeffs.len() * 4,
    numbers = |v| v.coeffs.iter().map(|x| f64::from(*x))
);
crate::stage_type!(GlossyLobe, "SH lobe", |v| v.factors.len() * 8 + 32);

/// Per-receiver incident radiance `R = L·V` in SH, RGB interleaved: `(receiver·n² + k)·3 + c`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct IncidentSh {
    pub bands: usize,
    pub coeffs: Vec<f32>,
}

impl IncidentSh {
    pub fn receiver(&self, i: usize) -> &[f32] {
        let n = self.bands * self.bands * 3;
        &self.coeffs[i * n..(i + 1) * n]
    }
}

/// The lighting truncated or zero-padded to `bands`.
pub fn light_to_bands(light: &ShRgb, bands: usize) -> ShRgb {
    let mut out = ShRgb::zero(bands);
    for (o, l) in out.coeffs.iter_mut().zip(&light.coeffs) {
        *o = *l;
    }
    out
}

/// `R = L·V` for every receiver of `transport` (at the transport's band count).
///
/// One product matrix per channel, `R_c = M_c V` with `(M_c)_kj = Σ_i C_ijk L_ci`, applied to
/// blocks of receivers at once as one single-precision matrix product (`nalgebra`'s GEMM,
/// `matrixmultiply`'s SIMD kernels): `[R]` (receivers × 3n², RGB interleaved) `= [V]`
/// (receivers × n²) `· B` with `B_j,(3k+c) = (M_c)_kj`.
pub fn incident_radiance(
    light: &ShRgb,
    transport: &ShTransport,
    cancel: &CancelToken,
) -> Result<IncidentSh, StageError> {
    const BLOCK: usize = 256;
    let bands = transport.bands;
    let n = bands * bands;
    if n == 0 || transport.visibility.is_empty() {
        return Ok(IncidentSh { bands, coeffs: Vec::new() });
    }
    let matrices = product_matrices(light, bands);
    // Column-major `Bᵀ` (3n² × n²): entry (3k + c, j) is (M_c)_kj.
    let product = nalgebra::DMatrix::<f32>::from_fn(3 * n, n, |row, j| matrices[row % 3][(row / 3) * n + j] as f32);
    let receivers = transport.visibility.len() / n;
    let mut coeffs = vec![0f32; receivers * n * 3];
    coeffs.par_chunks_mut(BLOCK * n * 3).zip(transport.visibility.par_chunks(BLOCK * n)).try_for_each(
        |(out, visibility)| {
            cancel.check()?;
            let count = visibility.len() / n;
            // Row-major blocks are the column-major transposes: Rᵀ = Bᵀ Vᵀ.
            let visibility = nalgebra::DMatrixView::<f32>::from_slice(visibility, n, count);
            let mut out = nalgebra::DMatrixViewMut::<f32>::from_slice(out, 3 * n, count);
            out.gemm(1.0, &product, &visibility, 0.0);
            Ok::<(), StageError>(())
        },
    )?;
    Ok(IncidentSh { bands, coeffs })
}

/// Per channel the `n² × n²` row-major matrix `(M_c)_kj = Σ_i C_ijk L_ci` of multiplying by
/// the lighting truncated to `bands`.
fn product_matrices(light: &ShRgb, bands: usize) -> Vec<Vec<f64>> {
    let light = light_to_bands(light, bands);
    let gaunt = GauntTable::new(bands, bands, bands);
    (0..3).map(|c| gaunt.product_matrix(&light.channel(c))).collect()
}

/// The plain per-receiver product in double precision, [`incident_radiance`]'s reference.
#[cfg(test)]
fn incident_radiance_plain(light: &ShRgb, transport: &ShTransport) -> Vec<f32> {
    let n = transport.bands * transport.bands;
    let matrices = product_matrices(light, transport.bands);
    let mut out = Vec::new();
    for v in transport.visibility.chunks(n) {
        for k in 0..n {
            for m in &matrices {
                out.push(m[k * n..(k + 1) * n].iter().zip(v).map(|(a, b)| a * *b as f64).sum::<f64>() as f32);
            }
        }
    }
    out
}

/// Diffuse shadowed exit radiance `(albedo/π) Σ T_k L_k`.
pub fn diffuse_exit(light: &ShRgb, transfer: &[f32], albedo: DVec3) -> DVec3 {
    let mut sum = DVec3::ZERO;
    for (t, l) in transfer.iter().zip(&light.coeffs) {
        sum += DVec3::from(*l) * *t as f64;
    }
    albedo / std::f64::consts::PI * sum
}

/// Per-band factors `sqrt(4π/(2l+1)) z_l` of a zonal lobe (the shader's uniform).
pub fn lobe_factors(zonal: &[f64]) -> Vec<f64> {
    sh::zonal_convolution_factors(zonal)
}

/// Glossy exit radiance `max(n·r,0) Σ_lm f_l R_lm Y_lm(r)` for one receiver's interleaved `R`.
pub fn glossy_exit(incident: &[f32], factors: &[f64], normal: DVec3, mirror: DVec3) -> DVec3 {
    let bands = sh::bands_of_len(incident.len() / 3).min(factors.len());
    let y = ShBasis::new(bands).eval_vec(mirror.normalize());
    let mut sum = DVec3::ZERO;
    for (k, yk) in y.iter().enumerate() {
        let f = factors[sh::band_of(k)] * yk;
        sum += DVec3::new(incident[k * 3] as f64, incident[k * 3 + 1] as f64, incident[k * 3 + 2] as f64) * f;
    }
    sum * normal.dot(mirror.normalize()).max(0.0)
}

/// The glossy part of a material as the SH mode shades it: per-band convolution factors of
/// its equivalent Phong lobe ([`crate::brdf::Brdf::equivalent_phong_exponent`]) and the lobe's
/// RGB weight (`specular colour × f0`). `None` for Lambert.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct GlossyLobe {
    pub exponent: f64,
    /// Per band `l`: `sqrt(4π/(2l+1)) z_l` (empty for Lambert: no glossy lobe).
    pub factors: Vec<f64>,
    pub weight: [f64; 3],
}

/// Bands of the BRDF editor's SH lobe stage (renderers use a prefix).
pub const LOBE_BANDS: usize = 16;

pub fn glossy_lobe(material: &crate::brdf::Material, bands: usize) -> Option<GlossyLobe> {
    let brdf = crate::brdf::Brdf::from_material(material);
    let exponent = brdf.equivalent_phong_exponent()?;
    let factors = lobe_factors(&crate::brdf::Brdf::phong_zonal(exponent, bands));
    Some(GlossyLobe { exponent, factors, weight: (brdf.specular * brdf.f0).to_array() })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::quadrature::SphereQuadrature;
    use std::f64::consts::PI;

    /// Visibility of a receiver with normal +Z whose upper hemisphere is blocked where x > 0.5.
    fn blocked(d: DVec3) -> f64 {
        if d.z > 0.0 && d.x < 0.5 { 1.0 } else { 0.0 }
    }

    fn transport_of(bands: usize) -> ShTransport {
        let q = SphereQuadrature::new(400, 800);
        let basis = ShBasis::new(bands);
        let mut visibility = vec![0.0f64; bands * bands];
        let mut transfer = vec![0.0f64; bands * bands];
        for (d, w) in q.directions.iter().zip(&q.weights) {
            let y = basis.eval_vec(*d);
            for k in 0..bands * bands {
                visibility[k] += w * blocked(*d) * y[k];
                transfer[k] += w * blocked(*d) * d.z.max(0.0) * y[k];
            }
        }
        let to_f32 = |v: Vec<f64>| v.into_iter().map(|x| x as f32).collect();
        ShTransport { bands, rays: 0, visibility: to_f32(visibility), transfer: to_f32(transfer) }
    }

    #[test]
    fn the_blocked_product_equals_the_plain_one_on_random_inputs() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::SmallRng::seed_from_u64(3);
        for bands in [1, 3, 6, 8] {
            let n = bands * bands;
            // 700 receivers: two whole blocks and a partial one.
            let mut random = |len: usize| (0..len).map(|_| rng.random::<f32>() * 2.0 - 0.5).collect::<Vec<f32>>();
            let transport = ShTransport { bands, rays: 0, visibility: random(700 * n), transfer: random(700 * n) };
            let light =
                ShRgb { bands, coeffs: (0..n).map(|_| [0, 1, 2].map(|_| rng.random::<f64>() * 4.0 - 1.0)).collect() };
            let fast = incident_radiance(&light, &transport, &CancelToken::default()).unwrap();
            let plain = incident_radiance_plain(&light, &transport);
            let scale = plain.iter().fold(0f32, |m, x| m.max(x.abs()));
            let worst = fast.coeffs.iter().zip(&plain).map(|(a, b)| (a - b).abs()).fold(0f32, f32::max);
            assert_eq!(fast.coeffs.len(), plain.len());
            assert!(worst <= 1e-5 * scale, "{bands} bands: {worst} against values up to {scale}");
        }
    }

    #[test]
    fn incident_radiance_is_the_projection_of_the_band_limited_product() {
        let bands = 5;
        let light_fn = |d: DVec3| [1.0 + d.y, 0.5 + 0.3 * d.x * d.z, 2.0 * d.z.max(0.0)];
        let light = sh::project_samples(
            bands,
            SphereQuadrature::new(200, 400)
                .directions
                .iter()
                .zip(SphereQuadrature::new(200, 400).weights)
                .map(|(d, w)| (*d, w, light_fn(*d))),
        );
        let transport = transport_of(bands);
        let incident = incident_radiance(&light, &transport, &CancelToken::default()).unwrap();
        // Independent: quadrature projection of L_n(ω)·V_n(ω) (both reconstructed from SH).
        let basis = ShBasis::new(bands);
        let q = SphereQuadrature::exact_for_degree(3 * bands);
        for c in 0..3 {
            let lc = light.channel(c);
            let v: Vec<f64> = transport.visibility.iter().map(|x| *x as f64).collect();
            for k in 0..bands * bands {
                let exact = q.integrate(|d| {
                    let y = basis.eval_vec(d);
                    sh::reconstruct(&lc, d) * sh::reconstruct(&v, d) * y[k]
                });
                let got = incident.receiver(0)[k * 3 + c] as f64;
                assert!((got - exact).abs() < 1e-4, "k {k} c {c}: {got} vs {exact}");
            }
        }
    }

    #[test]
    fn diffuse_exit_under_constant_light_is_albedo_times_visible_cosine_fraction() {
        // Constant L = 1: B = albedo/π ∫ V cos = albedo/π · (π - blocked share), exact because
        // a constant needs only Y_00 and T_00 is exact.
        let transport = transport_of(4);
        let mut light = ShRgb::zero(4);
        light.coeffs[0] = [(4.0 * PI).sqrt(); 3];
        let b = diffuse_exit(&light, &transport.transfer, DVec3::ONE);
        let visible_cos = SphereQuadrature::new(400, 800).integrate(|d| blocked(d) * d.z.max(0.0));
        assert!((b.x - visible_cos / PI).abs() < 1e-5, "{} vs {}", b.x, visible_cos / PI);
    }

    #[test]
    fn glossy_exit_of_a_sharp_lobe_reads_the_incident_radiance_in_the_mirror_direction() {
        // With a unit-integral lobe, B_spec(r) → R(r)·(n·r) as the lobe narrows; at 8 bands a
        // Phong-8 lobe is resolved, so compare against the lobe-filtered R by quadrature.
        let bands = 8;
        let transport = transport_of(bands);
        let mut light = ShRgb::zero(bands);
        light.coeffs[0] = [(4.0 * PI).sqrt(); 3];
        let incident = incident_radiance(&light, &transport, &CancelToken::default()).unwrap();
        let zonal = crate::brdf::Brdf::phong_zonal(8.0, bands);
        let factors = lobe_factors(&zonal);
        let r = DVec3::new(-0.3, 0.2, 0.93).normalize();
        let got = glossy_exit(incident.receiver(0), &factors, DVec3::Z, r).x;
        // Independent: ∫ lobe(ω·r) R_n(ω) dω with R_n reconstructed (quadrature), times n·r.
        let rx: Vec<f64> = (0..bands * bands).map(|k| incident.receiver(0)[k * 3] as f64).collect();
        let lobe = |c: f64| 10.0 / (2.0 * PI) * c.max(0.0).powi(8);
        let exact = SphereQuadrature::new(600, 1200).integrate(|d| lobe(d.dot(r)) * sh::reconstruct(&rx, d)) * r.z;
        assert!((got - exact).abs() < 2e-3 * exact.abs().max(0.1), "{got} vs {exact}");
    }
}
