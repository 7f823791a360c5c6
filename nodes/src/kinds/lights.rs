//! Point light node: isotropic point lights, chained into a light list.

use crate::engine::spec::{Availability, NodeKindSpec, ParamKind, ParamSpec, PortSpec, PortType, StageSpec};
use crate::engine::{StageContext, StageError, StageValue};

pub use crate::light::PointLight;

pub fn point_light_spec() -> NodeKindSpec {
    NodeKindSpec {
        name: "PointLight",
        label: "Point light",
        doc: "An isotropic point light (unshadowed; diffuse and the material's Phong-equivalent lobe, with \
              fog glows and scattering when a medium is linked); chain several through the `lights` input.",
        inputs: vec![PortSpec { name: "lights", ty: PortType::Lights, required: false, many: false }],
        outputs: vec![PortSpec { name: "lights", ty: PortType::Lights, required: false, many: false }],
        params: vec![
            ParamSpec {
                name: "position",
                label: "Position",
                unit: "m",
                kind: ParamKind::Vec3 { min: -1e4, max: 1e4, default: [0.0, 3.0, 0.0] },
                doc: "World-space position.",
            },
            ParamSpec {
                name: "intensity",
                label: "Intensity",
                unit: "W/sr",
                kind: ParamKind::Color { max: 1e7, default: [50.0, 45.0, 40.0] },
                doc: "Radiant intensity per channel.",
            },
        ],
        stages: vec![StageSpec {
            name: "lights",
            version: 1,
            params: &["position", "intensity"],
            stages: &[],
            inputs: &[("lights", "lights")],
            persist: None,
            compute: lights,
        }],
        previews: Vec::new(),
        gizmo: crate::engine::spec::GizmoSpec::Light { position: "position", colour: "intensity", aim: None },
        availability: Availability::Ready,
        relevant: crate::engine::spec::always_relevant,
        groups: &[],
        referenced_files: crate::engine::spec::no_referenced_files,
    }
}

fn lights(ctx: &StageContext) -> Result<StageValue, StageError> {
    let mut list = ctx.input::<Vec<PointLight>>("lights", "lights")?.cloned().unwrap_or_default();
    list.push(PointLight::isotropic(ctx.vec3("position")?, ctx.vec3("intensity")?));
    Ok(StageValue::new(list))
}
