//! The Output's choice to light the environment's sun apart from the mode's transport
//! ([`crate::sun`]): the parameter, the decision, and the transport's inputs over the sky
//! without its sun. The viewport shadows the disc (`render/src/passes/sun.rs`).

use super::{Mode, incident_from, wavelet_grid};
use crate::engine::spec::{ParamKind, ParamSpec, ParamValue};
use crate::engine::{Graph, StageContext, StageError, StageValue};

/// The Output parameter choosing whether the environment's sun is lit apart from the
/// transport ([`crate::sun`]).
pub const SUN: &str = "sun";

/// Whether the Output lights the environment's sun separately: it asks for it, its `mode` can
/// (the SH and wavelet modes, their unshadowed preview too, and `rsl`, whose square lights then
/// come from the sky without its sun), an environment is linked, and neither a medium nor
/// blocker spheres are (their transport of the sun is not shadow-mapped).
pub fn separates_sun(graph: &Graph, output: &str, mode: Mode) -> bool {
    let Some(node) = graph.node(output) else { return false };
    let asked = !matches!(node.params.get(SUN), Some(ParamValue::Choice(c)) if c == "in_environment");
    let linked = |port: &str| graph.upstream(output, port).is_some();
    asked
        && matches!(
            mode,
            Mode::ShIrradiance | Mode::ShPrt | Mode::ShAdaptive | Mode::WaveletVertex | Mode::WaveletPixel | Mode::Rsl
        )
        && linked("environment")
        && !linked("medium")
        && !linked("blockers")
}

/// The Output's [`SUN`] parameter.
pub(super) fn param() -> ParamSpec {
    ParamSpec {
        name: SUN,
        label: "Sun",
        unit: "",
        kind: ParamKind::Choice {
            options: &["separate", "in_environment"],
            default: "separate",
            labels: &[
                (
                    "Separate, shadow-mapped",
                    "The sun lights each pixel as a disc with shadow maps; the transport carries the sky.",
                ),
                ("In the environment", "The transport carries the sun with the sky."),
            ],
        },
        doc: "separate: the environment's sun (its brightest compact source) lights each pixel as a disc, \
              shadowed through shadow maps over the disc, and the mode's transport carries the sky \
              without it, so small bright suns cast sharp, correct shadows and do not band (in rsl, the \
              square lights come from the sky without its sun). Applies to the SH, wavelet and rsl \
              modes without a medium or blocker spheres linked. \
              in_environment: the transport carries the sun too.",
    }
}

/// `incident_sh` of the sky without its sun, when the sun is lit separately ([`SUN`]).
pub(super) fn incident_residual_sh(ctx: &StageContext) -> Result<StageValue, StageError> {
    incident_from(ctx, "residual_sh")
}

/// `wavelet_environment` of the sky without its sun, when the sun is lit separately ([`SUN`]).
pub(super) fn wavelet_residual_environment(ctx: &StageContext) -> Result<StageValue, StageError> {
    let grid = wavelet_grid(ctx)?;
    Ok(StageValue::new(match ctx.input::<crate::sun::SunSplit>("environment", "sun")? {
        Some(split) => crate::triple_product::prefiltered(&split.residual, grid),
        None => crate::cubemap::CubeMap { size: 0, texels: Vec::new() },
    }))
}
