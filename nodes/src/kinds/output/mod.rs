//! Output node: what the viewport and `lightloom render` draw, and how (relighting mode,
//! exposure, tone mapping).

use crate::engine::spec::{
    Availability, NodeKindSpec, ParamKind, ParamSpec, ParamValue, PortSpec, PortType, StageSpec,
};
use crate::engine::{Graph, GraphNode, StageContext, StageError, StageValue};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

pub mod adaptive;
pub mod area;
mod bake;
pub mod relight;
mod sun;

// Stage value types this module owns (see `engine::value`).
crate::stage_type!(OutputSettings, "output settings");

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct OutputSettings {
    pub mode: Mode,
    pub exposure: f64,
    pub tonemap: Tonemap,
    pub background: bool,
    /// What the viewport shows: the approximation, the Monte Carlo reference, or the error map.
    pub view: View,
    /// Reference samples per pixel.
    pub reference_samples: usize,
    /// Whether the environment's sun is lit apart from the transport where the mode can
    /// ([`SUN`], [`separates_sun`]).
    pub separate_sun: bool,
    /// Detail terms each receiver keeps in the wavelet modes ([`crate::triple_product::details`]).
    #[serde(default)]
    pub wavelet_details: usize,
}

crate::choice_enum! {
    /// Relighting modes.
    pub enum Mode {
        /// Unshadowed diffuse lighting from the environment's SH, per pixel.
        ShIrradiance = "sh_irradiance",
        /// Shadowed SH transfer per vertex, glossy lobes on the shadowed incident radiance.
        ShPrt = "sh_prt",
        /// High-order SH with locally adaptive products per vertex (Lee 2014).
        ShAdaptive = "sh_adaptive",
        /// All-frequency local-frame triple product per vertex.
        WaveletVertex = "wavelet_vertex",
        /// The same, per pixel on objects with a visibility texture.
        WaveletPixel = "wavelet_pixel",
        /// Rotatable square lights per vertex (Xu et al. 2006): objects may move.
        Rsl = "rsl",
    }
}

impl Mode {
    pub fn is_wavelet(self) -> bool {
        matches!(self, Mode::WaveletVertex | Mode::WaveletPixel)
    }

    /// Whether surfaces are shadowed (needs precomputed visibility transport).
    pub fn is_shadowed(self) -> bool {
        self != Mode::ShIrradiance
    }

    /// Whether the mode's environment highlight is the true lobe of the GGX-prefiltered light
    /// once that is ready, occluded as the per-vertex SH highlight is (the SH modes: their
    /// Phong lobe to a few bands blurs bright lights into dark reflections).
    pub fn prefilters_highlight(self) -> bool {
        matches!(self, Mode::ShPrt | Mode::ShAdaptive)
    }
}

crate::choice_enum! {
    /// What the viewport shows.
    pub enum View {
        Approximation = "approximation",
        Reference = "reference",
        Error = "error",
    }
}

crate::choice_enum! {
    pub enum Tonemap {
        Aces = "aces",
        Reinhard = "reinhard",
        Linear = "linear",
    }
}

pub const WAVELET_TERMS: &[&str] = &["80", "320"];

/// Each mode in plain language, with what it shows and what it costs (in `Mode::NAMES` order).
pub const MODE_LABELS: &[(&str, &str)] = &[
    (
        "Soft light, no shadows",
        "Unshadowed diffuse light from the environment's low-frequency SH, per pixel. Updates instantly; \
         no shadows and no gloss.",
    ),
    (
        "Soft shadows and gloss",
        "Shadowed SH transfer per vertex, glossy lobes on the shadowed light (Sloan-style PRT). Relights \
         fast; shadows and highlights are low-frequency (blurred). Precomputes once per scene.",
    ),
    (
        "Sharper gloss, adaptive SH",
        "As soft shadows and gloss, at high SH order (level 10: 121 coefficients) for sharper highlights: \
         each vertex adds SH levels only while they still change its shading (Lee 2014), and the node \
         shows the PSNR against computing every level. Raise the environment's and the scene's SH bands.",
    ),
    (
        "Sharp shadows, per vertex",
        "All-frequency lighting (wavelet triple product) per vertex: sharp sun shadows and highlights \
         on finely tessellated meshes. Each lighting change recomputes per-vertex products (about a second \
         here).",
    ),
    (
        "Sharp shadows, per pixel",
        "As per vertex, plus per-texel visibility on objects with a visibility texture, so even a \
         coarse floor gets sharp shadows. Most accurate, slowest to precompute.",
    ),
    (
        "Square lights, movable objects",
        "The environment as a few dozen square lights (link an RSL decomposer to the Output's square \
         lights), each with per-vertex visibility from distance tables kept in each object's own space: \
         objects move and turn, and the environment rotates, without new precomputation; BRDF edits \
         rebuild small tables. Shadows between objects come from fields sampled around each object.",
    ),
];

pub fn spec() -> NodeKindSpec {
    let input = |name, ty, required| PortSpec { name, ty, required, many: false };
    NodeKindSpec {
        name: "Output",
        label: "Output",
        doc: "The rendered view: relighting mode, exposure and tone mapping.",
        inputs: vec![
            input("scene", PortType::Scene, true),
            input("environment", PortType::Environment, false),
            // Several materials: objects name theirs (`material` on a Scene object or the glTF
            // material name); unnamed objects take the first.
            PortSpec { name: "material", ty: PortType::Material, required: false, many: true },
            input("medium", PortType::Medium, false),
            input("lights", PortType::Lights, false),
            input("blockers", PortType::Blockers, false),
            input("square_lights", PortType::SquareLights, false),
            area::input(),
        ],
        outputs: vec![],
        params: vec![
            ParamSpec {
                name: "mode",
                label: "Relighting mode",
                unit: "",
                kind: ParamKind::Choice { options: Mode::NAMES, default: "sh_prt", labels: MODE_LABELS },
                doc: "sh_irradiance: unshadowed diffuse lighting from the environment's SH, per pixel (Sun 2008 \
                      eq. 2.20). sh_prt: shadowed diffuse transfer per vertex; glossy lobes on the shadowed \
                      incident radiance per vertex, then, once the environment is prefiltered, the true lobe \
                      per pixel, occluded by the vertex's transfer. sh_adaptive: the same at high SH order, each vertex adding SH \
                      levels only while they change its shading (Lee 2014). wavelet_vertex: all-frequency triple \
                      product in each vertex's local frame (Ma et al. eq. 7), 80 or 320 top-only coefficients. \
                      wavelet_pixel: the same, per pixel on objects with a \
                      visibility texture (sharp shadows and reflections on coarse meshes). rsl: the square lights \
                      of a linked RSL decomposer, per vertex (Xu et al. 2006 eq. 5). Each mode computes the \
                      transport it reads when first chosen; until then the view shows the unshadowed SH \
                      lighting and says so.",
            },
            ParamSpec {
                name: "wavelet_terms",
                label: "Wavelet coefficients",
                unit: "",
                kind: ParamKind::Choice { options: WAVELET_TERMS, default: "320", labels: &[] },
                doc: "Top-only spherical Haar coefficients per function in the wavelet mode (Ma et al.'s 80 or 320).",
            },
            ParamSpec {
                name: "wavelet_details",
                label: "Wavelet detail terms",
                unit: "",
                kind: ParamKind::Int { min: 0, max: crate::triple_product::details::MAX_DETAILS as i64, default: 32 },
                doc: "Finer wavelet terms each point keeps beyond the coefficients above, chosen per point where its \
                      lighting × visibility varies most within a cell and a glossy material can show it (a sun's \
                      glow, a softbox's edge). They sharpen glossy reflections; 0 keeps the coefficients alone.",
            },
            sun::param(),
            ParamSpec {
                name: "exposure",
                label: "Exposure",
                unit: "EV",
                kind: ParamKind::Float { min: -20.0, max: 20.0, default: 0.0 },
                doc: "Display exposure.",
            },
            ParamSpec {
                name: "tonemap",
                label: "Tone mapping",
                unit: "",
                kind: ParamKind::Choice { options: Tonemap::NAMES, default: "aces", labels: &[] },
                doc: "Applied to PNG output and the viewport; EXR output stays linear.",
            },
            ParamSpec {
                name: "background",
                label: "Show environment",
                unit: "",
                kind: ParamKind::Bool { default: true },
                doc: "Draw the environment behind the scene.",
            },
            ParamSpec {
                name: "view",
                label: "View",
                unit: "",
                kind: ParamKind::Choice { options: View::NAMES, default: "approximation", labels: &[] },
                doc: "approximation: the relighting mode; reference: Monte Carlo ground truth (same scene, BRDF, \
                      environment and camera); error: heat map of |approximation - reference| with its RMSE.",
            },
            ParamSpec {
                name: "reference_samples",
                label: "Reference samples",
                unit: "spp",
                kind: ParamKind::Int { min: 1, max: 65536, default: 64 },
                doc: "Samples per pixel of the reference (each: one environment and one BRDF sample, MIS).",
            },
            ParamSpec {
                name: HIGHLIGHT_EYE,
                label: "Highlights seen from",
                unit: "m",
                kind: ParamKind::Vec3 { min: -1e6, max: 1e6, default: [0.0, 1.5, 4.0] },
                doc: "The viewpoint area-light highlights are computed for (a glossy transport per view, Sun 2008 \
                      §4.9): the render camera's position, or the editor's view once it rests. Set by the \
                      program, not shown.",
            },
        ]
        .into_iter()
        .chain(adaptive::params())
        .chain(bake::params())
        .collect(),
        stages: [
            StageSpec {
                name: "settings",
                version: 1,
                params: &[
                    "mode",
                    "exposure",
                    "tonemap",
                    "background",
                    "view",
                    "reference_samples",
                    SUN,
                    "wavelet_details",
                ],
                stages: &[],
                inputs: &[],
                persist: None,
                compute: settings,
            },
            StageSpec {
                name: "blocked_transport",
                version: 2,
                params: &[],
                stages: &[],
                inputs: &[("scene", "transport_sh"), ("scene", "receivers"), ("blockers", "spheres")],
                persist: None,
                compute: blocked_transport,
            },
            StageSpec {
                name: "incident_sh",
                version: 3,
                params: &[],
                stages: &["blocked_transport"],
                inputs: &[("environment", "sh")],
                persist: None,
                compute: incident_sh,
            },
            StageSpec {
                name: "incident_residual_sh",
                version: 1,
                params: &[],
                stages: &["blocked_transport"],
                inputs: &[("environment", "residual_sh")],
                persist: None,
                compute: sun::incident_residual_sh,
            },
            StageSpec {
                name: "local_visibility",
                version: 1,
                params: &["wavelet_terms"],
                stages: &[],
                inputs: &[("scene", "transport_local")],
                persist: None,
                compute: local_visibility,
            },
            StageSpec {
                name: "wavelet_environment",
                version: 1,
                params: &["wavelet_terms"],
                stages: &[],
                inputs: &[("environment", "radiance")],
                persist: None,
                compute: wavelet_environment,
            },
            StageSpec {
                name: "wavelet_residual_environment",
                version: 1,
                params: &["wavelet_terms"],
                stages: &[],
                inputs: &[("environment", "sun")],
                persist: None,
                compute: sun::wavelet_residual_environment,
            },
            StageSpec {
                name: "texel_visibility",
                version: 1,
                params: &["wavelet_terms"],
                stages: &[],
                inputs: &[("scene", "geometry"), ("scene", "texel_receivers"), ("scene", "transport_texels")],
                persist: None,
                compute: texel_visibility,
            },
            StageSpec {
                name: "rsl_visibility",
                version: 1,
                params: &[],
                stages: &[],
                inputs: &[
                    ("scene", "rsl_self_visibility"),
                    ("scene", "rsl_occluders"),
                    ("square_lights", "turned_lights"),
                ],
                persist: None,
                compute: |ctx| rsl_visibility_of(ctx, "turned_lights"),
            },
            StageSpec {
                name: "rsl_residual_visibility",
                version: 1,
                params: &[],
                stages: &[],
                inputs: &[
                    ("scene", "rsl_self_visibility"),
                    ("scene", "rsl_occluders"),
                    ("square_lights", "residual_turned_lights"),
                ],
                persist: None,
                compute: |ctx| rsl_visibility_of(ctx, "residual_turned_lights"),
            },
        ]
        .into_iter()
        .chain(adaptive::stages())
        .chain(area::stages())
        .chain(bake::stages())
        .chain(relight::stages())
        .collect(),
        previews: Vec::new(),
        gizmo: crate::engine::spec::GizmoSpec::None,
        availability: Availability::Ready,
        relevant: relevant_to_mode,
        groups: bake::GROUPS,
        referenced_files: crate::engine::spec::no_referenced_files,
    }
}

/// The Output parameter holding the viewpoint of area-light highlights: derived from the camera
/// when a project becomes a graph ([`crate::project::Project::graph_seen_from`]), never edited.
pub const HIGHLIGHT_EYE: &str = "highlight_eye";

/// Which of the `linked` materials (node ids in link order) a mesh naming `material` takes;
/// `None` for an unnamed mesh or a name none has (both take the first).
pub fn named_material<'a>(material: &str, mut linked: impl Iterator<Item = &'a str>) -> Option<usize> {
    if material.is_empty() { None } else { linked.position(|node| node == material) }
}

/// Sets every Output's [`HIGHLIGHT_EYE`] in `graph`: view-dependent results for `eye`.
pub fn see_from(graph: &mut Graph, eye: [f64; 3]) {
    for node in graph.nodes.iter_mut().filter(|n| n.kind.name == "Output") {
        node.params.insert(HIGHLIGHT_EYE.into(), ParamValue::Vec3(eye));
    }
}

/// The wavelet and adaptive-SH settings matter only in their modes (the inspector hides them
/// elsewhere).
fn relevant_to_mode(value: &dyn Fn(&str) -> Option<ParamValue>, name: &str) -> bool {
    let mode @ Some(ParamValue::Choice(_)) = value("mode") else { return true };
    let mode = mode_of(mode.as_ref());
    match name {
        HIGHLIGHT_EYE => false,
        "wavelet_terms" | "wavelet_details" => mode.is_wavelet(),
        n if n.starts_with("adaptive_") => mode == Mode::ShAdaptive,
        _ => true,
    }
}

fn settings(ctx: &StageContext) -> Result<StageValue, StageError> {
    Ok(StageValue::new(OutputSettings {
        mode: ctx.option("mode")?,
        exposure: ctx.float("exposure")?,
        tonemap: ctx.option("tonemap")?,
        background: ctx.boolean("background")?,
        view: ctx.option("view")?,
        reference_samples: ctx.int("reference_samples")? as usize,
        separate_sun: ctx.choice(SUN)? == "separate",
        wavelet_details: ctx.int("wavelet_details")? as usize,
    }))
}

/// Shadowed incident radiance `R = L·V` per receiver for the `sh_prt` mode (pulled only by it).
/// Depends on lighting and transport only: BRDF and camera edits reuse it.
fn incident_sh(ctx: &StageContext) -> Result<StageValue, StageError> {
    incident_from(ctx, "sh")
}

pub(super) fn incident_from(ctx: &StageContext, lighting: &str) -> Result<StageValue, StageError> {
    let transport = ctx.stage::<crate::transport::ShTransport>("blocked_transport")?;
    let Some(light) = ctx.input::<crate::sh::ShRgb>("environment", lighting)? else {
        return Ok(StageValue::new(crate::prt::IncidentSh::default()));
    };
    Ok(StageValue::new(crate::prt::incident_radiance(light, transport, ctx.cancel_token())?))
}

/// At most this many receivers per memoised part of [`blocked_transport`].
const BLOCKED_PART: usize = 256;

/// One part of the blocked transport (both SH vectors of its receivers).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
struct BlockedPart {
    visibility: Vec<f32>,
    transfer: Vec<f32>,
}
crate::stage_type!(BlockedPart, "blocked transport part", encoding = 1, |v| (v.visibility.len() + v.transfer.len())
    * 4);

/// The scene's SH transport with the blocker spheres' visibility multiplied in per receiver
/// (Sun 2008 §5.2; pulled by `sh_prt`). Receivers are clustered by space into parts
/// (`sh_exponential::receiver_parts`), each memoised on its receivers, their transport and the
/// spheres within reach of its bounds, so moving one sphere recomputes only the parts it
/// reached before or reaches now. Without blockers it is the scene's transport.
fn blocked_transport(ctx: &StageContext) -> Result<StageValue, StageError> {
    let transport = ctx.required_input::<crate::transport::ShTransport>("scene", "transport_sh")?;
    let receivers = ctx.required_input::<crate::transport::Receivers>("scene", "receivers")?;
    Ok(StageValue::new(with_blockers(ctx, transport, receivers)?))
}

/// `transport` of `receivers` with the linked blocker spheres' visibility multiplied in (the
/// transport itself without blockers), memoised per part as [`blocked_transport`] says.
pub(super) fn with_blockers(
    ctx: &StageContext,
    transport: &crate::transport::ShTransport,
    receivers: &crate::transport::Receivers,
) -> Result<crate::transport::ShTransport, StageError> {
    use crate::sh_exponential::{BlockedProduct, blockers_in_reach, receiver_parts};
    use glam::DVec3;
    let Some(set) = ctx.input::<crate::kinds::blockers::BlockerSet>("blockers", "spheres")? else {
        return Ok(transport.clone());
    };
    let positions: Vec<DVec3> = receivers.positions.iter().map(|p| DVec3::from(p.map(f64::from))).collect();
    let n = transport.bands * transport.bands;
    if transport.transfer.len() != positions.len() * n || transport.visibility.len() != positions.len() * n {
        return Err(StageError::Failed(format!(
            "the transport covers {} of {} receivers",
            transport.transfer.len() / n.max(1),
            positions.len()
        )));
    }
    let product = BlockedProduct::new(set.shexp(), transport.bands);
    let parts = receiver_parts(&positions, BLOCKED_PART);
    // What every part depends on besides its own receivers and spheres, hashed once.
    let common = xxhash_rust::xxh3::xxh3_128(
        &postcard::to_allocvec(&(transport.bands, set.bands(), set.method, set.strength, &set.tables))
            .unwrap_or_default(),
    );
    let gather = |data: &[f32], indices: &[usize]| -> Vec<f32> {
        indices.iter().flat_map(|&i| data[i * n..(i + 1) * n].iter().copied()).collect()
    };
    let computed: Vec<Result<Option<crate::engine::Memo<BlockedPart>>, StageError>> = parts
        .par_iter()
        .map(|indices| {
            let points: Vec<DVec3> = indices.iter().map(|&i| positions[i]).collect();
            let near = blockers_in_reach(&points, &set.blockers);
            if near.is_empty() {
                return Ok(None);
            }
            let (v, t) = (gather(&transport.visibility, indices), gather(&transport.transfer, indices));
            let mut key = xxhash_rust::xxh3::Xxh3::new();
            key.update(&common.to_le_bytes());
            let described = (indices, points.iter().map(|p| p.to_array()).collect::<Vec<_>>(), &near);
            key.update(&postcard::to_allocvec(&described).unwrap_or_default());
            key.update(bytemuck::cast_slice(&v));
            key.update(bytemuck::cast_slice(&t));
            ctx.memo(key.digest128(), || {
                ctx.check_cancel()?;
                let (mut visibility, mut transfer) = (v.clone(), t.clone());
                product.apply(
                    &points,
                    &near,
                    &set.tables.log,
                    set.method,
                    set.strength,
                    &mut [&mut visibility, &mut transfer],
                );
                Ok(BlockedPart { visibility, transfer })
            })
            .map(Some)
        })
        .collect();
    let mut out = transport.clone();
    for (indices, part) in parts.iter().zip(computed) {
        if let Some(part) = part? {
            for (k, &i) in indices.iter().enumerate() {
                out.visibility[i * n..(i + 1) * n].copy_from_slice(&part.visibility[k * n..(k + 1) * n]);
                out.transfer[i * n..(i + 1) * n].copy_from_slice(&part.transfer[k * n..(k + 1) * n]);
            }
        }
    }
    Ok(out)
}

/// Per-vertex visibility cells `V_c` for the wavelet modes (pulled only by them). The
/// viewport multiplies the lighting in on the GPU, so lighting edits rebuild none of it.
fn local_visibility(ctx: &StageContext) -> Result<StageValue, StageError> {
    let transport = ctx.required_input::<crate::transport::SphericalTransport>("scene", "transport_local")?;
    let grid = wavelet_grid(ctx)?;
    Ok(StageValue::new(crate::triple_product::local_visibility(grid, transport, ctx.cancel_token())?))
}

pub(super) fn wavelet_grid(ctx: &StageContext) -> Result<&'static crate::triple_product::CellGrid, StageError> {
    let terms: usize =
        ctx.choice("wavelet_terms")?.parse().map_err(|_| StageError::Internal("wavelet_terms".into()))?;
    crate::triple_product::CellGrid::for_coefficients(terms).map_err(StageError::Failed)
}

/// The unrotated environment prefiltered to the wavelet grid's sub-cells (empty without an
/// environment): what the cell averages sample. A rotation does not rebuild it.
fn wavelet_environment(ctx: &StageContext) -> Result<StageValue, StageError> {
    let grid = wavelet_grid(ctx)?;
    Ok(StageValue::new(match ctx.input::<crate::cubemap::CubeMap>("environment", "radiance")? {
        Some(environment) => crate::triple_product::prefiltered(environment, grid),
        None => crate::cubemap::CubeMap { size: 0, texels: Vec::new() },
    }))
}

/// Per-texel-slot frames and visibility cells for the `wavelet_pixel` mode (pulled only by
/// it).
fn texel_visibility(ctx: &StageContext) -> Result<StageValue, StageError> {
    let meshes = ctx.required_input::<crate::mesh::MeshSet>("scene", "geometry")?;
    let texels = ctx.required_input::<crate::transport::TexelReceivers>("scene", "texel_receivers")?;
    let transport = ctx.required_input::<crate::transport::SphericalTransport>("scene", "transport_texels")?;
    Ok(StageValue::new(crate::triple_product::texel_visibility(
        wavelet_grid(ctx)?,
        texels,
        transport,
        meshes.meshes.len(),
        ctx.cancel_token(),
    )?))
}

/// `V̄` per vertex and square light for the `rsl` mode (pulled only by it): the lights' world
/// directions through each object's current pose into its self-visibility tables. Reruns on an
/// environment rotation or an object move (O(vertices × lights) lookups), never on a camera
/// move or a BRDF edit. `lights`: the decomposer's stage (the whole sky's lights, or those of
/// the sky without its sun).
fn rsl_visibility_of(ctx: &StageContext, lights: &str) -> Result<StageValue, StageError> {
    let objects = ctx.required_input::<Vec<crate::rsl::vdt::ObjectSvdf>>("scene", "rsl_self_visibility")?;
    let occluders = ctx.required_input::<Vec<crate::rsl::ovdf::ObjectOvdf>>("scene", "rsl_occluders")?;
    // Without square lights there is nothing to see (drawing the mode then says what to link).
    let Some(lights) = ctx.input::<crate::rsl::WorldLights>("square_lights", lights)? else {
        return Ok(StageValue::new(crate::rsl::shade::LightVisibility::default()));
    };
    let vertices: usize = objects.iter().map(|o| o.svdf.vertices).sum();
    let bytes = (vertices * lights.lights.len() * 4) as u64;
    if bytes > crate::limits::MAX_RSL_TABLE_BYTES {
        return Err(StageError::Failed(format!(
            "the per-vertex visibility of {vertices} vertices × {} square lights would take {} MiB; the limit is {} MiB: \
             use fewer lights or a lower tessellation",
            lights.lights.len(),
            bytes >> 20,
            crate::limits::MAX_RSL_TABLE_BYTES >> 20
        )));
    }
    Ok(StageValue::new(crate::rsl::shade::light_visibility(
        objects,
        occluders,
        lights,
        crate::rsl::vdt::Ramp::StraightEdge,
        ctx.cancel_token(),
    )?))
}

pub use sun::{SUN, separates_sun};

/// Finds the output node (the one named, or the only one).
pub fn find_output<'g>(graph: &'g Graph, name: Option<&str>) -> Result<&'g crate::engine::GraphNode, String> {
    let outputs: Vec<_> = graph.nodes.iter().filter(|n| n.kind.name == "Output").collect();
    match name {
        Some(id) => outputs.into_iter().find(|n| n.id == id).ok_or_else(|| format!("no Output node with id `{id}`")),
        None => match outputs.as_slice() {
            [one] => Ok(one),
            [] => Err("the project has no Output node".into()),
            _ => Err(format!(
                "the project has {} Output nodes; choose one ({})",
                outputs.len(),
                outputs.iter().map(|n| n.id.as_str()).collect::<Vec<_>>().join(", ")
            )),
        },
    }
}

/// The Output's mode and view as set in the graph.
pub fn output_mode_and_view(node: &GraphNode) -> (Mode, View) {
    let view = match node.params.get("view") {
        Some(ParamValue::Choice(c)) => c.parse().unwrap_or(View::Approximation),
        _ => View::Approximation,
    };
    (mode_of(node.params.get("mode")), view)
}

/// The mode a `mode` parameter value names (`sh_irradiance` for none or another value).
fn mode_of(value: Option<&ParamValue>) -> Mode {
    match value {
        Some(ParamValue::Choice(c)) => c.parse().unwrap_or(Mode::ShIrradiance),
        _ => Mode::ShIrradiance,
    }
}
