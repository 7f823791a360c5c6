//! The BRDF editor's normal map: its parameters, the stages that load it and build its NDF
//! pyramids ([`crate::normal_filtering`], Sun 2008 §5.1), and what the Output asks of them.
//! Loading and pyramids are keyed by the file and strength alone, so the filter choice and
//! tiling (read by `normal_settings`) rebuild nothing.

use crate::engine::spec::{ParamKind, ParamSpec, StageSpec};
use crate::engine::{StageContext, StageError, StageValue};
use crate::normal_filtering::{MomentPyramid, NormalMap, VmfPyramid};
use serde::{Deserialize, Serialize};

crate::stage_type!(NormalSettings, "normal-map settings");

/// How a minified normal map's texels are combined into what a pixel shades with.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum NormalFilter {
    /// Each texel's NDF as its SH to band 2 (its first two moments), MIP-mapped by averaging.
    Sh,
    /// [`NormalFilter::Sh`] for diffuse light; highlights from each texel's six vMF lobes.
    Vmf,
    /// One lobe from the averaged normal's length.
    Toksvig,
    /// The averaged normal, renormalised (the unfiltered baseline).
    None,
}

impl NormalFilter {
    pub const OPTIONS: &'static [&'static str] = &["sh", "vmf", "toksvig", "none"];

    pub fn parse(name: &str) -> Option<Self> {
        Some(match name {
            "sh" => Self::Sh,
            "vmf" => Self::Vmf,
            "toksvig" => Self::Toksvig,
            "none" => Self::None,
            _ => return None,
        })
    }
}

/// The filter and tiling a material's normal map is shaded with.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct NormalSettings {
    pub filter: NormalFilter,
    /// Repeats of the map per unit of texture coordinate.
    pub tiling: f64,
}

pub(super) fn params() -> Vec<ParamSpec> {
    vec![
        ParamSpec {
            name: "normal_map",
            label: "Normal map",
            unit: "",
            kind: ParamKind::Path { extensions: &["png", "exr", "jpg", "jpeg", "gltf", "glb"], selects: None },
            doc: "Tangent-space normal map (OpenGL convention, +Y up; linear values), relative to the \
                  project; or a glTF model: the normal texture of its material named as this node's id (as \
                  the model's meshes find their BRDF node), else of the first material with one, its scale \
                  multiplying the strength. Empty: none.",
        },
        ParamSpec::float(
            "normal_strength",
            "Normal strength",
            "",
            (0.0, 8.0, 1.0),
            "Scales the map's tilts (glTF's normalTexture scale); 0 flattens it.",
        ),
        ParamSpec::float(
            "normal_tiling",
            "Normal tiling",
            "",
            (0.001, 10000.0, 1.0),
            "Repeats of the normal map per unit of texture coordinate.",
        ),
        ParamSpec {
            name: "normal_filter",
            label: "Normal filtering",
            unit: "",
            kind: ParamKind::Choice {
                options: NormalFilter::OPTIONS,
                default: "sh",
                labels: &[
                    (
                        "SH NDF",
                        "Diffuse light sees each pixel's distribution of normals exactly to SH band 2; \
                         highlights widen by its spread along each of its axes (GGX and Ward), so ribs \
                         stretch a highlight one way. Fast to build.",
                    ),
                    (
                        "vMF mixture (6 lobes)",
                        "As SH for diffuse light; highlights from six lobes per texel fitted by EM, so \
                         highlights that split stay split. Fitting takes seconds per megapixel.",
                    ),
                    ("Toksvig", "One lobe whose width follows the averaged normal's length."),
                    (
                        "None (averaged normals)",
                        "The averaged normal, renormalised: distant bumps shine like a flat mirror.",
                    ),
                ],
            },
            doc: "How the texels a pixel covers are combined. Filtering is exact for Lambert, Blinn-Phong \
                  and isotropic GGX; Phong and the anisotropic lobes are filtered approximately.",
        },
        ParamSpec {
            name: "normal_preview_level",
            label: "Preview MIP level",
            unit: "",
            kind: ParamKind::Int { min: 0, max: 12, default: 4 },
            doc: "The node's preview shows the normal distribution and the effective lobe of the map's centre \
                  texel at this MIP level (a block of 2^level texels a side; past the top, the whole map).",
        },
    ]
}

/// The normal-map preview: the map, the NDF of its centre texel at the preview level, and the
/// effective lobe there ([`crate::preview::normal_map_panels`]).
pub(super) fn preview() -> crate::engine::spec::PreviewSpec {
    crate::engine::spec::PreviewSpec {
        stages: &["normal_preview"],
        make: |v| {
            let image = v[0].get::<crate::picture::PreviewImage>()?;
            (image.width > 0).then(|| crate::picture::Preview::Image(image.clone()))
        },
        size: [216.0, 72.0],
        caption: "Normal map; the normal distribution of its centre texel at the preview MIP level (seen from \
                  above); the effective lobe there, f·cos θi for a viewer 30° off the normal (both scaled to \
                  their peak)",
    }
}

pub(super) fn stages() -> Vec<StageSpec> {
    vec![
        StageSpec {
            name: "normal_map",
            version: 2,
            params: &["normal_map", "normal_strength", crate::engine::spec::NODE_ID],
            stages: &[],
            inputs: &[],
            persist: None,
            compute: normal_map,
        },
        StageSpec {
            name: "ndf_moments",
            version: 1,
            params: &[],
            stages: &["normal_map"],
            inputs: &[],
            persist: None,
            compute: ndf_moments,
        },
        StageSpec {
            name: "vmf_lobes",
            version: 2,
            params: &[],
            stages: &["normal_map"],
            inputs: &[],
            persist: None,
            compute: vmf_lobes,
        },
        StageSpec {
            name: "normal_preview",
            version: 1,
            params: &["normal_preview_level"],
            stages: &["material", "normal_map"],
            inputs: &[],
            persist: None,
            compute: normal_preview,
        },
        StageSpec {
            name: "normal_settings",
            version: 1,
            params: &["normal_filter", "normal_tiling"],
            stages: &[],
            inputs: &[],
            persist: None,
            compute: normal_settings,
        },
    ]
}

/// The map, tilts scaled by the strength (empty without a file).
fn normal_map(ctx: &StageContext) -> Result<StageValue, StageError> {
    let Some(path) = ctx.path("normal_map")? else { return Ok(StageValue::new(NormalMap::default())) };
    let gltf = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("gltf") || e.eq_ignore_ascii_case("glb"));
    let (map, scale) = if gltf {
        let loaded = crate::normal_filtering::load_gltf_normal_map(&path, ctx.node_id).map_err(StageError::Failed)?;
        let which = if loaded.named {
            "named as this node's id".to_string()
        } else {
            format!("the first with one: no material is named `{}`, this node's id", ctx.node_id)
        };
        ctx.inform(format!(
            "the normal texture of glTF material `{}` ({which}; scale {})",
            loaded.material, loaded.scale
        ));
        for warning in loaded.warnings {
            ctx.warn(warning);
        }
        (loaded.map, loaded.scale)
    } else {
        (crate::normal_filtering::load_normal_map(&path).map_err(StageError::Failed)?, 1.0)
    };
    Ok(StageValue::new(map.with_strength(ctx.float("normal_strength")? * scale)))
}

fn ndf_moments(ctx: &StageContext) -> Result<StageValue, StageError> {
    Ok(StageValue::new(MomentPyramid::build(ctx.stage::<NormalMap>("normal_map")?)))
}

fn vmf_lobes(ctx: &StageContext) -> Result<StageValue, StageError> {
    let map = ctx.stage::<NormalMap>("normal_map")?;
    match VmfPyramid::build(map, ctx.cancel_token()) {
        Ok(p) => Ok(StageValue::new(p)),
        Err(_) if ctx.cancel_token().is_cancelled() => Err(StageError::Cancelled),
        Err(e) => Err(StageError::Failed(e)),
    }
}

fn normal_preview(ctx: &StageContext) -> Result<StageValue, StageError> {
    let map = ctx.stage::<NormalMap>("normal_map")?;
    let brdf = crate::brdf::Brdf::from_material(ctx.stage::<super::brdf::Material>("material")?);
    let level = ctx.int("normal_preview_level")?.clamp(0, 24) as usize;
    Ok(StageValue::new(crate::preview::normal_map_panels(map, &brdf, level, 72)))
}

fn normal_settings(ctx: &StageContext) -> Result<StageValue, StageError> {
    let filter = ctx.choice("normal_filter")?;
    Ok(StageValue::new(NormalSettings {
        filter: NormalFilter::parse(filter)
            .ok_or_else(|| StageError::Internal(format!("unknown normal filter `{filter}`")))?,
        tiling: ctx.float("normal_tiling")?,
    }))
}
