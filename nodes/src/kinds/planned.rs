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
        relevant: crate::node_kind::always_relevant,
    }
}
