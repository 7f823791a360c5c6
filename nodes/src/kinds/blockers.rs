//! Blocker sphere sets: spheres that cast soft shadows from the environment through SH
//! exponentials (the math is in `crate::sh_exponential`, Sun 2008 §5.2). The Output's
//! `blocked_transport` stage multiplies each receiver's SH transport by the spheres'
//! visibility in the `sh_prt` mode.

use crate::engine::{StageContext, StageError, StageValue};
use crate::node_kind::{Availability, NodeKindSpec, ParamKind, ParamSpec, ParamValue, PortSpec, PortType, StageSpec};
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

/// Entries of the log-cap table over `θ ∈ [0, π/2]`.
const LOG_TABLE_ENTRIES: usize = 512;

pub fn spec() -> NodeKindSpec {
    NodeKindSpec {
        name: "BlockerSpheres",
        label: "Blocker sphere set",
        doc: "Spheres that cast soft shadows from the environment onto the scene in the sh_prt mode (SH \
              exponentials, Sun 2008 §5.2). The spheres themselves are not drawn: they stand in for geometry.",
        inputs: vec![],
        outputs: vec![PortSpec { name: "blockers", ty: PortType::Blockers, required: false, many: false }],
        params: vec![
            ParamSpec {
                name: "spheres",
                label: "Spheres",
                unit: "m",
                kind: ParamKind::Spheres { default: vec![([0.0, 1.0, 0.0], 0.5)] },
                doc: "Centres and radii, before the offset.",
            },
            ParamSpec {
                name: "offset",
                label: "Offset",
                unit: "m",
                kind: ParamKind::Vec3 { min: -1e4, max: 1e4, default: [0.0; 3] },
                doc: "Moves the whole set.",
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
                name: "spheres",
                version: 2,
                params: &["spheres", "offset", "exponential", "strength"],
                stages: &["tables"],
                inputs: &[],
                persist: None,
                compute: spheres,
            },
        ],
        previews: Vec::new(),
        availability: Availability::Ready,
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

fn spheres(ctx: &StageContext) -> Result<StageValue, StageError> {
    let ParamValue::Spheres(list) = ctx.value("spheres")? else {
        return Err(StageError::Internal("spheres".into()));
    };
    let offset = DVec3::from(ctx.vec3("offset")?);
    let method = match ctx.choice("exponential")? {
        "ps_star_8" => ExpMethod::PsStar(8),
        "hyb" => ExpMethod::Hyb,
        _ => ExpMethod::PsStar(2),
    };
    let blockers = list
        .iter()
        .filter(|(_, r)| *r > 0.0)
        .map(|(c, r)| Blocker { centre: (DVec3::from(*c) + offset).to_array(), radius: *r })
        .collect();
    Ok(StageValue::new(BlockerSet {
        blockers,
        method,
        strength: ctx.float("strength")?,
        tables: ctx.stage::<ShadowTables>("tables")?.clone(),
    }))
}
