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
