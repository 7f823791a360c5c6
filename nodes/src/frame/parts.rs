//! Each input of the Output that a frame draws in every mode, as one value ([`FramePart`]):
//! the port it reads, the stages a frame reads of the node linked there, and its share of the
//! frame. [`mode_stages`](super::mode_stages), the frame request and the gather run over
//! [`PARTS`], so a new kind of input is its part, its field of the frame and one line in
//! [`PARTS`]. Three inputs are not parts: the materials (every mode reads them its own way,
//! [`super::ModeFrame::material_stages`]), and the area lights, which join in later request
//! tiers of their own.

use super::gather::{Gather, MaterialParts};
use super::modes::Linked;
use super::*;
use std::collections::BTreeMap;

/// What the parts have gathered so far (each reads what the parts before it built).
#[derive(Default)]
pub(super) struct Assembled {
    pub geometry: Option<Geometry>,
    /// Mesh material names that matched no linked material, with how many meshes each.
    pub unmatched: BTreeMap<String, usize>,
    pub ray_scene: Option<Keyed>,
    /// The environment's SH light, and the rotated radiance drawn behind the scene.
    pub sh: Option<Keyed>,
    pub radiance: Option<Keyed>,
    /// The SH light the mode's transport carries: the sky without its sun when the sun is lit
    /// apart, else the environment's SH.
    pub lighting_sh: Option<Keyed>,
    /// The same light GGX-prefiltered ([`crate::specular_cube::SpecularCube`]), once evaluated:
    /// what normal-mapped surfaces correct a per-vertex highlight with.
    pub lighting_cube: Option<Keyed>,
    pub sun: Option<SunFrame>,
    pub fog: Option<FogFrame>,
    pub lights: Vec<PointLight>,
    pub blockers: Option<crate::kinds::blockers::BlockerSet>,
    /// Linked inputs the frame does not draw as linked, said plainly.
    pub ignored: Vec<String>,
}

/// One input of the Output drawn in every mode.
pub(super) trait FramePart: Sync {
    /// The Output's input port it reads.
    fn port(&self) -> &'static str;

    /// What a frame of any mode reads of `node`, linked at [`Self::port`].
    fn stages(&self, _node: &str, _linked: &Linked) -> Vec<StageRef> {
        Vec::new()
    }

    /// What the reference and error views (and picking) also read of `node`.
    fn reference_stages(&self, _node: &str) -> Vec<StageRef> {
        Vec::new()
    }

    /// Its share of the frame, from `node`.
    fn gather(&self, g: &Gather, node: &str, parts: &MaterialParts, frame: &mut Assembled) -> Result<(), String>;
}

/// Every part, in gather order: a part reads what the parts before it gathered (the medium
/// carries the environment's light, so it comes after it).
pub(super) const PARTS: &[&dyn FramePart] =
    &[&Scene, &super::environment::Environment, &super::medium::Medium, &Lights, &Blockers, &SquareLights];

/// The scene's meshes (with the index of each one's material) and, when requested, its BVH.
struct Scene;

impl FramePart for Scene {
    fn port(&self) -> &'static str {
        "scene"
    }

    fn stages(&self, node: &str, _: &Linked) -> Vec<StageRef> {
        vec![StageRef::new(node, "geometry"), StageRef::new(node, "vertex_frames")]
    }

    fn reference_stages(&self, node: &str) -> Vec<StageRef> {
        vec![StageRef::new(node, "ray_scene")]
    }

    fn gather(&self, g: &Gather, node: &str, parts: &MaterialParts, frame: &mut Assembled) -> Result<(), String> {
        frame.ray_scene = g.evaluation.get(node, "ray_scene").map(|_| g.keyed(node, "ray_scene")).transpose()?;
        let meshes = g.keyed(node, "geometry")?;
        let mut mesh_materials = Vec::new();
        if let Some(set) = meshes.value.get::<crate::mesh::MeshSet>() {
            for mesh in &set.meshes {
                let linked = parts.materials.iter().map(|m| m.node.as_str());
                let found = crate::kinds::output::named_material(&mesh.material, linked);
                if found.is_none() && !mesh.material.is_empty() {
                    *frame.unmatched.entry(mesh.material.clone()).or_default() += 1;
                }
                mesh_materials.push(found.unwrap_or(0) as u32);
            }
        }
        let frames = g.keyed(node, "vertex_frames")?;
        frame.geometry = Some(Geometry { meshes, frames, mesh_materials });
        Ok(())
    }
}

/// Point lights (and spot lights), at most [`MAX_LIGHTS`].
struct Lights;

impl FramePart for Lights {
    fn port(&self) -> &'static str {
        "lights"
    }

    fn stages(&self, node: &str, _: &Linked) -> Vec<StageRef> {
        vec![StageRef::new(node, "lights")]
    }

    fn gather(&self, g: &Gather, node: &str, _: &MaterialParts, frame: &mut Assembled) -> Result<(), String> {
        let mut lights: Vec<PointLight> = typed(&g.keyed(node, "lights")?, "lights")?;
        if lights.len() > MAX_LIGHTS {
            frame.ignored.push(format!("{} point lights are linked; the first {MAX_LIGHTS} are drawn", lights.len()));
            lights.truncate(MAX_LIGHTS);
        }
        frame.lights = lights;
        Ok(())
    }
}

/// Blocker spheres: shadows in the SH modes (their stages are the modes'), traced by the
/// reference in every mode.
struct Blockers;

impl FramePart for Blockers {
    fn port(&self) -> &'static str {
        "blockers"
    }

    fn reference_stages(&self, node: &str) -> Vec<StageRef> {
        vec![StageRef::new(node, "spheres")]
    }

    fn gather(&self, g: &Gather, node: &str, _: &MaterialParts, frame: &mut Assembled) -> Result<(), String> {
        if !matches!(g.settings.mode, Mode::ShPrt | Mode::ShAdaptive) {
            frame.ignored.push(format!(
                "`blockers` (from `{node}`) shadow the SH modes sh_prt and sh_adaptive only (the reference traces \
                 them in every mode)"
            ));
        }
        if !g.graph.upstream_all(g.output, "area_lights").is_empty() {
            frame.ignored.push(
                "`area_lights` cast no blocker-sphere shadows (the reference has them): the spheres shadow the \
                 environment only"
                    .into(),
            );
        }
        if g.evaluation.get(node, "spheres").is_some() {
            frame.blockers = Some(typed(&g.keyed(node, "spheres")?, "spheres")?);
        }
        Ok(())
    }
}

/// Square lights: drawn by the `rsl` mode alone (its stages are the mode's).
struct SquareLights;

impl FramePart for SquareLights {
    fn port(&self) -> &'static str {
        "square_lights"
    }

    fn gather(&self, g: &Gather, node: &str, _: &MaterialParts, frame: &mut Assembled) -> Result<(), String> {
        if g.settings.mode != Mode::Rsl {
            frame.ignored.push(format!("`square_lights` (from `{node}`) are drawn by the rsl mode only"));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use crate::engine::spec::ParamValue;
    use crate::kinds::output::{Mode, View};
    use crate::project::{ProjectLink, ProjectNode, default_project};
    use std::collections::BTreeMap;
    use std::path::Path;

    /// The default project with a node of every kind the Output reads linked to it, in `mode`
    /// and `view`.
    fn everything_linked(mode: Mode, view: View) -> crate::engine::Graph {
        everything_linked_project(mode, view).graph(Path::new("p.ron")).unwrap()
    }

    fn node(id: &str, kind: &str) -> ProjectNode {
        ProjectNode {
            id: id.into(),
            kind: kind.into(),
            label: String::new(),
            position: [0.0; 2],
            params: BTreeMap::new(),
        }
    }

    fn link(from: (&str, &str), to: (&str, &str)) -> ProjectLink {
        ProjectLink { from: (from.0.into(), from.1.into()), to: (to.0.into(), to.1.into()) }
    }

    fn everything_linked_project(mode: Mode, view: View) -> crate::project::Project {
        let mut project = default_project();
        for (id, kind, from, to) in [
            ("fog", "FogMedium", "medium", "medium"),
            ("lamp", "PointLight", "lights", "lights"),
            ("rsl", "RslDecomposer", "square_lights", "square_lights"),
            ("spheres", "BlockerSpheres", "blockers", "blockers"),
            ("panel", "AreaLightPainter", "area_light", "area_lights"),
        ] {
            project.nodes.push(node(id, kind));
            project.links.push(link((id, from), ("output", to)));
        }
        project.links.push(link(("sky", "environment"), ("rsl", "environment")));
        // A normal map fitted to vMF lobes, so a frame reads every normal-map stage.
        let material = project.nodes.iter_mut().find(|n| n.id == "material").unwrap();
        material.params.insert("normal_map".into(), ParamValue::Path("dimples.png".into()));
        material.params.insert("normal_filter".into(), ParamValue::Choice("vmf".into()));
        let output = project.nodes.iter_mut().find(|n| n.id == "output").unwrap();
        output.params.insert("mode".into(), ParamValue::Choice(mode.as_str().into()));
        output.params.insert("view".into(), ParamValue::Choice(view.as_str().into()));
        project
    }

    /// What a frame does not draw as linked is said, each once: blocker spheres outside the SH
    /// modes that shadow with them, square lights outside `rsl`, lights past the limit (dropped),
    /// area lights beside blockers.
    #[test]
    fn the_frame_names_the_inputs_it_does_not_draw() {
        use crate::engine::{CancelToken, Engine, Request};
        let mut project = everything_linked_project(Mode::ShIrradiance, View::Approximation);
        // A chain of lights past the limit.
        for i in 1..=super::MAX_LIGHTS {
            let (id, before) = (format!("lamp{i}"), if i == 1 { "lamp".to_string() } else { format!("lamp{}", i - 1) });
            project.nodes.push(node(&id, "PointLight"));
            project.links.push(link((&id, "lights"), (&before, "lights")));
        }
        let graph = project.graph(Path::new("p.ron")).unwrap();
        // The unshadowed tier alone: the area lights' transport is not needed to gather.
        let first = super::frame_request(&graph, "output", false).tiers.swap_remove(0);
        let evaluation = Engine::in_memory().evaluate_request(
            &graph,
            &Request::new(first.label, first.stages),
            &CancelToken::default(),
            None,
            &|_, _| {},
        );
        let frame = super::FrameInputs::gather(&evaluation, &graph, "output").unwrap();
        assert_eq!(frame.medium.lights.len(), super::MAX_LIGHTS);
        let said = |what: &str| frame.ignored_inputs.iter().filter(|n| n.contains(what)).count();
        assert_eq!(said("shadow the SH modes sh_prt and sh_adaptive only"), 1, "{:?}", frame.ignored_inputs);
        assert_eq!(said("are drawn by the rsl mode only"), 1, "{:?}", frame.ignored_inputs);
        assert_eq!(
            said(&format!("{} point lights are linked", super::MAX_LIGHTS + 1)),
            1,
            "{:?}",
            frame.ignored_inputs
        );
        assert_eq!(said("cast no blocker-sphere shadows"), 1, "{:?}", frame.ignored_inputs);
        assert_eq!(frame.ignored_inputs.len(), 4, "{:?}", frame.ignored_inputs);
    }

    /// Whatever is linked, in every mode and view, a frame requests only stages its nodes have
    /// and every other kind offering the same port type has too (the frame's share of each
    /// port's contract), and reads every linked input's part.
    #[test]
    fn a_frame_requests_only_stages_every_producer_has() {
        for &mode in Mode::ALL {
            for &view in View::ALL {
                let graph = everything_linked(mode, view);
                let needs = super::FrameNeeds { picking: true, relight_on_cpu: true };
                let request = super::frame_request_for(&graph, "output", needs);
                let stages: Vec<_> = request.tiers.iter().flat_map(|t| &t.stages).collect();
                for s in &stages {
                    let node = graph.node(&s.node).unwrap_or_else(|| panic!("{mode} {view}: no node {}", s.node));
                    assert!(
                        node.kind.stage(&s.stage).is_some(),
                        "{mode} {view}: {} ({}) has no stage {}",
                        s.node,
                        node.kind.name,
                        s.stage
                    );
                    for port in &node.kind.outputs {
                        let producers =
                            crate::kinds::registry().iter().filter(|k| k.outputs.iter().any(|o| o.ty == port.ty));
                        for other in producers {
                            assert!(
                                other.stage(&s.stage).is_some(),
                                "{mode} {view}: a frame reads {} of a {}, and {} offers one without it",
                                s.stage,
                                port.ty,
                                other.name
                            );
                        }
                    }
                }
                let read = |node: &str, stage: &str| stages.iter().any(|s| s.node == node && s.stage == stage);
                for (node, stage) in [
                    ("fog", "f_tables"),
                    ("lamp", "lights"),
                    ("scene", "ray_scene"),
                    ("scene", "vertex_frames"),
                    ("spheres", "spheres"),
                    ("material", "vmf_lobes"),
                ] {
                    assert!(read(node, stage), "{mode} {view}: {node}.{stage} is not requested");
                }
                assert_eq!(read("rsl", "world_lights"), mode == Mode::Rsl, "{mode} {view}");
                assert_eq!(read("material", "rsl_tables"), mode == Mode::Rsl, "{mode} {view}");
            }
        }
    }
}
