//! The area light painter as a user meets it: added from the Add menu, its inspector shows
//! the light's texture as a canvas, a drag paints one stroke (one undo step), and the texture
//! the engine renders changes with it.

use super::*;
use lightloom_nodes::light_texture::{LightTexture, PaintOp};

fn paint_log(harness: &Harness<'_, EditorApp>, node: &str) -> Vec<PaintOp> {
    match edits::node(&harness.state().doc.project, node).and_then(|n| n.params.get("paint")) {
        Some(ParamValue::Paint(ops)) => ops.clone(),
        _ => Vec::new(),
    }
}

fn texture_mean(harness: &Harness<'_, EditorApp>, node: &str) -> f64 {
    let evaluation = &harness.state().evaluator.last.as_ref().expect("an evaluation").0;
    let value = evaluation.value(node, "texture").expect("the texture stage ran");
    let texture = value.expect::<LightTexture>().unwrap();
    texture.emission().iter().map(|c| c[0] + c[1] + c[2]).sum::<f64>() / texture.emission().len() as f64
}

#[test]
fn painting_on_the_canvas_adds_one_undoable_stroke() {
    let mut harness = default_harness();
    let added = add_from_menu(&mut harness, "Area light painter");
    assert_eq!(harness.state().selection, Selection::Node(added.clone()));
    settle(&mut harness);
    harness.run_steps(2);
    let white = texture_mean(&harness, &added);
    assert!((white - 3.0).abs() < 1e-9, "a new light is white: {white}");
    harness.get_by_label_contains("Paint: 0 operations");

    // A dark stroke across the middle of the canvas.
    harness.state_mut().paint_canvas.colour = [0.0, 0.0, 0.0];
    harness.state_mut().paint_canvas.hardness = 1.0;
    let rect = harness.state().paint_canvas.last_rect.expect("the canvas is drawn");
    pointer_drag(
        &mut harness,
        egui::PointerButton::Primary,
        rect.lerp_inside(egui::vec2(0.2, 0.5)),
        rect.lerp_inside(egui::vec2(0.8, 0.5)),
    );
    let ops = paint_log(&harness, &added);
    assert_eq!(ops.len(), 1, "one stroke: {ops:?}");
    let PaintOp::Stroke { points, .. } = &ops[0] else { panic!("a stroke: {ops:?}") };
    assert!(points.iter().all(|p| (p[1] - 0.5).abs() < 0.02), "{points:?}");
    // Dabs a quarter radius apart, however fast the pointer moved.
    assert!(points.windows(2).all(|w| (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]) <= 0.06 / 4.0 + 1e-9), "{points:?}");
    assert!((points[0][0] - 0.2).abs() < 0.05 && (points.last().unwrap()[0] - 0.8).abs() < 0.05, "{points:?}");
    assert_eq!(harness.state().doc.undo_label(), Some("Paint stroke"));
    settle(&mut harness);
    harness.run_steps(2);
    let painted = texture_mean(&harness, &added);
    assert!(painted < white - 0.2, "the stroke darkens the light: {white} → {painted}");
    harness.get_by_label_contains("Paint: 1 operation");
    harness
        .render()
        .unwrap()
        .save(state_dir().join("area_light_canvas.png"))
        .expect("screenshot for a person to look at");

    harness.state_mut().undo();
    settle(&mut harness);
    assert!(paint_log(&harness, &added).is_empty(), "undo removes the stroke");
    assert!((texture_mean(&harness, &added) - white).abs() < 1e-9);

    // A click paints one dab where it lands (in the canvas's upper half: in the test's window
    // its lower part lies below the inspector's fold).
    pointer_click(&mut harness, rect.lerp_inside(egui::vec2(0.25, 0.6)));
    let ops = paint_log(&harness, &added);
    assert_eq!(ops.len(), 1, "{ops:?}");
    let PaintOp::Stroke { points, .. } = &ops[0] else { panic!("a stroke: {ops:?}") };
    assert!(points.len() == 1 && (points[0][0] - 0.25).abs() < 0.01 && (points[0][1] - 0.6).abs() < 0.01, "{points:?}");
}

/// The light is drawn in the viewport as its rectangle with a centre handle; dragging the
/// handle moves it in its level plane under the pointer (one undo step), and a Shift-drag
/// raises it.
#[test]
fn the_area_light_shows_in_the_viewport_and_drags() {
    let mut harness = default_harness();
    let added = add_from_menu(&mut harness, "Area light painter");
    inspector::set_param(&mut harness.state_mut().doc, &added, "position", ParamValue::Vec3([0.5, 1.5, 0.5])).unwrap();
    harness.state_mut().doc.seal();
    settle(&mut harness);
    let gizmo = harness.state().gizmos().into_iter().find(|g| g.id == added).expect("the area light has a gizmo");
    assert!(matches!(gizmo.target, gizmos::GizmoTarget::AreaLight { width: 1.0, depth: 1.0, .. }));
    let rect = harness.state().viewport_rect;
    let camera = harness.state().viewport_camera(rect);
    let at = gizmos::screen_pos(&camera, rect, gizmo.position).expect("in front of the camera");
    assert!(harness.state().render_frame(rect).contains(at), "the handle is in view at {at:?}");
    harness
        .render()
        .unwrap()
        .save(state_dir().join("area_light_gizmo.png"))
        .expect("screenshot for a person to look at");
    pointer_drag(&mut harness, egui::PointerButton::Primary, at, at + egui::vec2(80.0, 0.0));
    let position = match edits::node(&harness.state().doc.project, &added).and_then(|n| n.params.get("position")) {
        Some(ParamValue::Vec3(p)) => *p,
        other => panic!("position: {other:?}"),
    };
    assert!(
        (position[0] - 0.5).abs() > 0.1 || (position[2] - 0.5).abs() > 0.1,
        "the drag moves the light: {position:?}"
    );
    assert_eq!(position[1], 1.5, "a drag keeps the light's height");
    // The handle stays under the pointer: the light moved in its level plane.
    let camera = harness.state().viewport_camera(rect);
    let now = gizmos::screen_pos(&camera, rect, position).unwrap();
    assert!(
        now.distance(at + egui::vec2(80.0, 0.0)) < 6.0,
        "the handle is at {now:?}, the pointer at {:?}",
        at + egui::vec2(80.0, 0.0)
    );
    assert_eq!(harness.state().doc.undo_label(), Some(format!("Set {added}.position").as_str()));
    // With Shift, a drag up raises it and moves it nowhere else.
    let up = now - egui::vec2(0.0, 60.0);
    pointer_drag_with(&mut harness, egui::PointerButton::Primary, now, up, egui::Modifiers::SHIFT);
    let raised = match edits::node(&harness.state().doc.project, &added).and_then(|n| n.params.get("position")) {
        Some(ParamValue::Vec3(p)) => *p,
        other => panic!("position: {other:?}"),
    };
    assert!(raised[1] > 1.6, "a Shift-drag up raises the light: {raised:?}");
    assert_eq!((raised[0], raised[2]), (position[0], position[2]), "and moves it nowhere else");
}

/// A tilted light's rectangle is drawn tilted, and a drag moves it within its own tilted plane
/// (its height in its own frame kept), under the pointer.
#[test]
fn a_tilted_area_light_drags_in_its_own_plane() {
    let mut harness = default_harness();
    let added = add_from_menu(&mut harness, "Area light painter");
    let doc = &mut harness.state_mut().doc;
    inspector::set_param(doc, &added, "position", ParamValue::Vec3([0.5, 1.5, 0.5])).unwrap();
    inspector::set_param(doc, &added, "angle", ParamValue::Float(20.0)).unwrap();
    inspector::set_param(doc, &added, "tilt", ParamValue::Float(40.0)).unwrap();
    harness.state_mut().doc.seal();
    settle(&mut harness);
    let gizmo = harness.state().gizmos().into_iter().find(|g| g.id == added).expect("the area light has a gizmo");
    assert!(matches!(gizmo.target, gizmos::GizmoTarget::AreaLight { tilt: 40.0, .. }));
    let orientation =
        glam::DMat3::from_rotation_y(20f64.to_radians()) * glam::DMat3::from_rotation_x(40f64.to_radians());
    let normal = orientation * glam::DVec3::Y;
    // Its edge handles lie in the tilted plane, off the level one.
    let handles: Vec<glam::DVec3> = gizmo.edges().into_iter().map(|(_, p)| glam::DVec3::from(p)).collect();
    let centre = glam::DVec3::from(gizmo.position);
    assert!(handles.iter().all(|h| (*h - centre).dot(normal).abs() < 1e-9));
    assert!(handles.iter().any(|h| (h.y - centre.y).abs() > 0.1), "the rectangle is tilted: {handles:?}");
    let rect = harness.state().viewport_rect;
    let camera = harness.state().viewport_camera(rect);
    let at = gizmos::screen_pos(&camera, rect, gizmo.position).expect("in front of the camera");
    harness.render().unwrap().save(state_dir().join("area_light_tilted.png")).expect("screenshot for a person");
    pointer_drag(&mut harness, egui::PointerButton::Primary, at, at + egui::vec2(60.0, 30.0));
    let position = match edits::node(&harness.state().doc.project, &added).and_then(|n| n.params.get("position")) {
        Some(ParamValue::Vec3(p)) => glam::DVec3::from(*p),
        other => panic!("position: {other:?}"),
    };
    assert!((position - centre).length() > 0.1, "the drag moves the light: {position}");
    assert!((position - centre).dot(normal).abs() < 1e-9, "within its own plane: {position}");
    let camera = harness.state().viewport_camera(rect);
    let now = gizmos::screen_pos(&camera, rect, position.to_array()).unwrap();
    assert!(now.distance(at + egui::vec2(60.0, 30.0)) < 6.0, "the handle is at {now:?}");
}

/// Linked to the Output, the light brightens the viewport once its transport is traced; an
/// edge handle resizes it about its centre (one undo step), and the light follows.
#[test]
fn a_linked_area_light_lights_the_viewport_and_its_edges_resize_it() {
    let mut harness = default_harness();
    settle(&mut harness);
    let dark = viewport_mean(&mut harness);
    let added = add_from_menu(&mut harness, "Area light painter");
    let link = ((added.clone(), "area_light".into()), ("output".to_string(), "area_lights".to_string()));
    harness.state_mut().doc.edit("Link", None, |p| edits::connect(p, &link.0, &link.1)).unwrap();
    inspector::set_param(&mut harness.state_mut().doc, &added, "position", ParamValue::Vec3([0.0, 1.8, 0.5])).unwrap();
    inspector::set_param(&mut harness.state_mut().doc, &added, "intensity", ParamValue::Float(60.0)).unwrap();
    harness.state_mut().doc.seal();
    settle(&mut harness);
    // Deselected: the light's own preview is not drawn, so only its lighting counts.
    harness.state_mut().selection = Selection::None;
    settle(&mut harness);
    let lit = viewport_mean(&mut harness);
    assert!(lit > dark + 2.0, "the area light brightens the view: {dark:.1} → {lit:.1}");
    harness.render().unwrap().save(state_dir().join("area_light_lit.png")).expect("screenshot for a person to look at");

    // Drag the +width edge handle outward along the light's width axis.
    let rect = harness.state().viewport_rect;
    let camera = harness.state().viewport_camera(rect);
    let gizmo = harness.state().gizmos().into_iter().find(|g| g.id == added).unwrap();
    let centre = gizmos::screen_pos(&camera, rect, gizmo.position).unwrap();
    let edge =
        gizmos::screen_pos(&camera, rect, [gizmo.position[0] + 0.5, gizmo.position[1], gizmo.position[2]]).unwrap();
    let hit = harness.state().gizmo_at(edge, rect).expect("the edge handle is under the pointer");
    assert_eq!(hit.edge, Some(gizmos::Edge::Width(1.0)));
    let outward = (edge - centre).normalized() * 60.0;
    pointer_drag(&mut harness, egui::PointerButton::Primary, edge, edge + outward);
    let param = |name: &str| match edits::node(&harness.state().doc.project, &added).and_then(|n| n.params.get(name)) {
        Some(ParamValue::Float(v)) => *v,
        Some(ParamValue::Vec3(p)) => p[0],
        _ => f64::NAN,
    };
    assert!(param("width") > 1.3, "the drag widens the light: {}", param("width"));
    assert_eq!(param("position"), 0.0, "resizing keeps the centre");
    assert_eq!(harness.state().doc.undo_label(), Some(format!("Set {added}.width").as_str()));
    harness.state_mut().selection = Selection::None;
    settle(&mut harness);
    let wider = viewport_mean(&mut harness);
    assert!(wider > lit, "a wider light of the same radiance gives more light: {lit:.1} → {wider:.1}");
    harness.render().unwrap().save(state_dir().join("area_light_resized.png")).expect("screenshot");
}

/// The selected light shows its painted texture on its rectangle in the viewport, inside the
/// gizmo's outline; deselected, only the outline is left.
#[test]
fn the_selected_area_light_previews_its_texture_in_the_viewport() {
    let mut harness = default_harness();
    let added = add_from_menu(&mut harness, "Area light painter");
    let doc = &mut harness.state_mut().doc;
    inspector::set_param(doc, &added, "position", ParamValue::Vec3([0.5, 1.5, 0.5])).unwrap();
    let red = PaintOp::Fill { colour: [1.0, 0.05, 0.05], intensity: 1.0 };
    inspector::set_param(doc, &added, "paint", ParamValue::Paint(vec![red])).unwrap();
    doc.seal();
    harness.state_mut().selection = Selection::Node(added.clone());
    settle(&mut harness);
    let rect = harness.state().viewport_rect;
    let camera = harness.state().viewport_camera(rect);
    // Halfway from the centre handle to a corner (the light is 1 × 1 and not turned).
    let probe = gizmos::screen_pos(&camera, rect, [0.75, 1.5, 0.75]).expect("in front of the camera");
    let ppp = harness.ctx.pixels_per_point();
    let pixel = |harness: &mut Harness<'_, EditorApp>| {
        let image = harness.render().expect("the UI renders through wgpu");
        let p = image.get_pixel((probe.x * ppp) as u32, (probe.y * ppp) as u32);
        [p[0], p[1], p[2]].map(f64::from)
    };
    let shown = pixel(&mut harness);
    harness
        .render()
        .unwrap()
        .save(state_dir().join("area_light_preview.png"))
        .expect("screenshot for a person to look at");
    assert!(
        shown[0] > 100.0 && shown[0] > 2.0 * shown[1] && shown[0] > 2.0 * shown[2],
        "the painted red shows: {shown:?}"
    );
    harness.state_mut().selection = Selection::None;
    settle(&mut harness);
    let hidden = pixel(&mut harness);
    assert!(hidden[0] < 2.0 * hidden[1], "deselected, the view behind shows: {hidden:?}");
}

/// Highlights hold for one viewpoint: a glossy floor under a light reflects it toward the
/// viewport camera; after a right-drag orbit they stay until the camera rests, then are
/// recomputed for the new view (only the highlights stage reruns) and move on the floor.
#[test]
fn area_light_highlights_follow_the_view_once_the_camera_rests() {
    use lightloom_nodes::kinds::output::area::AreaHighlights;
    let mut harness = default_harness();
    let added = add_from_menu(&mut harness, "Area light painter");
    let link = ((added.clone(), "area_light".into()), ("output".to_string(), "area_lights".to_string()));
    harness.state_mut().doc.edit("Link", None, |p| edits::connect(p, &link.0, &link.1)).unwrap();
    let doc = &mut harness.state_mut().doc;
    inspector::set_param(doc, &added, "position", ParamValue::Vec3([0.0, 1.5, 0.0])).unwrap();
    inspector::set_param(doc, "material", "model", ParamValue::Choice("phong".into())).unwrap();
    inspector::set_param(doc, "material", "exponent", ParamValue::Float(20.0)).unwrap();
    inspector::set_param(doc, "material", "f0", ParamValue::Float(0.5)).unwrap();
    doc.seal();
    harness.state_mut().selection = Selection::None;
    let highlights = |harness: &Harness<'_, EditorApp>| {
        let evaluation = &harness.state().evaluator.last.as_ref().expect("an evaluation").0;
        let value = evaluation.value("output", "area_highlights").expect("the highlights ran");
        value.expect::<AreaHighlights>().unwrap().radiance.clone()
    };
    let rest = |harness: &mut Harness<'_, EditorApp>| {
        std::thread::sleep(Duration::from_millis(500));
        harness.run_steps(2);
        settle(harness);
    };
    rest(&mut harness);
    let eye = harness.state().view.camera.to_camera("").position;
    assert_eq!(harness.state().highlight_eye, Some(eye), "computed for the view");
    let before = highlights(&harness);
    assert!(before.iter().any(|c| c[0] > 0.01), "the glossy floor reflects the light");
    harness.render().unwrap().save(state_dir().join("area_highlights_before.png")).expect("screenshot");

    let rect = harness.state().viewport_rect;
    let centre = rect.center();
    pointer_drag(&mut harness, egui::PointerButton::Secondary, centre, centre + egui::vec2(120.0, 0.0));
    let moved = harness.state().view.camera.to_camera("").position;
    assert_ne!(moved, eye, "the right-drag orbits");
    harness.step();
    assert_eq!(harness.state().highlight_eye, Some(eye), "not while the camera may still move");
    rest(&mut harness);
    assert_eq!(harness.state().highlight_eye, Some(moved));
    let after = highlights(&harness);
    let ran = computed_stages(&harness);
    assert!(ran.contains(&"output.area_highlights".to_string()), "{ran:?}");
    assert!(!ran.iter().any(|s| s.ends_with("area_transport") || s.ends_with("area_irradiance")), "{ran:?}");
    let change = before.iter().zip(&after).map(|(a, b)| (a[0] - b[0]).abs()).fold(0.0, f32::max);
    let peak = before.iter().map(|c| c[0]).fold(0.0, f32::max);
    assert!(change > 0.2 * peak, "the highlights move with the view: change {change}, peak {peak}");
    harness.render().unwrap().save(state_dir().join("area_highlights_after.png")).expect("screenshot");
}
