//! Node kinds whose techniques are not implemented: their parameters, ports and stage
//! structure are defined now so projects, validation and the editor treat them like any other
//! kind; their stages report that the technique is not available yet.

use crate::engine::{StageContext, StageError, StageValue};
use crate::node_kind::{Availability, NodeKindSpec, ParamKind, ParamSpec, PortSpec, PortType, StageSpec};

fn not_yet(ctx: &StageContext) -> Result<StageValue, StageError> {
    Err(StageError::Failed(format!("node `{}`: this technique is not available yet", ctx.node_id)))
}

pub fn area_light_painter_spec() -> NodeKindSpec {
    NodeKindSpec {
        name: "AreaLightPainter",
        label: "Area light painter",
        doc: "A textured area light for near-field relighting (Sun 2008 ch. 4).",
        inputs: vec![],
        outputs: vec![PortSpec { name: "lights", ty: PortType::Lights, required: false, many: false }],
        params: vec![
            ParamSpec {
                name: "texture",
                label: "Texture",
                unit: "",
                kind: ParamKind::Path { extensions: &["png", "exr", "hdr"], selects: None },
                doc: "Painted emission.",
            },
            ParamSpec {
                name: "position",
                label: "Centre",
                unit: "m",
                kind: ParamKind::Vec3 { min: -1e4, max: 1e4, default: [0.0, 2.0, 0.0] },
                doc: "Centre of the light.",
            },
            ParamSpec {
                name: "size",
                label: "Size",
                unit: "m",
                kind: ParamKind::Float { min: 1e-3, max: 1e3, default: 1.0 },
                doc: "Side length.",
            },
            ParamSpec {
                name: "intensity",
                label: "Intensity",
                unit: "",
                kind: ParamKind::Float { min: 0.0, max: 1e6, default: 10.0 },
                doc: "Emitted radiance scale.",
            },
        ],
        stages: vec![StageSpec {
            name: "lights",
            version: 1,
            params: &["texture", "position", "size", "intensity"],
            stages: &[],
            inputs: &[],
            persist: None,
            compute: not_yet,
        }],
        previews: Vec::new(),
        availability: Availability::Planned("painted area lights are not computed or drawn"),
    }
}

pub fn rsl_decomposer_spec() -> NodeKindSpec {
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
                version: 1,
                params: &[],
                stages: &["cube"],
                inputs: &[],
                persist: None,
                compute: rsl_merge_sequence,
            },
            StageSpec {
                name: "square_lights",
                version: 2,
                params: &["light_count"],
                stages: &["merge_sequence", "cube"],
                inputs: &[],
                persist: None,
                compute: rsl_square_lights,
            },
        ],
        previews: Vec::new(),
        availability: Availability::Planned("square lights are fitted but not drawn by any mode yet"),
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

fn rsl_merge_sequence(ctx: &StageContext) -> Result<StageValue, StageError> {
    let cube = ctx.stage::<crate::cubemap::CubeMap>("cube")?;
    let sequence = crate::rsl::MergeSequence::compute(cube, ctx.cancel_token(), &|f| ctx.progress(f))
        .map_err(|_| StageError::Cancelled)?;
    Ok(StageValue::new(sequence))
}

/// A cut of the merge sequence at K: O(fits of K regions), no new decomposition.
fn rsl_square_lights(ctx: &StageContext) -> Result<StageValue, StageError> {
    let cube = ctx.stage::<crate::cubemap::CubeMap>("cube")?;
    let sequence = ctx.stage::<crate::rsl::MergeSequence>("merge_sequence")?;
    Ok(StageValue::new(sequence.cut(cube, ctx.int("light_count")? as usize)))
}

pub fn blocker_spheres_spec() -> NodeKindSpec {
    NodeKindSpec {
        name: "BlockerSpheres",
        label: "Blocker sphere set",
        doc: "Spheres casting soft shadows via SH exponentials (Sun 2008 §5.2).",
        inputs: vec![],
        outputs: vec![PortSpec { name: "blockers", ty: PortType::Blockers, required: false, many: false }],
        params: vec![
            ParamSpec {
                name: "spheres",
                label: "Spheres",
                unit: "m",
                kind: ParamKind::Spheres { default: vec![([0.0, 1.0, 0.0], 0.5)] },
                doc: "Centres and radii.",
            },
            ParamSpec {
                name: "sh_bands",
                label: "SH bands",
                unit: "",
                kind: ParamKind::Int { min: 2, max: 8, default: 4 },
                doc: "Order of the SH visibility.",
            },
        ],
        stages: vec![StageSpec {
            name: "spheres",
            version: 1,
            params: &["spheres", "sh_bands"],
            stages: &[],
            inputs: &[],
            persist: None,
            compute: blocker_spheres,
        }],
        previews: Vec::new(),
        availability: Availability::Planned("blocker spheres cast no shadows"),
    }
}

crate::stage_type!(Vec<([f64; 3], f64)>, "spheres", |v| v.len() * 32);

fn blocker_spheres(ctx: &StageContext) -> Result<StageValue, StageError> {
    match ctx.value("spheres")? {
        crate::node_kind::ParamValue::Spheres(s) => {
            let _ = ctx.int("sh_bands")?;
            Ok(StageValue::new(s.clone()))
        }
        _ => Err(StageError::Internal("spheres".into())),
    }
}
