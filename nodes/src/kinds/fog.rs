//! Fog medium node (Sun 2008 ch. 3): scattering coefficient and phase function, and the
//! tables of [`crate::single_scattering`]: `F^k` (eqs. 3.15, 3.19) and `G_n` (eq. 3.23) for
//! Lambert and a ladder of Phong exponents. The tables depend only on their resolution and the
//! number of phase terms, so changing β, the phase weights, a material or a light recomputes
//! no table.

use crate::engine::spec::PreviewSpec;
use crate::engine::spec::{Availability, NodeKindSpec, ParamKind, ParamSpec, PortSpec, PortType, StageSpec};
use crate::engine::{Codec, StageContext, StageError, StageValue};
use crate::picture::Preview;
use serde::{Deserialize, Serialize};

// Stage value types this module owns (see `engine::value`).
crate::stage_type!(Medium, "medium");

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Medium {
    /// Scattering coefficient per channel, 1/m.
    pub beta: [f64; 3],
    pub phase: String,
    /// Coefficients of the phase polynomial in cos α (eq. 3.18).
    pub phase_coefficients: [f64; 3],
    pub table_resolution: usize,
    /// Distance of the environment's light sources (sec. 3.6.4), m.
    pub environment_distance: f64,
}

impl Medium {
    /// Its phase function; `None` for an invalid polynomial.
    pub fn phase_function(&self) -> Option<crate::single_scattering::Phase> {
        if self.phase == "polynomial" {
            crate::single_scattering::Phase::polynomial(&self.phase_coefficients)
        } else {
            Some(crate::single_scattering::Phase::isotropic())
        }
    }
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
                kind: ParamKind::Choice { options: &["isotropic", "polynomial"], default: "isotropic", labels: &[] },
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
                name: "environment_distance",
                label: "Environment distance",
                unit: "m",
                kind: ParamKind::Float { min: 0.1, max: 1e5, default: 40.0 },
                doc: "How far away the environment's light is (sec. 3.6.4): the sky is dimmed by e^(-β·D) and \
                      its glow, the light the fog scatters from it, lights surfaces and fills the view.",
            },
            ParamSpec {
                name: "table_resolution",
                label: "Table resolution",
                unit: "",
                kind: ParamKind::Choice { options: &["32", "64", "128", "256", "512"], default: "512", labels: &[] },
                doc: "Resolution of the F tables (G tables use a quarter, at least 32). 512 keeps the \
                      airlight within 0.3% of numerical integration (bilinear lookups).",
            },
        ],
        stages: vec![
            StageSpec {
                name: "medium",
                version: 3,
                params: &["beta", "phase", "phase_coefficients", "table_resolution", "environment_distance"],
                stages: &[],
                inputs: &[],
                persist: None,
                compute: medium,
            },
            StageSpec {
                name: "f_tables",
                version: 1,
                params: &["phase", "table_resolution"],
                stages: &[],
                inputs: &[],
                persist: Some(Codec::of::<Vec<crate::single_scattering::FTable>>()),
                compute: f_tables,
            },
            StageSpec {
                name: "g_tables",
                version: 2,
                params: &["table_resolution"],
                stages: &[],
                inputs: &[],
                persist: Some(Codec::of::<crate::single_scattering::PhongGTables>()),
                compute: g_tables,
            },
        ],
        previews: vec![PreviewSpec {
            stages: &["medium", "f_tables"],
            make: |v| {
                let (m, tables) = (v[0].get::<Medium>()?, v[1].get::<Vec<crate::single_scattering::FTable>>()?);
                let phase = if m.phase == "polynomial" {
                    crate::single_scattering::Phase::polynomial(&m.phase_coefficients)?
                } else {
                    crate::single_scattering::Phase::isotropic()
                };
                Some(Preview::Image(crate::preview::fog_glow(m.beta, &phase, tables, 64)))
            },
            size: [80.0, 80.0],
            caption: "a point light 10 m away seen through this fog (airlight, eq. 3.16)",
        }],
        gizmo: crate::engine::spec::GizmoSpec::None,
        availability: Availability::Ready,
        relevant: crate::engine::spec::always_relevant,
        groups: &[],
        referenced_files: crate::engine::spec::no_referenced_files,
    }
}

fn resolution(ctx: &StageContext) -> Result<usize, StageError> {
    Ok(ctx.choice("table_resolution")?.parse().unwrap_or(crate::single_scattering::DEFAULT_RESOLUTION))
}

fn medium(ctx: &StageContext) -> Result<StageValue, StageError> {
    let beta = ctx.vec3("beta")?;
    let phase = ctx.choice("phase")?.to_string();
    let phase_coefficients = ctx.vec3("phase_coefficients")?;
    if phase == "polynomial" && crate::single_scattering::Phase::polynomial(&phase_coefficients).is_none() {
        return Err(StageError::Failed(format!(
            "phase coefficients {phase_coefficients:?} make a phase function that is negative for some angle \
             or integrates to zero; use a0 > 0 with |a1| ≤ a0 + a2, e.g. (1, 0.5, 0)"
        )));
    }
    let densest = beta.iter().copied().fold(0.0, f64::max);
    if densest > 2.0 {
        ctx.warn(format!(
            "β = {densest} /m: half the light is gone after {:.2} m, so anything a few metres away is black",
            std::f64::consts::LN_2 / densest
        ));
    }
    Ok(StageValue::new(Medium {
        beta,
        phase,
        phase_coefficients,
        table_resolution: resolution(ctx)?,
        environment_distance: ctx.float("environment_distance")?,
    }))
}

fn f_tables(ctx: &StageContext) -> Result<StageValue, StageError> {
    let terms = if ctx.choice("phase")? == "polynomial" { 3 } else { 1 };
    let resolution = resolution(ctx)?;
    let mut tables = Vec::new();
    for k in 0..terms {
        ctx.check_cancel()?;
        ctx.progress(k as f64 / terms as f64);
        tables.push(crate::single_scattering::FTable::new(k, resolution));
    }
    Ok(StageValue::new(tables))
}

fn g_tables(ctx: &StageContext) -> Result<StageValue, StageError> {
    let resolution = (resolution(ctx)? / 4).max(32);
    Ok(StageValue::new(crate::single_scattering::PhongGTables::new(resolution)))
}

#[cfg(test)]
mod tests {
    use crate::engine::spec::ParamValue;
    use crate::engine::{CancelToken, Engine};
    use crate::project::{Project, ProjectNode};
    use std::collections::BTreeMap;
    use std::path::Path;

    fn fog_project(beta: f64, resolution: &str) -> Project {
        let mut params = BTreeMap::new();
        params.insert("beta".to_string(), ParamValue::Color([beta; 3]));
        params.insert("table_resolution".to_string(), ParamValue::Choice(resolution.into()));
        let mut project = crate::project::default_project();
        project.nodes.push(ProjectNode {
            id: "fog".into(),
            kind: "FogMedium".into(),
            label: String::new(),
            position: [0.0, 0.0],
            params,
        });
        project
    }

    #[test]
    fn changing_beta_recomputes_no_table_and_resolution_does() {
        let engine = Engine::in_memory();
        let evaluate =
            |p: &Project| engine.evaluate(&p.graph(Path::new("fog.ron")).unwrap(), &CancelToken::default(), None);
        let first = evaluate(&fog_project(0.04, "32"));
        assert!(first.report.failed().is_empty());
        let computed = |e: &crate::engine::Evaluation| {
            e.report.computed().into_iter().filter(|(n, _)| n == "fog").map(|(_, s)| s).collect::<Vec<_>>()
        };
        assert_eq!(computed(&first), ["medium", "f_tables", "g_tables"]);
        assert_eq!(computed(&evaluate(&fog_project(0.2, "32"))), ["medium"], "β is a uniform, not a table input");
        assert_eq!(computed(&evaluate(&fog_project(0.2, "64"))), ["medium", "f_tables", "g_tables"]);
    }

    #[test]
    fn bad_media_are_explained() {
        let engine = Engine::in_memory();
        let mut dense = fog_project(30.0, "32");
        let result = engine.evaluate(&dense.graph(Path::new("fog.ron")).unwrap(), &CancelToken::default(), None);
        assert!(result.report.notes.iter().any(|n| n.contains("black")), "{:?}", result.report.notes);
        let fog = dense.nodes.iter_mut().find(|n| n.id == "fog").unwrap();
        fog.params.insert("phase".into(), ParamValue::Choice("polynomial".into()));
        fog.params.insert("phase_coefficients".into(), ParamValue::Vec3([0.0, 1.0, 0.0]));
        let result = engine.evaluate(&dense.graph(Path::new("fog.ron")).unwrap(), &CancelToken::default(), None);
        let failed = result.report.failed();
        assert!(failed.iter().any(|s| s.error.as_deref().is_some_and(|e| e.contains("negative"))), "{failed:?}");
        // Negative β never reaches a stage: the parameter's range refuses it.
        let mut negative = fog_project(0.04, "32");
        negative.nodes.last_mut().unwrap().params.insert("beta".into(), ParamValue::Color([-0.1, 0.0, 0.0]));
        let errors = negative.graph(Path::new("fog.ron")).unwrap_err();
        assert!(errors.iter().any(|e| e.message.contains("outside 0")), "{errors:?}");
    }
}
