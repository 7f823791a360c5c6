//! Spot light node: a point light shining into a cone, optionally with a measured photometric
//! profile (an IES LM-63 file, [`crate::ies`]), chained into the light list like point lights.
//! Everything that draws point lights draws it through its angular profile
//! ([`crate::light::AngularProfile`]).

use crate::engine::spec::{Availability, GizmoSpec, NodeKindSpec, ParamKind, ParamSpec, PortSpec, PortType, StageSpec};
use crate::engine::{StageContext, StageError, StageValue};
use crate::ies::{LUMENS_PER_WATT, Photometry};
use crate::light::{AngularProfile, PointLight, cone};
use glam::DVec3;
use std::sync::Arc;

// Stage value types this module owns (see `engine::value`).
crate::stage_type!(Option<Photometry>, "photometric profile", |v| v.as_ref().map_or(0, |p| p
    .candela
    .iter()
    .map(|r| r.len() * 8)
    .sum()));

crate::choice_enum! {
    /// What sets the light's strength.
    pub enum Strength {
        /// `intensity` W/sr where the profile peaks.
        Intensity = "intensity",
        /// The file's peak candela (1/683 W/sr each), tinted by `intensity`'s hue.
        File = "file",
    }
}

pub fn spec() -> NodeKindSpec {
    NodeKindSpec {
        name: "SpotLight",
        label: "Spot light",
        doc: "A point light shining into a cone with a soft edge, shaped by a photometric (IES) profile when one \
              is given; chain it with point lights through the `lights` input.",
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
                name: "direction",
                label: "Direction",
                unit: "",
                kind: ParamKind::Vec3 { min: -1.0, max: 1.0, default: [0.0, -1.0, 0.0] },
                doc: "Where the cone's axis points (the profile's nadir, vertical angle 0°).",
            },
            ParamSpec {
                name: "intensity",
                label: "Intensity",
                unit: "W/sr",
                kind: ParamKind::Color { max: 1e7, default: [80.0, 76.0, 70.0] },
                doc: "Radiant intensity per channel along the brightest direction (with strength `file`, only its \
                      hue counts).",
            },
            ParamSpec::float(
                "cone",
                "Cone angle",
                "°",
                (1.0, 180.0, 35.0),
                "Half-angle of the cone outside which the light is dark (180: no cone).",
            ),
            ParamSpec::float(
                "falloff",
                "Falloff",
                "",
                (0.0, 1.0, 0.25),
                "Fraction of the cone over which the light fades smoothly to its edge.",
            ),
            ParamSpec {
                name: "profile",
                label: "IES profile",
                unit: "",
                kind: ParamKind::Path { extensions: &["ies"], selects: None },
                doc: "A photometric file (IES LM-63, type C) whose candela distribution shapes the light inside the cone.",
            },
            ParamSpec::float(
                "spin",
                "Spin",
                "°",
                (-180.0, 180.0, 0.0),
                "Turns the profile about the axis (an asymmetric profile's 0° plane).",
            ),
            ParamSpec {
                name: "strength",
                label: "Strength from",
                unit: "",
                kind: ParamKind::Choice { options: Strength::NAMES, default: "intensity", labels: &[] },
                doc: "`intensity`: the intensity parameter at the peak; `file`: the profile's own candela.",
            },
        ],
        stages: vec![
            StageSpec {
                name: "photometry",
                version: 1,
                params: &["profile"],
                stages: &[],
                inputs: &[],
                persist: None,
                compute: photometry,
            },
            StageSpec {
                name: "lights",
                version: 1,
                params: &["position", "direction", "intensity", "cone", "falloff", "spin", "strength"],
                stages: &["photometry"],
                inputs: &[("lights", "lights")],
                persist: None,
                compute: lights,
            },
        ],
        previews: Vec::new(),
        gizmo: GizmoSpec::Light { position: "position", colour: "intensity", aim: Some("direction") },
        availability: Availability::Ready,
        relevant: crate::engine::spec::always_relevant,
        groups: &[],
        referenced_files: crate::engine::spec::no_referenced_files,
    }
}

fn photometry(ctx: &StageContext) -> Result<StageValue, StageError> {
    let profile = match ctx.path("profile")? {
        Some(path) => Some(Photometry::load(&path).map_err(|e| StageError::Failed(e.to_string()))?),
        None => None,
    };
    Ok(StageValue::new(profile))
}

fn lights(ctx: &StageContext) -> Result<StageValue, StageError> {
    let mut list = ctx.input::<Vec<PointLight>>("lights", "lights")?.cloned().unwrap_or_default();
    let photometry = ctx.stage::<Option<Photometry>>("photometry")?.as_ref();
    let outer = ctx.float("cone")?.to_radians();
    let inner = outer * (1.0 - ctx.float("falloff")?);
    let peak = photometry.map_or(1.0, Photometry::peak);
    let cut = outer < std::f64::consts::PI;
    // Type C horizontal angles turn counter-clockwise seen from above the luminaire (from
    // behind its nadir), the opposite way to the light frame's φ about its nadir axis.
    let shape = |theta: f64, phi: f64| {
        let file = photometry.map_or(1.0, |p| p.candela(theta.to_degrees(), -phi.to_degrees()) / peak.max(1e-30));
        file * if cut { cone(theta, inner, outer) } else { 1.0 }
    };
    let aim = DVec3::from(ctx.vec3("direction")?);
    let mut profile = AngularProfile::tabulate(aim, ctx.float("spin")?.to_radians(), shape);
    profile.cone = beam(&profile, cut.then_some((inner, outer)));
    let intensity = ctx.vec3("intensity")?;
    let intensity = match (ctx.option::<Strength>("strength")?, photometry) {
        (Strength::File, Some(_)) => {
            let hue = intensity.iter().fold(1e-30f64, |m, &c| m.max(c));
            intensity.map(|c| c / hue * peak / LUMENS_PER_WATT)
        }
        _ => intensity,
    };
    list.push(PointLight { position: ctx.vec3("position")?, intensity, profile: Some(Arc::new(profile)) });
    Ok(StageValue::new(list))
}

/// The cone a format without profiles keeps of the light: where its brightest ring falls
/// below half its peak (inner) and below 1% (outer), within the node's own cone; `None` when
/// light leaves wider than a hemisphere (it is no spot).
fn beam(profile: &AngularProfile, node_cone: Option<(f64, f64)>) -> Option<(f64, f64)> {
    use crate::light::{PROFILE_PHI, PROFILE_THETA};
    let ring =
        |row: usize| profile.values[row * PROFILE_PHI..(row + 1) * PROFILE_PHI].iter().fold(0.0f32, |m, &v| m.max(v));
    let theta = |row: usize| std::f64::consts::PI * row as f64 / (PROFILE_THETA - 1) as f64;
    let last_above = |level: f32| (0..PROFILE_THETA).rev().find(|&r| ring(r) >= level).map_or(0.0, theta);
    let (mut inner, mut outer) = (last_above(0.5), last_above(0.01));
    if let Some((cone_inner, cone_outer)) = node_cone {
        (inner, outer) = (inner.min(cone_inner), outer.min(cone_outer));
    }
    (outer <= std::f64::consts::FRAC_PI_2).then_some((inner.min(outer), outer))
}
