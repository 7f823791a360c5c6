//! Analytic BRDFs in the local shading frame (tangent `+X`, bitangent `+Y`, normal `+Z`), as
//! the BRDF editor exposes them: Lambert, normalised Phong, normalised Blinn-Phong,
//! Cook-Torrance with the GGX distribution (isotropic and anisotropic) and Ward's anisotropic
//! Gaussian. Each has exact evaluation, importance sampling with its exact pdf (for the Monte
//! Carlo reference) and the projections the relighting modes read (`Ma et al.` eq. 3's
//! `ρ̃ = ρ·(ω_i·n)`, tabulated per outgoing direction; an SH zonal lobe for the SH mode).
//!
//! Conventions: `f(ω_i, ω_o)` is the BRDF without the cosine; both directions point away from
//! the surface and are zero below the horizon. Every model is a diffuse part `albedo/π` plus a
//! specular lobe. The lobe's weight is `specular colour × f0` for Phong, Blinn-Phong and Ward
//! (no Fresnel), and `specular colour × F_Schlick(f0)` for GGX.

pub use crate::picture::LobePreview;
use glam::DVec3;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

// Stage value types this module owns (see `engine::value`).
crate::stage_type!(LobePreview, "BRDF lobe preview", |v| v.curves.iter().map(|c| c.len() * 4).sum());
crate::stage_type!(Material, "material");

crate::choice_enum! {
    /// The BRDF models (see [`Lobe`]).
    pub enum Model {
        Lambert = "lambert",
        Phong = "phong",
        BlinnPhong = "blinn_phong",
        Ggx = "ggx",
        GgxAnisotropic = "ggx_anisotropic",
        Ward = "ward",
    }
}

/// A material's parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Material {
    pub model: Model,
    pub albedo: [f64; 3],
    pub specular: [f64; 3],
    pub roughness: f64,
    pub exponent: f64,
    pub anisotropy: f64,
    pub f0: f64,
}

impl Default for Material {
    fn default() -> Self {
        Self {
            model: Model::Lambert,
            albedo: [0.8; 3],
            specular: [1.0; 3],
            roughness: 0.4,
            exponent: 64.0,
            anisotropy: 0.0,
            f0: 0.04,
        }
    }
}

/// The specular lobe of a model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Lobe {
    None,
    /// Normalised (modified) Phong: `(s+2)/2π · cos^s α`, `α` from the mirror direction.
    Phong {
        exponent: f64,
    },
    /// Normalised Blinn-Phong: `(s+8)/8π · cos^s θ_h`.
    BlinnPhong {
        exponent: f64,
    },
    /// Cook-Torrance with the anisotropic GGX distribution, height-correlated Smith masking and
    /// Schlick's Fresnel (Walter et al. 2007; Heitz 2014).
    Ggx {
        alpha_x: f64,
        alpha_y: f64,
    },
    /// Ward's anisotropic Gaussian (Ward 1992, eq. 5a).
    Ward {
        alpha_x: f64,
        alpha_y: f64,
    },
}

impl Lobe {
    /// The lobe seen through a vMF lobe of normals of concentration `kappa` (Han et al. 2007),
    /// and the factor its values take: a lobe `e^{s(h·n − 1)}` about the normal convolved with
    /// `e^{κ(n·μ − 1)}` is one of `κs/(κ + s)` about `μ`, so Blinn-Phong's exponent becomes
    /// that, and GGX's and Ward's slope variances `α²/2` grow by `1/κ` per axis. Phong's lobe
    /// is about the mirror direction, which turns twice as far as the normal: it sees `κ/4`.
    /// A convolution keeps the lobe's integral: GGX's and Ward's distributions stay normalised
    /// as they widen, and the Phong lobes' factor restores `∫ cos^s = 2π/(s + 1)` under their
    /// normalisation.
    pub fn widened(self, kappa: f64) -> (Self, f64) {
        if kappa >= super::normal_filtering::MAX_KAPPA {
            return (self, 1.0);
        }
        let kappa = kappa.max(1e-9);
        let exponent = |s: f64, k: f64| k * s / (k + s);
        let alpha = |a: f64| (a * a + 2.0 / kappa).sqrt();
        // (s + c)/(s + 1) per unit of the lobe's integral, before and after.
        let kept = |s: f64, widened: f64, c: f64| (s + c) * (widened + 1.0) / ((s + 1.0) * (widened + c));
        match self {
            Lobe::None => (Lobe::None, 1.0),
            Lobe::Phong { exponent: s } => {
                let w = exponent(s, kappa / 4.0);
                (Lobe::Phong { exponent: w }, kept(s, w, 2.0))
            }
            Lobe::BlinnPhong { exponent: s } => {
                let w = exponent(s, kappa);
                (Lobe::BlinnPhong { exponent: w }, kept(s, w, 8.0))
            }
            Lobe::Ggx { alpha_x, alpha_y } => (Lobe::Ggx { alpha_x: alpha(alpha_x), alpha_y: alpha(alpha_y) }, 1.0),
            Lobe::Ward { alpha_x, alpha_y } => (Lobe::Ward { alpha_x: alpha(alpha_x), alpha_y: alpha(alpha_y) }, 1.0),
        }
    }

    /// Whether the lobe is radially symmetric about the normal (a function of `h·n`), the
    /// family normal-map filtering is exact for (Sun 2008 eq. 5.3): Blinn-Phong and isotropic
    /// GGX (and Lambert, without a lobe).
    pub fn radially_symmetric(self) -> bool {
        match self {
            Lobe::None | Lobe::BlinnPhong { .. } => true,
            Lobe::Ggx { alpha_x, alpha_y } => alpha_x == alpha_y,
            Lobe::Phong { .. } | Lobe::Ward { .. } => false,
        }
    }
}

/// A BRDF ready to evaluate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Brdf {
    pub diffuse: DVec3,
    pub specular: DVec3,
    pub f0: f64,
    pub lobe: Lobe,
}

/// `(α_x, α_y)` from roughness and anisotropy: `α = roughness²`, stretched along the tangent
/// for positive anisotropy (Burley 2012's aspect `sqrt(1 - 0.9|a|)`).
pub fn anisotropic_alphas(roughness: f64, anisotropy: f64) -> (f64, f64) {
    let alpha = (roughness * roughness).max(1e-4);
    let aspect = (1.0 - 0.9 * anisotropy.abs().min(1.0)).sqrt();
    if anisotropy >= 0.0 { (alpha / aspect, alpha * aspect) } else { (alpha * aspect, alpha / aspect) }
}

/// Schlick's Fresnel approximation.
pub fn schlick(f0: f64, cos_d: f64) -> f64 {
    f0 + (1.0 - f0) * (1.0 - cos_d.clamp(0.0, 1.0)).powi(5)
}

/// Mirror of `w` about the normal.
pub fn mirror(w: DVec3) -> DVec3 {
    DVec3::new(-w.x, -w.y, w.z)
}

/// Anisotropic GGX normal distribution `D(h)`; `∫ D(h) h_z dω_h = 1`.
pub fn ggx_distribution(h: DVec3, ax: f64, ay: f64) -> f64 {
    if h.z <= 0.0 {
        return 0.0;
    }
    let s = (h.x / ax).powi(2) + (h.y / ay).powi(2) + h.z * h.z;
    1.0 / (PI * ax * ay * s * s)
}

/// Smith's `Λ` for anisotropic GGX.
fn ggx_lambda(w: DVec3, ax: f64, ay: f64) -> f64 {
    let t2 = ((ax * w.x).powi(2) + (ay * w.y).powi(2)) / (w.z * w.z);
    (-1.0 + (1.0 + t2).sqrt()) / 2.0
}

impl Brdf {
    pub fn from_material(m: &Material) -> Self {
        let (alpha_x, alpha_y) = anisotropic_alphas(m.roughness, m.anisotropy);
        let (ax_iso, _) = anisotropic_alphas(m.roughness, 0.0);
        let lobe = match m.model {
            Model::Lambert => Lobe::None,
            Model::Phong => Lobe::Phong { exponent: m.exponent },
            Model::BlinnPhong => Lobe::BlinnPhong { exponent: m.exponent },
            Model::Ggx => Lobe::Ggx { alpha_x: ax_iso, alpha_y: ax_iso },
            Model::GgxAnisotropic => Lobe::Ggx { alpha_x, alpha_y },
            Model::Ward => Lobe::Ward { alpha_x, alpha_y },
        };
        let specular = if lobe == Lobe::None { DVec3::ZERO } else { DVec3::from(m.specular) };
        Self { diffuse: DVec3::from(m.albedo), specular, f0: m.f0, lobe }
    }

    /// `f(ω_i, ω_o)` per RGB channel (local frame, zero below the horizon).
    pub fn eval(&self, wi: DVec3, wo: DVec3) -> DVec3 {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return DVec3::ZERO;
        }
        self.diffuse / PI + self.specular * self.lobe_value(wi, wo)
    }

    /// The scalar specular lobe (before the specular colour).
    pub fn lobe_value(&self, wi: DVec3, wo: DVec3) -> f64 {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return 0.0;
        }
        match self.lobe {
            Lobe::None => 0.0,
            Lobe::Phong { exponent } => {
                let c = wi.dot(mirror(wo)).max(0.0);
                self.f0 * (exponent + 2.0) / (2.0 * PI) * c.powf(exponent)
            }
            Lobe::BlinnPhong { exponent } => {
                let h = (wi + wo).normalize();
                self.f0 * (exponent + 8.0) / (8.0 * PI) * h.z.max(0.0).powf(exponent)
            }
            Lobe::Ggx { alpha_x, alpha_y } => {
                let h = (wi + wo).normalize();
                let d = ggx_distribution(h, alpha_x, alpha_y);
                let g = 1.0 / (1.0 + ggx_lambda(wi, alpha_x, alpha_y) + ggx_lambda(wo, alpha_x, alpha_y));
                schlick(self.f0, wi.dot(h)) * d * g / (4.0 * wi.z * wo.z)
            }
            Lobe::Ward { alpha_x, alpha_y } => {
                let h = (wi + wo).normalize();
                let e = ((h.x / alpha_x).powi(2) + (h.y / alpha_y).powi(2)) / (h.z * h.z);
                self.f0 * (-e).exp() / (4.0 * PI * alpha_x * alpha_y * (wi.z * wo.z).sqrt())
            }
        }
    }

    /// Probability of choosing the specular lobe when sampling.
    fn specular_probability(&self) -> f64 {
        let luminance = |c: DVec3| c.dot(DVec3::new(0.2126, 0.7152, 0.0722));
        let s = luminance(self.specular) * if self.lobe == Lobe::None { 0.0 } else { self.f0.max(0.02) };
        let d = luminance(self.diffuse);
        if s <= 0.0 {
            0.0
        } else if d <= 0.0 {
            1.0
        } else {
            (s / (s + d)).clamp(0.25, 0.9)
        }
    }

    /// Half-vector distribution parameters used to sample microfacet-like lobes.
    fn sampling_alphas(&self) -> Option<(f64, f64)> {
        match self.lobe {
            Lobe::BlinnPhong { exponent } => Some(((2.0 / (exponent + 2.0)).sqrt(), (2.0 / (exponent + 2.0)).sqrt())),
            Lobe::Ggx { alpha_x, alpha_y } | Lobe::Ward { alpha_x, alpha_y } => Some((alpha_x, alpha_y)),
            _ => None,
        }
    }

    /// Draws `ω_i` for `ω_o` from a mixture of cosine-weighted hemisphere and lobe sampling;
    /// `u ∈ [0,1)³`. The direction may lie below the horizon (then `f = 0`).
    pub fn sample(&self, wo: DVec3, u: [f64; 3]) -> DVec3 {
        let ps = self.specular_probability();
        if u[0] >= ps {
            return cosine_hemisphere(u[1], u[2]);
        }
        match (self.lobe, self.sampling_alphas()) {
            (Lobe::Phong { exponent }, _) => {
                let cos = u[1].powf(1.0 / (exponent + 1.0));
                let sin = (1.0 - cos * cos).max(0.0).sqrt();
                let phi = 2.0 * PI * u[2];
                let (t, b) = mirror(wo).any_orthonormal_pair();
                (t * sin * phi.cos() + b * sin * phi.sin() + mirror(wo) * cos).normalize()
            }
            (_, Some((ax, ay))) => {
                // Slopes of a unit GGX, stretched: h has density D(h)·h_z.
                let r = (u[1] / (1.0 - u[1]).max(1e-12)).sqrt();
                let phi = 2.0 * PI * u[2];
                let h = DVec3::new(-ax * r * phi.cos(), -ay * r * phi.sin(), 1.0).normalize();
                (2.0 * wo.dot(h) * h - wo).normalize()
            }
            _ => cosine_hemisphere(u[1], u[2]),
        }
    }

    /// Solid-angle density of [`Brdf::sample`] producing `ω_i`.
    pub fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        let ps = self.specular_probability();
        let diffuse = if wi.z > 0.0 { wi.z / PI } else { 0.0 };
        let lobe = match (self.lobe, self.sampling_alphas()) {
            (Lobe::Phong { exponent }, _) => {
                let c = wi.dot(mirror(wo)).max(0.0);
                (exponent + 1.0) / (2.0 * PI) * c.powf(exponent)
            }
            (_, Some((ax, ay))) => {
                let h = (wi + wo).normalize_or_zero();
                let cos_oh = wo.dot(h);
                if cos_oh <= 0.0 { 0.0 } else { ggx_distribution(h, ax, ay) * h.z / (4.0 * cos_oh) }
            }
            _ => diffuse,
        };
        (1.0 - ps) * diffuse + ps * lobe
    }

    /// A Phong exponent whose lobe about the mirror direction approximates this lobe: exact
    /// for Phong; Blinn-Phong's `s/4` (the half-angle is about half the mirror angle); GGX
    /// and Ward through the Blinn-Phong exponent `2/α² - 2` of their mean `α`. Used by the SH
    /// mode, which can only shade lobes symmetric about a direction.
    pub fn equivalent_phong_exponent(&self) -> Option<f64> {
        let from_alpha = |ax: f64, ay: f64| ((2.0 / (ax * ay) - 2.0) / 4.0).max(0.0);
        match self.lobe {
            Lobe::None => None,
            Lobe::Phong { exponent } => Some(exponent),
            Lobe::BlinnPhong { exponent } => Some(exponent / 4.0),
            Lobe::Ggx { alpha_x, alpha_y } | Lobe::Ward { alpha_x, alpha_y } => Some(from_alpha(alpha_x, alpha_y)),
        }
    }

    /// Zonal SH coefficients of the normalised Phong lobe `(s+2)/2π · cos^s α` about +Z (with
    /// `cos α < 0` clamped), `bands` long; the SH mode convolves incident radiance with it.
    pub fn phong_zonal(exponent: f64, bands: usize) -> Vec<f64> {
        crate::sh::zonal_project(bands, 256.max(bands * 4), |c| {
            (exponent + 2.0) / (2.0 * PI) * c.max(0.0).powf(exponent)
        })
    }
}

/// Half-angle (radians) at which a Phong lobe `cos^n α` falls to half its peak.
pub fn phong_half_width(exponent: f64) -> f64 {
    0.5f64.powf(1.0 / exponent.max(1e-9)).acos()
}

/// Fraction of the normalised Phong lobe's energy (its squared L2 norm) that the first `bands`
/// SH bands keep: how much of the highlight's shape an SH mode of that order can show. The
/// norm has the closed form `∫ f² dω = (n+2)² / (2π (2n+1))` (upper hemisphere).
pub fn phong_sh_energy_kept(exponent: f64, bands: usize) -> f64 {
    let kept: f64 = Brdf::phong_zonal(exponent, bands).iter().map(|z| z * z).sum();
    let total = (exponent + 2.0).powi(2) / (2.0 * PI * (2.0 * exponent + 1.0));
    (kept / total).min(1.0)
}

/// The sharpest Phong exponent whose lobe `bands` SH bands show with at least `keep` of its
/// energy (bisection in log exponent; the kept energy falls as the exponent grows).
pub fn sharpest_phong_for_sh(bands: usize, keep: f64) -> f64 {
    // Memoised: the editor asks after every evaluation.
    static KNOWN: std::sync::Mutex<Vec<(usize, u64, f64)>> = std::sync::Mutex::new(Vec::new());
    if let Some(&(.., n)) = KNOWN.lock().unwrap().iter().find(|(b, k, _)| *b == bands && *k == keep.to_bits()) {
        return n;
    }
    let n = bisect_sharpest_phong_for_sh(bands, keep);
    KNOWN.lock().unwrap().push((bands, keep.to_bits(), n));
    n
}

fn bisect_sharpest_phong_for_sh(bands: usize, keep: f64) -> f64 {
    let (mut lo, mut hi) = (0.0f64, 12.0f64); // ln exponent: 1 .. 160 000
    if phong_sh_energy_kept(hi.exp(), bands) >= keep {
        return hi.exp();
    }
    for _ in 0..40 {
        let mid = 0.5 * (lo + hi);
        if phong_sh_energy_kept(mid.exp(), bands) >= keep { lo = mid } else { hi = mid }
    }
    lo.exp()
}

/// The sharpest Phong exponent a table of `cells` equal cells over the sphere shows: the
/// lobe's half-maximum cone must cover at least two cells (`2π(1 - cos θ½) ≥ 2 · 4π/cells`).
pub fn sharpest_phong_for_cells(cells: usize) -> f64 {
    let cos_half = 1.0 - 4.0 / cells.max(5) as f64;
    0.5f64.ln() / cos_half.ln()
}

impl LobePreview {
    pub fn of(brdf: &Brdf) -> Self {
        let theta_out_deg = vec![0.0, 45.0, 75.0];
        let luminance = |c: DVec3| c.dot(DVec3::new(0.2126, 0.7152, 0.0722));
        let quadrature = crate::quadrature::SphereQuadrature::new(360, 720);
        let mut curves = Vec::new();
        let mut directional_albedo = Vec::new();
        for theta_o in &theta_out_deg {
            let t = f64::to_radians(*theta_o);
            let wo = DVec3::new(t.sin(), 0.0, t.cos());
            curves.push(
                (-90..=90)
                    .map(|deg| {
                        let a = f64::from(deg).to_radians();
                        let wi = DVec3::new(a.sin(), 0.0, a.cos().max(0.0));
                        (luminance(brdf.eval(wi, wo)) * wi.z) as f32
                    })
                    .collect(),
            );
            directional_albedo.push(quadrature.integrate(|wi| luminance(brdf.eval(wi, wo)) * wi.z.max(0.0)));
        }
        Self { theta_out_deg, curves, directional_albedo }
    }
}

/// Cosine-weighted direction in the upper hemisphere (pdf `cos θ / π`), Malley's method.
pub fn cosine_hemisphere(u1: f64, u2: f64) -> DVec3 {
    let r = u1.sqrt();
    let phi = 2.0 * PI * u2;
    DVec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u1).max(0.0).sqrt())
}

#[cfg(test)]
mod lobe_limit_tests {
    use super::*;

    #[test]
    fn sh_keeps_all_of_a_broad_lobe_and_little_of_a_sharp_one() {
        // Enough bands keep the whole lobe: the closed-form norm matches the projection.
        assert!((phong_sh_energy_kept(4.0, 40) - 1.0).abs() < 1e-3, "{}", phong_sh_energy_kept(4.0, 40));
        // Kept energy grows with the bands and falls with the exponent.
        assert!(phong_sh_energy_kept(20.0, 4) < phong_sh_energy_kept(20.0, 8));
        assert!(phong_sh_energy_kept(200.0, 6) < phong_sh_energy_kept(20.0, 6));
        assert!(phong_sh_energy_kept(200.0, 6) < 0.2, "6 bands cannot show Phong 200");
        // The sharpest lobe kept at one half is where the kept energy crosses one half.
        let n = sharpest_phong_for_sh(6, 0.5);
        assert!((phong_sh_energy_kept(n, 6) - 0.5).abs() < 1e-3 && n > 1.0 && n < 200.0, "{n}");
    }

    #[test]
    fn the_half_width_and_the_cell_limit_agree_with_their_definitions() {
        let n = 200.0;
        let h = phong_half_width(n);
        assert!((h.cos().powf(n) - 0.5).abs() < 1e-12);
        // At the cell limit the half-maximum cone covers exactly two cells.
        let cells = 320;
        let limit = sharpest_phong_for_cells(cells);
        let cone = 2.0 * PI * (1.0 - phong_half_width(limit).cos());
        assert!((cone - 2.0 * 4.0 * PI / cells as f64).abs() < 1e-9);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::quadrature::SphereQuadrature;
    use crate::sampling::{random_unit_vector, test_rng};
    use rand::Rng;

    fn material(model: &str, roughness: f64, exponent: f64, anisotropy: f64) -> Material {
        Material {
            model: model.parse().unwrap(),
            albedo: [0.5, 0.3, 0.2],
            specular: [1.0; 3],
            roughness,
            exponent,
            anisotropy,
            f0: 0.9,
        }
    }

    fn all_models() -> Vec<Brdf> {
        [
            material("lambert", 0.5, 10.0, 0.0),
            material("phong", 0.5, 30.0, 0.0),
            material("blinn_phong", 0.5, 60.0, 0.0),
            material("ggx", 0.5, 10.0, 0.0),
            material("ggx_anisotropic", 0.4, 10.0, 0.7),
            material("ward", 0.5, 10.0, -0.6),
        ]
        .iter()
        .map(Brdf::from_material)
        .collect()
    }

    fn upper(rng: &mut impl Rng) -> DVec3 {
        let d = random_unit_vector(rng);
        DVec3::new(d.x, d.y, d.z.abs().max(0.05)).normalize()
    }

    #[test]
    fn every_model_is_reciprocal_and_non_negative() {
        let mut rng = test_rng(3);
        for brdf in all_models() {
            for _ in 0..500 {
                let (a, b) = (upper(&mut rng), upper(&mut rng));
                let (fab, fba) = (brdf.eval(a, b), brdf.eval(b, a));
                assert!(fab.min_element() >= 0.0);
                assert!((fab - fba).abs().max_element() <= 1e-9 * (1.0 + fab.max_element()), "{brdf:?}: {fab} {fba}");
            }
        }
    }

    #[test]
    fn ggx_distribution_is_normalised_and_projects_to_unit_area() {
        // ∫ D(h) h_z dω = 1 (the microfacets' projected area), isotropic and anisotropic.
        let q = SphereQuadrature::new(800, 800);
        for (ax, ay) in [(0.5, 0.5), (0.3, 0.3), (0.6, 0.2)] {
            let total = q.integrate(|h| ggx_distribution(h, ax, ay) * h.z.max(0.0));
            assert!((total - 1.0).abs() < 2e-3, "({ax},{ay}): {total}");
        }
    }

    #[test]
    fn normalised_phong_and_blinn_phong_reflect_f0_at_normal_incidence() {
        // Directional albedo of the lobe alone at ω_o = n: ∫ f cos θ_i dω = f0 for Phong (exact
        // for the modified Phong normalisation (s+2)/2π); Blinn-Phong's (s+8)/8π is the usual
        // approximation, within a few percent.
        let q = SphereQuadrature::new(1200, 400);
        for (model, tolerance) in [("phong", 1e-3), ("blinn_phong", 0.05)] {
            let mut m = material(model, 0.5, 40.0, 0.0);
            m.albedo = [0.0; 3];
            let brdf = Brdf::from_material(&m);
            let albedo = q.integrate(|wi| brdf.eval(wi, DVec3::Z).x * wi.z.max(0.0));
            assert!((albedo / m.f0 - 1.0).abs() < tolerance, "{model}: {albedo} vs f0 {}", m.f0);
        }
    }

    #[test]
    fn lambert_white_furnace_and_energy_bounds() {
        let q = SphereQuadrature::new(400, 400);
        let mut m = material("lambert", 0.5, 10.0, 0.0);
        m.albedo = [1.0; 3];
        let brdf = Brdf::from_material(&m);
        let albedo = q.integrate(|wi| brdf.eval(wi, DVec3::new(0.3, 0.1, 0.95).normalize()).x * wi.z.max(0.0));
        assert!((albedo - 1.0).abs() < 1e-3, "{albedo}");
        // With F = 1 the GGX lobe reflects at most everything (Smith masking loses energy).
        let mut m = material("ggx", 0.6, 10.0, 0.0);
        (m.albedo, m.f0) = ([0.0; 3], 1.0);
        let brdf = Brdf::from_material(&m);
        for theta in [0.1f64, 0.7, 1.2] {
            let wo = DVec3::new(theta.sin(), 0.0, theta.cos());
            let albedo = q.integrate(|wi| brdf.eval(wi, wo).x * wi.z.max(0.0));
            assert!(albedo <= 1.0 + 2e-3 && albedo > 0.75, "θ {theta}: {albedo}");
        }
    }

    #[test]
    fn sampling_pdfs_integrate_to_one_and_match_the_sampler() {
        // 1) ∫ pdf dω = 1 by quadrature; 2) E[g(ω)/pdf(ω)] over the sampler = ∫ g dω for a
        // smooth g: a wrong pdf or sampler biases it.
        let q = SphereQuadrature::new(1000, 1000);
        let mut rng = test_rng(11);
        for brdf in all_models() {
            let wo = DVec3::new(0.4, -0.2, 0.89).normalize();
            let total = q.integrate(|wi| brdf.pdf(wo, wi));
            assert!((total - 1.0).abs() < 5e-3, "{brdf:?}: ∫pdf = {total}");
            let g = |w: DVec3| brdf.eval(w, wo).x * w.z.max(0.0);
            let exact = q.integrate(g);
            let n = 200_000;
            let estimate: f64 = (0..n)
                .map(|_| {
                    let wi = brdf.sample(wo, [rng.random(), rng.random(), rng.random()]);
                    let p = brdf.pdf(wo, wi);
                    if p > 0.0 { g(wi) / p } else { 0.0 }
                })
                .sum::<f64>()
                / n as f64;
            assert!((estimate - exact).abs() < 0.01 * exact.max(0.05), "{brdf:?}: MC {estimate} vs {exact}");
        }
    }

    #[test]
    fn lobe_preview_albedos_match_closed_forms() {
        // Lambert: directional albedo = albedo at every angle; the curve is albedo·cos/π.
        // Normalised Phong at normal incidence adds f0 (the lobe integrates to f0 there).
        let grey = |v: f64| [v; 3];
        let lambert = LobePreview::of(&Brdf::from_material(&Material { albedo: grey(0.6), ..Default::default() }));
        for a in &lambert.directional_albedo {
            assert!((a - 0.6).abs() < 2e-3, "{a}");
        }
        assert!((lambert.curves[0][90] as f64 - 0.6 / PI).abs() < 1e-6);
        assert!((lambert.curves[0][150] as f64 - 0.6 / PI * 60f64.to_radians().cos()).abs() < 1e-6);
        let phong = LobePreview::of(&Brdf::from_material(&Material {
            model: crate::brdf::Model::Phong,
            albedo: grey(0.3),
            specular: grey(1.0),
            exponent: 20.0,
            f0: 0.5,
            ..Default::default()
        }));
        assert!((phong.directional_albedo[0] - 0.8).abs() < 5e-3, "{}", phong.directional_albedo[0]);
        // The 45° curve peaks near the mirror direction (-45° on this axis; index 45), pulled a
        // few degrees towards the normal by the cosine.
        let peak = phong.curves[1].iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1)).unwrap().0;
        assert!((45..=50).contains(&peak), "peak at index {peak}");
    }

    #[test]
    fn phong_zonal_lobe_matches_its_function() {
        let zonal = Brdf::phong_zonal(20.0, 12);
        // Reconstruct at several angles: a 20-exponent lobe is well captured by 12 bands.
        let f = |c: f64| 22.0 / (2.0 * PI) * c.max(0.0).powf(20.0);
        for c in [1.0, 0.95, 0.8, 0.5] {
            let dir = DVec3::new((1.0f64 - c * c).sqrt(), 0.0, c);
            let value = crate::sh::reconstruct(&crate::sh::rotate_zonal(&zonal, DVec3::Z), dir);
            assert!((value - f(c)).abs() < 0.03 * f(1.0), "cos {c}: {value} vs {}", f(c));
        }
    }
}
