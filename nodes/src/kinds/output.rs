//! Output node: what the viewport and `lightloom render` draw, and how (relighting mode,
//! exposure, tone mapping).

use crate::engine::{Evaluation, Graph, GraphNode, Key, Request, StageContext, StageError, StageRef, StageValue};
use crate::graph::{Availability, NodeKindSpec, ParamKind, ParamSpec, ParamValue, PortSpec, PortType, StageSpec};
use serde::{Deserialize, Serialize};
use std::sync::Arc;

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
}

crate::choice_enum! {
    /// Relighting modes.
    pub enum Mode {
        /// Unshadowed diffuse lighting from the environment's SH, per pixel.
        ShIrradiance = "sh_irradiance",
        /// Shadowed SH transfer per vertex, glossy lobes on the shadowed incident radiance.
        ShPrt = "sh_prt",
        /// All-frequency local-frame triple product per vertex.
        WaveletVertex = "wavelet_vertex",
        /// The same, per pixel on objects with a visibility texture.
        WaveletPixel = "wavelet_pixel",
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
        ],
        outputs: vec![],
        params: vec![
            ParamSpec {
                name: "mode",
                label: "Relighting mode",
                unit: "",
                kind: ParamKind::Choice { options: Mode::NAMES, default: "sh_prt" },
                doc: "sh_irradiance: unshadowed diffuse lighting from the environment's SH, per pixel (Sun 2008 \
                      eq. 2.20). sh_prt: shadowed diffuse transfer plus glossy lobes on the shadowed incident \
                      radiance, per vertex. wavelet_vertex: all-frequency triple \
                      product in each vertex's local frame (Ma et al. eq. 7), 80 or 320 top-only coefficients. \
                      wavelet_pixel: the same, per pixel on objects with a \
                      visibility texture (sharp shadows and reflections on coarse meshes). Each mode computes the \
                      transport it reads when first chosen; until then the view shows the unshadowed SH \
                      lighting and says so.",
            },
            ParamSpec {
                name: "wavelet_terms",
                label: "Wavelet coefficients",
                unit: "",
                kind: ParamKind::Choice { options: WAVELET_TERMS, default: "320" },
                doc: "Top-only spherical Haar coefficients per function in the wavelet mode (Ma et al.'s 80 or 320).",
            },
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
                kind: ParamKind::Choice { options: Tonemap::NAMES, default: "aces" },
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
                kind: ParamKind::Choice { options: View::NAMES, default: "approximation" },
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
        ],
        stages: vec![
            StageSpec {
                name: "settings",
                version: 1,
                params: &["mode", "exposure", "tonemap", "background", "view", "reference_samples"],
                stages: &[],
                inputs: &[],
                persist: None,
                compute: settings,
            },
            StageSpec {
                name: "incident_sh",
                version: 2,
                params: &[],
                stages: &[],
                inputs: &[("scene", "transport_sh"), ("environment", "sh")],
                persist: None,
                compute: incident_sh,
            },
            StageSpec {
                name: "local_products",
                version: 2,
                params: &["wavelet_terms"],
                stages: &[],
                inputs: &[
                    ("scene", "receivers"),
                    ("scene", "transport_local"),
                    ("environment", "radiance"),
                    ("environment", "rotation"),
                ],
                persist: None,
                compute: local_products,
            },
            StageSpec {
                name: "texel_irradiance",
                version: 2,
                params: &["wavelet_terms"],
                stages: &[],
                inputs: &[
                    ("scene", "geometry"),
                    ("scene", "texel_receivers"),
                    ("scene", "transport_texels"),
                    ("environment", "radiance"),
                    ("environment", "rotation"),
                ],
                persist: None,
                compute: texel_irradiance,
            },
        ],
        availability: Availability::Ready,
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
    }))
}

/// Shadowed incident radiance `R = L·V` per receiver for the `sh_prt` mode (pulled only by it).
/// Depends on lighting and transport only: BRDF and camera edits reuse it.
fn incident_sh(ctx: &StageContext) -> Result<StageValue, StageError> {
    let transport = ctx.required_input::<crate::transport::ShTransport>("scene", "transport_sh")?;
    let Some(light) = ctx.input::<crate::sh::ShRgb>("environment", "sh")? else {
        return Ok(StageValue::new(crate::prt::IncidentSh::default()));
    };
    Ok(StageValue::new(crate::prt::incident_radiance(light, transport, ctx.cancel_token())?))
}

/// Per-vertex `P_c = ΔΩ_c L^x_c V^x_c` for the wavelet modes (pulled only by them).
/// Depends on lighting and transport only: BRDF and camera edits reuse it.
fn local_products(ctx: &StageContext) -> Result<StageValue, StageError> {
    let terms: usize =
        ctx.choice("wavelet_terms")?.parse().map_err(|_| StageError::Internal("wavelet_terms".into()))?;
    let receivers = ctx.required_input::<crate::transport::Receivers>("scene", "receivers")?;
    let transport = ctx.required_input::<crate::transport::SphericalTransport>("scene", "transport_local")?;
    let grid = crate::triple_product::CellGrid::for_coefficients(terms).map_err(StageError::Failed)?;
    let Some((environment, rotation)) = wavelet_lighting(ctx)? else {
        return Ok(StageValue::new(crate::triple_product::LocalProducts::default()));
    };
    // Big meshes: the pre-rotated table, memoised on the environment's content, so rotating
    // the environment only re-reads it with rotated frames.
    let table = if receivers.len() > crate::triple_product::FRAME_TABLE_THRESHOLD {
        let key = environment_key(environment, terms);
        Some(ctx.memo(key, || Ok(crate::triple_product::FrameTable::build(grid, environment)))?)
    } else {
        None
    };
    let lighting = crate::triple_product::Lighting { environment, rotation, table: table.as_deref() };
    Ok(StageValue::new(crate::triple_product::local_products(
        grid,
        &lighting,
        receivers,
        transport,
        ctx.cancel_token(),
    )?))
}

/// The unrotated environment and its rotation, or `None` without an environment.
fn wavelet_lighting<'a>(
    ctx: &'a StageContext,
) -> Result<Option<(&'a crate::cubemap::CubeMap, glam::DMat3)>, StageError> {
    match (
        ctx.input::<crate::cubemap::CubeMap>("environment", "radiance")?,
        ctx.input::<glam::DMat3>("environment", "rotation")?,
    ) {
        (Some(cube), Some(rotation)) => Ok(Some((cube, *rotation))),
        _ => Ok(None),
    }
}

/// A content key for memoising per-environment tables.
fn environment_key(cube: &crate::cubemap::CubeMap, cells: usize) -> crate::engine::Key {
    let mut bytes = Vec::with_capacity(cube.texels.len() * 12 + 32);
    bytes.extend_from_slice(format!("frame-table v1 {} {cells}", cube.size).as_bytes());
    for t in &cube.texels {
        for c in t {
            bytes.extend_from_slice(&c.to_le_bytes());
        }
    }
    xxhash_rust::xxh3::xxh3_128(&bytes)
}

/// Per-texel diffuse transfer for the `wavelet_pixel` mode (pulled only by it).
fn texel_irradiance(ctx: &StageContext) -> Result<StageValue, StageError> {
    let terms: usize =
        ctx.choice("wavelet_terms")?.parse().map_err(|_| StageError::Internal("wavelet_terms".into()))?;
    let meshes = ctx.required_input::<crate::mesh::MeshSet>("scene", "geometry")?;
    let texels = ctx.required_input::<crate::transport::TexelReceivers>("scene", "texel_receivers")?;
    let t = ctx.required_input::<crate::transport::SphericalTransport>("scene", "transport_texels")?;
    let Some((environment, rotation)) = wavelet_lighting(ctx)? else {
        return Ok(StageValue::new(crate::triple_product::TexelIrradiance::default()));
    };
    let grid = crate::triple_product::CellGrid::for_coefficients(terms).map_err(StageError::Failed)?;
    let lighting = crate::triple_product::Lighting { environment, rotation, table: None };
    Ok(StageValue::new(crate::triple_product::texel_irradiance(
        grid,
        &lighting,
        texels,
        t,
        meshes.meshes.len(),
        ctx.cancel_token(),
    )?))
}

/// A copy of a gathered stage's value as `T` (an error naming both types otherwise).
fn typed<T: crate::engine::StageType + Clone>(keyed: &Keyed, stage: &str) -> Result<T, String> {
    keyed.value.expect::<T>().cloned().map_err(|e| format!("stage `{stage}`: {e}"))
}

/// A stage value with its key (renderers re-upload only when the key changes).
#[derive(Clone, Debug)]
pub struct Keyed {
    pub key: Key,
    pub value: Arc<StageValue>,
}

/// Everything the renderer needs for one frame, gathered from an evaluation.
#[derive(Clone, Debug)]
pub struct FrameInputs {
    pub meshes: Keyed,
    /// The scene's BVH (for the reference renderer and picking), when it was requested.
    pub ray_scene: Option<Keyed>,
    /// The mode drawn: the Output's mode, or [`Mode::ShIrradiance`] while that mode's transport
    /// is still computing (then `pending` says so).
    pub mode: Mode,
    pub pending: Option<String>,
    pub sh: Option<Keyed>,
    pub radiance: Option<Keyed>,
    /// `sh_prt` only: the scene's SH transport and the incident radiance per receiver.
    pub transport: Option<Keyed>,
    pub incident: Option<Keyed>,
    /// Wavelet modes only: per-vertex lighting × visibility.
    pub local_products: Option<Keyed>,
    /// `wavelet_pixel` only: per-texel diffuse transfer of the visibility textures.
    pub texel_irradiance: Option<Keyed>,
    /// The materials linked to the Output, in link order (the default material when none is),
    /// at most [`MAX_MATERIALS`].
    pub materials: Vec<FrameMaterial>,
    /// Per mesh of the scene: its index in `materials`.
    pub mesh_materials: Vec<u32>,
    pub settings: OutputSettings,
    /// Connected inputs the renderer does not draw yet, and material names that matched
    /// nothing, to tell the user.
    pub ignored_inputs: Vec<String>,
    /// The medium linked to the Output, if any.
    pub fog: Option<FogFrame>,
    /// Point lights linked to the Output (at most [`MAX_LIGHTS`]).
    pub lights: Vec<crate::kinds::lights::PointLight>,
}

/// Materials one frame can shade with (the shaders' uniform arrays).
pub const MAX_MATERIALS: usize = 8;

/// Point lights one frame can shade with.
pub const MAX_LIGHTS: usize = 8;

/// A participating medium for one frame (Sun 2008 ch. 3): coefficients and its tables.
#[derive(Clone, Debug)]
pub struct FogFrame {
    /// Scattering coefficient per channel, 1/m.
    pub beta: [f64; 3],
    /// Distance of the environment's light sources, m (sec. 3.6.4).
    pub environment_distance: f64,
    /// Normalised phase polynomial weights `W_k` (eq. 3.18), one per `F^k` table.
    pub phase: Vec<f64>,
    /// `F^k` tables (`Vec<FTable>`) and the `G_n` ladder (`PhongGTables`).
    pub f_tables: Keyed,
    pub g_tables: Keyed,
    /// With an environment linked: its light through the medium (sec. 3.6.4).
    pub environment: Option<crate::single_scattering::FoggedEnvironment>,
}

/// One material of a frame.
#[derive(Clone, Debug)]
pub struct FrameMaterial {
    /// The BRDF editor node (empty for the default material).
    pub node: String,
    pub material: crate::kinds::brdf::Material,
    /// Its SH lobe (`sh_prt` only; no factors for Lambert).
    pub sh_lobe: Option<crate::prt::GlossyLobe>,
    /// Its local-frame table (wavelet modes only).
    pub table: Option<Keyed>,
    /// Its Phong-equivalent lobe `(weight per channel, exponent)` for light scattered by fog
    /// onto surfaces (eq. 3.28; `None` for Lambert).
    pub phong_lobe: Option<([f64; 3], f64)>,
}

impl FrameMaterial {
    pub fn new(
        node: String,
        material: crate::kinds::brdf::Material,
        sh_lobe: Option<crate::prt::GlossyLobe>,
        table: Option<Keyed>,
    ) -> Self {
        let brdf = crate::brdf::Brdf::from_material(&material);
        let phong_lobe = brdf.equivalent_phong_exponent().map(|n| ((brdf.specular * brdf.f0).to_array(), n.max(1.0)));
        Self { node, material, sh_lobe, table, phong_lobe }
    }
}

impl FrameInputs {
    /// The material of mesh `i`.
    pub fn mesh_material(&self, i: usize) -> &crate::kinds::brdf::Material {
        &self.materials[self.mesh_materials.get(i).copied().unwrap_or(0) as usize].material
    }
}

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

/// The stages a frame of `mode` reads from the Output node `output` and what feeds it.
pub fn mode_stages(graph: &Graph, output: &str, mode: Mode) -> Vec<StageRef> {
    let mut stages = vec![StageRef::new(output, "settings")];
    let upstream = |port: &str| graph.upstream(output, port).map(|n| n.id.clone());
    if let Some(scene) = upstream("scene") {
        stages.push(StageRef::new(&scene, "geometry"));
        if mode == Mode::ShPrt {
            stages.push(StageRef::new(&scene, "transport_sh"));
        }
    }
    if let Some(env) = upstream("environment") {
        stages.push(StageRef::new(&env, "sh"));
        stages.push(StageRef::new(&env, "rotated_radiance"));
    }
    for material in graph.upstream_all(output, "material") {
        stages.push(StageRef::new(&material.id, "material"));
        match mode {
            Mode::ShPrt => stages.push(StageRef::new(&material.id, "sh_lobe")),
            Mode::WaveletVertex | Mode::WaveletPixel => stages.push(StageRef::new(&material.id, "local_table")),
            Mode::ShIrradiance => {}
        }
    }
    if let Some(medium) = upstream("medium") {
        stages.extend(["medium", "f_tables", "g_tables"].map(|s| StageRef::new(&medium, s)));
    }
    if let Some(lights) = upstream("lights") {
        stages.push(StageRef::new(&lights, "lights"));
    }
    match mode {
        Mode::ShIrradiance => {}
        Mode::ShPrt => stages.push(StageRef::new(output, "incident_sh")),
        Mode::WaveletVertex => stages.push(StageRef::new(output, "local_products")),
        Mode::WaveletPixel => {
            stages.push(StageRef::new(output, "local_products"));
            stages.push(StageRef::new(output, "texel_irradiance"));
        }
    }
    stages
}

/// The Output's mode and view as set in the graph.
pub fn output_mode_and_view(node: &GraphNode) -> (Mode, View) {
    let choice = |name: &str| match node.params.get(name) {
        Some(ParamValue::Choice(c)) => c.clone(),
        _ => String::new(),
    };
    (choice("mode").parse().unwrap_or(Mode::ShIrradiance), choice("view").parse().unwrap_or(View::Approximation))
}

/// What drawing the Output node `output` needs, as an engine request. A shadowed mode first
/// gets an unshadowed tier, so a frame is ready before its transport is. The reference and
/// error views (and `picking`, for the editor's object selection) add the scene's BVH.
pub fn frame_request(graph: &Graph, output: &str, picking: bool) -> Request {
    let Some(node) = graph.node(output) else { return Request::default() };
    let (mode, view) = output_mode_and_view(node);
    let mut first = mode_stages(graph, output, Mode::ShIrradiance);
    if (picking || view != View::Approximation)
        && let Some(scene) = graph.upstream(output, "scene")
    {
        first.push(StageRef::new(&scene.id, "ray_scene"));
    }
    if mode.is_shadowed() {
        Request::new(format!("output `{output}`: unshadowed preview"), first)
            .then(format!("output `{output}`: mode {mode}"), mode_stages(graph, output, mode))
    } else {
        Request::new(format!("output `{output}`: mode {mode}"), first)
    }
}

impl FrameInputs {
    /// The Monte Carlo reference of this frame (see [`crate::reference`]).
    pub fn render_reference(
        &self,
        camera: &crate::reference::PinholeCamera,
        size: (usize, usize),
        seed: u64,
        cancel: &crate::engine::CancelToken,
        progress: &(dyn Fn(f64) + Sync),
    ) -> Result<crate::reference::HdrImage, String> {
        let Some(scene) = self.ray_scene.as_ref().and_then(|r| r.value.get::<crate::raycast::RayScene>()) else {
            return Err("the scene's ray_scene stage was not evaluated".into());
        };
        let meshes = self.meshes.value.expect::<crate::mesh::MeshSet>().map_err(|e| e.to_string())?;
        let black = crate::cubemap::CubeMap::new(1, vec![[0.0; 3]; 6]);
        let environment = match &self.radiance {
            Some(r) => r.value.expect::<crate::cubemap::CubeMap>().map_err(|e| e.to_string())?,
            None => &black,
        };
        let rs = crate::reference::ReferenceScene {
            scene,
            meshes,
            brdfs: (0..meshes.meshes.len()).map(|i| crate::brdf::Brdf::from_material(self.mesh_material(i))).collect(),
            environment,
            background: self.settings.background,
        };
        crate::reference::render(&rs, camera, size, self.settings.reference_samples, seed, cancel, progress)
            .map_err(|e| e.to_string())
    }

    /// The mesh seen through image point `(x, y)` (pixels, `y` down) of a `width × height` view:
    /// its index in the scene's meshes, or `None` for the background.
    pub fn pick(
        &self,
        camera: &crate::reference::PinholeCamera,
        (x, y): (f64, f64),
        (width, height): (usize, usize),
    ) -> Option<usize> {
        let (Some(scene), Some(meshes)) = (
            self.ray_scene.as_ref().and_then(|r| r.value.get::<crate::raycast::RayScene>()),
            self.meshes.value.get::<crate::mesh::MeshSet>(),
        ) else {
            return None;
        };
        let dir = camera.ray(x, y, width.max(1), height.max(1));
        let (_, triangle) = scene.closest(camera.position.as_vec3a(), dir.as_vec3a())?;
        meshes.mesh_of_triangle(triangle as usize)
    }

    pub fn gather(evaluation: &Evaluation, graph: &Graph, output: &str) -> Result<Self, String> {
        let keyed = |node: &str, stage: &str| -> Result<Keyed, String> {
            let r = evaluation.get(node, stage).ok_or_else(|| format!("stage {node}.{stage} was not evaluated"))?;
            match &r.value {
                Ok(v) => Ok(Keyed { key: r.key, value: v.clone() }),
                Err(e) => Err(format!("{node}.{stage} failed: {e}")),
            }
        };
        let upstream = |port: &str| graph.upstream(output, port).map(|n| n.id.clone());
        let scene = upstream("scene").ok_or("the Output node's scene input is not connected")?;
        let meshes = keyed(&scene, "geometry")?;
        let ray_scene = evaluation.get(&scene, "ray_scene").map(|_| keyed(&scene, "ray_scene")).transpose()?;
        let (sh, radiance) = match upstream("environment") {
            Some(env) => (Some(keyed(&env, "sh")?), Some(keyed(&env, "rotated_radiance")?)),
            None => (None, None),
        };
        let material_nodes = graph.upstream_all(output, "material");
        if material_nodes.len() > MAX_MATERIALS {
            return Err(format!(
                "{} materials are linked to the Output; at most {MAX_MATERIALS} are supported",
                material_nodes.len()
            ));
        }
        let settings: OutputSettings = typed(&keyed(output, "settings")?, "settings")?;
        // The best mode ready now: the requested one, or the unshadowed preview while the
        // requested mode's transport is still computing.
        let ready =
            mode_stages(graph, output, settings.mode).iter().all(|r| evaluation.get(&r.node, &r.stage).is_some());
        let mode = if ready { settings.mode } else { Mode::ShIrradiance };
        let pending =
            (!ready).then(|| format!("unshadowed preview: mode {} is still computing what it needs", settings.mode));
        let (transport, incident) = if mode == Mode::ShPrt {
            (Some(keyed(&scene, "transport_sh")?), Some(keyed(output, "incident_sh")?))
        } else {
            (None, None)
        };
        let wavelets = mode.is_wavelet();
        let mut materials = Vec::new();
        for node in &material_nodes {
            let material = typed(&keyed(&node.id, "material")?, "material")?;
            let table = if wavelets { Some(keyed(&node.id, "local_table")?) } else { None };
            let sh_lobe =
                if mode == Mode::ShPrt { Some(typed(&keyed(&node.id, "sh_lobe")?, "sh_lobe")?) } else { None };
            materials.push(FrameMaterial::new(node.id.clone(), material, sh_lobe, table));
        }
        if materials.is_empty() {
            if wavelets {
                return Err("the wavelet modes need a material: link a BRDF editor to the Output".into());
            }
            materials.push(FrameMaterial::new(String::new(), Default::default(), None, None));
        }
        let local_products = if wavelets { Some(keyed(output, "local_products")?) } else { None };
        let texel_irradiance = if mode == Mode::WaveletPixel { Some(keyed(output, "texel_irradiance")?) } else { None };
        let fog = match upstream("medium") {
            Some(node) => {
                let m: crate::kinds::fog::Medium = typed(&keyed(&node, "medium")?, "medium")?;
                let phase = if m.phase == "polynomial" {
                    crate::single_scattering::Phase::polynomial(&m.phase_coefficients)
                        .ok_or_else(|| format!("{node}: the phase polynomial is invalid"))?
                } else {
                    crate::single_scattering::Phase::isotropic()
                };
                let f_tables = keyed(&node, "f_tables")?;
                let environment = match &sh {
                    Some(sh) => {
                        let tables = f_tables
                            .value
                            .expect::<Vec<crate::single_scattering::FTable>>()
                            .map_err(|e| e.to_string())?;
                        let light = sh.value.expect::<crate::sh::ShRgb>().map_err(|e| e.to_string())?;
                        Some(crate::single_scattering::FoggedEnvironment::new(
                            m.beta,
                            m.environment_distance,
                            &phase,
                            tables,
                            light,
                        ))
                    }
                    None => None,
                };
                Some(FogFrame {
                    beta: m.beta,
                    environment_distance: m.environment_distance,
                    phase: phase.weights,
                    f_tables,
                    g_tables: keyed(&node, "g_tables")?,
                    environment,
                })
            }
            None => None,
        };
        let mut lights = match upstream("lights") {
            Some(node) => typed::<Vec<crate::kinds::lights::PointLight>>(&keyed(&node, "lights")?, "lights")?,
            None => Vec::new(),
        };
        let mut ignored_inputs: Vec<String> = ["blockers", "square_lights"]
            .into_iter()
            .filter_map(|p| upstream(p).map(|n| format!("`{p}` (from `{n}`) is not drawn yet")))
            .collect();
        if lights.len() > MAX_LIGHTS {
            ignored_inputs.push(format!("{} point lights are linked; the first {MAX_LIGHTS} are drawn", lights.len()));
            lights.truncate(MAX_LIGHTS);
        }
        let mut mesh_materials = Vec::new();
        let mut unmatched: std::collections::BTreeMap<&str, usize> = Default::default();
        if let Some(set) = meshes.value.get::<crate::mesh::MeshSet>() {
            for mesh in &set.meshes {
                let found = materials.iter().position(|m| !mesh.material.is_empty() && m.node == mesh.material);
                if found.is_none() && !mesh.material.is_empty() {
                    *unmatched.entry(mesh.material.as_str()).or_default() += 1;
                }
                mesh_materials.push(found.unwrap_or(0) as u32);
            }
        }
        // With one material linked everything uses it by design; with several, say which
        // names matched nothing.
        if materials.len() > 1 && !unmatched.is_empty() {
            let names: Vec<String> = unmatched.iter().map(|(name, n)| format!("`{name}` ({n} mesh(es))")).collect();
            ignored_inputs.push(format!(
                "materials not linked to the Output: {}; those meshes use `{}`",
                names.join(", "),
                materials[0].node
            ));
        }
        Ok(Self {
            meshes,
            ray_scene,
            mode,
            pending,
            sh,
            radiance,
            transport,
            incident,
            local_products,
            texel_irradiance,
            materials,
            mesh_materials,
            settings,
            ignored_inputs,
            fog,
            lights,
        })
    }
}
