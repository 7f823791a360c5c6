//! A blocker set fitted to a model, as a user meets it: the fitted spheres are drawn in the
//! viewport, and dragging one moves the whole set.

use super::*;

#[test]
fn a_set_fitted_to_a_model_draws_its_spheres_and_drags_as_one() {
    let model =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/gltf/assimp-glTF2/BoxTextured-glTF/BoxTextured.gltf");
    assert!(model.is_file(), "the repository's assets/ folder is expected at {}", model.display());
    let mut harness = default_harness();
    pick(&mut harness, "Mode", "Soft shadows and gloss");
    let added = add_from_menu(&mut harness, "Blocker sphere set");
    for (name, value) in [
        ("fit_model", ParamValue::Path(model.display().to_string())),
        ("fit_count", ParamValue::Int(12)),
        ("offset", ParamValue::Vec3([1.2, 1.0, 1.0])),
    ] {
        inspector::set_param(&mut harness.state_mut().doc, &added, name, value).unwrap();
    }
    harness.state_mut().doc.seal();
    harness.state_mut().selection = Selection::Node("output".into());
    harness.run_steps(3);
    assert!(harness.query_by_label("Adaptive threshold").is_none(), "sh_prt's inspector hides the adaptive settings");
    pick(&mut harness, "blockers (Blockers)", &format!("{added}.blockers"));
    harness.key_press(egui::Key::Escape);
    settle(&mut harness);
    let spheres: Vec<_> = harness.state().gizmos().into_iter().filter(|g| g.id == added).collect();
    assert_eq!(spheres.len(), 12, "the fitted spheres are drawn");
    harness.render().unwrap().save(state_dir().join("fitted-spheres.png")).expect("screenshot for a person to look at");
    let rect = harness.state().viewport_rect;
    let camera = harness.state().viewport_camera(rect);
    let radius = |g: &gizmos::Gizmo| match g.target {
        gizmos::GizmoTarget::Sphere { radius, .. } => radius,
        _ => 0.0,
    };
    let biggest = spheres.iter().max_by(|a, b| radius(a).total_cmp(&radius(b))).unwrap();
    let at = gizmos::screen_pos(&camera, rect, biggest.position).expect("in front of the camera");
    pointer_drag(&mut harness, egui::PointerButton::Primary, at, at + egui::vec2(-80.0, 0.0));
    let spec = lightloom_nodes::kinds::kind("BlockerSpheres").unwrap();
    let offset = inspector::param_value(&harness.state().doc.project, &added, spec.param("offset").unwrap());
    let ParamValue::Vec3(offset) = offset else { panic!("offset is a Vec3") };
    assert!(offset[0] < 1.0, "dragging a fitted sphere to the left moves the set: offset {offset:?}");
    assert_eq!(harness.state().doc.undo_label(), Some(format!("Set {added}.offset").as_str()));
}
