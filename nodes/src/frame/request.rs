//! What drawing an Output needs, as engine requests.

use super::*;

/// The stages a frame of `mode` reads from the Output node `output` and what feeds it: what
/// every mode reads, then what the mode's part asks for ([`ModeFrame::stages`]).
pub fn mode_stages(graph: &Graph, output: &str, mode: Mode) -> Vec<StageRef> {
    stages_of(graph, &Linked::new(graph, output), mode)
}

/// [`mode_stages`] of the Output `linked` describes: its settings, each linked input's part
/// ([`parts::FramePart::stages`]), each material and what the mode reads of it, then the mode's
/// own stages.
pub(super) fn stages_of(graph: &Graph, linked: &Linked, mode: Mode) -> Vec<StageRef> {
    let frame = modes::of(mode);
    let output = linked.output;
    let mut stages = vec![StageRef::new(output, "settings")];
    for part in parts::PARTS {
        if let Some(node) = graph.upstream(output, part.port()) {
            stages.extend(part.stages(&node.id, linked));
        }
    }
    for material in graph.upstream_all(output, "material") {
        stages.push(StageRef::new(&material.id, "material"));
        stages.extend(frame.material_stages().iter().map(|s| StageRef::new(&material.id, *s)));
    }
    stages.extend(frame.stages(linked));
    stages
}

/// What a frame is drawn with besides the Output's own settings.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FrameNeeds {
    /// The scene's BVH, for the editor's object selection.
    pub picking: bool,
    /// The wavelet modes' receivers relit by the engine, for a viewport that relights on the
    /// CPU (faster there than its kernel): cached, and cancelled with the evaluation.
    pub relight_on_cpu: bool,
}

/// What drawing the Output node `output` needs, as an engine request ([`frame_request_for`]
/// with only `picking`).
pub fn frame_request(graph: &Graph, output: &str, picking: bool) -> Request {
    frame_request_for(graph, output, FrameNeeds { picking, ..FrameNeeds::default() })
}

/// What drawing the Output node `output` needs, as an engine request. A shadowed mode first
/// gets an unshadowed tier, so a frame is ready before its transport is. The reference and
/// error views (and `picking`) add the scene's BVH.
pub fn frame_request_for(graph: &Graph, output: &str, needs: FrameNeeds) -> Request {
    if graph.node(output).is_none() {
        return Request::default();
    }
    let linked = Linked::new(graph, output);
    let (mode, view) = (linked.mode, linked.view);
    let mut first = stages_of(graph, &linked, Mode::ShIrradiance);
    // Normal maps load with the first frame; their vMF lobes (seconds to fit) come last.
    let (normal_maps, normal_lobes): (Vec<StageRef>, Vec<StageRef>) = graph
        .upstream_all(output, "material")
        .iter()
        .flat_map(|m| normal_map_stages(graph, &m.id))
        .partition(|s| s.stage != "vmf_lobes");
    let normal_maps_empty = normal_maps.is_empty();
    first.extend(normal_maps);
    // The reference traces the scene (and the blocker spheres) whatever the mode.
    if (needs.picking || view != View::Approximation) && linked.scene.is_some() {
        for part in parts::PARTS {
            if let Some(node) = graph.upstream(output, part.port()) {
                first.extend(part.reference_stages(&node.id));
            }
        }
    }
    let request = if mode == Mode::ShAdaptive {
        // The PSNR against the full product comes after the frame.
        Request::new(format!("output `{output}`: unshadowed preview"), first)
            .then(format!("output `{output}`: mode {mode}"), stages_of(graph, &linked, mode))
            .then(
                format!("output `{output}`: error of mode {mode}"),
                vec![StageRef::new(output, crate::kinds::output::adaptive::stage_names(linked.separate_sun).1)],
            )
    } else if mode.is_shadowed() {
        let mut stages = stages_of(graph, &linked, mode);
        if needs.relight_on_cpu {
            stages.extend(modes::of(mode).cpu_relight_stages(&linked));
        }
        Request::new(format!("output `{output}`: unshadowed preview"), first)
            .then(format!("output `{output}`: mode {mode}"), stages)
    } else {
        Request::new(format!("output `{output}`: mode {mode}"), first)
    };
    // Modes that light the environment per vertex correct its highlight for a map through the
    // prefiltered light, which comes with the lobes; the SH modes draw their highlight from it.
    let mut normal_lobes = normal_lobes;
    // (A model's own materials go without it: their highlight stays the vertices' Phong lobe.)
    let glossy = graph
        .upstream_all(output, "material")
        .iter()
        .any(|m| super::normal_maps::node_model(m) != crate::brdf::Model::Lambert);
    if mode.is_shadowed() && !normal_maps_empty || mode.prefilters_highlight() && glossy {
        normal_lobes
            .extend(linked.environment.as_deref().map(|e| super::environment::highlight_cube(e, linked.separate_sun)));
    }
    let request = if normal_lobes.is_empty() {
        request
    } else {
        let tier = if normal_maps_empty { "prefiltered highlight" } else { "normal-map lobes" };
        request.then(format!("output `{output}`: {tier}"), normal_lobes)
    };
    // Area lights trace their own transport: frames show without them until it is ready.
    if graph.upstream_all(output, "area_lights").is_empty() {
        request
    } else {
        // An unshadowed preview (closed form, no ray) shows while the transport is traced;
        // highlights follow the view: the diffuse light shows first.
        request
            .then(format!("output `{output}`: area lights, unshadowed"), vec![StageRef::new(output, "area_preview")])
            .then(format!("output `{output}`: area lights"), vec![StageRef::new(output, "area_irradiance")])
            .then(format!("output `{output}`: area-light highlights"), vec![StageRef::new(output, "area_highlights")])
            // Meanwhile textured meshes show the per-vertex light.
            .then(format!("output `{output}`: area lights per texel"), {
                let mut stages = vec![StageRef::new(output, "area_texel_irradiance")];
                stages.extend(linked.scene.as_ref().map(|scene| StageRef::new(scene, "texel_receivers")));
                stages
            })
    }
}
