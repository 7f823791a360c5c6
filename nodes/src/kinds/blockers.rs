//! Blocker sphere sets: spheres that cast soft shadows from the environment through SH
//! exponentials (the math is in `crate::sh_exponential`, Sun 2008 §5.2). The Output's
//! `blocked_transport` stage multiplies each receiver's SH transport by the spheres'
//! visibility in the `sh_prt` mode.

use crate::engine::spec::{
    Availability, NodeKindSpec, ParamKind, ParamSpec, ParamValue, PortSpec, PortType, StageSpec,
};
use crate::engine::{StageContext, StageError, StageValue};
use crate::sh_exponential::{Blocker, ExpMethod, LOG_CLIP_RELATIVE, LogCapTable, OlTable, ShExp};
use glam::DVec3;
use serde::{Deserialize, Serialize};

crate::stage_type!(ShadowTables, "blocker shadow tables", |v| v.log.zonal.len() * 8 + v.ol.a.len() * 16 + 64);
crate::stage_type!(BlockerSet, "blocker spheres", |v| v.blockers.len() * 32 + v.tables.log.zonal.len() * 8 + 64);

/// The per-order tables: the log of a cap against its angular radius, and HYB's OL fit.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShadowTables {
    pub log: LogCapTable,
    pub ol: OlTable,
}

/// The spheres in world space with how their visibility is exponentiated.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BlockerSet {
    pub blockers: Vec<Blocker>,
    pub method: ExpMethod,
    /// Scales every sphere's log visibility: 1 opaque, 0 no shadow.
    pub strength: f64,
    pub tables: ShadowTables,
}

impl BlockerSet {
    pub fn bands(&self) -> usize {
        self.tables.log.bands
    }

    /// The exponential at this set's order, with its OL table.
    pub fn shexp(&self) -> ShExp {
        ShExp::with_ol(self.bands(), self.tables.ol.clone())
    }
}

/// A set's placement: its spheres are turned, scaled, then moved by the offset.
#[derive(Clone, Copy, Debug)]
pub struct SetTransform {
    pub rotation: glam::DQuat,
    pub scale: f64,
    pub offset: DVec3,
}

impl SetTransform {
    pub fn new(offset: [f64; 3], rotation_deg: [f64; 3], scale: f64) -> Self {
        let [x, y, z] = rotation_deg.map(f64::to_radians);
        let rotation =
            glam::DQuat::from_rotation_y(y) * glam::DQuat::from_rotation_x(x) * glam::DQuat::from_rotation_z(z);
        Self { rotation, scale, offset: DVec3::from(offset) }
    }

    /// A sphere centre as given, in the world.
    pub fn to_world(&self, centre: [f64; 3]) -> DVec3 {
        self.offset + self.rotation * (DVec3::from(centre) * self.scale)
    }

    /// The inverse of [`Self::to_world`].
    pub fn to_set(&self, world: DVec3) -> [f64; 3] {
        (self.rotation.inverse() * (world - self.offset) / self.scale).to_array()
    }
}

/// Entries of the log-cap table over `θ ∈ [0, π/2]`.
const LOG_TABLE_ENTRIES: usize = 512;

pub fn spec() -> NodeKindSpec {
    NodeKindSpec {
        name: "BlockerSpheres",
        label: "Blocker sphere set",
        doc: "Spheres that cast soft shadows from the environment onto the scene in the SH modes (SH \
              exponentials, Sun 2008 §5.2), given by hand or fitted to a model. The spheres themselves are not \
              drawn: they stand in for geometry.",
        inputs: vec![],
        outputs: vec![PortSpec { name: "blockers", ty: PortType::Blockers, required: false, many: false }],
        params: vec![
            ParamSpec {
                name: "spheres",
                label: "Spheres",
                unit: "m",
                kind: ParamKind::Spheres { default: vec![([0.0, 1.0, 0.0], 0.5)] },
                doc: "Centres and radii in the set's own frame (before its rotation, scale and offset).",
            },
            ParamSpec {
                name: "fit_model",
                label: "Fit to model",
                unit: "",
                kind: ParamKind::Path { extensions: &["gltf", "glb"], selects: None },
                doc: "A closed glTF model to approximate by spheres (in its own frame, then the set's rotation, \
                      scale and offset). When set, the fitted spheres replace the list above.",
            },
            ParamSpec {
                name: "fit_count",
                label: "Fitted spheres",
                unit: "",
                kind: ParamKind::Int { min: 1, max: 2000, default: 60 },
                doc: "How many spheres approximate the model (the thesis uses 60, 244 and 500); the node reports \
                      the share of the model's volume they leave uncovered.",
            },
            ParamSpec {
                name: "fit_resolution",
                label: "Fit grid",
                unit: "voxels",
                kind: ParamKind::Int { min: 16, max: 160, default: 64 },
                doc: "Voxels along the model's longest side for the fit: finer follows thin parts, slower.",
            },
            ParamSpec {
                name: "offset",
                label: "Offset",
                unit: "m",
                kind: ParamKind::Vec3 { min: -1e4, max: 1e4, default: [0.0; 3] },
                doc: "Moves the whole set.",
            },
            ParamSpec {
                name: "rotation",
                label: "Rotation",
                unit: "°",
                kind: ParamKind::Vec3 { min: -360.0, max: 360.0, default: [0.0; 3] },
                doc: "Turns the whole set about its origin (X, Y, Z Euler angles, applied Y·X·Z like objects).",
            },
            ParamSpec {
                name: "scale",
                label: "Scale",
                unit: "",
                kind: ParamKind::Float { min: 0.01, max: 100.0, default: 1.0 },
                doc: "Scales the whole set (centres and radii) about its origin.",
            },
            ParamSpec {
                name: "sh_bands",
                label: "SH order",
                unit: "",
                kind: ParamKind::Int { min: 3, max: 6, default: 4 },
                doc: "Bands of the spheres' visibility (n² coefficients); the thesis shades with 4.",
            },
            ParamSpec {
                name: "exponential",
                label: "Exponential",
                unit: "",
                kind: ParamKind::Choice {
                    options: &["ps_star_2", "ps_star_8", "hyb"],
                    default: "ps_star_2",
                    labels: &[
                        ("PS*-2", "accurate (within 0.1% of the exact exponential); the default"),
                        ("PS*-8", "a degree-8 series: no more accurate after scaling, slower"),
                        ("HYB", "fastest: a linear fit after halving, a few percent off"),
                    ],
                },
                doc: "How the summed log visibility is exponentiated: PS* isolates the DC term, scales and squares, \
                      and sums a factored series of that degree; HYB uses the optimal linear fit after halving.",
            },
            ParamSpec {
                name: "strength",
                label: "Strength",
                unit: "",
                kind: ParamKind::Float { min: 0.0, max: 1.0, default: 1.0 },
                doc: "Fades the shadows (scales the log visibility): 1 opaque, 0 none.",
            },
        ],
        stages: vec![
            StageSpec {
                name: "tables",
                version: 1,
                params: &["sh_bands"],
                stages: &[],
                inputs: &[],
                persist: None,
                compute: tables,
            },
            StageSpec {
                name: "fitted",
                version: 1,
                params: &["fit_model", "fit_count", "fit_resolution"],
                stages: &[],
                inputs: &[],
                persist: Some(crate::engine::Codec::of::<crate::sphere_set::SphereSetFit>()),
                compute: fitted,
            },
            StageSpec {
                name: "spheres",
                version: 3,
                params: &["spheres", "offset", "rotation", "scale", "exponential", "strength"],
                stages: &["tables", "fitted"],
                inputs: &[],
                persist: None,
                compute: spheres,
            },
        ],
        previews: Vec::new(),
        gizmo: crate::engine::spec::GizmoSpec::None,
        availability: Availability::Ready,
        relevant: crate::engine::spec::always_relevant,
        groups: &[],
        referenced_files: crate::gltf_import::referenced_files,
    }
}

/// The log-cap table (eigen log, clipped at 0.02 λ_max) and the OL fit on sums of random
/// sphere logs, at the set's order.
fn tables(ctx: &StageContext) -> Result<StageValue, StageError> {
    let bands = ctx.int("sh_bands")? as usize;
    let shexp = ShExp::new(bands);
    let log = LogCapTable::new(&shexp, LOG_TABLE_ENTRIES, LOG_CLIP_RELATIVE);
    let training = crate::sh_exponential::training_logs(&log, 1500, 0x5EED);
    ctx.check_cancel()?;
    let ol = OlTable::fit(&shexp, &training, 64, 8.0, 0.5);
    Ok(StageValue::new(ShadowTables { log, ol }))
}

/// Spheres fitted to the model file, if one is set (none otherwise).
fn fitted(ctx: &StageContext) -> Result<StageValue, StageError> {
    let Some(path) = ctx.path("fit_model")? else {
        return Ok(StageValue::new(crate::sphere_set::SphereSetFit::default()));
    };
    let model = crate::gltf_import::import(&path).map_err(StageError::Failed)?;
    for w in &model.warnings {
        ctx.warn(w.clone());
    }
    let meshes = crate::mesh::MeshSet { meshes: model.meshes };
    let (count, resolution) = (ctx.int("fit_count")? as usize, ctx.int("fit_resolution")? as usize);
    Ok(StageValue::new(crate::sphere_set::fit_spheres(&meshes, count, resolution, ctx.cancel_token())?))
}

fn spheres(ctx: &StageContext) -> Result<StageValue, StageError> {
    let ParamValue::Spheres(hand) = ctx.value("spheres")? else {
        return Err(StageError::Internal("spheres".into()));
    };
    let fit = ctx.stage::<crate::sphere_set::SphereSetFit>("fitted")?;
    let list = if fit.spheres.is_empty() { hand } else { &fit.spheres };
    // Said here rather than by the fit, which may come from the disk cache without its report.
    if !fit.spheres.is_empty() {
        ctx.inform(format!(
            "{} spheres leave {:.1}% of the model's volume uncovered (grid of {:.3} m voxels)",
            fit.spheres.len(),
            100.0 * fit.uncovered,
            fit.voxel
        ));
    }
    let transform = SetTransform::new(ctx.vec3("offset")?, ctx.vec3("rotation")?, ctx.float("scale")?);
    let method = match ctx.choice("exponential")? {
        "ps_star_8" => ExpMethod::PsStar(8),
        "hyb" => ExpMethod::Hyb,
        _ => ExpMethod::PsStar(2),
    };
    let blockers = list
        .iter()
        .filter(|(_, r)| *r > 0.0)
        .map(|(c, r)| Blocker { centre: transform.to_world(*c).to_array(), radius: r * transform.scale })
        .collect();
    Ok(StageValue::new(BlockerSet {
        blockers,
        method,
        strength: ctx.float("strength")?,
        tables: ctx.stage::<ShadowTables>("tables")?.clone(),
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The set's rotation, scale and offset place a sphere as a 90° turn about +Y, a doubling
    /// and a move should, and `to_set` undoes `to_world` (what dragging a sphere relies on).
    #[test]
    fn the_set_transform_places_spheres_and_inverts() {
        let t = SetTransform::new([1.0, 2.0, 3.0], [0.0, 90.0, 0.0], 2.0);
        let world = t.to_world([1.0, 0.5, 0.0]);
        assert!((world - DVec3::new(1.0, 3.0, 1.0)).length() < 1e-12, "{world}");
        let t = SetTransform::new([-0.3, 0.7, 4.0], [20.0, -35.0, 110.0], 0.4);
        let c = [0.9, -1.2, 0.25];
        let back = t.to_set(t.to_world(c));
        assert!(back.iter().zip(c).all(|(a, b)| (a - b).abs() < 1e-12), "{back:?}");
    }
}
