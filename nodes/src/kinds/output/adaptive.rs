//! The Output's `sh_adaptive` mode: high-order SH lighting with Lee 2014's locally adaptive
//! products ([`crate::adaptive_sh`]). Its parameters and stages, kept apart from the other
//! modes'.

use crate::adaptive_sh::{
    AdaptiveIncident, AdaptiveInputs, AdaptiveSettings, Adjacency, LightProducts, ShadingWeights, adaptive_incident,
    full_incident, view_mse, view_psnr,
};
use crate::engine::spec::{ParamKind, ParamSpec, StageSpec};
use crate::engine::{StageContext, StageError, StageValue};
use crate::prt::GlossyLobe;
use crate::sh::ShRgb;
use crate::transport::ShTransport;
use serde::{Deserialize, Serialize};

const PARAMS: &[&str] =
    &["adaptive_level", "adaptive_threshold", "adaptive_refine", "adaptive_smooth", "adaptive_hysteresis", "exposure"];
const INPUTS: &[(&str, &str)] =
    &[("environment", "sh"), ("scene", "geometry"), ("scene", "adjacency"), ("material", "sh_lobe")];
/// With the sun lit apart ([`super::sun`]), the products take the sky without it.
const RESIDUAL_INPUTS: &[(&str, &str)] =
    &[("environment", "residual_sh"), ("scene", "geometry"), ("scene", "adjacency"), ("material", "sh_lobe")];

/// The incident and error stages' names, for the whole environment or (`separate_sun`) the sky
/// without its sun.
pub fn stage_names(separate_sun: bool) -> (&'static str, &'static str) {
    if separate_sun {
        ("adaptive_residual_incident", "adaptive_residual_error")
    } else {
        ("adaptive_incident", "adaptive_error")
    }
}

pub fn params() -> Vec<ParamSpec> {
    vec![
        ParamSpec {
            name: "adaptive_level",
            label: "SH level",
            unit: "",
            kind: ParamKind::Int { min: 2, max: 11, default: 10 },
            doc: "High-order SH mode: highest SH level of the glossy lighting (level 10 = 121 coefficients; the \
                  viewport draws up to 11). Limited by the environment's and the scene's SH bands (level = \
                  bands - 1).",
        },
        ParamSpec {
            name: "adaptive_threshold",
            label: "Adaptive threshold",
            unit: "of white",
            kind: ParamKind::Float { min: 0.0, max: 1.0, default: 0.005 },
            doc: "High-order SH mode: a vertex stops adding SH levels when the next one changes its glossy \
                  shading by less than this fraction of display white (averaged over view directions). 0 \
                  computes every level everywhere; larger is faster and less accurate. The node shows the \
                  PSNR against the full computation.",
        },
        ParamSpec {
            name: "adaptive_refine",
            label: "Refine borders",
            unit: "",
            kind: ParamKind::Bool { default: true },
            doc: "High-order SH mode: search outward from vertices of higher level and raise neighbours that \
                  stopped too early.",
        },
        ParamSpec {
            name: "adaptive_smooth",
            label: "Smooth borders",
            unit: "",
            kind: ParamKind::Bool { default: true },
            doc: "High-order SH mode: blend the higher levels two vertex rings outward where the level changes, \
                  so no seam shows.",
        },
        ParamSpec {
            name: "adaptive_hysteresis",
            label: "Hysteresis",
            unit: "",
            kind: ParamKind::Float { min: 0.05, max: 1.0, default: 0.5 },
            doc: "High-order SH mode: a vertex keeps a level it had in the previous frame until that level's \
                  change falls below this fraction of the threshold, and starts from it (1: no hysteresis, \
                  every frame computed afresh). Stops levels flickering while the lighting moves.",
        },
    ]
}

pub fn stages() -> Vec<StageSpec> {
    vec![
        StageSpec {
            name: "adaptive_incident",
            version: 1,
            params: PARAMS,
            stages: &["blocked_transport"],
            inputs: INPUTS,
            persist: None,
            compute: |ctx| adaptive_stage(ctx, "sh"),
        },
        StageSpec {
            name: "adaptive_error",
            version: 1,
            params: PARAMS,
            stages: &["blocked_transport", "adaptive_incident"],
            inputs: INPUTS,
            persist: None,
            compute: |ctx| error_stage(ctx, "sh", "adaptive_incident"),
        },
        StageSpec {
            name: "adaptive_residual_incident",
            version: 1,
            params: PARAMS,
            stages: &["blocked_transport"],
            inputs: RESIDUAL_INPUTS,
            persist: None,
            compute: |ctx| adaptive_stage(ctx, "residual_sh"),
        },
        StageSpec {
            name: "adaptive_residual_error",
            version: 1,
            params: PARAMS,
            stages: &["blocked_transport", "adaptive_residual_incident"],
            inputs: RESIDUAL_INPUTS,
            persist: None,
            compute: |ctx| error_stage(ctx, "residual_sh", "adaptive_residual_incident"),
        },
    ]
}

/// How the adaptive product went against the full one.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct AdaptiveError {
    pub psnr_db: f64,
    /// Multiply-adds of the adaptive product over the full product's.
    pub work: f64,
    pub full_ms: f64,
}
crate::stage_type!(AdaptiveError, "adaptive SH error", |_v| 24);

/// Everything both stages read, resolved.
struct Setup<'a> {
    products: LightProducts,
    transport: &'a ShTransport,
    adjacency: &'a Adjacency,
    lobe_of: Vec<Option<u16>>,
    weights: Vec<ShadingWeights>,
    settings: AdaptiveSettings,
    white: f64,
    /// The level asked for, when the SH bands of the environment or the scene allow less.
    limited_from: Option<usize>,
}

impl Setup<'_> {
    fn inputs<'s>(&'s self, previous: Option<&'s [u8]>) -> AdaptiveInputs<'s> {
        AdaptiveInputs {
            products: &self.products,
            visibility: &self.transport.visibility,
            stride: self.transport.bands * self.transport.bands,
            lobe_of: &self.lobe_of,
            weights: &self.weights,
            adjacency: self.adjacency,
            previous_levels: previous,
        }
    }
}

/// `None` without an environment. The lighting is the environment's SH output `light`.
fn setup<'a>(ctx: &'a StageContext, light: &str) -> Result<Option<Setup<'a>>, StageError> {
    let transport = ctx.stage::<ShTransport>("blocked_transport")?;
    let Some(light) = ctx.input::<ShRgb>("environment", light)? else { return Ok(None) };
    let meshes = ctx.required_input::<crate::mesh::MeshSet>("scene", "geometry")?;
    let adjacency = ctx.required_input::<Adjacency>("scene", "adjacency")?;
    let materials = ctx.inputs_all::<GlossyLobe>("material", "sh_lobe")?;
    let wanted = ctx.int("adaptive_level")? as usize;
    let level = wanted.min(light.bands.min(transport.bands).saturating_sub(1));
    let bands = level + 1;
    let vertices = adjacency.offsets.len().saturating_sub(1);
    if transport.visibility.len() != vertices * transport.bands * transport.bands {
        return Err(StageError::Failed(format!(
            "the transport has {} receivers for {vertices} vertices",
            transport.visibility.len() / (transport.bands * transport.bands).max(1)
        )));
    }
    let bytes = vertices as u64 * (bands * bands) as u64 * 12;
    if bytes > crate::limits::MAX_INCIDENT_BYTES {
        return Err(StageError::Failed(format!(
            "level {level} on {vertices} vertices needs {:.1} GiB of incident radiance (at most {:.0} GiB): lower \
             the SH level or the Scene's tessellation",
            bytes as f64 / (1u64 << 30) as f64,
            crate::limits::MAX_INCIDENT_BYTES as f64 / (1u64 << 30) as f64
        )));
    }
    // Per material (link order, as the frame assigns them): its weights, if glossy.
    let mut weights = Vec::new();
    let slots: Vec<Option<u16>> = materials
        .iter()
        .map(|(_, lobe)| {
            (!lobe.factors.is_empty()).then(|| {
                weights.push(ShadingWeights::new(&lobe.factors, lobe.weight, bands));
                (weights.len() - 1) as u16
            })
        })
        .collect();
    let mut lobe_of = Vec::with_capacity(vertices);
    for mesh in &meshes.meshes {
        let material =
            materials.iter().position(|(id, _)| !mesh.material.is_empty() && *id == mesh.material).unwrap_or(0);
        lobe_of.extend(std::iter::repeat_n(slots.get(material).copied().flatten(), mesh.positions.len()));
    }
    lobe_of.resize(vertices, None);
    let white = 2f64.powf(-ctx.float("exposure")?);
    let settings = AdaptiveSettings {
        threshold: ctx.float("adaptive_threshold")? * white,
        level,
        refine: ctx.boolean("adaptive_refine")?,
        smooth: ctx.boolean("adaptive_smooth")?,
        hysteresis: ctx.float("adaptive_hysteresis")?,
    };
    Ok(Some(Setup {
        products: LightProducts::new(light, bands),
        transport,
        adjacency,
        lobe_of,
        weights,
        settings,
        white,
        limited_from: (wanted > level).then_some(wanted),
    }))
}

/// Per-vertex incident radiance at adaptive levels; the previous result's levels give the
/// hysteresis.
fn adaptive_stage(ctx: &StageContext, light: &str) -> Result<StageValue, StageError> {
    let Some(setup) = setup(ctx, light)? else { return Ok(StageValue::new(AdaptiveIncident::default())) };
    let previous = ctx.previous::<AdaptiveIncident>();
    // With hysteresis the previous result's levels carry over to the next evaluation (under the
    // same settings and vertex count), so the result depends on the edits before it, as
    // hysteresis must; at 1 (none) every evaluation starts afresh and matches a fresh render.
    let previous_levels = previous
        .as_ref()
        .and_then(|p| p.get::<AdaptiveIncident>())
        .filter(|p| setup.settings.hysteresis < 1.0 && p.settings == Some(setup.settings))
        .map(|p| p.levels.as_slice());
    let result = adaptive_incident(&setup.inputs(previous_levels), &setup.settings, ctx.cancel_token())?;
    let s = &result.stats;
    if let Some(wanted) = setup.limited_from {
        ctx.inform(format!(
            "level {} of the {wanted} asked for: raise the environment's SH bands and the Scene's transport SH \
             bands to {} for it",
            setup.settings.level,
            wanted + 1
        ));
    }
    if s.glossy > 0 {
        ctx.inform(format!(
            "level {}: {:.0}% of the full product's work; {:.0}% of glossy vertices at the top level, {} raised by \
             the border search",
            setup.settings.level,
            100.0 * s.macs as f64 / s.full_macs.max(1) as f64,
            100.0 * s.roi as f64 / s.glossy as f64,
            s.refined
        ));
    }
    Ok(StageValue::new(result))
}

/// The full product, for the PSNR of the adaptive one (pulled after the frame is drawn).
fn error_stage(ctx: &StageContext, light: &str, incident: &str) -> Result<StageValue, StageError> {
    let Some(setup) = setup(ctx, light)? else { return Ok(StageValue::new(AdaptiveError::default())) };
    let adaptive = ctx.stage::<AdaptiveIncident>(incident)?;
    let start = std::time::Instant::now();
    let full = full_incident(&setup.inputs(None), ctx.cancel_token())?;
    let full_ms = start.elapsed().as_secs_f64() * 1e3;
    let psnr_db = view_psnr(view_mse(&adaptive.incident, &full, &setup.lobe_of, &setup.weights), setup.white);
    let work = adaptive.stats.macs as f64 / adaptive.stats.full_macs.max(1) as f64;
    if adaptive.stats.glossy > 0 {
        ctx.inform(format!(
            "PSNR {psnr_db:.1} dB against the full level-{} product ({full_ms:.0} ms), averaged over view \
             directions with white at the exposure",
            setup.settings.level
        ));
    } else {
        ctx.inform("no glossy material: the high-order product has nothing to do");
    }
    Ok(StageValue::new(AdaptiveError { psnr_db, work, full_ms }))
}
