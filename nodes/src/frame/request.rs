//! What drawing an Output needs, as engine requests.

use super::*;

/// The stages a frame of `mode` reads from the Output node `output` and what feeds it.
pub fn mode_stages(graph: &Graph, output: &str, mode: Mode) -> Vec<StageRef> {
    let mut stages = vec![StageRef::new(output, "settings")];
    let upstream = |port: &str| graph.upstream(output, port).map(|n| n.id.clone());
    if let Some(scene) = upstream("scene") {
        stages.push(StageRef::new(&scene, "geometry"));
        if matches!(mode, Mode::ShPrt | Mode::ShAdaptive) {
            stages.push(StageRef::new(&scene, "transport_sh"));
            stages.push(StageRef::new(output, "blocked_transport"));
        }
        if mode == Mode::ShAdaptive {
            stages.push(StageRef::new(&scene, "adjacency"));
        }
        if mode == Mode::Rsl {
            stages.push(StageRef::new(&scene, "rsl_self_visibility"));
            stages.push(StageRef::new(&scene, "rsl_occluders"));
        }
    }
    if mode == Mode::Rsl
        && let Some(lights) = upstream("square_lights")
    {
        stages.push(StageRef::new(&lights, "world_lights"));
    }
    if let Some(env) = upstream("environment") {
        stages.push(StageRef::new(&env, "sh"));
        stages.push(StageRef::new(&env, "rotated_radiance"));
    }
    for material in graph.upstream_all(output, "material") {
        stages.push(StageRef::new(&material.id, "material"));
        match mode {
            Mode::ShPrt | Mode::ShAdaptive => stages.push(StageRef::new(&material.id, "sh_lobe")),
            Mode::WaveletVertex | Mode::WaveletPixel => stages.push(StageRef::new(&material.id, "local_table")),
            Mode::Rsl => stages.push(StageRef::new(&material.id, "rsl_tables")),
            Mode::ShIrradiance => {}
        }
    }
    if let Some(medium) = upstream("medium") {
        stages.extend(["medium", "f_tables", "g_tables"].map(|s| StageRef::new(&medium, s)));
    }
    if let Some(lights) = upstream("lights") {
        stages.push(StageRef::new(&lights, "lights"));
    }
    let separate_sun = separates_sun(graph, output);
    if separate_sun && let Some(env) = upstream("environment") {
        stages.extend(["sun", "residual_sh", "rotation"].map(|s| StageRef::new(&env, s)));
    }
    match mode {
        Mode::ShIrradiance => {}
        Mode::ShPrt => {
            stages.push(StageRef::new(output, if separate_sun { "incident_residual_sh" } else { "incident_sh" }))
        }
        Mode::ShAdaptive => {
            stages.push(StageRef::new(output, crate::kinds::output::adaptive::stage_names(separate_sun).0))
        }
        Mode::WaveletVertex | Mode::WaveletPixel => {
            let environment = if separate_sun { "wavelet_residual_environment" } else { "wavelet_environment" };
            stages.extend(["local_visibility", environment].map(|s| StageRef::new(output, s)));
            if let Some(environment) = upstream("environment") {
                stages.push(StageRef::new(&environment, "rotation"));
            }
            if let Some(scene) = upstream("scene") {
                stages.push(StageRef::new(&scene, "receivers"));
            }
            if mode == Mode::WaveletPixel {
                stages.push(StageRef::new(output, "texel_visibility"));
            }
        }
        Mode::Rsl => stages.push(StageRef::new(output, "rsl_visibility")),
    }
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
    let picking = needs.picking;
    let Some(node) = graph.node(output) else { return Request::default() };
    let (mode, view) = crate::kinds::output::output_mode_and_view(node);
    let mut first = mode_stages(graph, output, Mode::ShIrradiance);
    // Normal maps load with the first frame; their vMF lobes (seconds to fit) come last.
    let (normal_maps, normal_lobes): (Vec<StageRef>, Vec<StageRef>) = graph
        .upstream_all(output, "material")
        .iter()
        .flat_map(|m| normal_map_stages(graph, &m.id))
        .partition(|s| s.stage != "vmf_lobes");
    first.extend(normal_maps);
    if (picking || view != View::Approximation)
        && let Some(scene) = graph.upstream(output, "scene")
    {
        first.push(StageRef::new(&scene.id, "ray_scene"));
        // The reference traces the blocker spheres whatever the mode.
        if let Some(blockers) = graph.upstream(output, "blockers") {
            first.push(StageRef::new(&blockers.id, "spheres"));
        }
    }
    let request = if mode == Mode::ShAdaptive {
        // The PSNR against the full product comes after the frame.
        Request::new(format!("output `{output}`: unshadowed preview"), first)
            .then(format!("output `{output}`: mode {mode}"), mode_stages(graph, output, mode))
            .then(
                format!("output `{output}`: error of mode {mode}"),
                vec![StageRef::new(
                    output,
                    crate::kinds::output::adaptive::stage_names(separates_sun(graph, output)).1,
                )],
            )
    } else if mode.is_shadowed() {
        let mut stages = mode_stages(graph, output, mode);
        if needs.relight_on_cpu && mode.is_wavelet() {
            use crate::kinds::output::relight::stage_name;
            let separate_sun = separates_sun(graph, output);
            stages.push(StageRef::new(output, stage_name(false, separate_sun)));
            if mode == Mode::WaveletPixel {
                stages.push(StageRef::new(output, stage_name(true, separate_sun)));
            }
        }
        Request::new(format!("output `{output}`: unshadowed preview"), first)
            .then(format!("output `{output}`: mode {mode}"), stages)
    } else {
        Request::new(format!("output `{output}`: mode {mode}"), first)
    };
    let request = if normal_lobes.is_empty() {
        request
    } else {
        request.then(format!("output `{output}`: normal-map lobes"), normal_lobes)
    };
    // Area lights trace their own transport: frames show without them until it is ready.
    if graph.upstream_all(output, "area_lights").is_empty() {
        request
    } else {
        // Highlights follow the view: the diffuse light shows first.
        request
            .then(format!("output `{output}`: area lights"), vec![StageRef::new(output, "area_irradiance")])
            .then(format!("output `{output}`: area-light highlights"), vec![StageRef::new(output, "area_highlights")])
    }
}
