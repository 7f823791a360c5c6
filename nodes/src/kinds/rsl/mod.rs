//! RSL decomposer node: the environment as rotatable square lights (Xu et al. 2006 §4.1,
//! `crate::rsl`). The decomposition reads the environment before exposure, tint and rotation,
//! so those edits only rescale and turn the lights (`world_lights`, O(K)). The `residual_`
//! stages decompose the sky without its sun (the environment's `source_sun`), for an Output
//! that lights the sun apart with its own shadows.

use crate::engine::spec::{
    Availability, NodeKindSpec, ParamKind, ParamSpec, PortSpec, PortType, PreviewSpec, StageSpec,
};
use crate::engine::{StageContext, StageError, StageValue};
use crate::preview::{self, Preview};

pub mod receivers;

pub fn spec() -> NodeKindSpec {
    NodeKindSpec {
        name: "RslDecomposer",
        label: "RSL decomposer",
        doc: "Fits rotatable square lights to an environment (Xu et al. 2006 §4.1): bright regions stay \
              small, dim ones grow; energy is kept exactly. Exposure does not change the fit.",
        inputs: vec![PortSpec { name: "environment", ty: PortType::Environment, required: true, many: false }],
        outputs: vec![PortSpec { name: "square_lights", ty: PortType::SquareLights, required: false, many: false }],
        params: vec![
            ParamSpec {
                name: "light_count",
                label: "Lights",
                unit: "",
                kind: ParamKind::Int { min: 6, max: 256, default: 30 },
                doc: "Number of square lights K (at least one per cube face; 20–40 suit most maps).",
            },
            ParamSpec {
                name: "cube_resolution",
                label: "Cube resolution",
                unit: "px",
                kind: ParamKind::Choice { options: &["16", "32", "64"], default: "32", labels: &[] },
                doc: "Texels per cube face the regions are merged from (64 is about 5x slower).",
            },
            ParamSpec {
                name: "merge_rule",
                label: "Merge rule",
                unit: "",
                kind: ParamKind::Choice {
                    options: &["merged_error", "error_increase"],
                    default: "merged_error",
                    labels: &[],
                },
                doc: "merged_error (the paper): merge the pair whose merged region fits best. error_increase: merge \
                      the pair that adds the least fitting error; keeps a uniform bright patch as one light.",
            },
        ],
        stages: vec![
            StageSpec {
                name: "cube",
                version: 1,
                params: &["cube_resolution"],
                stages: &[],
                inputs: &[("environment", "source")],
                persist: None,
                compute: rsl_cube,
            },
            StageSpec {
                name: "merge_sequence",
                version: 2,
                params: &["merge_rule"],
                stages: &["cube"],
                inputs: &[],
                persist: None,
                compute: |ctx| merge_sequence_of(ctx, "cube"),
            },
            StageSpec {
                name: "square_lights",
                version: 2,
                params: &["light_count"],
                stages: &["merge_sequence", "cube"],
                inputs: &[],
                persist: None,
                compute: |ctx| square_lights_of(ctx, "merge_sequence", "cube"),
            },
            StageSpec {
                name: "turned_lights",
                version: 1,
                params: &[],
                stages: &["square_lights"],
                inputs: &[("environment", "rotation")],
                persist: None,
                compute: |ctx| turned_lights_of(ctx, "square_lights"),
            },
            StageSpec {
                name: "world_lights",
                version: 2,
                params: &[],
                stages: &["turned_lights"],
                inputs: &[("environment", "radiance_scale")],
                persist: None,
                compute: |ctx| world_lights_of(ctx, "turned_lights"),
            },
            StageSpec {
                name: "residual_cube",
                version: 1,
                params: &["cube_resolution"],
                stages: &[],
                inputs: &[("environment", "source_sun")],
                persist: None,
                compute: rsl_residual_cube,
            },
            StageSpec {
                name: "residual_merge_sequence",
                version: 1,
                params: &["merge_rule"],
                stages: &["residual_cube"],
                inputs: &[],
                persist: None,
                compute: |ctx| merge_sequence_of(ctx, "residual_cube"),
            },
            StageSpec {
                name: "residual_square_lights",
                version: 1,
                params: &["light_count"],
                stages: &["residual_merge_sequence", "residual_cube"],
                inputs: &[],
                persist: None,
                compute: |ctx| square_lights_of(ctx, "residual_merge_sequence", "residual_cube"),
            },
            StageSpec {
                name: "residual_turned_lights",
                version: 1,
                params: &[],
                stages: &["residual_square_lights"],
                inputs: &[("environment", "rotation")],
                persist: None,
                compute: |ctx| turned_lights_of(ctx, "residual_square_lights"),
            },
            StageSpec {
                name: "residual_world_lights",
                version: 1,
                params: &[],
                stages: &["residual_turned_lights"],
                inputs: &[("environment", "radiance_scale")],
                persist: None,
                compute: |ctx| world_lights_of(ctx, "residual_turned_lights"),
            },
        ],
        previews: vec![
            PreviewSpec {
                // The lights the Output draws by default (the sun lit apart): one decomposition
                // for the first frame, not two.
                stages: &["residual_cube", "residual_square_lights"],
                make: |v| Some(Preview::Image(preview::square_light_regions(v[0].get()?, v[1].get()?, 192, 96))),
                size: [128.0, 64.0],
                caption: "regions of the square lights over the environment, its sun left to be lit apart (its \
                          own frame, auto-exposed)",
            },
            PreviewSpec {
                stages: &["residual_square_lights"],
                make: |v| Some(Preview::Image(preview::square_lights_sphere(v[0].get()?, 96))),
                size: [64.0, 64.0],
                caption: "the square lights on the environment sphere, its sun left to be lit apart (auto-exposed)",
            },
        ],
        gizmo: crate::engine::spec::GizmoSpec::None,
        availability: Availability::Ready,
        relevant: crate::engine::spec::always_relevant,
        groups: &[],
        referenced_files: crate::engine::spec::no_referenced_files,
    }
}

/// The environment before exposure and tint, as a cube map (exposure scales every candidate
/// merge's error alike, so it cannot change the fit).
fn rsl_cube(ctx: &StageContext) -> Result<StageValue, StageError> {
    let image = ctx.required_input::<crate::cubemap::Equirect>("environment", "source")?;
    let size: usize =
        ctx.choice("cube_resolution")?.parse().map_err(|_| StageError::Internal("cube_resolution".into()))?;
    Ok(StageValue::new(image.to_cubemap(size)))
}

/// The sky without its sun before exposure and tint, at the decomposition's resolution (the
/// environment's split box-filtered down, or resampled where it is coarser).
fn rsl_residual_cube(ctx: &StageContext) -> Result<StageValue, StageError> {
    let split = ctx.required_input::<crate::sun::SunSplit>("environment", "source_sun")?;
    let size: usize =
        ctx.choice("cube_resolution")?.parse().map_err(|_| StageError::Internal("cube_resolution".into()))?;
    let residual = &split.residual;
    Ok(StageValue::new(if residual.size >= size && residual.size.is_multiple_of(size) {
        residual.box_downsampled(size)
    } else {
        crate::cubemap::CubeMap::from_fn(size, 4, |d| residual.sample(d))
    }))
}

fn merge_sequence_of(ctx: &StageContext, cube: &str) -> Result<StageValue, StageError> {
    let cube = ctx.stage::<crate::cubemap::CubeMap>(cube)?;
    let rule = match ctx.choice("merge_rule")? {
        "error_increase" => crate::rsl::MergeRule::ErrorIncrease,
        _ => crate::rsl::MergeRule::MergedError,
    };
    let sequence = crate::rsl::MergeSequence::compute_with(cube, rule, ctx.cancel_token(), &|f| ctx.progress(f))
        .map_err(|_| StageError::Cancelled)?;
    Ok(StageValue::new(sequence))
}

/// A cut of the merge sequence at K: O(fits of K regions), no new decomposition.
fn square_lights_of(ctx: &StageContext, sequence: &str, cube: &str) -> Result<StageValue, StageError> {
    let cube = ctx.stage::<crate::cubemap::CubeMap>(cube)?;
    let sequence = ctx.stage::<crate::rsl::MergeSequence>(sequence)?;
    Ok(StageValue::new(sequence.cut(cube, ctx.int("light_count")? as usize)))
}

/// The lights turned into the world frame by the environment's rotation, before exposure and
/// tint: their directions and sizes, which is all visibility reads (so exposure reruns no
/// visibility). O(K).
fn turned_lights_of(ctx: &StageContext, lights: &str) -> Result<StageValue, StageError> {
    let lights = ctx.stage::<crate::rsl::SquareLights>(lights)?;
    let rotation = ctx.required_input::<glam::DMat3>("environment", "rotation")?;
    Ok(StageValue::new(crate::rsl::WorldLights {
        lights: lights.transformed([1.0; 3], glam::DQuat::from_mat3(rotation)),
    }))
}

/// The lights in the world frame with exposure and tint scaling their intensities: what
/// shading and export read. O(K): no new decomposition.
fn world_lights_of(ctx: &StageContext, turned: &str) -> Result<StageValue, StageError> {
    let turned = ctx.stage::<crate::rsl::WorldLights>(turned)?;
    let scale = ctx.required_input::<crate::kinds::environment::RadianceScale>("environment", "radiance_scale")?;
    Ok(StageValue::new(crate::rsl::WorldLights {
        lights: turned
            .lights
            .iter()
            .map(|l| crate::rsl::SquareLight { intensity: [0, 1, 2].map(|c| l.intensity[c] * scale.0[c]), ..l.clone() })
            .collect(),
    }))
}
