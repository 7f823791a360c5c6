//! Fog medium node (Sun 2008 ch. 3): scattering coefficient and phase function. The analytic
//! airlight and surface-radiance tables (eqs. 3.15–3.29) arrive with the fog issue.

use crate::engine::{StageContext, StageError, StageValue};
use crate::graph::{Availability, NodeKindSpec, ParamKind, ParamSpec, PortSpec, PortType, StageSpec};
use serde::{Deserialize, Serialize};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Medium {
    /// Scattering coefficient per channel, 1/m.
    pub beta: [f64; 3],
    pub phase: String,
    /// Coefficients of the phase polynomial in cos α (eq. 3.18).
    pub phase_coefficients: [f64; 3],
    pub table_resolution: usize,
}

pub fn spec() -> NodeKindSpec {
    NodeKindSpec {
        name: "FogMedium",
        label: "Fog medium",
        doc: "Homogeneous single-scattering fog: glows around lights, airlight, light scattered onto surfaces.",
        inputs: vec![],
        outputs: vec![PortSpec { name: "medium", ty: PortType::Medium, required: false, many: false }],
        params: vec![
            ParamSpec {
                name: "beta",
                label: "Scattering β",
                unit: "1/m",
                kind: ParamKind::Color { max: 100.0, default: [0.04, 0.04, 0.04] },
                doc: "Scattering coefficient per channel.",
            },
            ParamSpec {
                name: "phase",
                label: "Phase function",
                unit: "",
                kind: ParamKind::Choice { options: &["isotropic", "polynomial"], default: "isotropic" },
                doc: "Isotropic, or a polynomial in cos α (eq. 3.18).",
            },
            ParamSpec {
                name: "phase_coefficients",
                label: "Phase coefficients",
                unit: "",
                kind: ParamKind::Vec3 { min: -10.0, max: 10.0, default: [1.0, 0.0, 0.0] },
                doc: "a0 + a1 cos α + a2 cos² α (normalised on use).",
            },
            ParamSpec {
                name: "table_resolution",
                label: "Table resolution",
                unit: "",
                kind: ParamKind::Choice { options: &["32", "64", "128", "256", "512"], default: "128" },
                doc: "Resolution of the F and G tables.",
            },
        ],
        stages: vec![StageSpec {
            name: "medium",
            version: 1,
            params: &["beta", "phase", "phase_coefficients", "table_resolution"],
            stages: &[],
            inputs: &[],
            persist: false,
            compute: medium,
        }],
        availability: Availability::Planned("issue 7 (fog medium)"),
    }
}

fn medium(ctx: &StageContext) -> Result<StageValue, StageError> {
    Ok(StageValue::Medium(Medium {
        beta: ctx.vec3("beta")?,
        phase: ctx.choice("phase")?.to_string(),
        phase_coefficients: ctx.vec3("phase_coefficients")?,
        table_resolution: ctx.choice("table_resolution")?.parse().unwrap_or(128),
    }))
}
