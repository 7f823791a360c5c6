//! Painted area lights in a frame (Sun 2008 §4.5).

use super::*;
use crate::kinds::area_light::AreaLight;

/// Painted area lights (Sun 2008 §4.5): diffuse light per vertex, drawn over the mode's
/// surfaces as `albedo · colour / π · E`, plus their glossy highlights toward the view (§4.9).
#[derive(Clone, Debug)]
pub struct AreaLightFrame {
    /// [`crate::kinds::output::area::AreaIrradiance`]: `E` per vertex from every linked light.
    pub irradiance: Keyed,
    /// [`crate::kinds::output::area::AreaHighlights`]: reflected radiance per vertex (none, or
    /// empty, without a glossy material).
    pub highlights: Option<Keyed>,
    /// Per material: diffuse albedo.
    pub albedo: Vec<[f64; 3]>,
    /// The lights as the reference samples them.
    pub emitters: Vec<crate::reference::AreaEmitter>,
}

impl AreaLightFrame {
    /// Checks that the irradiance covers the scene's `vertices`.
    pub fn new(
        irradiance: Keyed,
        highlights: Option<Keyed>,
        emitters: Vec<crate::reference::AreaEmitter>,
        materials: &[FrameMaterial],
        vertices: usize,
    ) -> Result<Self, String> {
        let e = irradiance.value.expect::<crate::kinds::output::area::AreaIrradiance>().map_err(|e| e.to_string())?;
        if e.irradiance.len() != vertices {
            return Err(format!("the area lights cover {} receivers for {vertices} vertices", e.irradiance.len()));
        }
        if let Some(h) = &highlights {
            let h = h.value.expect::<crate::kinds::output::area::AreaHighlights>().map_err(|e| e.to_string())?;
            if !h.radiance.is_empty() && h.radiance.len() != vertices {
                return Err(format!("the area-light highlights cover {} of {vertices} vertices", h.radiance.len()));
            }
        }
        Ok(Self { irradiance, highlights, albedo: materials.iter().map(|m| m.material.albedo).collect(), emitters })
    }
}

/// The linked lights as one frame's [`AreaLightFrame`], once `area_irradiance` is evaluated.
/// A failed light is reported with its stage; the frame draws without area lights.
pub(super) fn area_light_frame(
    evaluation: &crate::engine::Evaluation,
    lights: &[&crate::engine::GraphNode],
    output: &str,
    keyed: &dyn Fn(&str, &str) -> Result<Keyed, String>,
    materials: &[FrameMaterial],
    vertices: usize,
) -> Result<Option<AreaLightFrame>, String> {
    match evaluation.get(output, "area_irradiance") {
        Some(r) if r.value.is_ok() && !lights.is_empty() => {
            let mut emitters = Vec::new();
            for node in lights {
                let light = keyed(&node.id, "light")?;
                let light = light.value.expect::<AreaLight>().map_err(|e| e.to_string())?;
                emitters.push(light.emitter.clone());
            }
            // Highlights as last evaluated, for the Output's `highlight_eye` (the editor
            // recomputes them once its camera rests).
            let highlights = match evaluation.get(output, "area_highlights") {
                Some(r) if r.value.is_ok() => Some(keyed(output, "area_highlights")?),
                _ => None,
            };
            Ok(Some(AreaLightFrame::new(keyed(output, "area_irradiance")?, highlights, emitters, materials, vertices)?))
        }
        _ => Ok(None),
    }
}
