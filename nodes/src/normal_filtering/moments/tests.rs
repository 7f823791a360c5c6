use super::*;
use crate::brdf::Lobe;
use crate::sh::ShBasis;
use rand::Rng;
use std::f64::consts::PI;

/// `count` unit normals spread about `axis` like a bumpy texel block.
fn spread_normals(seed: u64, count: usize, axis: DVec3, spread: f64) -> Vec<DVec3> {
    let mut rng = crate::sampling::test_rng(seed);
    let (t, b) = axis.any_orthonormal_pair();
    (0..count)
        .map(|_| {
            let (u, v): (f64, f64) = (rng.random_range(-spread..spread), rng.random_range(-spread..spread));
            (axis + t * u + b * v * 0.6 + t * (3.0 * v).sin() * 0.2 * spread).normalize()
        })
        .collect()
}

fn mean_moments(normals: &[DVec3]) -> NdfMoments {
    let share = 1.0 / normals.len() as f64;
    normals.iter().fold(NdfMoments { mean: DVec3::ZERO, second: DMat3::ZERO }, |acc, n| {
        let one = NdfMoments::of_normal(*n);
        NdfMoments { mean: acc.mean + one.mean * share, second: acc.second + one.second * share }
    })
}

/// The moments' SH are the NDF's SH to band 2, `(1/N) Σ Y_lm(n_q)` by the SH module's own
/// basis, in every frame: the moments turned by a rotation give the SH of the turned normals.
/// Packing keeps them to f32.
#[test]
fn moments_are_the_ndfs_sh_to_band_two_in_any_frame() {
    let basis = ShBasis::new(3);
    let normals = spread_normals(1, 50, DVec3::new(0.2, -0.3, 1.0).normalize(), 0.8);
    let frame = DMat3::from_euler(glam::EulerRot::YXZ, 0.7, -1.1, 0.4);
    for (moments, normals) in [
        (mean_moments(&normals), normals.clone()),
        (mean_moments(&normals).rotated(frame), normals.iter().map(|n| frame * *n).collect::<Vec<_>>()),
    ] {
        let mut truth = [0.0; 9];
        for n in &normals {
            for (t, y) in truth.iter_mut().zip(basis.eval_vec(*n)) {
                *t += y / normals.len() as f64;
            }
        }
        for (i, (a, b)) in moments.sh().iter().zip(&truth).enumerate() {
            assert!((a - b).abs() < 1e-12, "coefficient {i}: {a} against {b}");
        }
        let unpacked = NdfMoments::unpacked(moments.packed());
        for (a, b) in unpacked.sh().iter().zip(&truth) {
            assert!((a - b).abs() < 1e-6, "packed: {a} against {b}");
        }
    }
}

/// At power-of-two sizes every level's texel is the mean of the moments of the texels it
/// covers; at odd sizes the levels follow the GPU's sizes down to one texel and each texel
/// stays a distribution of unit normals (`tr S = 1`, `|m| ≤ 1`, `S − m mᵀ` positive
/// semi-definite).
#[test]
fn moment_pyramids_average_the_texels_they_cover() {
    let mut rng = crate::sampling::test_rng(2);
    let map = |w: usize, h: usize, rng: &mut rand::rngs::SmallRng| NormalMap {
        width: w,
        height: h,
        normals: (0..w * h)
            .map(|_| DVec3::new(rng.random_range(-0.8..0.8), rng.random_range(-0.8..0.8), 1.0).normalize())
            .collect(),
    };
    let square = map(16, 8, &mut rng);
    let pyramid = MomentPyramid::build(&square);
    assert_eq!(
        pyramid.levels.iter().map(|l| (l.width, l.height)).collect::<Vec<_>>(),
        [(16, 8), (8, 4), (4, 2), (2, 1), (1, 1)]
    );
    for (k, level) in pyramid.levels.iter().enumerate() {
        for y in 0..level.height {
            for x in 0..level.width {
                let size = 1 << k;
                let (w, h) = (square.width, square.height);
                let block: Vec<DVec3> = (y * size..((y + 1) * size).min(h))
                    .flat_map(|by| (x * size..((x + 1) * size).min(w)).map(move |bx| (bx, by)))
                    .map(|(bx, by)| square.normals[by * square.width + bx])
                    .collect();
                let truth = mean_moments(&block).packed();
                for (a, b) in level.texels[y * level.width + x].iter().zip(truth) {
                    assert!((a - b).abs() < 1e-6, "level {k} ({x}, {y}): {a} against {b}");
                }
            }
        }
    }
    let odd = MomentPyramid::build(&map(7, 5, &mut rng));
    assert_eq!(odd.levels.iter().map(|l| (l.width, l.height)).collect::<Vec<_>>(), [(7, 5), (3, 2), (1, 1)]);
    for level in &odd.levels {
        for t in &level.texels {
            let m = NdfMoments::unpacked(*t);
            let covariance = m.second - DMat3::from_cols(m.mean * m.mean.x, m.mean * m.mean.y, m.mean * m.mean.z);
            assert!(m.mean.length() <= 1.0 + 1e-6);
            for probe in [DVec3::X, DVec3::Y, DVec3::Z, DVec3::new(1.0, -1.0, 0.5).normalize()] {
                assert!(probe.dot(covariance * probe) > -1e-6, "not a distribution: {m:?}");
            }
        }
    }
}

/// Environment irradiance averaged over the NDF: exactly the texels' mean of `E(n_q)` when the
/// irradiance has 3 bands, and within 1% of it at 5 (the higher bands by Toksvig's
/// attenuation); a single normal gives `E(n)` itself at any band count (a flat map changes
/// nothing).
#[test]
fn filtered_irradiance_is_the_mean_over_the_texels() {
    let mut rng = crate::sampling::test_rng(3);
    let radiance: Vec<[f64; 3]> = (0..25).map(|_| [0.0; 3].map(|_: f64| rng.random_range(-0.3..0.3))).collect();
    let mut light = crate::sh::ShRgb { bands: 5, coeffs: radiance };
    light.coeffs[0] = [2.0, 1.5, 1.0];
    let e = light.irradiance();
    let irradiance = |bands: usize, n: DVec3| {
        let y = ShBasis::new(bands).eval_vec(n);
        (0..3).map(|k| y.iter().zip(&e.coeffs).map(|(y, c)| y * c[k]).sum::<f64>()).collect::<Vec<_>>()
    };
    let normals = spread_normals(4, 200, DVec3::new(0.3, 0.1, 1.0).normalize(), 0.5);
    let moments = mean_moments(&normals);
    for bands in [3usize, 5] {
        let filtered = moments.filtered_irradiance(&e.coeffs[..bands * bands]);
        for k in 0..3 {
            let truth = normals.iter().map(|n| irradiance(bands, *n)[k]).sum::<f64>() / normals.len() as f64;
            let tolerance = if bands == 3 { 1e-10 } else { 0.01 * truth.abs() };
            assert!(
                (filtered[k] - truth).abs() <= tolerance,
                "{bands} bands, channel {k}: {} against {truth}",
                filtered[k]
            );
        }
    }
    let n = DVec3::new(-0.4, 0.5, 0.7).normalize();
    let single = NdfMoments::of_normal(n).filtered_irradiance(&e.coeffs);
    for k in 0..3 {
        assert!((single[k] - irradiance(5, n)[k]).abs() < 1e-9);
    }
}

/// The closed form of `E[max(0, n·l)]` from the moments: exact for one normal, and within 2%
/// of the texels' own mean (of the mean response) for a spread block lit from every direction
/// down to grazing; the unnormalised mean normal alone is off by more near the terminator.
#[test]
fn the_direct_diffuse_closed_form_follows_the_texels() {
    let n = DVec3::new(0.3, -0.2, 0.9).normalize();
    for l in [DVec3::Z, DVec3::X, DVec3::new(-0.8, 0.3, -0.2).normalize()] {
        assert_eq!(NdfMoments::of_normal(n).direct_diffuse(l), n.dot(l).max(0.0));
    }
    let normals = spread_normals(5, 400, DVec3::Z, 0.9);
    let moments = mean_moments(&normals);
    let (mut error, mut mean_only, mut total) = (0.0, 0.0, 0.0);
    for i in 0..40 {
        let theta = i as f64 / 39.0 * 1.45;
        let l = DVec3::new(theta.sin(), 0.0, theta.cos());
        let truth = normals.iter().map(|n| n.dot(l).max(0.0)).sum::<f64>() / normals.len() as f64;
        error += (moments.direct_diffuse(l) - truth).abs();
        mean_only += (moments.mean.dot(l).max(0.0) - truth).abs();
        total += truth;
    }
    assert!(error / total < 0.02, "closed form off by {:.2}%", 100.0 * error / total);
    assert!(error < mean_only, "closed form {error} against the mean normal's {mean_only}");
}

/// A lobe widened by a vMF lobe of normals against the lobe averaged over normals drawn from
/// it (Monte Carlo over 20,000 normals, over the highlight's window of incident directions):
/// Blinn-Phong, whose convolution is exact in its vMF form, within 4% over the core and in
/// energy; GGX (widened by slope variance, its shape then only near the truth's) within 10% in
/// relative L1, under half the unwidened lobe's error. A concentrated NDF (κ at the limit)
/// leaves the lobe as it is.
#[test]
fn a_widened_lobe_is_the_lobe_averaged_over_its_normals() {
    let mut rng = crate::sampling::test_rng(6);
    let kappa: f64 = 150.0;
    let normals: Vec<DVec3> = (0..20_000)
        .map(|_| {
            let u: f64 = rng.random_range(0.0..1.0);
            let w = 1.0 + (u + (1.0 - u) * (-2.0 * kappa).exp()).ln() / kappa;
            let phi = rng.random_range(0.0..2.0 * PI);
            let s = (1.0 - w * w).max(0.0).sqrt();
            DVec3::new(s * phi.cos(), s * phi.sin(), w)
        })
        .collect();
    for lobe in [Lobe::BlinnPhong { exponent: 200.0 }, Lobe::Ggx { alpha_x: 0.15, alpha_y: 0.15 }] {
        let brdf = crate::brdf::Brdf { diffuse: DVec3::ZERO, specular: DVec3::ONE, f0: 1.0, lobe };
        let (wide, scale) = lobe.widened(kappa);
        let widened = crate::brdf::Brdf { lobe: wide, ..brdf };
        let wo = DVec3::new(0.3, 0.0, 1.0).normalize();
        let mut samples = Vec::new();
        for i in 0..31 {
            for j in 0..31 {
                let wi = DVec3::new(-0.3 + (i as f64 - 15.0) * 0.04, (j as f64 - 15.0) * 0.04, 1.0).normalize();
                let truth = normals
                    .iter()
                    .map(|n| {
                        let (t, b) = n.any_orthonormal_pair();
                        let to_local = DMat3::from_cols(t, b, *n).transpose();
                        brdf.lobe_value(to_local * wi, to_local * wo)
                    })
                    .sum::<f64>()
                    / normals.len() as f64;
                samples.push((truth, scale * widened.lobe_value(wi, wo), brdf.lobe_value(wi, wo)));
            }
        }
        let total: f64 = samples.iter().map(|s| s.0).sum();
        let peak = samples.iter().map(|s| s.0).fold(0.0, f64::max);
        let energy = samples.iter().map(|s| s.1).sum::<f64>() / total;
        let l1 = samples.iter().map(|s| (s.1 - s.0).abs()).sum::<f64>() / total;
        let l1_unwidened = samples.iter().map(|s| (s.2 - s.0).abs()).sum::<f64>() / total;
        let core = samples.iter().filter(|s| s.0 > 0.5 * peak).map(|s| (s.1 / s.0 - 1.0).abs()).fold(0.0, f64::max);
        eprintln!(
            "{lobe:?}: energy {energy:.4}, L1 {l1:.4} (unwidened {l1_unwidened:.4}), worst in the core {core:.4}"
        );
        assert!(l1 < 0.1 && l1 < l1_unwidened / 2.0, "{lobe:?}: L1 {l1} (unwidened {l1_unwidened})");
        if let Lobe::BlinnPhong { .. } = lobe {
            assert!((energy - 1.0).abs() < 0.04 && core < 0.04, "{lobe:?}: energy {energy}, core {core}");
        }
        assert_eq!(lobe.widened(crate::normal_filtering::MAX_KAPPA), (lobe, 1.0));
    }
}

/// The packed vMF pyramid holds each level's fitted mixtures:
/// unpacked, every texel's lobes are the fit's to f32, and weights sum to one.
#[test]
fn the_packed_vmf_pyramid_holds_the_fits() {
    let normals = spread_normals(7, 64, DVec3::Z, 0.7);
    let map = NormalMap { width: 8, height: 8, normals };
    let packed = VmfPyramid::build(&map, &crate::engine::CancelToken::default()).unwrap();
    let fitted = super::super::vmf_pyramid(&map, VMF_LOBES, 30, 1024);
    assert_eq!(packed.levels.len(), fitted.len());
    for (k, level) in packed.levels.iter().enumerate() {
        for y in 0..level.height {
            for x in 0..level.width {
                let lobes = packed.lobes(k, x, y);
                let fit = &fitted[k][y * level.width + x];
                assert_eq!(lobes.len(), fit.len());
                for (a, b) in lobes.iter().zip(fit) {
                    assert!((a.weight - b.weight).abs() < 1e-6 && a.mean.dot(b.mean) > 1.0 - 1e-6);
                    assert!((a.kappa / b.kappa - 1.0).abs() < 1e-5);
                }
                assert!((lobes.iter().map(|l| l.weight).sum::<f64>() - 1.0).abs() < 1e-5);
            }
        }
    }
    let big = NormalMap::flat(4096, 2049);
    let refused = VmfPyramid::build(&big, &crate::engine::CancelToken::default()).unwrap_err();
    assert!(refused.contains("2048 × 2048") && refused.contains("4096 × 2049"), "{refused}");
}
