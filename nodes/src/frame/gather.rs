//! A frame gathered from an evaluation: each feature's part from the stages linked to the
//! Output, then what the user should know about inputs the frame cannot draw.

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
            parts.materials.push(FrameMaterial { node: node.id.clone(), material, normal });
            let stages = frame.material_stages().iter().map(|s| self.keyed(&node.id, s)).collect::<Result<_, _>>()?;
            parts.mode_stages.push(stages);
        }
        if parts.materials.is_empty() {
            if frame.needs_material() {
                return Err(format!("the {mode} mode needs a material: link a BRDF editor to the Output"));
            }
            parts.materials.push(FrameMaterial { node: String::new(), material: Default::default(), normal: None });
            parts.mode_stages.push(Vec::new());
        }
        Ok(parts)
    }

    /// The SH light the mode's transport carries (the sky without its sun when the sun is lit
    /// apart), and the sun.
    fn sun(&self, sh: Option<&Keyed>) -> Result<(Option<Keyed>, Option<SunFrame>), String> {
        match self.upstream("environment") {
            Some(env) if self.separate_sun => {
                let split = self.keyed(&env, "sun")?;
                let split = split.value.expect::<crate::sun::SunSplit>().map_err(|e| e.to_string())?;
                let rotation =
                    *self.keyed(&env, "rotation")?.value.expect::<glam::DMat3>().map_err(|e| e.to_string())?;
                Ok((Some(self.keyed(&env, "residual_sh")?), split.sun.map(|s| SunFrame::new(&s.rotated(rotation)))))
            }
            _ => Ok((sh.cloned(), None)),
        }
    }

    /// The scene's meshes with the index of each one's material, and the material names that
    /// matched no linked material (with how many meshes each).
    fn geometry(&self, meshes: Keyed, materials: &[FrameMaterial]) -> (Geometry, BTreeMap<String, usize>) {
        let mut mesh_materials = Vec::new();
        let mut unmatched = BTreeMap::new();
        if let Some(set) = meshes.value.get::<crate::mesh::MeshSet>() {
            for mesh in &set.meshes {
                let linked = materials.iter().map(|m| m.node.as_str());
                let found = crate::kinds::output::named_material(&mesh.material, linked);
                if found.is_none() && !mesh.material.is_empty() {
                    *unmatched.entry(mesh.material.clone()).or_default() += 1;
                }
                mesh_materials.push(found.unwrap_or(0) as u32);
            }
        }
        (Geometry { meshes, mesh_materials }, unmatched)
    }

    /// Inputs the frame does not draw as linked, said plainly: blockers outside the SH modes,
    /// square lights outside `rsl`, lights beyond [`MAX_LIGHTS`] (dropped here), unmatched
    /// material names, area lights beside blockers.
    fn ignored_inputs(
        &self,
        lights: &mut Vec<PointLight>,
        materials: &[FrameMaterial],
        unmatched: &BTreeMap<String, usize>,
        area_lights: bool,
    ) -> Vec<String> {
        let mode = self.settings.mode;
        let mut ignored = Vec::new();
        let blockers = self.upstream("blockers");
        if let Some(n) = &blockers
            && !matches!(mode, Mode::ShPrt | Mode::ShAdaptive)
        {
            ignored.push(format!(
                "`blockers` (from `{n}`) shadow the SH modes sh_prt and sh_adaptive only (the reference traces them \
                 in every mode)"
            ));
        }
        if let Some(n) = self.upstream("square_lights")
            && mode != Mode::Rsl
        {
            ignored.push(format!("`square_lights` (from `{n}`) are drawn by the rsl mode only"));
        }
        if lights.len() > MAX_LIGHTS {
            ignored.push(format!("{} point lights are linked; the first {MAX_LIGHTS} are drawn", lights.len()));
            lights.truncate(MAX_LIGHTS);
        }
        // With one material linked everything uses it by design; with several, say which
        // names matched nothing.
        if materials.len() > 1 && !unmatched.is_empty() {
            let names: Vec<String> = unmatched.iter().map(|(name, n)| format!("`{name}` ({n} mesh(es))")).collect();
            ignored.push(format!(
                "materials not linked to the Output: {}; those meshes use `{}`",
                names.join(", "),
                materials[0].node
            ));
        }
        if area_lights && blockers.is_some() {
            ignored.push(
                "`area_lights` cast no blocker-sphere shadows (the reference has them): the spheres shadow the \
                 environment only"
                    .into(),
            );
        }
        ignored
    }
}

impl FrameInputs {
    pub fn gather(evaluation: &Evaluation, graph: &Graph, output: &str) -> Result<Self, String> {
        let settings: OutputSettings = typed(&keyed(evaluation, output, "settings")?, "settings")?;
        // The best mode ready now: the requested one, or the unshadowed preview while the
        // requested mode's transport is still computing.
        let requested = settings.mode;
        let ready = mode_stages(graph, output, requested).iter().all(|r| evaluation.get(&r.node, &r.stage).is_some());
        let mode = if ready { requested } else { Mode::ShIrradiance };
        let pending =
            (!ready).then(|| format!("unshadowed preview: mode {requested} is still computing what it needs"));
        let g = Gather { evaluation, graph, output, settings, mode, separate_sun: separates_sun(graph, output) };
        let scene = g.upstream("scene").ok_or("the Output node's scene input is not connected")?;
        let ray_scene = evaluation.get(&scene, "ray_scene").map(|_| g.keyed(&scene, "ray_scene")).transpose()?;
        let (sh, radiance) = match g.upstream("environment") {
            Some(env) => (Some(g.keyed(&env, "sh")?), Some(g.keyed(&env, "rotated_radiance")?)),
            None => (None, None),
        };
        let mut parts = g.materials()?;
        let mut normal_notes = std::mem::take(&mut parts.normal_notes);
        let keyed = |node: &str, stage: &str| g.keyed(node, stage);
        let fog = match g.upstream("medium") {
            Some(node) => Some(medium::fog_frame(&keyed, &node, sh.as_ref(), g.mode)?),
            None => None,
        };
        let fogged = fog.as_ref().and_then(|f| f.environment.as_ref());
        // With the sun lit apart, the transport carries the sky without it.
        let (lighting_sh, sun) = g.sun(sh.as_ref())?;
        let light = lighting_sh
            .as_ref()
            .map(|sh| sh.value.expect::<crate::sh::ShRgb>())
            .transpose()
            .map_err(|e| e.to_string())?;
        let (geometry, unmatched) = g.geometry(g.keyed(&scene, "geometry")?, &parts.materials);
        let surfaces = modes::of(g.mode).surfaces(&g, &parts, &SurfaceInputs { light, fogged, geometry: &geometry })?;
        let materials = parts.materials;
        let mut lights = match g.upstream("lights") {
            Some(node) => typed::<Vec<PointLight>>(&g.keyed(&node, "lights")?, "lights")?,
            None => Vec::new(),
        };
        let blockers = match g.upstream("blockers") {
            Some(n) if evaluation.get(&n, "spheres").is_some() => {
                Some(typed::<crate::kinds::blockers::BlockerSet>(&g.keyed(&n, "spheres")?, "spheres")?)
            }
            _ => None,
        };
        // Area lights join once their transport is traced (a later request tier).
        let light_nodes = graph.upstream_all(output, "area_lights");
        let vertices = geometry.vertex_count();
        let area_lights =
            area_lights::area_light_frame(evaluation, &light_nodes, output, &keyed, &materials, vertices)?;
        let ignored_inputs = g.ignored_inputs(&mut lights, &materials, &unmatched, !light_nodes.is_empty());
        let shadowed = !matches!(g.mode, Mode::ShIrradiance);
        let normal_maps = NormalMapFrame::new(&materials, light, shadowed, &mut normal_notes);
        let mut lobe_limits = lobe_limits::lobe_limits(graph, output, &scene, requested, &materials, sun.is_some());
        lobe_limits.extend(normal_notes);
        let medium = MediumFrame::new(lights, &materials, fog);
        Ok(Self {
            geometry,
            ray_scene,
            mode,
            pending,
            background: Background { radiance, visible: g.settings.background },
            settings: g.settings,
            ignored_inputs,
            lobe_limits,
            materials,
            surfaces,
            medium,
            area_lights,
            blockers,
            sun,
            normal_maps,
        })
    }
}
