//! Materials as glTF 2.0 metallic-roughness (plus `KHR_materials_specular` and
//! `KHR_materials_anisotropy`), with the error of the fit.
//!
//! glTF's dielectric is `(1 − F) baseColor/π + F D V` with the GGX distribution at
//! `α = roughness²`, height-correlated Smith visibility and Schlick's Fresnel from `F₀`.
//! - **GGX** maps directly: the same `α`, `F₀ = specular colour × f0`, metallic 0.
//! - **Phong, Blinn-Phong, Ward** map to the GGX `α` whose lobe is closest to theirs: the
//!   `α` minimising the cosine-weighted L2 difference of the two specular terms
//!   `f_s(ω_i, ω_o) cos θ_i` over the hemisphere of `ω_i`, at views of 0°, 30° and 60°
//!   (golden-section search on `log α`). The lobe's weight keeps its `F₀`.
//! - **Lambert** has no specular (`specularFactor` 0).
//!
//! [`MaterialFit::error`] is the relative L2 difference of the whole BRDF (diffuse and
//! specular, times `cos θ_i`) between the material and its glTF form, over the same
//! directions: 0 would be exact; the `(1 − F)` diffuse term glTF adds makes even GGX a little
//! off.

use crate::brdf::Material;
use crate::brdf::{Brdf, Lobe};
use glam::DVec3;
use std::f64::consts::PI;

/// A material in glTF's terms.
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialFit {
    pub base_color: [f64; 3],
    pub metallic: f64,
    /// glTF's perceptual roughness (`α = roughness²`); along the bitangent for anisotropic
    /// lobes.
    pub roughness: f64,
    /// `KHR_materials_specular`: `F₀ = 0.04 × specular_color × specular_factor`, `F₉₀ =
    /// specular_factor`.
    pub specular_factor: f64,
    pub specular_color: [f64; 3],
    /// `KHR_materials_anisotropy`: strength and rotation (radians from the tangent), when the
    /// lobe is anisotropic.
    pub anisotropy: Option<(f64, f64)>,
    /// Relative L2 difference of `f cos θ_i` between the material and this fit.
    pub error: f64,
}

/// glTF's dielectric `F₀` at `specularColor = specularFactor = 1` (ior 1.5).
const GLTF_F0: f64 = 0.04;

/// The view elevations the fit and its error average over (degrees from the normal).
const VIEW_ANGLES: [f64; 3] = [0.0, 30.0, 60.0];

/// `material` (whose diffuse colour `base_color` tints) in glTF's terms.
pub fn fit(material: &Material, base_color: [f32; 3]) -> MaterialFit {
    let brdf = Brdf::from_material(material);
    let tint = DVec3::from(base_color.map(f64::from));
    let albedo = (brdf.diffuse * tint).to_array();
    let (alpha_x, alpha_y) = match brdf.lobe {
        Lobe::None => (1.0, 1.0),
        Lobe::Ggx { alpha_x, alpha_y } => (alpha_x, alpha_y),
        Lobe::Phong { .. } | Lobe::BlinnPhong { .. } | Lobe::Ward { .. } => {
            let alpha = fit_alpha(&brdf);
            (alpha, alpha)
        }
    };
    let has_lobe = brdf.lobe != Lobe::None && brdf.specular.max_element() > 0.0;
    let (specular_factor, specular_color) = if has_lobe {
        // F₉₀ is the specular colour's largest channel; F₀ its colour times f0.
        let factor = brdf.specular.max_element().min(1.0);
        let color = (brdf.specular * brdf.f0 / (GLTF_F0 * factor.max(1e-6))).to_array();
        (factor, color)
    } else {
        (0.0, [1.0; 3])
    };
    let (alpha_b, alpha_t) = (alpha_x.min(alpha_y), alpha_x.max(alpha_y));
    let anisotropy = (has_lobe && alpha_t > alpha_b * 1.001).then(|| {
        // glTF: α_t = mix(α_b, 1, strength²).
        let strength = ((alpha_t - alpha_b) / (1.0 - alpha_b).max(1e-6)).clamp(0.0, 1.0).sqrt();
        let rotation = if alpha_x >= alpha_y { 0.0 } else { PI / 2.0 };
        (strength, rotation)
    });
    let mut fit = MaterialFit {
        base_color: albedo,
        metallic: 0.0,
        roughness: alpha_b.sqrt().clamp(0.0, 1.0),
        specular_factor,
        specular_color,
        anisotropy,
        error: 0.0,
    };
    let original = Brdf { diffuse: brdf.diffuse * tint, ..brdf };
    fit.error = relative_difference(|wi, wo| original.eval(wi, wo).to_array(), |wi, wo| gltf_brdf(&fit, wi, wo));
    fit
}

/// glTF's BRDF for `fit` (local frame, tangent `+X`), per RGB channel.
pub fn gltf_brdf(fit: &MaterialFit, wi: DVec3, wo: DVec3) -> [f64; 3] {
    if wi.z <= 0.0 || wo.z <= 0.0 {
        return [0.0; 3];
    }
    let h = (wi + wo).normalize();
    let alpha_b = (fit.roughness * fit.roughness).max(1e-4);
    let (alpha_x, alpha_y) = match fit.anisotropy {
        Some((strength, rotation)) => {
            let alpha_t = alpha_b + (1.0 - alpha_b) * strength * strength;
            if rotation == 0.0 { (alpha_t, alpha_b) } else { (alpha_b, alpha_t) }
        }
        None => (alpha_b, alpha_b),
    };
    let lobe = Brdf { diffuse: DVec3::ZERO, specular: DVec3::ONE, f0: 1.0, lobe: Lobe::Ggx { alpha_x, alpha_y } };
    // D·G/(4 cos cos) without Fresnel: the Ggx lobe at f0 = 1 has Schlick's F = 1.
    let dv = lobe.lobe_value(wi, wo);
    let schlick = (1.0 - wi.dot(h).clamp(0.0, 1.0)).powi(5);
    std::array::from_fn(|c| {
        let f0 = (GLTF_F0 * fit.specular_color[c] * fit.specular_factor).min(1.0);
        let f = f0 + (fit.specular_factor - f0) * schlick;
        (1.0 - f) * fit.base_color[c] / PI + f * dv
    })
}

/// The directions both the fit and the error integrate over: `(ω_i, ω_o, weight)` for every
/// view of [`VIEW_ANGLES`], with `weight` the cell's solid angle times `cos θ_i`. The grid is
/// polar about the view's mirror direction with rows denser near it (`angle = π t²`), so sharp
/// lobes are resolved; directions below the horizon are left out (both BRDFs are 0 there).
fn directions() -> &'static [(DVec3, DVec3, f64)] {
    static GRID: std::sync::OnceLock<Vec<(DVec3, DVec3, f64)>> = std::sync::OnceLock::new();
    GRID.get_or_init(|| {
        let (rows, cols) = (160, 128);
        let mut out = Vec::with_capacity(rows * cols * VIEW_ANGLES.len());
        for angle in VIEW_ANGLES {
            let (s, c) = angle.to_radians().sin_cos();
            let wo = DVec3::new(s, 0.0, c);
            let axis = crate::brdf::mirror(wo);
            let (t1, t2) = axis.any_orthonormal_pair();
            for i in 0..rows {
                let t = (i as f64 + 0.5) / rows as f64;
                let theta = PI * t * t;
                let d_theta = 2.0 * PI * t / rows as f64;
                for j in 0..cols {
                    let phi = 2.0 * PI * (j as f64 + 0.5) / cols as f64;
                    let wi = axis * theta.cos() + (t1 * phi.cos() + t2 * phi.sin()) * theta.sin();
                    if wi.z > 0.0 {
                        out.push((wi, wo, wi.z * theta.sin() * d_theta * 2.0 * PI / cols as f64));
                    }
                }
            }
        }
        out
    })
}

/// `‖a − b‖ / ‖a‖` of `f cos θ_i` over [`directions`], summed over channels.
fn relative_difference(a: impl Fn(DVec3, DVec3) -> [f64; 3], b: impl Fn(DVec3, DVec3) -> [f64; 3]) -> f64 {
    let (mut diff, mut norm) = (0.0, 0.0);
    for &(wi, wo, weight) in directions() {
        let (x, y) = (a(wi, wo), b(wi, wo));
        for c in 0..3 {
            diff += weight * (x[c] - y[c]).powi(2);
            norm += weight * x[c] * x[c];
        }
    }
    if norm > 0.0 { (diff / norm).sqrt() } else { 0.0 }
}

/// The GGX `α` whose specular term (at the same `F₀`) is closest to `brdf`'s.
fn fit_alpha(brdf: &Brdf) -> f64 {
    let target = |wi: DVec3, wo: DVec3| [brdf.lobe_value(wi, wo) / brdf.f0.max(1e-9), 0.0, 0.0];
    let error = |log_alpha: f64| {
        let alpha = log_alpha.exp();
        let ggx = Brdf {
            diffuse: DVec3::ZERO,
            specular: DVec3::ONE,
            f0: 1.0,
            lobe: Lobe::Ggx { alpha_x: alpha, alpha_y: alpha },
        };
        relative_difference(target, |wi, wo| [ggx.lobe_value(wi, wo), 0.0, 0.0])
    };
    // Golden-section search on log α in [α = 0.005, 1].
    let (mut lo, mut hi) = (0.005f64.ln(), 0.0f64);
    let ratio = (5f64.sqrt() - 1.0) / 2.0;
    let (mut x1, mut x2) = (hi - ratio * (hi - lo), lo + ratio * (hi - lo));
    let (mut f1, mut f2) = (error(x1), error(x2));
    for _ in 0..40 {
        if f1 < f2 {
            hi = x2;
            (x2, f2) = (x1, f1);
            x1 = hi - ratio * (hi - lo);
            f1 = error(x1);
        } else {
            lo = x1;
            (x1, f1) = (x2, f2);
            x2 = lo + ratio * (hi - lo);
            f2 = error(x2);
        }
    }
    ((lo + hi) / 2.0).exp()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn material(model: &str) -> Material {
        Material { model: model.parse().unwrap(), ..Material::default() }
    }

    #[test]
    fn ggx_maps_to_the_same_roughness_and_f0() {
        let m = Material { roughness: 0.5, f0: 0.04, specular: [1.0; 3], ..material("ggx") };
        let fit = fit(&m, [1.0; 3]);
        assert_eq!(fit.roughness, 0.5);
        assert!(fit.anisotropy.is_none());
        for c in fit.specular_color {
            assert!((c - 1.0).abs() < 1e-12);
        }
        // Only glTF's (1 − F) on the diffuse term differs.
        assert!(fit.error < 0.05, "{}", fit.error);
    }

    #[test]
    fn blinn_phong_fit_agrees_with_walters_beckmann_relation_and_beats_neighbours() {
        // Walter et al. 2007: Blinn-Phong exponent s ≈ 2/α² − 2 for Beckmann. GGX's sharper
        // core and longer tail move the L2 optimum wider, but within half of it.
        for exponent in [16.0, 64.0, 256.0] {
            let m = Material { exponent, ..material("blinn_phong") };
            let brdf = Brdf::from_material(&m);
            let alpha = fit_alpha(&brdf);
            let walter = (2.0 / (exponent + 2.0)).sqrt();
            assert!(alpha > walter && alpha < 1.5 * walter, "s {exponent}: α {alpha} vs {walter}");
            // A local minimum: 10% either way is worse.
            let err = |a: f64| {
                let g = Brdf {
                    diffuse: DVec3::ZERO,
                    specular: DVec3::ONE,
                    f0: 1.0,
                    lobe: Lobe::Ggx { alpha_x: a, alpha_y: a },
                };
                relative_difference(
                    |wi, wo| [brdf.lobe_value(wi, wo) / brdf.f0, 0.0, 0.0],
                    |wi, wo| [g.lobe_value(wi, wo), 0.0, 0.0],
                )
            };
            assert!(err(alpha) < err(alpha * 1.1) && err(alpha) < err(alpha / 1.1));
        }
    }

    #[test]
    fn reported_error_is_the_difference_measured_independently() {
        // Monte Carlo over the hemisphere (uniform sampling) of the same norm, at the same views.
        use rand::{Rng, SeedableRng};
        let m = Material { exponent: 40.0, specular: [0.6; 3], f0: 1.0, ..material("phong") };
        let fit = fit(&m, [1.0; 3]);
        let brdf = Brdf::from_material(&m);
        let mut rng = rand::rngs::SmallRng::seed_from_u64(7);
        let (mut diff, mut norm) = (0.0, 0.0);
        for angle in VIEW_ANGLES {
            let (s, c) = angle.to_radians().sin_cos();
            let wo = DVec3::new(s, 0.0, c);
            for _ in 0..200_000 {
                let z: f64 = rng.random();
                let phi = 2.0 * PI * rng.random::<f64>();
                let r = (1.0 - z * z).sqrt();
                let wi = DVec3::new(r * phi.cos(), r * phi.sin(), z);
                let a = brdf.eval(wi, wo).to_array();
                let b = gltf_brdf(&fit, wi, wo);
                for k in 0..3 {
                    diff += (z * (a[k] - b[k])).powi(2);
                    norm += (z * a[k]).powi(2);
                }
            }
        }
        let measured = (diff / norm).sqrt();
        assert!((measured / fit.error - 1.0).abs() < 0.1, "grid {} vs Monte Carlo {measured}", fit.error);
        assert!(fit.error > 0.0 && fit.error < 1.0);
    }

    #[test]
    fn lambert_has_no_specular_and_fits_to_the_fresnel_free_diffuse() {
        let fit = fit(&material("lambert"), [0.5, 1.0, 1.0]);
        assert_eq!(fit.specular_factor, 0.0);
        assert!((fit.base_color[0] - 0.4).abs() < 1e-12);
        assert!(fit.error < 1e-12, "{}", fit.error);
    }

    #[test]
    fn anisotropic_ggx_keeps_both_alphas() {
        let m = Material { roughness: 0.5, anisotropy: 0.6, ..material("ggx_anisotropic") };
        let fit = fit(&m, [1.0; 3]);
        let (strength, rotation) = fit.anisotropy.expect("anisotropic");
        let (ax, ay) = crate::brdf::anisotropic_alphas(0.5, 0.6);
        let alpha_b = fit.roughness * fit.roughness;
        assert!((alpha_b - ay).abs() < 1e-9);
        assert!((alpha_b + (1.0 - alpha_b) * strength * strength - ax).abs() < 1e-9);
        assert_eq!(rotation, 0.0);
        assert!(fit.error < 0.05, "{}", fit.error);
    }
}
