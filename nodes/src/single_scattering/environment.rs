//! The environment seen through the medium: its light scattered per SH band.

use super::*;

/// Environment light through fog (sec. 3.6.4): per SH band `l`, the factor that turns the
/// environment's radiance coefficients `L_lm` into the light scattered towards the viewer,
/// `√(4π/(2l+1)) PSF_l` (eq. 3.35), where `PSF(γ) = D² L_a(γ; D, ∞, β)/I_0` (eq. 3.30) treats
/// every environment texel as a point source at distance `D` (`I_0 = L dω D²`). The attenuated
/// part `e^{-βD} L` (eq. 3.37) is not included. Computed exactly from eq. 3.16 (no empirical
/// factorisation, eq. 3.32), so β and `D` stay interactive uniforms.
pub fn environment_scattering_bands(
    beta: f64,
    distance: f64,
    phase: &Phase,
    tables: &[FTable],
    bands: usize,
) -> Vec<f64> {
    let mut out = vec![0.0; bands];
    if beta <= 0.0 || distance <= 0.0 || bands == 0 {
        return out;
    }
    // γ = π t² clusters nodes near the source, where the PSF peaks like 1/γ.
    let (nodes, weights) = gauss_legendre(256);
    for (x, w) in nodes.iter().zip(&weights) {
        let t = (x + 1.0) / 2.0;
        let gamma = PI * t * t;
        let q = AirlightQuery { beta, d_sv: distance, d_vp: f64::INFINITY, gamma, i0: 1.0 };
        let psf = distance * distance * airlight(&q, phase, tables, Interpolation::Bilinear);
        // 2π ∫ PSF P_l(cos γ) sin γ dγ, with dγ = 2π t dt and dt = dx/2.
        let weight = 2.0 * PI * psf * gamma.sin() * 2.0 * PI * t * w / 2.0;
        let mu = gamma.cos();
        let (mut p_prev, mut p) = (0.0, 1.0);
        for (l, o) in out.iter_mut().enumerate() {
            *o += weight * p;
            let next = ((2 * l + 1) as f64 * mu * p - l as f64 * p_prev) / (l + 1) as f64;
            p_prev = p;
            p = next;
        }
    }
    out
}

/// Bands of the environment light that fog is applied to (the shaders' uniform arrays).
pub const MAX_ENVIRONMENT_FOG_BANDS: usize = 8;

/// An environment's light through a medium, ready to draw: the factors, the fogged light the
/// surfaces see (eq. 3.36) and the glow scattered towards the viewer.
#[derive(Clone, Debug, PartialEq)]
pub struct FoggedEnvironment {
    pub fog: EnvironmentFog,
    pub fogged: crate::sh::ShRgb,
    pub scattered: crate::sh::ShRgb,
}

impl FoggedEnvironment {
    /// `light` (SH) through a medium, on at most [`MAX_ENVIRONMENT_FOG_BANDS`] bands.
    pub fn new(beta: [f64; 3], distance: f64, phase: &Phase, tables: &[FTable], light: &crate::sh::ShRgb) -> Self {
        let fog = EnvironmentFog::new(beta, distance, phase, tables, light.bands.min(MAX_ENVIRONMENT_FOG_BANDS));
        Self { fogged: fog.fogged(light), scattered: fog.scattered(light), fog }
    }
}

/// How fog changes the light of an environment at distance `D` (eqs. 3.35–3.37), per channel.
#[derive(Clone, Debug, PartialEq)]
pub struct EnvironmentFog {
    /// `e^{-β D}`: what reaches the viewer directly (eq. 3.37).
    pub attenuation: [f64; 3],
    /// Per band: [`environment_scattering_bands`] (eq. 3.35).
    pub scattered: Vec<[f64; 3]>,
}

impl EnvironmentFog {
    pub fn new(beta: [f64; 3], distance: f64, phase: &Phase, tables: &[FTable], bands: usize) -> Self {
        let per_channel = beta.map(|b| environment_scattering_bands(b, distance, phase, tables, bands));
        Self {
            attenuation: beta.map(|b| (-b * distance).exp()),
            scattered: (0..bands).map(|l| [0, 1, 2].map(|c| per_channel[c][l])).collect(),
        }
    }

    /// The environment as seen through the fog, `L^attenuated + L^convolved` (eq. 3.36).
    pub fn fogged(&self, light: &crate::sh::ShRgb) -> crate::sh::ShRgb {
        let total: Vec<[f64; 3]> =
            self.scattered.iter().map(|s| [0, 1, 2].map(|c| s[c] + self.attenuation[c])).collect();
        light.scale_bands_rgb(&total)
    }

    /// The scattered part alone, `L^convolved` (eq. 3.35).
    pub fn scattered(&self, light: &crate::sh::ShRgb) -> crate::sh::ShRgb {
        light.scale_bands_rgb(&self.scattered)
    }
}
