//! Where a glossy lobe (Fresnel 1) sends the light it reflects, seen from a view direction: its
//! directional albedo `E(μ_o)` and the mean direction of its reflected rays; for isotropic GGX
//! and for Blinn-Phong (whose lobe has no long tail: Ward takes its table), and for Phong's lobe
//! about the mirror direction (whose albedo keeps the surface's cosine, `μ_o`, where it clears
//! the horizon: Blinn-Phong's, nearly flat, drew Phong's highlight too bright at oblique views).
//!
//! The split sum (Karis 2013, and [`crate::specular_cube`]) looks the prefiltered light up at
//! the mirror direction `r`, its lobe taken with `n = v = r`. That holds near the normal and
//! fails at grazing views: there the visible microfacets lean towards the viewer and GGX's long
//! tail carries much of the light far above `r`. At α 0.09 and `μ_o = n·ω_o = 0.05` (3° from
//! the horizon) the rays' mean direction lies 20° above the horizon, not 3°; the lookup at `r`
//! reads the horizon and, through a lobe as wide as the head-on one, the ground below it (on
//! the grazing test's sky 15% dark for the flat floor), while under a normal map the normals that
//! see the view at steeper angles are read nearly right, so the error does not cancel.
//!
//! Per `(μ_o, α)` the table holds `E = ∫ f (n·ω_i)₊ dω_i`, the fraction `t` of the angle from
//! `r` to `n` by which the mean of `ω_i` (weighted by `f (n·ω_i)`) has turned towards `n`, and
//! how much wider the rays spread than at normal incidence (where the split sum is exact): `b`,
//! the concentration at `μ_o = 1` over that at `μ_o` of the vMF of the same mean resultant length
//! (Banerjee et al. 2005), by which a lookup's `α²` grows.
//! GGX's come from sampling the visible normals (Heitz 2018, *Sampling the GGX distribution of
//! visible normals*, JCGT 7(4)): with `ω_i` the reflection of `ω_o` about a visible normal,
//! `f (n·ω_i) / p = G₂(ω_i, ω_o) / G₁(ω_o)` (Fresnel 1); Blinn-Phong's (exponent `2/α² − 2`,
//! normalised `(s + 8)/8π cosˢθ_h` as [`crate::brdf`] has it) from sampling half vectors by
//! `cosˢ⁺¹θ_h`; each on a fixed stratified grid.

use glam::DVec3;
use std::sync::OnceLock;

/// View cosines: `μ_o = (i / (MU_STEPS − 1))²`, dense at grazing views.
pub const MU_STEPS: usize = 16;
/// Roughnesses: `α = (j / (ALPHA_STEPS − 1))²`, 0 (a mirror) to 1.
pub const ALPHA_STEPS: usize = 8;
/// Samples per entry: a `GRID × GRID` stratified grid (of visible normals for GGX, of half
/// vectors for Blinn-Phong, of directions about the mirror direction for Phong).
const GRID: usize = 96;

/// The lobe shapes the table holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LobeShape {
    Ggx = 0,
    BlinnPhong = 1,
    /// The (modified) Phong lobe about the mirror direction, of exponent `(2/α² − 2)/4` (the
    /// Blinn-Phong exponent's quarter): the cosine at the surface stays in its integral, so its
    /// albedo is `μ_o` where it clears the horizon.
    Phong = 2,
}

impl LobeShape {
    pub const ALL: [LobeShape; 3] = [LobeShape::Ggx, LobeShape::BlinnPhong, LobeShape::Phong];

    /// The shape a material's lobe is tabulated as: GGX's long tail; Phong's lobe about the
    /// mirror direction; or a half-vector lobe without a tail (Blinn-Phong and Ward).
    pub fn of(model: crate::brdf::Model) -> Self {
        use crate::brdf::Model;
        match model {
            Model::Ggx | Model::GgxAnisotropic => LobeShape::Ggx,
            Model::Phong => LobeShape::Phong,
            _ => LobeShape::BlinnPhong,
        }
    }
}

/// `E`, `t` and `b` per shape, `α` and `μ_o`: entry `(shape · ALPHA_STEPS + j) · MU_STEPS + i`.
#[derive(Clone, Debug, PartialEq)]
pub struct ReflectedLobeTable {
    pub entries: Vec<[f32; 3]>,
}

/// The table, computed once.
pub fn table() -> &'static ReflectedLobeTable {
    static TABLE: OnceLock<ReflectedLobeTable> = OnceLock::new();
    TABLE.get_or_init(|| {
        let mut entries = Vec::with_capacity(LobeShape::ALL.len() * MU_STEPS * ALPHA_STEPS);
        for shape in LobeShape::ALL {
            for j in 0..ALPHA_STEPS {
                let alpha = (j as f64 / (ALPHA_STEPS - 1) as f64).powi(2);
                let head_on = reflected_lobe(shape, 1.0, alpha).concentration();
                for i in 0..MU_STEPS {
                    let mu = (i as f64 / (MU_STEPS - 1) as f64).powi(2);
                    let lobe = reflected_lobe(shape, mu, alpha);
                    let broadening = (head_on / lobe.concentration()).max(1.0);
                    entries.push([lobe.albedo as f32, lobe.toward_normal as f32, broadening as f32]);
                }
            }
        }
        ReflectedLobeTable { entries }
    })
}

/// One entry of the table.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReflectedLobe {
    /// `E(μ_o)`, the directional albedo.
    pub albedo: f64,
    /// The mean reflected direction's turn from the mirror direction towards the normal, as a
    /// fraction of their angle (0 for a mirror and at normal incidence).
    pub toward_normal: f64,
    /// The mean reflected direction, in the frame where `n = +z` and `ω_o` lies in the `xz`
    /// plane at `+x`.
    pub mean: DVec3,
    /// The length of the weighted mean of the reflected directions (1 for a mirror).
    pub mean_length: f64,
}

impl ReflectedLobe {
    /// The concentration of the vMF of the rays' mean resultant length (Banerjee et al. 2005;
    /// large for a mirror).
    pub fn concentration(&self) -> f64 {
        let r = self.mean_length.clamp(0.0, 1.0 - 1e-9);
        (3.0 * r - r * r * r) / (1.0 - r * r)
    }
}

/// Smith's `Λ` for isotropic GGX at a direction of cosine `c` from the normal.
fn lambda(c: f64, alpha: f64) -> f64 {
    let c2 = (c * c).max(1e-300);
    ((1.0 + alpha * alpha * (1.0 - c2) / c2).sqrt() - 1.0) / 2.0
}

/// The reflected lobe of `shape` and `alpha` seen at view cosine `mu` (clamped to [1e-4, 1]).
pub fn reflected_lobe(shape: LobeShape, mu: f64, alpha: f64) -> ReflectedLobe {
    let mu = mu.clamp(1e-4, 1.0);
    let wo = DVec3::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu);
    let mirror = DVec3::new(-wo.x, 0.0, wo.z);
    if alpha < 1e-4 {
        return ReflectedLobe { albedo: 1.0, toward_normal: 0.0, mean: mirror, mean_length: 1.0 };
    }
    let (albedo, sum) = match shape {
        LobeShape::Ggx => ggx_rays(wo, alpha),
        LobeShape::BlinnPhong => blinn_phong_rays(wo, alpha),
        LobeShape::Phong => phong_rays(wo, alpha),
    };
    let mean = sum.try_normalize().unwrap_or(DVec3::Z);
    let mean_length = if albedo > 0.0 { sum.length() / (albedo * (GRID * GRID) as f64) } else { 1.0 };
    let span = mirror.z.clamp(-1.0, 1.0).acos();
    let toward_normal = if span > 1e-6 { (1.0 - mean.z.clamp(-1.0, 1.0).acos() / span).clamp(0.0, 1.0) } else { 0.0 };
    ReflectedLobe { albedo, toward_normal, mean, mean_length }
}

/// The stratified grid's points in [0, 1)².
fn grid() -> impl Iterator<Item = (f64, f64)> {
    (0..GRID * GRID).map(|k| (((k / GRID) as f64 + 0.5) / GRID as f64, ((k % GRID) as f64 + 0.5) / GRID as f64))
}

/// Blinn-Phong of exponent `2/α² − 2` from `wo`: `E` and the sum of `f (n·ω_i) ω_i / p`.
fn blinn_phong_rays(wo: DVec3, alpha: f64) -> (f64, DVec3) {
    let s = (2.0 / (alpha * alpha) - 2.0).max(0.0);
    let (mut albedo, mut sum) = (0.0, DVec3::ZERO);
    for (u1, u2) in grid() {
        // Half vectors of density (s + 2)/2π cosˢ⁺¹θ_h; f (n·ω_i) / p(ω_i) with p(ω_i) = p(h)/(4 ω_o·h).
        let c = u1.powf(1.0 / (s + 2.0));
        let sin = (1.0 - c * c).max(0.0).sqrt();
        let phi = 2.0 * std::f64::consts::PI * u2;
        let h = DVec3::new(sin * phi.cos(), sin * phi.sin(), c);
        let oh = wo.dot(h);
        let wi = 2.0 * oh * h - wo;
        if oh <= 0.0 || wi.z <= 0.0 || c <= 0.0 {
            continue;
        }
        let weight = (s + 8.0) / (s + 2.0) * wi.z * oh / c;
        albedo += weight;
        sum += weight * wi;
    }
    (albedo / (GRID * GRID) as f64, sum)
}

/// Phong of exponent `(2/α² − 2)/4` about the mirror direction of `wo`: `E` and the sum of
/// `f (n·ω_i) ω_i / p` over directions of density `(s + 1)/2π cosˢ` about it.
fn phong_rays(wo: DVec3, alpha: f64) -> (f64, DVec3) {
    let s = ((2.0 / (alpha * alpha) - 2.0) / 4.0).max(0.0);
    let mirror = DVec3::new(-wo.x, -wo.y, wo.z);
    let (t, b) = mirror.any_orthonormal_pair();
    let (mut albedo, mut sum) = (0.0, DVec3::ZERO);
    for (u1, u2) in grid() {
        let c = u1.powf(1.0 / (s + 1.0));
        let sin = (1.0 - c * c).max(0.0).sqrt();
        let phi = 2.0 * std::f64::consts::PI * u2;
        let wi = t * (sin * phi.cos()) + b * (sin * phi.sin()) + mirror * c;
        if wi.z <= 0.0 {
            continue;
        }
        // f (n·ω_i) / p = ((s + 2)/2π cosˢ) (n·ω_i) / ((s + 1)/2π cosˢ).
        let weight = (s + 2.0) / (s + 1.0) * wi.z;
        albedo += weight;
        sum += weight * wi;
    }
    (albedo / (GRID * GRID) as f64, sum)
}

/// GGX of `alpha` from `wo`: `E` and the sum of `f (n·ω_i) ω_i / p` over visible normals.
fn ggx_rays(wo: DVec3, alpha: f64) -> (f64, DVec3) {
    let mu = wo.z;
    // Heitz 2018, listing 1: the view stretched to the unit-roughness configuration.
    let vh = DVec3::new(alpha * wo.x, alpha * wo.y, wo.z).normalize();
    let t1 = if vh.x * vh.x + vh.y * vh.y > 0.0 { DVec3::new(-vh.y, vh.x, 0.0).normalize() } else { DVec3::X };
    let t2 = vh.cross(t1);
    let g1 = 1.0 / (1.0 + lambda(mu, alpha));
    let (mut albedo, mut sum) = (0.0, DVec3::ZERO);
    for (u1, u2) in grid() {
        let r = u1.sqrt();
        let phi = 2.0 * std::f64::consts::PI * u2;
        let p1 = r * phi.cos();
        let s = 0.5 * (1.0 + vh.z);
        let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * phi.sin();
        let nh = t1 * p1 + t2 * p2 + vh * (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt();
        let m = DVec3::new(alpha * nh.x, alpha * nh.y, nh.z.max(1e-9)).normalize();
        let wi = 2.0 * wo.dot(m) * m - wo;
        if wi.z <= 0.0 {
            continue;
        }
        let weight = (1.0 / (1.0 + lambda(mu, alpha) + lambda(wi.z, alpha))) / g1;
        albedo += weight;
        sum += weight * wi;
    }
    (albedo / (GRID * GRID) as f64, sum)
}

#[cfg(test)]
mod tests;
