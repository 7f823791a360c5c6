//! Blocker spheres as a user reaches them: added from the Add menu, linked, shadowing the
//! floor, and dragged in the viewport.

use super::*;

/// Blocker spheres as a user reaches them: added from the Add menu, linked to the Output's
/// blockers input, shadowing the floor in the `sh_prt` mode; each sphere drawn as its outline
/// in the viewport, and a drag moves it (the shadow follows), one undo step per drag.
#[test]
fn blocker_spheres_from_the_add_menu_shadow_and_drag() {
    let mut harness = default_harness();
    pick(&mut harness, "Mode", "Soft shadows and gloss");
    settle(&mut harness);
    let unblocked = viewport_mean(&mut harness);
    let added = add_from_menu(&mut harness, "Blocker sphere set");
    // A large sphere over the floor in front of the objects.
    inspector::set_param(
        &mut harness.state_mut().doc,
        &added,
        "spheres",
        ParamValue::Spheres(vec![([1.2, 1.0, 1.2], 0.6)]),
    )
    .unwrap();
    harness.state_mut().doc.seal();
    harness.state_mut().selection = Selection::Node("output".into());
    harness.run_steps(3);
    pick(&mut harness, "blockers (Blockers)", &format!("{added}.blockers"));
    harness.key_press(egui::Key::Escape);
    settle(&mut harness);
    assert!(harness.state().problems().iter().all(|p| !p.starts_with("error")), "{:?}", harness.state().problems());
    let shadowed = viewport_mean(&mut harness);
    assert!(shadowed < unblocked - 0.3, "the sphere darkens the scene: {unblocked:.2} → {shadowed:.2}");
    harness
        .render()
        .unwrap()
        .save(state_dir().join("blocker-spheres.png"))
        .expect("screenshot for a person to look at");

    let sphere = harness.state().gizmos().into_iter().find(|g| g.id == added).expect("a gizmo for the sphere");
    assert!(sphere.linked);
    let rect = harness.state().viewport_rect;
    let camera = harness.state().viewport_camera(rect);
    let at = gizmos::screen_pos(&camera, rect, sphere.position).expect("in front of the camera");
    assert!(harness.state().render_frame(rect).contains(at), "the sphere is in view");
    // A drag that starts inside its outline (off its centre) moves it with the pointer.
    let grab = at + egui::vec2(4.0, 3.0);
    pointer_drag(&mut harness, egui::PointerButton::Primary, grab, grab + egui::vec2(-90.0, 20.0));
    assert_eq!(harness.state().selection, Selection::Node(added.clone()));
    let moved = harness.state().gizmos().into_iter().find(|g| g.id == added).unwrap();
    let now = gizmos::screen_pos(&camera, rect, moved.position).unwrap();
    assert!((now - (at + egui::vec2(-90.0, 20.0))).length() < 3.0, "the sphere follows the pointer: {at:?} → {now:?}");
    assert_eq!(harness.state().doc.undo_label(), Some(format!("Set {added}.spheres").as_str()));
    settle(&mut harness);
    let after = viewport_mean(&mut harness);
    assert!((after - shadowed).abs() > 0.05, "the shadow follows the sphere: {shadowed:.2} → {after:.2}");
    harness.render().unwrap().save(state_dir().join("blocker-spheres-moved.png")).unwrap();
    harness.state_mut().undo();
    let back = harness.state().gizmos().into_iter().find(|g| g.id == added).unwrap();
    assert_eq!(back.position, sphere.position);
}
