//! The SH modes' surfaces.

use super::*;

/// `sh_irradiance`: unshadowed diffuse light per pixel (Sun 2008 eq. 2.20).
#[derive(Clone, Debug)]
pub struct IrradianceSurfaces {
    /// `E_lm = Â_l L_lm` on at most [`IRRADIANCE_BANDS`] bands (none without an environment).
    pub irradiance: Option<ShRgb>,
    /// Per material: diffuse albedo.
    pub albedo: Vec<[f64; 3]>,
}

impl IrradianceSurfaces {
    /// `light` is the environment's SH radiance; in fog, surfaces see it through the medium.
    pub fn new(light: Option<&ShRgb>, fog: Option<&FoggedEnvironment>, materials: &[FrameMaterial]) -> Self {
        let irradiance = light.map(|light| fog.map_or(light, |f| &f.fogged).irradiance().truncated(IRRADIANCE_BANDS));
        Self { irradiance, albedo: materials.iter().map(|m| m.material.albedo).collect() }
    }
}

/// `sh_prt`: shadowed diffuse transfer and glossy lobes on shadowed incident light, per vertex.
#[derive(Clone, Debug)]
pub struct PrtSurfaces {
    /// [`crate::transport::ShTransport`] and [`crate::prt::IncidentSh`] per vertex (or
    /// [`crate::adaptive_sh::AdaptiveIncident`]: read it with [`incident_sh`]; its bands may
    /// be fewer than the transport's).
    pub transport: Keyed,
    pub incident: Keyed,
    /// The light the diffuse transfer sees (through fog when there is one), if any.
    pub light: Option<ShRgb>,
    pub albedo: Vec<[f64; 3]>,
    /// Per material: its glossy lobe, its weight scaled by what reaches surfaces through fog.
    pub glossy: Vec<Option<crate::prt::GlossyLobe>>,
}

impl PrtSurfaces {
    /// Checks that the transport covers the scene's `vertices`. In fog the diffuse transfer
    /// sees the fogged environment (Sun 2008 sec. 3.6.5); the glossy lobes read per-vertex
    /// incident light computed without fog, so they get only its attenuation.
    pub fn new(
        transport: Keyed,
        incident: Keyed,
        light: Option<&ShRgb>,
        fog: Option<&FoggedEnvironment>,
        materials: &[FrameMaterial],
        lobes: Vec<Option<crate::prt::GlossyLobe>>,
        vertices: usize,
    ) -> Result<Self, String> {
        let t = transport.value.expect::<crate::transport::ShTransport>().map_err(|e| e.to_string())?;
        let r = incident_sh(&incident.value)?;
        let n = t.bands * t.bands;
        let ni = r.bands * r.bands;
        if t.transfer.len() != vertices * n || (!r.coeffs.is_empty() && r.coeffs.len() != vertices * ni * 3) {
            return Err(format!("the transport has {} receivers for {vertices} vertices", t.transfer.len() / n.max(1)));
        }
        let attenuation = fog.map_or([1.0; 3], |f| f.fog.attenuation);
        let glossy = lobes
            .into_iter()
            .map(|lobe| {
                lobe.filter(|l| !l.factors.is_empty()).map(|mut l| {
                    l.weight = std::array::from_fn(|c| l.weight[c] * attenuation[c]);
                    l
                })
            })
            .collect();
        Ok(Self {
            transport,
            incident,
            light: light.map(|l| fog.map_or(l, |f| &f.fogged).clone()),
            albedo: materials.iter().map(|m| m.material.albedo).collect(),
            glossy,
        })
    }
}

/// Per-vertex incident radiance from `incident_sh` or, in `sh_adaptive`, `adaptive_incident`.
pub fn incident_sh(value: &crate::engine::StageValue) -> Result<&crate::prt::IncidentSh, String> {
    match value.get::<crate::adaptive_sh::AdaptiveIncident>() {
        Some(a) => Ok(&a.incident),
        None => value.expect::<crate::prt::IncidentSh>().map_err(|e| e.to_string()),
    }
}
