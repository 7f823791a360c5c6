//! Which stages each edit reruns and each mode reads: the engine's recompute tables for every
//! parameter of the default project and every node kind, with the rules the bake and the
//! separately lit sun add.

use super::*;

/// `expected` with the bake's stages added by their design rule: the lightmap atlas follows
/// the scene's geometry, the texels' transports follow the vertices' (same parameters, same
/// scene), the texels' wavelet products follow the vertices' visibility cells, the wavelet
/// environment and the rotation (they are lit on the CPU), blocked transport, square-light
/// visibility and area-light stages follow the vertices' own, the traced square lights the BVH and the
/// lights, and the probes follow the geometry, the drawn
/// environment and the point lights; and the CPU relight's stages follow their receivers'
/// visibility, their environment, its rotation, the receivers, the materials' tables and the
/// medium.
fn with_bake(expected: &[&str]) -> BTreeSet<String> {
    let mut out = set(expected);
    for (vertex_stage, bake_stage) in [
        ("scene.geometry", "output.bake_atlas"),
        ("scene.transport_sh", "output.bake_texel_sh"),
        ("scene.transport_local", "output.bake_texel_local"),
        ("output.local_visibility", "output.bake_texel_products"),
        ("output.wavelet_environment", "output.bake_texel_products"),
        ("sky.rotation", "output.bake_texel_products"),
        ("output.blocked_transport", "output.bake_texel_blocked"),
        ("output.area_transport", "output.bake_texel_area_transport"),
        ("output.area_irradiance", "output.bake_texel_area"),
    ] {
        if out.contains(vertex_stage) {
            out.insert(bake_stage.to_string());
        }
    }
    // The unshadowed preview reads what the lights' sums read, but no transport.
    if out.contains("output.area_irradiance") {
        out.insert("output.area_preview".to_string());
    }
    // The area lights per texel follow their vertices' stages, and the texels.
    if out.contains("output.area_transport") || out.contains("scene.texel_receivers") {
        out.insert("output.area_texel_transport".to_string());
    }
    if out.contains("output.area_irradiance") || out.contains("output.area_texel_transport") {
        out.insert("output.area_texel_irradiance".to_string());
    }
    // The residual sky's texel products follow the whole sky's (the sun's split follows the
    // radiance the whole sky's prefiltered environment does).
    if out.contains("output.bake_texel_products") {
        out.insert("output.bake_texel_residual_products".to_string());
    }
    // The texels' square lights are traced in the scene toward the turned lights (no tables),
    // the whole sky's and the sky's without its sun.
    if out.iter().any(|s| s == "scene.ray_scene" || s.ends_with(".turned_lights")) {
        out.insert("output.bake_texel_square_lights".to_string());
    }
    if out.iter().any(|s| s == "scene.ray_scene" || s.ends_with(".residual_turned_lights")) {
        out.insert("output.bake_texel_residual_square_lights".to_string());
    }
    // The environment's SH and specular cube follow the drawn environment and its SH.
    if out.iter().any(|s| s.ends_with(".rotated_radiance") || s.ends_with(".sh")) {
        out.insert("output.bake_environment".to_string());
    }
    // The probes see the geometry, the environment as drawn (and its SH, through fog), the
    // point lights, the linked area lights (whose irradiance follows them) and the medium.
    let probe_inputs = [".rotated_radiance", ".sh", ".lights", ".medium", ".f_tables"];
    let follows = |s: &String| s == "scene.geometry" || s == "output.area_irradiance";
    if out.iter().any(|s| follows(s) || probe_inputs.iter().any(|i| s.ends_with(i))) {
        out.insert("output.bake_probes".to_string());
    }
    let shared =
        |s: &String| s == "sky.rotation" || s == "scene.receivers" || s.ends_with(".local_table") || s == "fog.medium";
    for (relit, visibility, environment) in [
        ("output.wavelet_relit", "output.local_visibility", "output.wavelet_environment"),
        ("output.wavelet_residual_relit", "output.local_visibility", "output.wavelet_residual_environment"),
        ("output.wavelet_texels_relit", "output.texel_visibility", "output.wavelet_environment"),
        ("output.wavelet_texels_residual_relit", "output.texel_visibility", "output.wavelet_residual_environment"),
    ] {
        let follows = |s: &String| s == visibility || s == environment || shared(s);
        if out.iter().any(follows) {
            out.insert(relit.to_string());
        }
    }
    out
}

/// `expected` with the stages of the sun's separation added by their design rule: the split
/// follows the environment's radiance, the residual sky's SH its SH, and the Output's residual
/// incident radiance and wavelet environment their whole-sky twins. The rotated radiance's
/// prefiltered cube (for normal-mapped per-vertex highlights) follows it, and its twin the sky's.
fn with_sun_split<'a>(expected: &[&'a str]) -> Vec<&'a str> {
    let mut expected = expected.to_vec();
    if expected.contains(&"sky.rotated_radiance") {
        expected.push("sky.highlight_cube");
    }
    let mut out = expected.clone();
    for (stage, twin) in [
        ("sky.highlight_cube", "sky.residual_highlight_cube"),
        ("sky.radiance", "sky.sun"),
        ("sky.sh_unrotated", "sky.residual_sh_unrotated"),
        ("sky.sh", "sky.residual_sh"),
        ("output.incident_sh", "output.incident_residual_sh"),
        ("output.adaptive_incident", "output.adaptive_residual_incident"),
        ("output.adaptive_error", "output.adaptive_residual_error"),
        ("output.wavelet_environment", "output.wavelet_residual_environment"),
        ("sky.source", "sky.source_sun"),
        ("rsl.cube", "rsl.residual_cube"),
        ("rsl.merge_sequence", "rsl.residual_merge_sequence"),
        ("rsl.square_lights", "rsl.residual_square_lights"),
        ("rsl.turned_lights", "rsl.residual_turned_lights"),
        ("rsl.world_lights", "rsl.residual_world_lights"),
        ("output.rsl_visibility", "output.rsl_residual_visibility"),
    ] {
        if expected.contains(&stage) {
            out.push(twin);
        }
    }
    out
}

/// What a new environment resolution reruns besides the radiance: the unexposed sun split, and
/// the square lights of the sky without its sun fitted to it (when a decomposer is linked).
const SOURCE_SUN_AFTER_RESOLUTION: &[&str] = &["sky.source_sun"];

/// Everything a new environment source reruns (exposure and tint, read alone by
/// `radiance_scale`, stay).
const SKY_ALL: &[&str] =
    &["sky.source", "sky.radiance", "sky.sh_unrotated", "sky.rotated_radiance", "sky.sh", "sky.haar"];
const SCENE_ALL: &[&str] = &[
    "scene.geometry",
    "scene.vertex_frames",
    "scene.receivers",
    "scene.adjacency",
    "scene.ray_scene",
    "scene.texel_receivers",
    "scene.transport_objects",
    "scene.transport_sh",
    "scene.transport_haar",
    "scene.transport_local",
    "scene.transport_texels",
    "scene.rsl_self_visibility",
    "scene.rsl_occluders",
    "output.rsl_visibility",
    "output.blocked_transport",
    "output.area_preview",
    "output.area_transport",
    "output.area_irradiance",
    "output.area_texel_transport",
    "output.area_texel_irradiance",
    "output.area_highlights",
    "output.adaptive_incident",
    "output.adaptive_error",
    "output.adaptive_residual_incident",
    "output.adaptive_residual_error",
];
const SKY_AFTER_SOURCE: &[&str] = &["sky.radiance", "sky.sh_unrotated", "sky.rotated_radiance", "sky.sh", "sky.haar"];

/// Edits of the environment's content also recompute what the modes read of it: the SH
/// incident radiance and the wavelet modes' prefiltered environment.
fn with_environment(stages: &[&'static str]) -> Vec<&'static str> {
    [stages, &["output.wavelet_environment"], with_rotation(&[]).as_slice()].concat()
}

/// Edits of the receivers also recompute the SH incident radiance and the wavelet modes'
/// visibility cells.
fn with_receivers(stages: &[&'static str]) -> Vec<&'static str> {
    [stages, &["output.local_visibility", "output.texel_visibility"], with_rotation(&[]).as_slice()].concat()
}

/// A rotation of the environment recomputes only the SH modes' incident radiance: the wavelet
/// modes rebuild their products from a uniform on the GPU.
fn with_rotation(stages: &[&'static str]) -> Vec<&'static str> {
    [stages, &["output.incident_sh", "output.adaptive_incident", "output.adaptive_error"]].concat()
}

#[test]
fn each_parameter_recomputes_exactly_its_stages() {
    use ParamValue::*;
    // (node, parameter, new value, stages expected to run) — written from the design, not
    // derived from the stage declarations.
    let table: Vec<(&str, &str, ParamValue, Vec<&str>)> = vec![
        (
            "sky",
            "rotation",
            Vec3([30.0, 0.0, 0.0]),
            with_rotation(&["sky.rotation", "sky.rotated_radiance", "sky.sh", "sky.haar"]),
        ),
        ("sky", "exposure", Float(1.0), with_environment(&[SKY_AFTER_SOURCE, &["sky.radiance_scale"]].concat())),
        (
            "sky",
            "tint",
            Color([1.0, 0.9, 0.8]),
            with_environment(&[SKY_AFTER_SOURCE, &["sky.radiance_scale"]].concat()),
        ),
        (
            "sky",
            "resolution",
            Choice("32".into()),
            with_environment(&[SKY_AFTER_SOURCE, SOURCE_SUN_AFTER_RESOLUTION].concat()),
        ),
        (
            "sky",
            "sh_bands",
            Int(3),
            vec![
                "sky.sh_unrotated",
                "sky.sh",
                "output.incident_sh",
                "output.adaptive_incident",
                "output.adaptive_error",
            ],
        ),
        ("sky", "wavelet_terms", Int(64), vec!["sky.haar"]),
        ("sky", "sun_elevation", Float(20.0), with_environment(SKY_ALL)),
        ("sky", "sun_azimuth", Float(-30.0), with_environment(SKY_ALL)),
        ("sky", "sun_intensity", Float(100.0), with_environment(SKY_ALL)),
        ("sky", "sun_size", Float(1.0), with_environment(SKY_ALL)),
        ("scene", "tessellation", Int(16), with_receivers(SCENE_ALL)),
        ("scene", "objects", Objects(crate::kinds::scene::default_objects()[..2].to_vec()), with_receivers(SCENE_ALL)),
        (
            "scene",
            "visibility_texture_size",
            Choice("16".into()),
            vec!["scene.texel_receivers", "scene.transport_texels", "output.texel_visibility"],
        ),
        (
            "scene",
            "transport_bands",
            Int(3),
            vec![
                "scene.transport_sh",
                "scene.transport_objects",
                "output.blocked_transport",
                "output.incident_sh",
                "output.adaptive_incident",
                "output.adaptive_error",
            ],
        ),
        (
            "scene",
            "transport_rays",
            Int(64),
            vec![
                "scene.transport_sh",
                "scene.transport_objects",
                "output.blocked_transport",
                "output.incident_sh",
                "output.adaptive_incident",
                "output.adaptive_error",
            ],
        ),
        ("scene", "haar_resolution", Choice("8".into()), vec!["scene.transport_haar"]),
        ("scene", "occluder_resolution", Choice("16".into()), vec!["scene.rsl_occluders", "output.rsl_visibility"]),
        ("scene", "haar_terms", Int(32), vec!["scene.transport_haar"]),
        (
            "scene",
            "local_frame_depth",
            Int(2),
            vec![
                "scene.transport_local",
                "scene.transport_texels",
                "output.local_visibility",
                "output.texel_visibility",
            ],
        ),
        (
            "scene",
            "local_frame_terms",
            Int(80),
            vec![
                "scene.transport_local",
                "scene.transport_texels",
                "output.local_visibility",
                "output.texel_visibility",
            ],
        ),
        (
            "material",
            "model",
            Choice("ggx".into()),
            vec![
                "material.material",
                "material.normal_preview",
                "material.preview",
                "material.sh_lobe",
                "output.adaptive_incident",
                "output.adaptive_error",
                "material.local_table",
                "material.rsl_tables",
                "output.area_highlights",
            ],
        ),
        (
            "material",
            "albedo",
            Color([0.5, 0.5, 0.5]),
            vec![
                "material.material",
                "material.normal_preview",
                "material.preview",
                "material.sh_lobe",
                "output.adaptive_incident",
                "output.adaptive_error",
                "material.local_table",
                "material.rsl_tables",
                "output.area_highlights",
            ],
        ),
        (
            "material",
            "specular",
            Color([0.2, 0.2, 0.2]),
            vec![
                "material.material",
                "material.normal_preview",
                "material.preview",
                "material.sh_lobe",
                "output.adaptive_incident",
                "output.adaptive_error",
                "material.local_table",
                "material.rsl_tables",
                "output.area_highlights",
            ],
        ),
        (
            "material",
            "roughness",
            Float(0.2),
            vec![
                "material.material",
                "material.normal_preview",
                "material.preview",
                "material.sh_lobe",
                "output.adaptive_incident",
                "output.adaptive_error",
                "material.local_table",
                "material.rsl_tables",
                "output.area_highlights",
            ],
        ),
        (
            "material",
            "exponent",
            Float(10.0),
            vec![
                "material.material",
                "material.normal_preview",
                "material.preview",
                "material.sh_lobe",
                "output.adaptive_incident",
                "output.adaptive_error",
                "material.local_table",
                "material.rsl_tables",
                "output.area_highlights",
            ],
        ),
        (
            "material",
            "anisotropy",
            Float(0.5),
            vec![
                "material.material",
                "material.normal_preview",
                "material.preview",
                "material.sh_lobe",
                "output.adaptive_incident",
                "output.adaptive_error",
                "material.local_table",
                "material.rsl_tables",
                "output.area_highlights",
            ],
        ),
        (
            "material",
            "f0",
            Float(0.5),
            vec![
                "material.material",
                "material.normal_preview",
                "material.preview",
                "material.sh_lobe",
                "output.adaptive_incident",
                "output.adaptive_error",
                "material.local_table",
                "material.rsl_tables",
                "output.area_highlights",
            ],
        ),
        // Setting the current value (the default project's shadowed mode) recomputes nothing.
        ("output", "mode", Choice("wavelet_pixel".into()), vec![]),
        (
            "output",
            "exposure",
            Float(-1.0),
            vec!["output.settings", "output.adaptive_incident", "output.adaptive_error"],
        ),
        ("output", "tonemap", Choice("reinhard".into()), vec!["output.settings"]),
        ("output", "background", Bool(false), vec!["output.settings"]),
        ("output", "view", Choice("error".into()), vec!["output.settings"]),
        ("output", "reference_samples", Int(16), vec!["output.settings"]),
        // The lighting products no longer read the mode: they are pulled by the modes that
        // draw them, so switching modes recomputes only the settings.
        ("output", "mode", Choice("sh_irradiance".into()), vec!["output.settings"]),
        (
            "output",
            "wavelet_terms",
            Choice("80".into()),
            vec!["output.local_visibility", "output.wavelet_environment", "output.texel_visibility"],
        ),
        ("output", "adaptive_level", Int(3), vec!["output.adaptive_incident", "output.adaptive_error"]),
        ("output", "adaptive_threshold", Float(0.1), vec!["output.adaptive_incident", "output.adaptive_error"]),
        ("output", "adaptive_refine", Bool(false), vec!["output.adaptive_incident", "output.adaptive_error"]),
        ("output", "adaptive_smooth", Bool(false), vec!["output.adaptive_incident", "output.adaptive_error"]),
        ("output", "adaptive_hysteresis", Float(0.9), vec!["output.adaptive_incident", "output.adaptive_error"]),
        (
            "material",
            "roughness",
            Float(0.7),
            vec![
                "material.material",
                "material.normal_preview",
                "material.preview",
                "material.sh_lobe",
                "output.adaptive_incident",
                "output.adaptive_error",
                "material.local_table",
                "material.rsl_tables",
                "output.area_highlights",
            ],
        ),
        // Without a map, the normal-map stages hold empty pyramids; their settings rebuild nothing.
        ("material", "normal_filter", Choice("vmf".into()), vec!["material.normal_settings"]),
        ("material", "normal_tiling", Float(4.0), vec!["material.normal_settings"]),
        (
            "material",
            "normal_strength",
            Float(0.5),
            vec!["material.normal_map", "material.ndf_moments", "material.vmf_lobes", "material.normal_preview"],
        ),
        ("material", "normal_preview_level", Int(2), vec!["material.normal_preview"]),
    ];
    let engine = Engine::in_memory();
    // A coarse scene: every scene edit recomputes each object's visibility tables.
    let mut graph = default_graph();
    graph.set_param("scene", "tessellation", Int(12)).unwrap();
    let first = engine.evaluate(&graph, &CancelToken::default(), None);
    assert!(first.report.failed().is_empty(), "{:?}", first.report.failed());
    assert_eq!(first.report.computed().len(), 73);
    let again = engine.evaluate(&graph, &CancelToken::default(), None);
    assert!(ran(&again.report).is_empty(), "an unchanged graph recomputed {:?}", ran(&again.report));
    for (node, param, value, expected) in table {
        graph.set_param(node, param, value).unwrap();
        let eval = engine.evaluate(&graph, &CancelToken::default(), None);
        assert_eq!(ran(&eval.report), with_bake(&with_sun_split(&expected)), "changing {node}.{param}");
        assert!(eval.report.failed().is_empty(), "changing {node}.{param}: {:?}", eval.report.failed());
    }
}

#[test]
fn every_kind_recomputes_exactly_its_stages() {
    use ParamValue::*;
    let mut project = default_project();
    let node = |id: &str, kind: &str| ProjectNode {
        id: id.into(),
        kind: kind.into(),
        label: String::new(),
        position: [0.0; 2],
        params: BTreeMap::new(),
    };
    let link =
        |a: &str, p: &str, b: &str, q: &str| ProjectLink { from: (a.into(), p.into()), to: (b.into(), q.into()) };
    project.nodes.extend([
        node("fog", "FogMedium"),
        node("light1", "PointLight"),
        node("light2", "PointLight"),
        node("blockers", "BlockerSpheres"),
        node("rsl", "RslDecomposer"),
        node("area", "AreaLightPainter"),
    ]);
    project.links.extend([
        link("fog", "medium", "output", "medium"),
        link("light1", "lights", "light2", "lights"),
        link("light2", "lights", "output", "lights"),
        link("blockers", "blockers", "output", "blockers"),
        link("sky", "environment", "rsl", "environment"),
        link("rsl", "square_lights", "output", "square_lights"),
    ]);
    // Small fog tables: this test is about keys, not accuracy.
    let fog = project.nodes.iter_mut().find(|n| n.id == "fog").unwrap();
    fog.params.insert("table_resolution".into(), Choice("32".into()));
    let mut graph = project.graph(std::path::Path::new("p.ron")).unwrap();
    let fog_tables = ["fog.medium", "fog.f_tables", "fog.g_tables"];
    let table: Vec<(&str, &str, ParamValue, Vec<&str>)> = vec![
        ("fog", "beta", Color([0.1, 0.1, 0.2]), vec!["fog.medium"]),
        // One F table for isotropic fog, one per term of the polynomial; the G tables (eq. 3.23,
        // isotropic scattering onto surfaces) do not depend on the phase.
        ("fog", "phase", Choice("polynomial".into()), vec!["fog.medium", "fog.f_tables"]),
        ("fog", "phase_coefficients", Vec3([1.0, 0.5, 0.0]), vec!["fog.medium"]),
        ("fog", "table_resolution", Choice("64".into()), fog_tables.to_vec()),
        ("light1", "position", Vec3([1.0, 2.0, 3.0]), vec!["light1.lights", "light2.lights"]),
        ("light1", "intensity", Color([1.0, 1.0, 1.0]), vec!["light1.lights", "light2.lights"]),
        ("light2", "intensity", Color([2.0, 1.0, 1.0]), vec!["light2.lights"]),
        (
            "blockers",
            "spheres",
            Spheres(vec![([0.0, 1.0, 0.0], 0.3), ([1.0, 1.0, 0.0], 0.2)]),
            vec![
                "blockers.spheres",
                "output.blocked_transport",
                "output.incident_sh",
                "output.adaptive_incident",
                "output.adaptive_error",
            ],
        ),
        (
            "blockers",
            "offset",
            Vec3([0.5, 0.0, 0.0]),
            vec![
                "blockers.spheres",
                "output.blocked_transport",
                "output.incident_sh",
                "output.adaptive_incident",
                "output.adaptive_error",
            ],
        ),
        (
            "blockers",
            "strength",
            Float(0.5),
            vec![
                "blockers.spheres",
                "output.blocked_transport",
                "output.incident_sh",
                "output.adaptive_incident",
                "output.adaptive_error",
            ],
        ),
        (
            "blockers",
            "rotation",
            Vec3([0.0, 30.0, 0.0]),
            vec![
                "blockers.spheres",
                "output.blocked_transport",
                "output.incident_sh",
                "output.adaptive_incident",
                "output.adaptive_error",
            ],
        ),
        (
            "blockers",
            "scale",
            Float(1.5),
            vec![
                "blockers.spheres",
                "output.blocked_transport",
                "output.incident_sh",
                "output.adaptive_incident",
                "output.adaptive_error",
            ],
        ),
        (
            "blockers",
            "exponential",
            Choice("hyb".into()),
            vec![
                "blockers.spheres",
                "output.blocked_transport",
                "output.incident_sh",
                "output.adaptive_incident",
                "output.adaptive_error",
            ],
        ),
        // A new order rebuilds the tables too.
        (
            "blockers",
            "sh_bands",
            Int(6),
            vec![
                "blockers.tables",
                "blockers.spheres",
                "output.blocked_transport",
                "output.incident_sh",
                "output.adaptive_incident",
                "output.adaptive_error",
            ],
        ),
        // A new K is a cut of the same merge sequence (then the O(K) world lights and the
        // per-vertex visibility of the new lights).
        (
            "rsl",
            "light_count",
            Int(10),
            vec!["rsl.square_lights", "rsl.turned_lights", "rsl.world_lights", "output.rsl_visibility"],
        ),
        (
            "rsl",
            "merge_rule",
            Choice("error_increase".into()),
            vec![
                "rsl.merge_sequence",
                "rsl.square_lights",
                "rsl.turned_lights",
                "rsl.world_lights",
                "output.rsl_visibility",
            ],
        ),
        (
            "rsl",
            "cube_resolution",
            Choice("16".into()),
            vec![
                "rsl.cube",
                "rsl.merge_sequence",
                "rsl.square_lights",
                "rsl.turned_lights",
                "rsl.world_lights",
                "output.rsl_visibility",
            ],
        ),
        ("area", "width", Float(2.0), vec!["area.source", "area.placement", "area.light"]),
        ("area", "intensity", Float(3.0), vec!["area.light"]),
        ("area", "position", Vec3([0.0, 3.0, 0.0]), vec!["area.placement", "area.light"]),
        (
            "sky",
            "exposure",
            Float(2.0),
            [
                // The square lights are fitted before exposure: only the O(K) world lights
                // rerun; visibility reads the turned lights, which exposure leaves alone.
                SKY_AFTER_SOURCE,
                &["sky.radiance_scale", "rsl.world_lights"],
                &["output.incident_sh", "output.wavelet_environment"],
                &["output.adaptive_incident", "output.adaptive_error"],
            ]
            .concat(),
        ),
        (
            "sky",
            "rotation",
            Vec3([0.0, 40.0, 0.0]),
            vec![
                "sky.rotation",
                "sky.rotated_radiance",
                "sky.sh",
                "sky.haar",
                "rsl.turned_lights",
                "rsl.world_lights",
                "output.rsl_visibility",
                "output.incident_sh",
                "output.adaptive_incident",
                "output.adaptive_error",
            ],
        ),
    ];
    let engine = Engine::in_memory();
    let first = engine.evaluate(&graph, &CancelToken::default(), None);
    let failed: BTreeSet<String> = first.report.failed().iter().map(|s| format!("{}.{}", s.node, s.stage)).collect();
    assert!(failed.is_empty(), "{failed:?}");
    let lights = value_of::<crate::rsl::SquareLights>(&first, "rsl", "square_lights");
    assert_eq!(lights.lights.len(), 30, "the default K");
    let lights = value_of::<Vec<crate::light::PointLight>>(&first, "light2", "lights");
    assert_eq!(lights.len(), 2, "point lights chain");
    for (node, param, value, expected) in table {
        graph.set_param(node, param, value).unwrap();
        let eval = engine.evaluate(&graph, &CancelToken::default(), None);
        assert_eq!(ran(&eval.report), with_bake(&with_sun_split(&expected)), "changing {node}.{param}");
    }
}

fn evaluated(report: &Report) -> BTreeSet<String> {
    report
        .stages
        .iter()
        .filter(|s| s.status != StageStatus::NotNeeded)
        .map(|s| format!("{}.{}", s.node, s.stage))
        .collect()
}

#[test]
fn each_mode_and_view_evaluates_exactly_the_stages_it_reads() {
    use crate::frame::frame_request;
    // Written from what each mode draws, not derived from the stage declarations.
    const UNSHADOWED: &[&str] = &[
        "output.settings",
        "scene.geometry",
        "scene.vertex_frames",
        "sky.source",
        "sky.radiance",
        "sky.sh_unrotated",
        "sky.sh",
        "sky.rotated_radiance",
        "material.material",
    ];
    // Every mode lights the sun apart here: each reads its split and the residual sky's SH.
    const SUN_SPLIT: &[&str] =
        &["sky.source_sun", "sky.sun", "sky.residual_sh_unrotated", "sky.residual_sh", "sky.rotation"];
    let with_sun = |extra: &[&'static str]| -> Vec<&'static str> { [UNSHADOWED, SUN_SPLIT, extra].concat() };
    let wavelet_vertex = with_sun(&[
        "scene.receivers",
        "scene.ray_scene",
        "scene.transport_local",
        "material.local_table",
        "output.local_visibility",
        "output.wavelet_residual_environment",
    ]);
    let table: Vec<(&str, &str, Vec<&str>)> = vec![
        ("sh_irradiance", "approximation", with_sun(&[])),
        (
            "sh_prt",
            "approximation",
            with_sun(&[
                "scene.receivers",
                "scene.ray_scene",
                "scene.transport_sh",
                "material.sh_lobe",
                "output.blocked_transport",
                "output.incident_residual_sh",
            ]),
        ),
        (
            "sh_adaptive",
            "approximation",
            with_sun(&[
                "scene.receivers",
                "scene.adjacency",
                "scene.ray_scene",
                "scene.transport_sh",
                "material.sh_lobe",
                "output.blocked_transport",
                "output.adaptive_residual_incident",
                "output.adaptive_residual_error",
            ]),
        ),
        ("wavelet_vertex", "approximation", wavelet_vertex.clone()),
        (
            "wavelet_pixel",
            "approximation",
            [
                wavelet_vertex.as_slice(),
                &["scene.texel_receivers", "scene.transport_texels", "output.texel_visibility"],
            ]
            .concat(),
        ),
        (
            "rsl",
            "approximation",
            // The sun lit apart: the visibility of the lights of the sky without it.
            with_sun(&[
                "scene.rsl_self_visibility",
                "scene.rsl_occluders",
                "material.rsl_tables",
                "output.rsl_residual_visibility",
            ]),
        ),
        ("sh_irradiance", "reference", with_sun(&["scene.ray_scene"])),
        ("sh_irradiance", "error", with_sun(&["scene.ray_scene"])),
    ];
    let engine = Engine::in_memory();
    for (mode, view, expected) in table {
        let mut graph = small_default_graph();
        graph.set_param("output", "mode", ParamValue::Choice(mode.into())).unwrap();
        graph.set_param("output", "view", ParamValue::Choice(view.into())).unwrap();
        let request = frame_request(&graph, "output", false);
        let eval = engine.evaluate_request(&graph, &request, &CancelToken::default(), None, &|_, _| {});
        assert!(eval.report.failed().is_empty(), "{mode}/{view}: {:?}", eval.report.failed());
        assert_eq!(evaluated(&eval.report), set(&expected), "{mode}/{view}");
        // Everything else is reported, with why it did not run.
        for s in eval.report.stages.iter().filter(|s| s.status == StageStatus::NotNeeded) {
            assert!(s.reasons[0].contains(&format!("mode {mode}")), "{}.{}: {:?}", s.node, s.stage, s.reasons);
        }
        assert_eq!(eval.report.stages.len(), 73, "every stage is reported");
    }
}

/// With a normal map set, a frame loads it and builds its moments and settings with the first
/// tier, and fits vMF lobes only with that filter, in a tier of their own. The filter and tiling
/// recompute only the settings, the strength the map and its pyramids; the frame hands the
/// renderer every piece. A map that cannot load leaves its material unmapped and says why, and
/// the frame still draws.
#[test]
fn normal_map_stages_follow_their_parameters() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bumps.png");
    let texels =
        image::RgbImage::from_fn(8, 8, |x, y| image::Rgb([128 + 40 * (x % 2) as u8, 128 + 30 * (y % 3) as u8, 230]));
    texels.save(&path).unwrap();
    let mut graph = small_default_graph();
    graph.set_param("material", "normal_map", ParamValue::Path(path.display().to_string())).unwrap();
    let engine = Engine::in_memory();
    let frame = |graph: &Graph| {
        let request = crate::frame::frame_request(graph, "output", false);
        let eval = engine.evaluate_request(graph, &request, &CancelToken::default(), None, &|_, _| {});
        assert!(eval.report.failed().is_empty(), "{:?}", eval.report.failed());
        let inputs = crate::frame::FrameInputs::gather(&eval, graph, "output").unwrap();
        (ran(&eval.report), inputs)
    };
    let (computed, inputs) = frame(&graph);
    let normal = ["material.normal_map", "material.ndf_moments", "material.normal_settings"];
    assert!(set(&normal).is_subset(&computed) && !computed.contains("material.vmf_lobes"), "{computed:?}");
    let detail = inputs.materials[0].normal.as_ref().expect("the material's normal map");
    assert!(detail.lobes.is_none() && detail.settings.tiling == 1.0);
    let map = detail.map.value.get::<crate::normal_filtering::NormalMap>().unwrap();
    assert_eq!((map.width, map.height), (8, 8));

    graph.set_param("material", "normal_filter", ParamValue::Choice("vmf".into())).unwrap();
    let (computed, inputs) = frame(&graph);
    assert_eq!(computed, set(&["material.normal_settings", "material.vmf_lobes"]));
    assert!(inputs.materials[0].normal.as_ref().unwrap().lobes.is_some());
    graph.set_param("material", "normal_tiling", ParamValue::Float(8.0)).unwrap();
    let (computed, inputs) = frame(&graph);
    assert_eq!(computed, set(&["material.normal_settings"]));
    assert_eq!(inputs.materials[0].normal.as_ref().unwrap().settings.tiling, 8.0);
    graph.set_param("material", "normal_strength", ParamValue::Float(2.0)).unwrap();
    assert_eq!(frame(&graph).0, set(&["material.normal_map", "material.ndf_moments", "material.vmf_lobes"]));

    graph
        .set_param("material", "normal_map", ParamValue::Path(dir.path().join("missing.png").display().to_string()))
        .unwrap();
    let request = crate::frame::frame_request(&graph, "output", false);
    let eval = engine.evaluate_request(&graph, &request, &CancelToken::default(), None, &|_, _| {});
    let inputs = crate::frame::FrameInputs::gather(&eval, &graph, "output").expect("the frame draws without the map");
    assert!(inputs.materials[0].normal.is_none());
    let why =
        inputs.lobe_limits.iter().find(|(node, _)| node == "material").map(|(_, why)| why.clone()).unwrap_or_default();
    assert!(why.contains("normal map is not shown") && why.contains("missing.png"), "{why}");
}
