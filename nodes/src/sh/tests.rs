use super::*;
use crate::quadrature::{SphereQuadrature, gauss_legendre};
use crate::sampling::{random_rotation, random_unit_vector, test_rng};
use glam::{DMat3, DVec3};
use rand::Rng;

fn random_coeffs(bands: usize, rng: &mut impl Rng) -> Vec<f64> {
    (0..coeff_count(bands)).map(|_| rng.random_range(-1.0..1.0)).collect()
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(a, b)| a * b).sum()
}

#[test]
fn low_bands_match_cartesian_closed_forms() {
    let basis = ShBasis::new(3);
    let mut rng = test_rng(1);
    for _ in 0..50 {
        let d = random_unit_vector(&mut rng);
        let y = basis.eval_vec(d);
        let c0 = 0.5 * (1.0 / PI).sqrt();
        let c1 = (3.0 / (4.0 * PI)).sqrt();
        let c2 = 0.5 * (15.0 / PI).sqrt();
        let c20 = 0.25 * (5.0 / PI).sqrt();
        let expected = [
            c0,
            c1 * d.y,
            c1 * d.z,
            c1 * d.x,
            c2 * d.x * d.y,
            c2 * d.y * d.z,
            c20 * (3.0 * d.z * d.z - 1.0),
            c2 * d.x * d.z,
            0.5 * c2 * (d.x * d.x - d.y * d.y),
        ];
        for (i, (a, b)) in y.iter().zip(&expected).enumerate() {
            assert!((a - b).abs() < 1e-12, "Y[{i}] at {d}: {a} vs {b}");
        }
    }
}

#[test]
fn orthonormal_to_twenty_bands_by_quadrature() {
    let bands = 20;
    let basis = ShBasis::new(bands);
    let q = SphereQuadrature::exact_for_degree(2 * bands);
    let n = coeff_count(bands);
    let mut gram = vec![0.0; n * n];
    let mut y = vec![0.0; n];
    for (d, w) in q.directions.iter().zip(&q.weights) {
        basis.eval(*d, &mut y);
        for i in 0..n {
            for j in i..n {
                gram[i * n + j] += w * y[i] * y[j];
            }
        }
    }
    let mut worst: f64 = 0.0;
    for i in 0..n {
        for j in i..n {
            let expected = if i == j { 1.0 } else { 0.0 };
            worst = worst.max((gram[i * n + j] - expected).abs());
        }
    }
    assert!(worst < 1e-11, "max |<Y_i,Y_j> - δ_ij| = {worst}");
}

#[test]
fn stable_at_the_poles_and_high_bands() {
    let basis = ShBasis::new(64);
    for d in [DVec3::Z, -DVec3::Z, DVec3::X, DVec3::new(1e-9, 0.0, 1.0).normalize()] {
        let y = basis.eval_vec(d);
        assert!(y.iter().all(|v| v.is_finite()));
        // Addition theorem: Σ_m Y_lm(ω)² = (2l+1)/4π for every band.
        for l in 0..64 {
            let s: f64 = (0..2 * l + 1).map(|k| y[l * l + k].powi(2)).sum();
            let expected = (2 * l + 1) as f64 / (4.0 * PI);
            assert!((s - expected).abs() < 1e-9 * expected, "band {l} at {d}: {s} vs {expected}");
        }
    }
}

#[test]
fn projection_of_a_constant_is_a_dc_term() {
    let f = project_fn(6, 0, |_| 2.5);
    assert!((f[0] - 2.5 * (4.0 * PI).sqrt()).abs() < 1e-12);
    assert!(f[1..].iter().all(|c| c.abs() < 1e-12));
}

#[test]
fn cosine_powers_are_reconstructed_exactly() {
    // z^n lives in bands <= n, so projecting to n+1 bands reproduces it everywhere.
    let mut rng = test_rng(2);
    for n in 0..10 {
        let coeffs = project_fn(n + 1, n, |d| d.z.powi(n as i32));
        // ∫ z^n dω = 4π/(n+1) for even n, 0 for odd n.
        let mean = if n % 2 == 0 { 4.0 * PI / (n as f64 + 1.0) } else { 0.0 };
        assert!((coeffs[0] * (4.0 * PI).sqrt() - mean).abs() < 1e-11);
        for _ in 0..20 {
            let d = random_unit_vector(&mut rng);
            let value = reconstruct(&coeffs, d);
            assert!((value - d.z.powi(n as i32)).abs() < 1e-10, "z^{n} at {d}: {value}");
        }
    }
}

#[test]
fn clamped_cosine_factors_match_direct_integration() {
    // Â_l = sqrt(4π/(2l+1)) · 2π ∫_0^1 z Y_l0(z) dz; the integrand is a polynomial on [0,1],
    // so a Gauss rule mapped to [0, 1] is exact.
    let (nodes, weights) = gauss_legendre(24);
    let basis = ShBasis::new(20);
    for l in 0..20 {
        let integral: f64 = nodes
            .iter()
            .zip(&weights)
            .map(|(x, w)| {
                let z = 0.5 * (x + 1.0);
                let y = basis.eval_vec(DVec3::new((1.0 - z * z).sqrt(), 0.0, z));
                0.5 * w * z * y[index(l, 0)]
            })
            .sum::<f64>()
            * 2.0
            * PI;
        let expected = (4.0 * PI / (2 * l + 1) as f64).sqrt() * integral;
        assert!(
            (clamped_cosine_factor(l) - expected).abs() < 1e-12,
            "Â_{l}: {} vs {expected}",
            clamped_cosine_factor(l)
        );
    }
    // The thesis's tabulated values (eq. 2.25).
    assert!((clamped_cosine_factor(2) - PI / 4.0).abs() < 1e-15);
    assert!((clamped_cosine_factor(4) + 0.130900).abs() < 1e-6);
    assert!((clamped_cosine_factor(6) - 0.049087).abs() < 1e-6);
}

#[test]
fn irradiance_matches_brute_force_hemisphere_integral() {
    let mut rng = test_rng(3);
    let bands = 5;
    let radiance = random_coeffs(bands, &mut rng);
    let irradiance = ShRgb::from_channels([&radiance, &radiance, &radiance]).irradiance().channel(0);
    let fine = SphereQuadrature::new(400, 800);
    for _ in 0..5 {
        let n = random_unit_vector(&mut rng);
        let basis = ShBasis::new(bands);
        // Integrate over the hemisphere around n with a rule built about +Z and rotated.
        let frame = DMat3::from_quat(glam::DQuat::from_rotation_arc(DVec3::Z, n));
        let (zs, ws) = gauss_legendre(64);
        let mut brute = 0.0;
        for (x, w) in zs.iter().zip(&ws) {
            let z = 0.5 * (x + 1.0);
            let r = (1.0 - z * z).sqrt();
            for k in 0..256 {
                let phi = (k as f64 + 0.5) * 2.0 * PI / 256.0;
                let d = frame * DVec3::new(r * phi.cos(), r * phi.sin(), z);
                let l = dot(&radiance, &basis.eval_vec(d));
                brute += 0.5 * w * (2.0 * PI / 256.0) * l * z;
            }
        }
        let sh = reconstruct(&irradiance, n);
        assert!((sh - brute).abs() < 1e-9, "E({n}): SH {sh} vs brute force {brute}");
        let _ = &fine;
    }
}

#[test]
fn rotation_equals_evaluation_at_rotated_direction() {
    let mut rng = test_rng(4);
    for bands in [2, 3, 8, 16] {
        let basis = ShBasis::new(bands);
        for _ in 0..10 {
            let f = random_coeffs(bands, &mut rng);
            let r = random_rotation(&mut rng);
            let g = ShRotation::new(bands, r).apply(&f);
            for _ in 0..10 {
                let d = random_unit_vector(&mut rng);
                // g(R d) = f(d)
                let lhs = dot(&g, &basis.eval_vec(r * d));
                let rhs = dot(&f, &basis.eval_vec(d));
                assert!((lhs - rhs).abs() < 1e-5 * (1.0 + rhs.abs()), "{bands} bands: {lhs} vs {rhs}");
            }
        }
    }
}

#[test]
fn rotation_preserves_band_energy_and_composes() {
    let mut rng = test_rng(5);
    let bands = 16;
    let f = random_coeffs(bands, &mut rng);
    let (r1, r2) = (random_rotation(&mut rng), random_rotation(&mut rng));
    let g = ShRotation::new(bands, r1).apply(&f);
    for (a, b) in band_energies(&f).iter().zip(band_energies(&g)) {
        assert!((a - b).abs() < 1e-9 * a.max(1.0));
    }
    let two_steps = ShRotation::new(bands, r2).apply(&g);
    let one_step = ShRotation::new(bands, r2 * r1).apply(&f);
    let worst = two_steps.iter().zip(&one_step).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    assert!(worst < 1e-9, "R2(R1 f) vs (R2 R1) f: {worst}");
    let identity = ShRotation::new(bands, DMat3::IDENTITY).apply(&f);
    assert!(identity.iter().zip(&f).all(|(a, b)| (a - b).abs() < 1e-14));
}

#[test]
fn rotated_zonal_harmonic_equals_projection_of_the_rotated_kernel() {
    let mut rng = test_rng(6);
    let kernel = |t: f64| (4.0 * (t - 1.0)).exp();
    let bands = 10;
    let zonal = zonal_project(bands, 64, kernel);
    for _ in 0..3 {
        let axis = random_unit_vector(&mut rng);
        let rotated = rotate_zonal(&zonal, axis);
        let direct = project_fn(bands, 60, |d| kernel(d.dot(axis)));
        let worst = rotated.iter().zip(&direct).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(worst < 1e-9, "ZH rotation vs projection: {worst}");
    }
}

#[test]
fn zonal_convolution_of_a_band_limited_function_matches_quadrature() {
    // Convolving with the clamped cosine through the generic zonal path equals Â_l.
    let zonal = zonal_project(8, 1024, |t| t.max(0.0));
    let factors = zonal_convolution_factors(&zonal);
    for (l, f) in factors.iter().enumerate() {
        // The kink at t = 0 limits Gauss accuracy to O(1/n²).
        assert!((f - clamped_cosine_factor(l)).abs() < 1e-5, "band {l}: {f}");
    }
}

#[test]
fn windows_taper_monotonically_from_one() {
    for window in [Window::Hanning { width: 6.0 }, Window::Lanczos { width: 6.0 }, Window::Gaussian { width: 3.0 }] {
        let w = window.factors(10);
        assert_eq!(w[0], 1.0);
        assert!(w.windows(2).all(|p| p[1] <= p[0] + 1e-15), "{window:?}: {w:?}");
        assert!(w.iter().all(|v| (0.0..=1.0).contains(v)));
    }
    assert!(Window::Hanning { width: 6.0 }.factors(10)[6..].iter().all(|v| *v == 0.0));
    assert!(Window::None.factors(4).iter().all(|v| *v == 1.0));
}

#[test]
fn gaunt_product_equals_pointwise_product() {
    // A product of an a-band and a b-band function lives in a+b-1 bands, so the Gaunt
    // product must reproduce f·g exactly at every direction.
    let mut rng = test_rng(7);
    let (a, b) = (6, 5);
    let table = GauntTable::new(a, b, a + b - 1);
    let f = random_coeffs(a, &mut rng);
    let g = random_coeffs(b, &mut rng);
    let fg = table.multiply(&f, &g);
    for _ in 0..50 {
        let d = random_unit_vector(&mut rng);
        let expected = reconstruct(&f, d) * reconstruct(&g, d);
        let got = reconstruct(&fg, d);
        assert!((got - expected).abs() < 1e-10, "{got} vs {expected}");
    }
}

#[test]
fn gaunt_coefficients_match_brute_force_quadrature() {
    // Midpoint rule in z (dω = dz dφ) on two grids with Richardson extrapolation, and the
    // trapezoid rule in φ: an integration scheme unrelated to the table's construction.
    let bands = 4;
    let out_bands = 2 * bands - 1;
    let table = GauntTable::new(bands, bands, out_bands);
    let n = coeff_count(bands);
    let n_out = coeff_count(out_bands);
    let mut dense = vec![0.0; n * n * n_out];
    for &(i, j, k, c) in table.entries() {
        dense[(i as usize * n + j as usize) * n_out + k as usize] = c;
    }
    let basis = ShBasis::new(out_bands);
    let midpoint = |nz: usize| {
        let nphi = 16;
        let mut brute = vec![0.0; n * n * n_out];
        let mut y = vec![0.0; n_out];
        for iz in 0..nz {
            let z = -1.0 + (iz as f64 + 0.5) * 2.0 / nz as f64;
            let r = (1.0 - z * z).sqrt();
            for ip in 0..nphi {
                let phi = ip as f64 * 2.0 * PI / nphi as f64;
                basis.eval(DVec3::new(r * phi.cos(), r * phi.sin(), z), &mut y);
                let w = (2.0 / nz as f64) * (2.0 * PI / nphi as f64);
                for i in 0..n {
                    for j in 0..n {
                        let yy = y[i] * y[j] * w;
                        for k in 0..n_out {
                            brute[(i * n + j) * n_out + k] += yy * y[k];
                        }
                    }
                }
            }
        }
        brute
    };
    let (coarse, fine) = (midpoint(1000), midpoint(2000));
    let brute: Vec<f64> = coarse.iter().zip(&fine).map(|(c, f)| (4.0 * f - c) / 3.0).collect();
    let worst = dense.iter().zip(&brute).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    assert!(worst < 1e-8, "max |table - brute force| = {worst}");
    // Known values: C(00,00,00) = 1/sqrt(4π); the table is symmetric in i and j.
    assert!((dense[0] - 1.0 / (4.0 * PI).sqrt()).abs() < 1e-14);
    for &(i, j, k, c) in table.entries() {
        let swapped = dense[(j as usize * n + i as usize) * n_out + k as usize];
        assert!((c - swapped).abs() < 1e-13);
    }
}

#[test]
fn gaunt_table_is_sparse_by_the_selection_rules() {
    let table = GauntTable::new(16, 16, 16);
    let dense_size = coeff_count(16).pow(3);
    assert!(table.len() > 10_000 && table.len() * 20 < dense_size, "{} of {dense_size}", table.len());
    for &(i, j, k, _) in table.entries() {
        let (l1, l2, l3) = (band_of(i as usize), band_of(j as usize), band_of(k as usize));
        assert!(l3 >= l1.abs_diff(l2) && l3 <= l1 + l2 && (l1 + l2 + l3) % 2 == 0);
    }
    // Product matrix agrees with multiply.
    let mut rng = test_rng(8);
    let f = random_coeffs(16, &mut rng);
    let g = random_coeffs(16, &mut rng);
    let m = table.product_matrix(&f);
    let via_matrix: Vec<f64> = (0..256).map(|k| dot(&m[k * 256..(k + 1) * 256], &g)).collect();
    let direct = table.multiply(&f, &g);
    assert!(via_matrix.iter().zip(&direct).all(|(a, b)| (a - b).abs() < 1e-12));
}

#[test]
fn equirect_projection_matches_exact_projection_of_the_same_function() {
    // A smooth function sampled into an equirect image projects to (nearly) the exact
    // coefficients; the per-row solid angles make the DC term exact for constants.
    let f = |d: DVec3| 1.0 + 0.5 * d.x - 0.25 * d.y * d.z + 0.3 * d.z * d.z;
    let image = crate::cubemap::Equirect::from_fn(512, 256, 1, |d| [f(d), 1.0, 0.0]);
    let sh = project_equirect(&image, 4);
    let exact = project_fn(4, 2, f);
    for (got, want) in sh.channel(0).iter().zip(&exact) {
        assert!((got - want).abs() < 2e-4, "{got} vs {want}");
    }
    assert!((sh.coeffs[0][1] - (4.0 * PI).sqrt()).abs() < 1e-5);
    assert!(sh.channel(1)[1..].iter().all(|c| c.abs() < 1e-4));
}
