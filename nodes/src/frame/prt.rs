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

/// `sh_irradiance` as a frame part: it reads only what every mode reads.
pub(super) struct Irradiance;

impl ModeFrame for Irradiance {
    fn stages(&self, _: &Linked) -> Vec<StageRef> {
        Vec::new()
    }

    fn surfaces(&self, _: &Gather, parts: &MaterialParts, inputs: &SurfaceInputs) -> Result<Surfaces, String> {
        Ok(Surfaces::Irradiance(IrradianceSurfaces::new(inputs.light, inputs.fogged, &parts.materials)))
    }
}

/// `sh_prt`, and `sh_adaptive` (`adaptive`: Lee's adaptive incident radiance instead of the full
/// Gaunt product) as frame parts: the scene's SH transport (blocked by the spheres), the
/// incident radiance per vertex, each material's glossy lobe.
pub(super) struct Prt {
    pub adaptive: bool,
}

impl Prt {
    /// The Output stage of the per-vertex incident radiance.
    fn incident(&self, separate_sun: bool) -> &'static str {
        match (self.adaptive, separate_sun) {
            (true, _) => crate::kinds::output::adaptive::stage_names(separate_sun).0,
            (false, true) => "incident_residual_sh",
            (false, false) => "incident_sh",
        }
    }
}

impl ModeFrame for Prt {
    fn material_stages(&self) -> &'static [&'static str] {
        &["sh_lobe"]
    }

    fn stages(&self, linked: &Linked) -> Vec<StageRef> {
        let mut stages = Vec::new();
        if let Some(scene) = &linked.scene {
            stages.push(StageRef::new(scene, "transport_sh"));
            stages.push(StageRef::new(linked.output, "blocked_transport"));
            if self.adaptive {
                stages.push(StageRef::new(scene, "adjacency"));
            }
        }
        stages.push(StageRef::new(linked.output, self.incident(linked.separate_sun)));
        stages
    }

    fn surfaces(&self, g: &Gather, parts: &MaterialParts, inputs: &SurfaceInputs) -> Result<Surfaces, String> {
        // The default material (none linked) has no lobe.
        let lobes = parts
            .mode_stages
            .iter()
            .map(|stages| stages.first().map(|lobe| typed(lobe, "sh_lobe")).transpose())
            .collect::<Result<_, String>>()?;
        Ok(Surfaces::Prt(PrtSurfaces::new(
            g.keyed(g.output, "blocked_transport")?,
            g.keyed(g.output, self.incident(g.separate_sun))?,
            inputs.light,
            inputs.fogged,
            &parts.materials,
            lobes,
            inputs.geometry.vertex_count(),
        )?))
    }
}
