//! Each input of the Output that a frame draws in every mode, as one value ([`FramePart`]):
//! the port it reads, the stages a frame reads of the node linked there, and its share of the
//! frame. [`mode_stages`](super::mode_stages), the frame request and the gather run over
//! [`PARTS`] and branch on no port, so a new kind of input is its part, its field of the frame
//! and one line in [`PARTS`]. The materials are not a part: every mode reads them its own way
//! ([`super::ModeFrame::material_stages`]).

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

/// Every part, in gather order.
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
        let mut project = default_project();
        for (id, kind, from, to) in [
            ("fog", "FogMedium", "medium", "medium"),
            ("lamp", "PointLight", "lights", "lights"),
            ("rsl", "RslDecomposer", "square_lights", "square_lights"),
            ("spheres", "BlockerSpheres", "blockers", "blockers"),
            ("panel", "AreaLightPainter", "area_light", "area_lights"),
        ] {
            project.nodes.push(ProjectNode {
                id: id.into(),
                kind: kind.into(),
                label: String::new(),
                position: [0.0; 2],
                params: BTreeMap::new(),
            });
            project.links.push(ProjectLink { from: (id.into(), from.into()), to: ("output".into(), to.into()) });
        }
        project
            .links
            .push(ProjectLink { from: ("sky".into(), "environment".into()), to: ("rsl".into(), "environment".into()) });
        let output = project.nodes.iter_mut().find(|n| n.id == "output").unwrap();
        output.params.insert("mode".into(), ParamValue::Choice(mode.as_str().into()));
        output.params.insert("view".into(), ParamValue::Choice(view.as_str().into()));
        project.graph(Path::new("p.ron")).unwrap()
    }

    /// Whatever is linked, in every mode and view, a frame requests only stages its nodes have,
    /// and reads every linked input's part.
    #[test]
    fn a_frame_requests_only_stages_its_nodes_have() {
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
                }
                let read = |node: &str, stage: &str| stages.iter().any(|s| s.node == node && s.stage == stage);
                for (node, stage) in
                    [("fog", "f_tables"), ("lamp", "lights"), ("scene", "ray_scene"), ("spheres", "spheres")]
                {
                    assert!(read(node, stage), "{mode} {view}: {node}.{stage} is not requested");
                }
                assert_eq!(read("rsl", "world_lights"), mode == Mode::Rsl, "{mode} {view}");
                assert_eq!(read("material", "rsl_tables"), mode == Mode::Rsl, "{mode} {view}");
            }
        }
    }
}
