//! A frame gathered from an evaluation: each feature's part from the stages linked to the
//! Output, then what the user should know about inputs the frame cannot draw.

use super::modes::Linked;
use super::parts::{Assembled, PARTS};
use super::*;
use std::collections::BTreeMap;

/// What every part of a gather reads: the evaluation, the Output and the mode drawn.
pub(super) struct Gather<'a> {
    pub evaluation: &'a Evaluation,
    pub graph: &'a Graph,
    pub output: &'a str,
    pub settings: OutputSettings,
    pub mode: Mode,
    /// The environment's sun is lit apart from the mode's transport.
    pub separate_sun: bool,
}

/// The materials linked to the Output and what the mode reads of each.
pub(super) struct MaterialParts {
    pub materials: Vec<FrameMaterial>,
    /// Per material, the stages the mode reads of it ([`ModeFrame::material_stages`], in that
    /// order; none for the default material).
    pub mode_stages: Vec<Vec<Keyed>>,
    /// Why a material's normal map is drawn approximately or not at all.
    normal_notes: Vec<(String, String)>,
}

/// A stage's value with its key, or why there is none.
fn keyed(evaluation: &Evaluation, node: &str, stage: &str) -> Result<Keyed, String> {
    let r = evaluation.get(node, stage).ok_or_else(|| format!("stage {node}.{stage} was not evaluated"))?;
    match &r.value {
        Ok(v) => Ok(Keyed { key: r.key, value: v.clone() }),
        Err(e) => Err(format!("{node}.{stage} failed: {e}")),
    }
}

impl Gather<'_> {
    pub fn keyed(&self, node: &str, stage: &str) -> Result<Keyed, String> {
        keyed(self.evaluation, node, stage)
    }

    pub fn upstream(&self, port: &str) -> Option<String> {
        self.graph.upstream(self.output, port).map(|n| n.id.clone())
    }

    fn materials(&self) -> Result<MaterialParts, String> {
        let nodes = self.graph.upstream_all(self.output, "material");
        if nodes.len() > MAX_MATERIALS {
            return Err(format!(
                "{} materials are linked to the Output; at most {MAX_MATERIALS} are supported",
                nodes.len()
            ));
        }
        let (mode, frame) = (self.mode, modes::of(self.mode));
        let mut parts = MaterialParts { materials: Vec::new(), mode_stages: Vec::new(), normal_notes: Vec::new() };
        let keyed = |node: &str, stage: &str| self.keyed(node, stage);
        for node in &nodes {
            let normal = normal_maps::normal_detail(&keyed, self.graph, &node.id, mode, &mut parts.normal_notes);
            let material = typed(&self.keyed(&node.id, "material")?, "material")?;
            parts.materials.push(FrameMaterial::new(node.id.clone(), material, normal));
            let stages = frame.material_stages().iter().map(|s| self.keyed(&node.id, s)).collect::<Result<_, _>>()?;
            parts.mode_stages.push(stages);
        }
        if parts.materials.is_empty() {
            if frame.needs_material() {
                return Err(format!("the {mode} mode needs a material: link a BRDF editor to the Output"));
            }
            parts.materials.push(FrameMaterial::new(String::new(), Default::default(), None));
            parts.mode_stages.push(Vec::new());
        }
        Ok(parts)
    }
}

/// Material names that matched no linked material, said plainly: with one material linked
/// everything uses it by design; with several, say which names matched nothing.
fn unmatched_note(materials: &[FrameMaterial], unmatched: &BTreeMap<String, usize>) -> Option<String> {
    (materials.len() > 1 && !unmatched.is_empty()).then(|| {
        let names: Vec<String> = unmatched.iter().map(|(name, n)| format!("`{name}` ({n} mesh(es))")).collect();
        format!("materials not linked to the Output: {}; those meshes use `{}`", names.join(", "), materials[0].node)
    })
}

impl FrameInputs {
    pub fn gather(evaluation: &Evaluation, graph: &Graph, output: &str) -> Result<Self, String> {
        let settings: OutputSettings = typed(&keyed(evaluation, output, "settings")?, "settings")?;
        // The best mode ready now: the requested one, or the unshadowed preview while the
        // requested mode's transport is still computing.
        let requested = settings.mode;
        let linked = Linked::new(graph, output);
        let ready =
            request::stages_of(graph, &linked, requested).iter().all(|r| evaluation.get(&r.node, &r.stage).is_some());
        let mode = if ready { requested } else { Mode::ShIrradiance };
        let pending =
            (!ready).then(|| format!("unshadowed preview: mode {requested} is still computing what it needs"));
        let g = Gather { evaluation, graph, output, settings, mode, separate_sun: linked.separate_sun };
        let scene = g.upstream("scene").ok_or("the Output node's scene input is not connected")?;
        let mut parts = g.materials()?;
        let mut normal_notes = std::mem::take(&mut parts.normal_notes);
        // Each linked input's share of the frame, in the parts' order.
        let mut frame = Assembled::default();
        for part in PARTS {
            if let Some(node) = g.upstream(part.port()) {
                part.gather(&g, &node, &parts, &mut frame)?;
            }
        }
        let geometry = frame.geometry.take().ok_or("the Output node's scene input is not connected")?;
        let light = frame
            .lighting_sh
            .as_ref()
            .map(|sh| sh.value.expect::<crate::sh::ShRgb>())
            .transpose()
            .map_err(|e| e.to_string())?;
        let fogged = frame.fog.as_ref().and_then(|f| f.environment.as_ref());
        let surfaces = modes::of(g.mode).surfaces(&g, &parts, &SurfaceInputs { light, fogged, geometry: &geometry })?;
        let materials = parts.materials;
        // Area lights join once their transport is traced (a later request tier).
        let light_nodes = graph.upstream_all(output, "area_lights");
        let keyed = |node: &str, stage: &str| g.keyed(node, stage);
        let area_lights =
            area_lights::area_light_frame(evaluation, &light_nodes, output, &keyed, &materials, &geometry, &scene)?;
        let mut ignored_inputs = std::mem::take(&mut frame.ignored);
        ignored_inputs.extend(unmatched_note(&materials, &frame.unmatched));
        let normal_maps =
            NormalMapFrame::new(&materials, light, frame.lighting_cube.as_ref(), g.mode, &mut normal_notes);
        normal_maps::note_meshes_without_uvs(&geometry, &materials, &normal_maps, &mut normal_notes);
        let sun = frame.sun;
        let mut lobe_limits = lobe_limits::lobe_limits(graph, output, &scene, requested, &materials, sun.is_some());
        lobe_limits.extend(normal_notes);
        let medium = MediumFrame::new(frame.lights, &materials, frame.fog);
        Ok(Self {
            geometry,
            ray_scene: frame.ray_scene,
            mode,
            pending,
            background: Background { radiance: frame.radiance, visible: g.settings.background },
            settings: g.settings,
            ignored_inputs,
            lobe_limits,
            materials,
            surfaces,
            medium,
            area_lights,
            blockers: frame.blockers,
            sun,
            normal_maps,
        })
    }
}
