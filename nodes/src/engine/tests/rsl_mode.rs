//! The `rsl` mode through the engine: what moves recompute, and rotation invariance.

use super::*;
use crate::rsl::brdf_sat::BrdfSat;
use crate::rsl::shade::{LightVisibility, shade, shading_frame};
use crate::rsl::{SquareLights, WorldLights};
use glam::{DMat3, DVec3};

/// The default project with an RSL decomposer feeding the Output in `rsl` mode, kept small.
fn rsl_graph(objects: Vec<SceneObject>) -> Graph {
    let mut graph = default_graph_with(
        "rsl",
        "RslDecomposer",
        &[("sky", "environment", "rsl", "environment"), ("rsl", "square_lights", "output", "square_lights")],
    );
    graph.set_param("rsl", "cube_resolution", ParamValue::Choice("16".into())).unwrap();
    graph.set_param("rsl", "light_count", ParamValue::Int(16)).unwrap();
    graph.set_param("scene", "objects", ParamValue::Objects(objects)).unwrap();
    graph.set_param("scene", "tessellation", ParamValue::Int(8)).unwrap();
    graph.set_param("output", "mode", ParamValue::Choice("rsl".into())).unwrap();
    // The whole sky in the square lights (the sun lit apart is tested on its own below).
    graph.set_param("output", "sun", ParamValue::Choice("in_environment".into())).unwrap();
    graph
}

fn objects() -> Vec<SceneObject> {
    vec![
        SceneObject::new("floor", Shape::Plane { size: 4.0 }),
        SceneObject::new("ball", Shape::Sphere { radius: 0.5 }).at([0.0, 0.5, 0.0]),
        SceneObject {
            rotation_deg: [60.0, 20.0, 0.0],
            ..SceneObject::new("ring", Shape::Torus { major: 0.5, minor: 0.2 }).at([1.2, 0.6, 0.3])
        },
    ]
}

fn reasons(eval: &Evaluation, stage: &str) -> Vec<String> {
    eval.report.stages.iter().find(|s| s.stage == stage).map(|s| s.reasons.clone()).unwrap_or_default()
}

#[test]
fn moving_and_turning_objects_casts_no_ray_and_rebuilds_no_table() {
    let engine = Engine::in_memory();
    let mut objects = objects();
    let mut graph = rsl_graph(objects.clone());
    let first = evaluate_frame(&engine, &graph);
    assert!(reasons(&first, "rsl_occluders").contains(&"3 part(s) computed, 0 reused".to_string()));
    let before = value_of::<LightVisibility>(&first, "output", "rsl_visibility");
    objects[1].translation = [1.0, 0.5, -1.0];
    objects[1].rotation_deg = [0.0, 30.0, 10.0];
    objects[2].rotation_deg = [10.0, 80.0, 0.0];
    graph.set_param("scene", "objects", ParamValue::Objects(objects)).unwrap();
    let moved = evaluate_frame(&engine, &graph);
    assert_eq!(
        ran(&moved.report),
        set(&[
            "scene.geometry",
            "scene.vertex_frames",
            "scene.rsl_self_visibility",
            "scene.rsl_occluders",
            "output.rsl_visibility"
        ]),
        "a move reruns the per-frame visibility and re-reads the per-object tables"
    );
    for stage in ["rsl_self_visibility", "rsl_occluders"] {
        assert!(
            reasons(&moved, stage).contains(&"0 part(s) computed, 3 reused".to_string()),
            "{stage}: {:?}",
            reasons(&moved, stage)
        );
    }
    // The ball's shadow moved: the floor vertex under its old place sees more of the sky.
    let after = value_of::<LightVisibility>(&moved, "output", "rsl_visibility");
    let meshes = value_of::<crate::mesh::MeshSet>(&first, "scene", "geometry");
    let floor = &meshes.meshes[0];
    let centre = (0..floor.positions.len())
        .min_by(|&a, &b| {
            let d = |i: usize| floor.positions[i][0].hypot(floor.positions[i][2]);
            d(a).total_cmp(&d(b))
        })
        .unwrap();
    let sum = |v: &LightVisibility| -> f32 { v.values[centre * v.lights..(centre + 1) * v.lights].iter().sum() };
    assert!(sum(&after) > sum(&before) + 1.0, "under the old place: {} before, {} after", sum(&before), sum(&after));
}

/// Per-vertex outgoing radiance of an `rsl` evaluation, computed on the CPU, seen from `camera`.
fn cpu_shading(eval: &Evaluation, camera: DVec3) -> Vec<DVec3> {
    let meshes = value_of::<crate::mesh::MeshSet>(eval, "scene", "geometry");
    let lights = value_of::<WorldLights>(eval, "rsl", "world_lights");
    let visibility = value_of::<LightVisibility>(eval, "output", "rsl_visibility");
    let sat = value_of::<BrdfSat>(eval, "material", "rsl_tables");
    let receivers = crate::transport::Receivers::from_meshes(&meshes);
    (0..receivers.len())
        .map(|v| {
            let (p, n) = receivers.point(v);
            let frame = shading_frame(n, DVec3::from(receivers.tangents[v].map(f64::from)));
            let row = &visibility.values[v * visibility.lights..(v + 1) * visibility.lights];
            shade(&sat, &lights.lights, row, frame, (camera - p).normalize())
        })
        .collect()
}

#[test]
fn turning_the_environment_with_the_scene_leaves_shading_unchanged() {
    let engine = Engine::in_memory();
    let camera = DVec3::new(0.5, 2.0, 4.0);
    let mut graph = rsl_graph(objects());
    graph.set_param("material", "model", ParamValue::Choice("ggx".into())).unwrap();
    let first = evaluate_frame(&engine, &graph);
    let base = cpu_shading(&first, camera);
    let yaw = 90.0f64;
    let turn = DMat3::from_rotation_y(yaw.to_radians());
    let turned: Vec<SceneObject> = objects()
        .into_iter()
        .map(|mut o| {
            o.translation = (turn * DVec3::from(o.translation)).to_array();
            let q = glam::DQuat::from_rotation_y(yaw.to_radians()) * {
                let [x, y, z] = o.rotation_deg.map(f64::to_radians);
                glam::DQuat::from_rotation_y(y) * glam::DQuat::from_rotation_x(x) * glam::DQuat::from_rotation_z(z)
            };
            // Back to the Y·X·Z Euler angles objects store.
            let (y, x, z) = q.to_euler(glam::EulerRot::YXZ);
            o.rotation_deg = [x, y, z].map(f64::to_degrees);
            o
        })
        .collect();
    graph.set_param("scene", "objects", ParamValue::Objects(turned)).unwrap();
    graph.set_param("sky", "rotation", ParamValue::Vec3([yaw, 0.0, 0.0])).unwrap();
    let second = evaluate_frame(&engine, &graph);
    assert!(
        ran(&second.report)
            .iter()
            .all(|s| !s.starts_with("rsl.") || s == "rsl.turned_lights" || s == "rsl.world_lights"),
        "{:?}",
        ran(&second.report)
    );
    let lights = value_of::<SquareLights>(&first, "rsl", "square_lights");
    assert_eq!(lights, value_of::<SquareLights>(&second, "rsl", "square_lights"), "the same decomposition");
    let rotated = cpu_shading(&second, turn * camera);
    let scale = base.iter().map(|b| b.length()).fold(0.0, f64::max);
    let worst = base.iter().zip(&rotated).map(|(a, b)| (*a - *b).length()).fold(0.0, f64::max);
    assert!(worst < 1e-4 * scale, "largest change {worst} (of {scale})");
}

/// Notes test 11: turning the environment in small steps changes shading smoothly (lights turn;
/// nothing is re-decomposed or re-projected, so nothing pops). A small step changes the image
/// by a small amount, and about in proportion to the step: a pop would not shrink with it.
#[test]
fn small_environment_turns_change_shading_smoothly() {
    let engine = Engine::in_memory();
    let camera = DVec3::new(0.5, 2.0, 4.0);
    let mut graph = rsl_graph(objects());
    let mut shading_at = |yaw: f64| {
        graph.set_param("sky", "rotation", ParamValue::Vec3([yaw, 0.0, 0.0])).unwrap();
        cpu_shading(&evaluate_frame(&engine, &graph), camera)
    };
    let base = shading_at(30.0);
    let peak = base.iter().map(|b| b.max_element()).fold(0.0, f64::max);
    let largest =
        |a: &[DVec3], b: &[DVec3]| a.iter().zip(b).map(|(x, y)| (*x - *y).abs().max_element()).fold(0.0, f64::max);
    let mut small_steps: f64 = 0.0;
    let mut previous = base.clone();
    for k in 1..=4 {
        let next = shading_at(30.0 + 0.5 * k as f64);
        small_steps = small_steps.max(largest(&previous, &next));
        previous = next;
    }
    let big_step = largest(&base, &shading_at(35.0));
    println!(
        "largest per-vertex change: {:.3}% of the peak per 0.5° step, {:.3}% for 5°",
        small_steps / peak * 100.0,
        big_step / peak * 100.0
    );
    // Measured: 2.4% per 0.5° (the sun's penumbra crossing vertices), 16.8% for 5°.
    assert!(
        small_steps < 0.05 * peak,
        "a 0.5° turn changed a vertex by {:.2}% of the peak",
        small_steps / peak * 100.0
    );
    assert!(big_step > 3.0 * small_steps, "changes do not shrink with the step (popping): {small_steps} vs {big_step}");
}

/// With the Output lighting the sun apart (its default), the `rsl` mode's square lights come
/// from the sky without its sun and the frame draws the sun with its own shadows: the residual
/// lights' power plus the sun's is the whole sky's lights' power, and none of the residual
/// lights holds the sun's radiance.
#[test]
fn the_sun_lit_apart_leaves_the_square_lights_to_the_sky() {
    let engine = Engine::in_memory();
    let mut graph = rsl_graph(objects());
    graph.set_param("output", "sun", ParamValue::Choice("separate".into())).unwrap();
    let everything = engine.evaluate(&graph, &CancelToken::default(), None);
    assert!(everything.report.failed().is_empty(), "{:?}", everything.report.failed());
    let whole = value_of::<SquareLights>(&everything, "rsl", "square_lights");
    let residual = value_of::<SquareLights>(&everything, "rsl", "residual_square_lights");
    let split = value_of::<crate::sun::SunSplit>(&everything, "sky", "source_sun");
    let sun = split.sun.expect("the default sky has a sun");
    let power =
        |lights: &SquareLights, c: usize| lights.lights.iter().map(|l| l.intensity[c] * l.solid_angle).sum::<f64>();
    for c in 0..3 {
        let (all, sky) = (power(&whole, c), power(&residual, c));
        assert!(
            (sky + sun.power()[c] - all).abs() < 0.03 * all,
            "channel {c}: sky {sky} + sun {} against the whole sky's {all}",
            sun.power()[c]
        );
    }
    let brightest = |lights: &SquareLights| lights.lights.iter().map(|l| l.intensity[1]).fold(0.0, f64::max);
    assert!(brightest(&residual) < 0.2 * brightest(&whole), "the sun is out of the square lights");
    assert_eq!(residual.lights.len(), whole.lights.len(), "K lights either way");
    // The frame draws the residual lights and the sun.
    let frame_eval = evaluate_frame(&engine, &graph);
    let frame = crate::frame::FrameInputs::gather(&frame_eval, &graph, "output").unwrap();
    assert!(frame.sun.is_some(), "the sun is drawn apart");
    let drawn = value_of::<WorldLights>(&frame_eval, "rsl", "residual_world_lights");
    assert_eq!(drawn.lights.len(), residual.lights.len());
}
