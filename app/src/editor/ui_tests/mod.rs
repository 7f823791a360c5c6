//! UI tests: the real editor driven through egui_kittest (headless, rendered by wgpu on
//! lavapipe): add a node from the Shift+A menu, link it from the inspector, edit a parameter,
//! undo, save and reopen; refused links say why.

use super::*;
use eframe::egui::accesskit::Role;
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;
use std::path::Path;

mod adaptive;
mod area_light;
mod bake;
mod blockers;
mod fitted_spheres;
mod normal_maps;
mod wavelet;

fn state_dir() -> PathBuf {
    document::test_state_dir()
}

/// The default project evaluated and drawn, with no recovery question in the way (tests
/// running beside this one may leave autosaves behind).
fn default_harness() -> Harness<'static, EditorApp> {
    let mut harness = harness(None);
    settle(&mut harness);
    harness.state_mut().pending = None;
    harness.run_steps(1);
    harness
}

fn harness(project: Option<PathBuf>) -> Harness<'static, EditorApp> {
    harness_with_options(EditorOptions { project, no_disk_cache: true, ..Default::default() })
}

fn harness_with_options(options: EditorOptions) -> Harness<'static, EditorApp> {
    state_dir();
    let untitled = options.project.is_none();
    let mut setup = eframe::egui_wgpu::WgpuSetupCreateNew::without_display_handle();
    setup.device_descriptor = Arc::new(lightloom_render::device_descriptor);
    let mut harness = Harness::builder()
        .with_size(egui::vec2(1400.0, 800.0))
        .with_max_steps(100_000)
        .wgpu_setup(eframe::egui_wgpu::WgpuSetup::CreateNew(setup))
        .build_eframe(move |cc| EditorApp::new(&cc.egui_ctx, options).expect("editor starts"));
    // Untitled documents share one recovery file, which tests running beside this one may
    // leave behind: their recovery question (a modal that dims the viewport) is not ours.
    if untitled && matches!(harness.state().pending, Some(Pending::Recover(..))) {
        harness.state_mut().pending = None;
    }
    harness
}

/// Steps until the evaluation is done and its frame drawn.
fn settle(harness: &mut Harness<'_, EditorApp>) {
    let start = Instant::now();
    let mut quiet = 0;
    loop {
        harness.step();
        let app = harness.state();
        let drawing = app.host.as_ref().is_some_and(|h| h.is_busy());
        let done = !app.evaluator.is_running() && app.view.frame.is_some() && app.view.drawn != 0 && !drawing;
        // Two quiet passes in a row: a frame that just arrived may ask for the next one.
        quiet = if done { quiet + 1 } else { 0 };
        if quiet >= 2 {
            break;
        }
        assert!(start.elapsed() < Duration::from_secs(240), "the editor did not finish evaluating");
        std::thread::sleep(Duration::from_millis(10));
    }
    harness.step();
}

/// `node.stage` of every stage the last evaluation computed.
fn computed_stages(harness: &Harness<'_, EditorApp>) -> Vec<String> {
    let report = &harness.state().evaluator.last.as_ref().expect("an evaluation").0.report;
    report
        .stages
        .iter()
        .filter(|s| s.status == lightloom_nodes::engine::StageStatus::Computed)
        .map(|s| format!("{}.{}", s.node, s.stage))
        .collect()
}

/// Adds a node from the Add menu by (part of) its entry's label; returns its id.
fn add_from_menu(harness: &mut Harness<'_, EditorApp>, entry: &str) -> String {
    let before: Vec<String> = harness.state().doc.project.nodes.iter().map(|n| n.id.clone()).collect();
    harness.get_by_label("Add").click();
    harness.run_steps(2);
    harness.get_by_label_contains(entry).click();
    harness.run_steps(4);
    harness.state().doc.project.nodes.iter().find(|n| !before.contains(&n.id)).expect("a node was added").id.clone()
}

/// Opens the combo box labelled `combo` and clicks its entry labelled `item`, else the one
/// whose label contains it (the popup's, not a label that was there before it opened). A
/// pointer click lands where the widget was last drawn, so a layout that moves under it (a
/// preview arriving) can miss; the popup is reopened until the entry shows, at most three
/// times.
fn pick(harness: &mut Harness<'_, EditorApp>, combo: &str, item: &str) {
    let counts =
        |h: &Harness<'_, EditorApp>| (h.query_all_by_label(item).count(), h.query_all_by_label_contains(item).count());
    for _ in 0..3 {
        let before = counts(harness);
        harness.get_by_role_and_label(Role::ComboBox, combo).click();
        for _ in 0..12 {
            harness.step();
            if counts(harness) == before {
                continue;
            }
            // A popup's first frame only sizes it: its entries are where they will be drawn
            // once it has been laid out for real.
            harness.run_steps(2);
            let now = counts(harness);
            let entry = if now.0 > before.0 {
                harness.query_all_by_label(item).last()
            } else if now.1 > before.1 {
                harness.query_all_by_label_contains(item).last()
            } else {
                None
            };
            if let Some(entry) = entry {
                entry.click();
                harness.run_steps(2);
                return;
            }
        }
        // Closed or never opened: let the layout settle before trying again.
        harness.key_press(egui::Key::Escape);
        harness.run_steps(2);
    }
    panic!("the {combo:?} list shows no entry {item:?}");
}

/// Mean sRGB value of the viewport's render frame in a screenshot.
fn viewport_mean(harness: &mut Harness<'_, EditorApp>) -> f64 {
    let rect = harness.state().render_frame(harness.state().viewport_rect).shrink(1.0);
    let image = harness.render().expect("the UI renders through wgpu");
    let ppp = harness.ctx.pixels_per_point();
    let (x0, y0) = ((rect.left() * ppp) as u32, (rect.top() * ppp) as u32);
    let (x1, y1) = ((rect.right() * ppp) as u32 - 1, (rect.bottom() * ppp) as u32 - 1);
    let mut sum = 0.0;
    let mut n = 0.0;
    for y in (y0..y1).step_by(3) {
        for x in (x0..x1).step_by(3) {
            let p = image.get_pixel(x, y);
            sum += f64::from(p[0]) + f64::from(p[1]) + f64::from(p[2]);
            n += 3.0;
        }
    }
    sum / n
}

fn output_exposure(app: &EditorApp) -> f64 {
    match edits::node(&app.doc.project, "output").and_then(|n| n.params.get("exposure")) {
        Some(ParamValue::Float(v)) => *v,
        _ => 0.0,
    }
}

#[test]
fn add_link_edit_undo_save_and_reopen() {
    let mut harness = harness(None);
    settle(&mut harness);
    let lit = viewport_mean(&mut harness);
    assert!(lit > 20.0, "the viewport shows a lit scene (mean sRGB {lit:.1})");
    // What the window shows is what the renderer wrote (no colour-space slip on the way).
    let written = harness.state().host.as_ref().unwrap().capture_ldr().unwrap();
    let (w, h) = harness.state().host.as_ref().unwrap().size;
    let (panel, frame) = (harness.state().viewport_rect, harness.state().render_frame(harness.state().viewport_rect));
    let inside = frame.shrink(1.0);
    let mut sum = 0.0;
    let mut n = 0.0;
    for y in 0..h {
        for x in 0..w {
            let at = panel.min
                + egui::vec2((x as f32 + 0.5) / w as f32 * panel.width(), (y as f32 + 0.5) / h as f32 * panel.height());
            if inside.contains(at) {
                let p = written[(y * w + x) as usize];
                sum += f64::from(p[0]) + f64::from(p[1]) + f64::from(p[2]);
                n += 3.0;
            }
        }
    }
    let written = sum / n;
    assert!((written - lit).abs() < 3.0, "the viewport shows {lit:.1}, the renderer wrote {written:.1} (mean sRGB)");
    let nodes_before = harness.state().doc.project.nodes.len();

    // Add: Shift+A over the graph, search, pick.
    let graph_point = egui::pos2(150.0, 500.0);
    harness.hover_at(graph_point);
    harness.step();
    harness.key_press_modifiers(egui::Modifiers::SHIFT, egui::Key::A);
    harness.step();
    harness.step();
    // The menu's search field has the keyboard focus.
    harness.get_by(|n| n.role() == Role::TextInput && n.is_focused()).type_text("point");
    harness.step();
    harness.get_by_label_contains("Point light").click();
    harness.run_steps(2);
    let app = harness.state();
    assert_eq!(app.doc.project.nodes.len(), nodes_before + 1);
    let added = app.doc.project.nodes.last().unwrap().clone();
    assert_eq!(added.kind, "PointLight");
    assert_eq!(app.selection, Selection::Node(added.id.clone()), "the new node is selected");

    // Link: select the Output node, link its `lights` input from the inspector.
    harness.state_mut().selection = Selection::Node("output".into());
    settle(&mut harness);
    pick(&mut harness, "lights (Lights)", &format!("{}.lights", added.id));
    let linked = harness
        .state()
        .doc
        .project
        .links
        .iter()
        .any(|l| l.from == (added.id.clone(), "lights".into()) && l.to == ("output".into(), "lights".into()));
    assert!(linked, "the inspector linked the point light into the output");
    settle(&mut harness);
    let lit_before = lit;
    let lit = viewport_mean(&mut harness);
    assert!(lit > lit_before + 1.0, "the linked point light adds light: {lit_before:.1} → {lit:.1}");

    // Edit: +2 EV exposure from the viewport toolbar; the viewport gets brighter.
    // (The inspector, drawn first, shows the Output's exposure too: the toolbar's is last.)
    harness.key_press(egui::Key::Escape);
    harness.step();
    harness
        .query_all_by(|n| n.role() == Role::SpinButton && n.label().as_deref() == Some("Exposure"))
        .last()
        .expect("the toolbar's exposure field")
        .click();
    harness.step();
    harness.step();
    harness.event(egui::Event::Text("2".into()));
    harness.step();
    harness.key_press(egui::Key::Enter);
    harness.step();
    settle(&mut harness);
    assert_eq!(output_exposure(harness.state()), 2.0);
    let brighter = viewport_mean(&mut harness);
    assert!(brighter > lit * 1.15, "+2 EV must brighten the viewport: {lit:.1} → {brighter:.1}");
    assert!(harness.state().doc.is_dirty());

    // Undo (Ctrl+Z) restores the exposure and the image.
    harness.hover_at(graph_point);
    harness.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    settle(&mut harness);
    assert_eq!(output_exposure(harness.state()), 0.0);
    let restored = viewport_mean(&mut harness);
    assert!((restored - lit).abs() < 2.0, "undo restores the image: {lit:.1} vs {restored:.1}");

    // Save (Ctrl+S) to the document's path, then reopen it in a new editor.
    let path = state_dir().join("saved.ron");
    harness.state_mut().doc.path = Some(path.clone());
    harness.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::S);
    harness.step();
    assert!(!harness.state().doc.is_dirty(), "saved");
    assert!(harness.state().doc.title().contains("saved.ron") && !harness.state().doc.title().starts_with('●'));
    let saved = harness.state().doc.project.clone();
    drop(harness);

    let mut reopened =
        harness_with_options(EditorOptions { project: Some(path.clone()), no_disk_cache: true, ..Default::default() });
    settle(&mut reopened);
    assert_eq!(reopened.state().doc.project, saved, "the saved project reopens unchanged");
    reopened.get_by_label_contains(&format!("{} · Point light", added.id));
    let again = viewport_mean(&mut reopened);
    assert!((again - lit).abs() < 2.0, "the reopened project renders the same: {lit:.1} vs {again:.1}");
}

#[test]
fn refused_links_say_why_and_edits_are_undoable() {
    let mut harness = harness(None);
    settle(&mut harness);
    // What the graph widget reports when a wire is dropped on an input of another type.
    let reason = edits::check_link(
        &harness.state().doc.project,
        &("sky".into(), "environment".into()),
        &("output".into(), "scene".into()),
    )
    .unwrap_err();
    harness.state_mut().apply(vec![GraphAction::Refused(reason.clone())]);
    harness.step();
    let before = harness.state().doc.project.clone();
    assert!(harness.state().graph.notice.as_ref().is_some_and(|(t, _)| t == &reason));
    assert_eq!(harness.state().doc.undo_label(), None, "a refused link changes nothing");

    // Delete, duplicate and paste are each one undo step.
    harness.state_mut().apply(vec![GraphAction::Duplicate(vec!["material".into()])]);
    harness.state_mut().apply(vec![GraphAction::Remove(vec!["sky".into()])]);
    harness.step();
    let app = harness.state();
    assert_eq!(app.doc.project.nodes.len(), before.nodes.len());
    assert!(app.doc.project.links.iter().all(|l| l.from.0 != "sky"));
    assert!(!app.graph_errors.is_empty() || app.doc.project.graph(Path::new("x.ron")).is_ok());
    harness.state_mut().undo();
    harness.state_mut().undo();
    harness.step();
    assert_eq!(harness.state().doc.project, before);
}

#[test]
fn offers_to_recover_autosaved_work_after_a_crash() {
    let dir = state_dir().join("recovery-test");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("crashed.ron");
    let project = lightloom_nodes::project::default_project();
    project.save(&path).unwrap();
    // The session that crashed had renamed the project and autosaved.
    let mut unsaved = project.clone();
    unsaved.name = "unsaved work".into();
    let recovery = document::recovery_path(Some(&path));
    std::fs::create_dir_all(recovery.parent().unwrap()).unwrap();
    std::thread::sleep(Duration::from_millis(20));
    unsaved.save_without_backup(&recovery).unwrap();

    let mut harness = harness(Some(path.clone()));
    harness.run_steps(2);
    harness.get_by_label("Recover unsaved work?");
    harness.get_by_label("Recover").click();
    harness.run_steps(2);
    let app = harness.state();
    assert_eq!(app.doc.project.name, "unsaved work", "the autosaved project is back");
    assert!(app.doc.is_dirty(), "recovered work is unsaved until saved");
    assert_eq!(app.doc.path.as_deref(), Some(path.as_path()));
    // Undo returns to the file's contents.
    harness.state_mut().undo();
    assert_eq!(harness.state().doc.project, project);
}

/// Asks the window to close, as the window manager's close button does.
fn request_close(harness: &mut Harness<'_, EditorApp>) {
    harness.input_mut().viewports.entry(egui::ViewportId::ROOT).or_default().events.push(egui::ViewportEvent::Close);
    harness.step();
}

#[test]
fn closing_with_unsaved_work_asks_first() {
    let mut harness = harness(None);
    settle(&mut harness);
    // Nothing unsaved: closing needs no question.
    request_close(&mut harness);
    assert!(harness.query_by_label("Save changes?").is_none());
    let output = "output".to_string();
    inspector::set_param(&mut harness.state_mut().doc, &output, "exposure", ParamValue::Float(1.0)).unwrap();
    // Let the edit's evaluation finish (its status-bar Cancel would be a second "Cancel").
    settle(&mut harness);
    assert!(harness.state().doc.title().starts_with('●'), "the title marks unsaved changes");
    request_close(&mut harness);
    harness.run_steps(2);
    harness.get_by_label("Save changes?");
    harness.get_by_label("Cancel").click();
    harness.run_steps(2);
    assert!(harness.query_by_label("Save changes?").is_none());
    assert!(!harness.state().close_confirmed, "cancel keeps the editor open");
    request_close(&mut harness);
    harness.run_steps(2);
    harness.get_by_label("Discard changes").click();
    harness.run_steps(2);
    assert!(harness.state().close_confirmed, "discarding lets the window close");
}

#[test]
fn the_ui_stays_responsive_while_a_slow_viewport_frame_renders() {
    // Every viewport frame takes 1.5 s, as on a slow adapter; the UI must not wait for it.
    let slow = Duration::from_millis(1500);
    let mut harness =
        harness_with_options(EditorOptions { no_disk_cache: true, viewport_slow_down: slow, ..Default::default() });
    settle(&mut harness);
    let shown = harness.state().view.drawn;
    // Orbit: a new frame is requested and renders on the viewport thread.
    harness.state_mut().view.camera.orbit((40.0, 10.0), 600.0);
    harness.step();
    assert!(harness.state().host.as_ref().unwrap().is_busy(), "the new frame is rendering");
    let mut passes = Vec::new();
    let start = Instant::now();
    while start.elapsed() < Duration::from_millis(800) {
        let t = Instant::now();
        harness.step();
        passes.push(t.elapsed().as_secs_f64() * 1e3);
    }
    // Meanwhile the last finished frame stays on screen, and the slow one is still rendering.
    assert_eq!(harness.state().view.drawn, shown, "the previous frame stays on screen");
    assert!(harness.state().host.as_ref().unwrap().is_busy());
    passes.sort_by(f64::total_cmp);
    let median = passes[passes.len() / 2];
    assert!(passes.len() >= 10, "only {} UI passes in 0.8 s: the UI waits for the viewport", passes.len());
    assert!(median < 16.0, "median UI pass {median:.1} ms while the viewport renders ({passes:?})");
    // And the new frame arrives.
    let start = Instant::now();
    while harness.state().view.drawn == shown {
        harness.step();
        std::thread::sleep(Duration::from_millis(10));
        assert!(start.elapsed() < Duration::from_secs(60), "the slow frame never arrived");
    }
}

/// A save that fails (here: the folder is a file; in life, a full disk or a lost network
/// share) shows an error in the Problems panel and keeps the work unsaved, so nothing is lost.
#[test]
fn a_failed_save_is_shown_and_keeps_the_work_unsaved() {
    let mut harness = harness(None);
    settle(&mut harness);
    let blocker = state_dir().join("not-a-folder");
    std::fs::write(&blocker, "a file where a folder should be").unwrap();
    harness
        .state_mut()
        .doc
        .edit("test edit", None, |p| {
            p.cameras[0].fov_y_deg = 50.0;
            Ok(())
        })
        .unwrap();
    harness.state_mut().doc.path = Some(blocker.join("project.ron"));
    harness.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::S);
    harness.run_steps(3);
    assert!(harness.state().doc.is_dirty(), "the work stays marked unsaved");
    harness.get_by_label_contains("not-a-folder/project.ron");
    assert!(!blocker.join("project.ron").exists());
}

/// A node that feeds no output never blocks the rest: a saved project with an unlinked RSL
/// decomposer (its required environment input unconnected) reopens and renders, and the
/// unconnected input is listed as a warning, not a silent spinner.
#[test]
fn an_unlinked_node_with_a_missing_input_does_not_block_rendering() {
    let mut project = lightloom_nodes::project::default_project();
    project.nodes.push(lightloom_nodes::project::ProjectNode {
        id: "rsl".into(),
        kind: "RslDecomposer".into(),
        label: String::new(),
        position: [40.0, 400.0],
        params: Default::default(),
    });
    let path = state_dir().join("unlinked.ron");
    project.save(&path).unwrap();
    let mut harness = harness(Some(path));
    settle(&mut harness);
    let problems = harness.state().problems();
    assert!(
        problems.iter().any(|p| p.starts_with("warning:") && p.contains("rsl") && p.contains("not connected")),
        "{problems:?}"
    );
    assert!(harness.state().evaluator.last.is_some(), "the project evaluated");
    assert!(viewport_mean(&mut harness) > 20.0, "the scene is drawn");
}

/// Undo after moving nodes restores the old positions and offers Redo; it used to redo the
/// move at once (the widget still showed the moved node and wrote it back as a new move).
#[test]
fn undo_after_moving_a_node_sticks() {
    let mut harness = harness(None);
    settle(&mut harness);
    let position =
        |h: &Harness<'_, EditorApp>| h.state().doc.project.nodes.iter().find(|n| n.id == "sky").unwrap().position;
    let before = position(&harness);
    harness.state_mut().graph.move_in_widget("sky", [before[0] + 120.0, before[1] + 40.0]);
    harness.run_steps(2);
    assert_eq!(position(&harness), [before[0] + 120.0, before[1] + 40.0]);
    assert_eq!(harness.state().doc.undo_label(), Some("Move nodes"));
    harness.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    harness.run_steps(4);
    assert_eq!(position(&harness), before, "undo restores the position and it stays");
    assert_eq!(harness.state().doc.undo_label(), None);
    assert_eq!(harness.state().doc.redo_label(), Some("Move nodes"));
}

/// Choosing an environment file uses it: the node's source switches to `file` in the same
/// undo step (it stayed on the procedural sky, so nothing changed on screen).
#[test]
fn choosing_an_environment_file_uses_it() {
    let hdr = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/envmaps/courtyard.hdr");
    let mut harness = default_harness();
    harness.state_mut().selection = Selection::Node("sky".into());
    harness.run_steps(2);
    let field = harness.get_by_role_and_label(Role::TextInput, "File");
    field.click();
    harness.run_steps(1);
    harness.get_by_role_and_label(Role::TextInput, "File").type_text(&hdr.display().to_string());
    harness.key_press(egui::Key::Enter);
    harness.run_steps(2);
    let sky = harness.state().doc.project.nodes.iter().find(|n| n.id == "sky").unwrap().clone();
    assert_eq!(sky.params.get("source"), Some(&ParamValue::Choice("file".into())), "{:?}", sky.params);
    assert_eq!(sky.params.get("file"), Some(&ParamValue::Path(hdr.display().to_string())));
    harness.state_mut().undo();
    let sky = harness.state().doc.project.nodes.iter().find(|n| n.id == "sky").unwrap().clone();
    assert_ne!(sky.params.get("source"), Some(&ParamValue::Choice("file".into())), "one undo step takes both back");
}

/// The relighting modes say in plain words what they show and cost (menus and tooltips), and
/// the status bar reads durations as a person would.
#[test]
fn modes_are_explained_in_plain_language() {
    let mut harness = default_harness();
    harness.get_by_role_and_label(Role::ComboBox, "Mode").click();
    harness.run_steps(2);
    for label in [
        "Soft light, no shadows (sh_irradiance)",
        "Soft shadows and gloss (sh_prt)",
        "Sharp shadows, per pixel (wavelet_pixel)",
    ] {
        harness.get_by_label_contains(label);
    }
    // "evaluated in 1.9 s", not "evaluated in 1873 ms".
    let took = harness.state().evaluator.last.as_ref().map(|(e, _)| e.report.total_ms).unwrap_or_default();
    let shown = crate::project_commands::duration_text(took / 1e3);
    assert!(took < 1000.0 || !shown.ends_with("ms"), "{shown}");
    harness.key_press(egui::Key::Escape);
    harness.run_steps(1);
    harness.get_by_label_contains(&format!("evaluated in {shown}"));
}

/// A node added from the Add menu lands in view without covering another node, and is the
/// node the inspector shows (it landed on the Output node, and the inspector kept showing the
/// node selected in the graph before).
#[test]
fn a_node_from_the_add_menu_lands_in_view_and_is_selected() {
    let mut harness = default_harness();
    let before: Vec<String> = harness.state().doc.project.nodes.iter().map(|n| n.id.clone()).collect();
    harness.get_by_label("Add").click();
    harness.run_steps(2);
    harness.get_by_label_contains("Point light").click();
    harness.run_steps(4);
    let project = &harness.state().doc.project;
    let added = project.nodes.iter().find(|n| !before.contains(&n.id)).expect("a node was added").clone();
    for other in project.nodes.iter().filter(|n| n.id != added.id) {
        let apart = (other.position[0] - added.position[0]).abs() >= 190.0
            || (other.position[1] - added.position[1]).abs() >= 110.0;
        assert!(apart, "{} at {:?} covers {} at {:?}", added.id, added.position, other.id, other.position);
    }
    assert_eq!(harness.state().selection, Selection::Node(added.id.clone()));
    let header = harness.get_by_label_contains(&format!("{} · Point light", added.id)).rect();
    let graph = harness.state().graph_rect;
    assert!(graph.contains(header.center()), "the new node at {header:?} is outside the graph view {graph:?}");
}

/// The error view carries its colour scale, in linear radiance, and its numbers sit on a
/// backing (white text on a bright sky was unreadable).
#[test]
fn the_error_view_has_a_colour_scale() {
    let mut harness = default_harness();
    for (param, value) in [("reference_samples", ParamValue::Int(4)), ("view", ParamValue::Choice("error".into()))] {
        inspector::set_param(&mut harness.state_mut().doc, "output", param, value).unwrap();
    }
    let start = Instant::now();
    while harness.state().view.error_scale.is_none() {
        assert!(start.elapsed().as_secs() < 240, "the error view never finished");
        harness.step();
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    harness.run_steps(3);
    let scale = harness.state().view.error_scale.unwrap();
    assert!(scale > 0.0 && scale.is_finite(), "{scale}");
    if let Ok(dir) = std::env::var("LIGHTLOOM_SCREENSHOTS") {
        harness.render().unwrap().save(Path::new(&dir).join("error-view.png")).unwrap();
    }
}

/// Presses a pointer button at `from`, moves to `to` in steps and releases there.
fn pointer_drag(harness: &mut Harness<'_, EditorApp>, button: egui::PointerButton, from: egui::Pos2, to: egui::Pos2) {
    pointer_drag_with(harness, button, from, to, egui::Modifiers::NONE);
}

/// [`pointer_drag`] with `modifiers` held from the press to the release.
fn pointer_drag_with(
    harness: &mut Harness<'_, EditorApp>,
    button: egui::PointerButton,
    from: egui::Pos2,
    to: egui::Pos2,
    modifiers: egui::Modifiers,
) {
    let press = |pos, pressed| egui::Event::PointerButton { pos, button, pressed, modifiers };
    harness.hover_at(from);
    harness.step();
    harness.event(egui::Event::ModifiersChanged(modifiers));
    harness.event(press(from, true));
    harness.step();
    for i in 1..=6 {
        harness.hover_at(from + (to - from) * (i as f32 / 6.0));
        harness.step();
    }
    harness.event(press(to, false));
    harness.event(egui::Event::ModifiersChanged(egui::Modifiers::NONE));
    harness.step();
    harness.step();
}

/// A quick click (egui counts a press held longer than 0.8 s as no click).
fn pointer_click(harness: &mut Harness<'_, EditorApp>, at: egui::Pos2) {
    let press = |pressed| egui::Event::PointerButton {
        pos: at,
        button: egui::PointerButton::Primary,
        pressed,
        modifiers: egui::Modifiers::NONE,
    };
    harness.hover_at(at);
    harness.step();
    harness.event(press(true));
    harness.step();
    harness.event(press(false));
    harness.step();
    harness.step();
}

/// The graph takes Blender's pointer bindings: a click selects one node and the inspector
/// follows; dragging the header moves the node (the title is not selected as text); a left
/// drag on empty space box-selects; a click on empty space clears; a middle drag pans.
#[test]
fn graph_nodes_select_on_click_move_by_header_and_box_select() {
    let mut harness = default_harness();
    let rect = |h: &Harness<'_, EditorApp>, id: &str| h.state().graph.node_rect(id).expect("node drawn");
    let position = |h: &Harness<'_, EditorApp>, id: &str| {
        h.state().doc.project.nodes.iter().find(|n| n.id == id).unwrap().position
    };

    // Click on a node's header: it alone is selected and the inspector shows it.
    let sky = rect(&harness, "sky");
    pointer_click(&mut harness, sky.center_top() + egui::vec2(0.0, 14.0));
    assert_eq!(harness.state().graph.selected, vec!["sky".to_string()]);
    assert_eq!(harness.state().selection, Selection::Node("sky".into()));
    let material = rect(&harness, "material");
    pointer_click(&mut harness, material.center());
    assert_eq!(harness.state().graph.selected, vec!["material".to_string()], "a plain click replaces the selection");
    assert_eq!(harness.state().selection, Selection::Node("material".into()));

    // Drag the header: the node moves by the drag (in graph units) as one undo step.
    let before = position(&harness, "output");
    let grab = rect(&harness, "output").center_top() + egui::vec2(0.0, 12.0);
    pointer_drag(&mut harness, egui::PointerButton::Primary, grab, grab + egui::vec2(60.0, 30.0));
    let after = position(&harness, "output");
    assert!(after[0] > before[0] + 20.0 && after[1] > before[1] + 10.0, "header drag moves: {before:?} → {after:?}");
    assert_eq!(harness.state().doc.undo_label(), Some("Move nodes"));

    // Box select: a left drag on empty space around two nodes selects both.
    let (sky, scene) = (rect(&harness, "sky"), rect(&harness, "scene"));
    let around = sky.union(scene).expand(12.0);
    let others: Vec<_> = ["material", "output"].iter().filter_map(|id| harness.state().graph.node_rect(id)).collect();
    assert!(others.iter().all(|r| !r.intersects(around)), "the default layout leaves room for the box");
    let positions_before = harness.state().doc.project.nodes.clone();
    pointer_drag(&mut harness, egui::PointerButton::Primary, around.left_top(), around.right_bottom());
    let mut selected = harness.state().graph.selected.clone();
    selected.sort();
    assert_eq!(selected, vec!["scene".to_string(), "sky".to_string()]);
    assert_eq!(harness.state().doc.project.nodes, positions_before, "a box selection moves nothing");

    // A click on empty space clears the selection.
    let empty = harness.state().graph_rect.right_bottom() - egui::vec2(40.0, 40.0);
    assert!(harness.state().doc.project.nodes.iter().all(|n| !rect(&harness, &n.id).contains(empty)));
    pointer_click(&mut harness, empty);
    assert!(harness.state().graph.selected.is_empty());

    // A middle drag pans the view: every node moves on screen, none in the project.
    let sky_before = rect(&harness, "sky");
    pointer_drag(&mut harness, egui::PointerButton::Middle, empty, empty - egui::vec2(40.0, 25.0));
    let sky_after = rect(&harness, "sky");
    assert!((sky_after.min - sky_before.min + egui::vec2(40.0, 25.0)).length() < 3.0, "{sky_before:?} → {sky_after:?}");
    assert_eq!(harness.state().doc.project.nodes, positions_before);
    let path = state_dir().join("graph-gestures.png");
    harness.render().unwrap().save(&path).unwrap();
}

/// Mean of `image` over the cells of a `cols`×`rows` grid laid on `rect` (sRGB, 0..255 per
/// channel).
fn cell_means(sample: impl Fn(f32, f32) -> [u8; 4], rect: egui::Rect, cols: usize, rows: usize) -> Vec<[f64; 3]> {
    let mut cells = vec![[0.0; 3]; cols * rows];
    let per_cell = 6;
    for (i, cell) in cells.iter_mut().enumerate() {
        let (cx, cy) = (i % cols, i / cols);
        for sy in 0..per_cell {
            for sx in 0..per_cell {
                let u = (cx as f32 + (sx as f32 + 0.5) / per_cell as f32) / cols as f32;
                let v = (cy as f32 + (sy as f32 + 0.5) / per_cell as f32) / rows as f32;
                let p = sample(rect.left() + u * rect.width(), rect.top() + v * rect.height());
                for c in 0..3 {
                    cell[c] += f64::from(p[c]) / (per_cell * per_cell) as f64;
                }
            }
        }
    }
    cells
}

/// The view the user framed is saved with the project, the editor reopens on it, and the
/// CLI render of the saved file matches what the viewport showed inside its render frame.
#[test]
fn the_saved_view_is_what_the_cli_renders() {
    let mut editor = default_harness();
    // Orbit and dolly away from the project's camera, as a user framing a shot would.
    editor.state_mut().view.camera.orbit((90.0, -30.0), 600.0);
    editor.state_mut().view.camera.zoom(0.8);
    editor.step();
    settle(&mut editor);
    let framed = editor.state().view.camera;
    let frame = editor.state().render_frame(editor.state().viewport_rect);
    let screenshot = editor.render().unwrap();
    let ppp = editor.ctx.pixels_per_point();
    let shown = cell_means(|x, y| screenshot.get_pixel((x * ppp) as u32, (y * ppp) as u32).0, frame.shrink(1.0), 16, 9);

    // "Render what I see": File → Render image… renders the same picture.
    let png = state_dir().join("framed-render.png");
    editor.state_mut().render_image_to(png.clone());
    let start = Instant::now();
    while editor.state().image_render.is_some() {
        assert!(start.elapsed() < Duration::from_secs(240), "the image render finished");
        editor.step();
        std::thread::sleep(Duration::from_millis(20));
    }
    let written = image::open(&png).expect("the render wrote a PNG").to_rgba8();
    let written_cells = cell_means(
        |x, y| written.get_pixel((x as u32).min(written.width() - 1), (y as u32).min(written.height() - 1)).0,
        egui::Rect::from_min_size(egui::Pos2::ZERO, egui::vec2(written.width() as f32, written.height() as f32)),
        16,
        9,
    );

    let path = state_dir().join("framed.ron");
    editor.state_mut().doc.path = Some(path.clone());
    editor.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::S);
    editor.step();
    drop(editor);

    // The CLI's path: load the file, evaluate, render at the project's render size.
    let (project, graph) = crate::project_commands::load(&path, &[]).unwrap();
    let engine = Arc::new(Engine::new(EngineConfig { disk_cache: None, ..Default::default() }));
    let rendered =
        crate::project_commands::render_project(&project, &graph, engine, None, None, (None, None), true).unwrap();
    let image = &rendered.frame;
    let rendered_cells = cell_means(
        |x, y| {
            image.ldr[(y as usize).min(image.height as usize - 1) * image.width as usize
                + (x as usize).min(image.width as usize - 1)]
        },
        egui::Rect::from_min_size(egui::Pos2::ZERO, egui::vec2(image.width as f32, image.height as f32)),
        16,
        9,
    );
    for (what, cells) in [("CLI render", &rendered_cells), ("Render image…", &written_cells)] {
        let differences: Vec<f64> =
            shown.iter().zip(cells).flat_map(|(a, b)| (0..3).map(move |c| (a[c] - b[c]).abs())).collect();
        let mean = differences.iter().sum::<f64>() / differences.len() as f64;
        let worst = differences.iter().cloned().fold(0.0, f64::max);
        assert!(
            mean < 3.0 && worst < 24.0,
            "viewport vs {what}: mean cell difference {mean:.2}, worst {worst:.1} (sRGB)"
        );
    }

    // The editor reopens on the framed view.
    let reopened = harness(Some(path));
    let view = reopened.state().view.camera;
    assert!((view.position() - framed.position()).length() < 1e-9 && (view.target - framed.target).length() < 1e-9);
}

/// A glTF model is imported as an object: the Add menu offers it, it joins the Objects list
/// (selected, resting on the floor at the origin, the view framed on it), its size is shown
/// and its units set its scale; it renders and can be picked in the viewport.
#[test]
fn a_gltf_model_is_an_object_in_the_list_and_framed() {
    let model = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../assets/gltf/assimp-glTF2/BoxTextured-glTF-Binary/BoxTextured.glb");
    let mut harness = default_harness();
    harness.state_mut().selection = Selection::Node("scene".into());
    harness.run_steps(2);
    harness.get_by_label("+ Add").click();
    harness.run_steps(2);
    harness.get_by_label("glTF model…").click();
    harness.run_steps(2);
    assert!(
        matches!(
            &harness.state().file_action,
            Some(FileAction::Browse { target: inspector::FileTarget::NewModel, .. })
        ),
        "the menu asks for a model file"
    );
    assert!(harness.state().asset_dialog.is_some(), "a file dialog is open");
    // What the file dialog does with the file picked.
    harness.state_mut().asset_dialog = None;
    harness.state_mut().file_action = None;
    let before = harness.state().view.camera;
    harness.state_mut().import_model("scene", &model.display().to_string()).unwrap();
    let objects = match edits::node(&harness.state().doc.project, "scene").and_then(|n| n.params.get("objects")) {
        Some(ParamValue::Objects(o)) => o.clone(),
        _ => panic!("the scene lists objects"),
    };
    let imported = objects.last().unwrap();
    assert_eq!(imported.name, "BoxTextured");
    assert!(matches!(imported.shape, lightloom_nodes::kinds::scene::Shape::Gltf { .. }));
    assert_eq!(harness.state().view.selected_object, Some(objects.len() - 1));
    assert_eq!(harness.state().doc.undo_label(), Some("Import BoxTextured"));
    let framed = harness.state().view.camera;
    assert!(framed.target != before.target && framed.distance < before.distance, "the view frames the model");
    settle(&mut harness);

    // It renders: its parts are in the scene, resting on the floor at the origin.
    let meshes = harness
        .state()
        .view
        .frame
        .as_ref()
        .unwrap()
        .geometry
        .meshes
        .value
        .get::<lightloom_nodes::mesh::MeshSet>()
        .unwrap()
        .clone();
    let parts: Vec<_> = meshes.meshes.iter().filter(|m| m.name.starts_with("BoxTextured/")).collect();
    assert!(!parts.is_empty());
    let (lo, hi) = lightloom_nodes::mesh::union_bounds(parts.iter().copied());
    assert!(lo[1].abs() < 1e-4 && (lo[0] + hi[0]).abs() < 1e-4 && (lo[2] + hi[2]).abs() < 1e-4, "{lo:?} {hi:?}");
    // The Objects list shows it, with its size; units set a uniform scale.
    harness.get_by_label_contains("1.00 × 1.00 × 1.00 m");
    pick(&mut harness, "Units", "centimetres");
    let objects = match edits::node(&harness.state().doc.project, "scene").and_then(|n| n.params.get("objects")) {
        Some(ParamValue::Objects(o)) => o.clone(),
        _ => panic!("the scene lists objects"),
    };
    assert_eq!(objects.last().unwrap().scale, [0.01; 3]);
    harness.state_mut().undo();
    settle(&mut harness);
    // Clicking the model in the viewport selects it.
    harness.state_mut().view.selected_object = None;
    let frame = harness.state().render_frame(harness.state().viewport_rect);
    let (rect, camera) =
        (harness.state().viewport_rect, harness.state().viewport_camera(harness.state().viewport_rect));
    let at = gizmos::screen_pos(&camera, rect, [0.0, 0.5, 0.0]).expect("in front of the camera");
    assert!(frame.contains(at));
    harness.state_mut().pick(at, rect);
    assert_eq!(harness.state().view.selected_object, Some(objects.len() - 1), "picking the model selects its object");
    harness.render().unwrap().save(state_dir().join("gltf-object.png")).unwrap();
}

/// Point lights have gizmos: a linked light is drawn where it is; clicking it selects its
/// node; dragging it moves the light in the view plane as one undo step, and the lighting
/// follows.
#[test]
fn a_light_gizmo_drag_moves_the_light() {
    light_gizmo_drag("PointLight", &[]);
}

/// A spot light's gizmo is a point light's with a line along its aim, and drags the same way.
#[test]
fn a_spot_light_gizmo_drag_moves_the_light() {
    let spot = light_gizmo_drag("SpotLight", &[("cone", ParamValue::Float(80.0))]);
    let gizmos::GizmoTarget::Light { aim, .. } = spot.target else { panic!("a light gizmo: {:?}", spot.target) };
    assert_eq!(aim, Some([0.0, -1.0, 0.0]), "the spot shows where it points");
}

fn light_gizmo_drag(kind: &str, params: &[(&str, ParamValue)]) -> gizmos::Gizmo {
    let mut harness = default_harness();
    harness
        .state_mut()
        .doc
        .edit("Add light", None, |p| {
            let id = edits::add_node(p, kind, [320.0, 420.0])?;
            let n = p.nodes.iter_mut().find(|n| n.id == id).unwrap();
            n.params.insert("position".into(), ParamValue::Vec3([1.2, 1.5, 1.0]));
            n.params.insert("intensity".into(), ParamValue::Color([30.0, 30.0, 30.0]));
            for (name, value) in params {
                n.params.insert((*name).into(), value.clone());
            }
            p.links.push(lightloom_nodes::project::ProjectLink {
                from: (id.clone(), "lights".into()),
                to: ("output".into(), "lights".into()),
            });
            Ok(())
        })
        .unwrap();
    settle(&mut harness);
    let light = harness.state().gizmos().pop().expect("a gizmo for the light");
    assert!(light.linked, "the linked light is drawn as lighting the output");
    let rect = harness.state().viewport_rect;
    let camera = harness.state().viewport_camera(rect);
    let at = gizmos::screen_pos(&camera, rect, light.position).expect("in front of the camera");
    assert!(harness.state().render_frame(rect).contains(at), "the light is in view");
    let lit_before = viewport_mean(&mut harness);

    // Click: the light's node is selected.
    pointer_click(&mut harness, at);
    assert_eq!(harness.state().selection, Selection::Node(light.id.clone()));

    // Drag 80 points right and 30 up: the light follows the pointer at its depth.
    pointer_drag(&mut harness, egui::PointerButton::Primary, at, at + egui::vec2(80.0, -30.0));
    let moved = harness.state().gizmos().pop().unwrap();
    let now = gizmos::screen_pos(&camera, rect, moved.position).unwrap();
    assert!((now - (at + egui::vec2(80.0, -30.0))).length() < 3.0, "the gizmo follows the pointer: {at:?} → {now:?}");
    assert_eq!(harness.state().doc.undo_label(), Some(format!("Set {}.position", light.id).as_str()));
    settle(&mut harness);
    let lit_after = viewport_mean(&mut harness);
    assert!((lit_after - lit_before).abs() > 0.2, "the lighting follows the light: {lit_before:.2} → {lit_after:.2}");
    // One undo puts it back.
    harness.state_mut().undo();
    let back = harness.state().gizmos().pop().unwrap();
    assert_eq!(back.position, light.position);
    harness.render().unwrap().save(state_dir().join(format!("light-gizmo-{kind}.png"))).unwrap();
    back
}

/// Where the mode cannot show a material's highlight, the editor says so (Problems and the
/// material's inspector), naming what would show it; a lobe the mode shows gets no note.
#[test]
fn a_highlight_the_mode_cannot_show_is_named() {
    let mut harness = default_harness();
    let set = |h: &mut Harness<'_, EditorApp>, node: &str, name: &str, v: ParamValue| {
        inspector::set_param(&mut h.state_mut().doc, node, name, v).unwrap();
        h.state_mut().doc.seal();
    };
    set(&mut harness, "material", "model", ParamValue::Choice("phong".into()));
    set(&mut harness, "material", "exponent", ParamValue::Float(20.0));
    settle(&mut harness);
    assert!(!harness.state().problems().iter().any(|p| p.starts_with("note: material")), "Phong 20 is shown");

    set(&mut harness, "material", "exponent", ParamValue::Float(200.0));
    settle(&mut harness);
    let problems = harness.state().problems();
    let note = problems.iter().find(|p| p.starts_with("note: material `material`")).expect("a note on the material");
    assert!(note.contains("sharper than 320 wavelet cells"), "{note}");
    harness.state_mut().selection = Selection::Node("material".into());
    harness.run_steps(2);
    harness.get_by_label_contains("⚠ its phong highlight (about Phong 200");

    set(&mut harness, "output", "mode", ParamValue::Choice("sh_prt".into()));
    settle(&mut harness);
    let problems = harness.state().problems();
    let note = problems.iter().find(|p| p.starts_with("note: material `material`")).expect("a note on the material");
    assert!(note.contains("sharper than 6 SH bands"), "{note}");
}

/// Smaller stumbles: an unconnected node is dimmed with a hint of what to link it to; a
/// refused action's problem leaves with an undo; the layout does not move when the
/// inspector shows another node; the right-click menu's search starts empty.
#[test]
fn small_stumbles_are_gone() {
    let mut harness = default_harness();
    // An unconnected node says what to link it to.
    harness
        .state_mut()
        .doc
        .edit("Add sky", None, |p| edits::add_node(p, "EnvironmentMap", [600.0, 500.0]).map(|_| ()))
        .unwrap();
    settle(&mut harness);
    harness.get_by_label("not connected: link `environment` to the Output's `environment` input");

    // A problem from an action disappears with an undo of the state it was about.
    harness.state_mut().log_error("something about this state");
    assert!(harness.state().problems().iter().any(|p| p == "something about this state"));
    harness.state_mut().undo();
    assert!(!harness.state().problems().iter().any(|p| p == "something about this state"));

    // The inspector keeps its width whatever it shows.
    let mut edges = Vec::new();
    for id in ["sky", "scene", "material", "output"] {
        harness.state_mut().selection = Selection::Node(id.into());
        harness.run_steps(3);
        edges.push((harness.state().viewport_rect.right(), harness.state().viewport_rect.top()));
    }
    assert!(edges.windows(2).all(|w| (w[0].0 - w[1].0).abs() < 0.5 && (w[0].1 - w[1].1).abs() < 0.5), "{edges:?}");

    // The right-click add menu opens with an empty search, even after a search that matched
    // nothing.
    let empty = harness.state().graph_rect.right_bottom() - egui::vec2(40.0, 40.0);
    for round in 0..2 {
        harness.hover_at(empty);
        harness.step();
        harness.event(egui::Event::PointerButton {
            pos: empty,
            button: egui::PointerButton::Secondary,
            pressed: true,
            modifiers: egui::Modifiers::NONE,
        });
        harness.step();
        harness.event(egui::Event::PointerButton {
            pos: empty,
            button: egui::PointerButton::Secondary,
            pressed: false,
            modifiers: egui::Modifiers::NONE,
        });
        harness.run_steps(3);
        harness.get_by_label("Add node");
        harness.get_by_label("Point light");
        if round == 0 {
            harness.event(egui::Event::Text("zzzz".into()));
            harness.run_steps(2);
            harness.get_by_label("no node kind matches");
            harness.key_press(egui::Key::Escape);
            harness.run_steps(3);
        }
    }
}

/// File → Open sample opens a copy of a sample (untitled, so saving never changes it) that
/// evaluates without problems and draws.
#[test]
fn a_sample_opens_from_the_file_menu() {
    let mut harness = default_harness();
    open_sample(&mut harness, "glossy objects under a courtyard HDRI");
    assert_eq!(harness.state().doc.path, None, "a copy, not the sample file");
    assert!(harness.state().doc.project.name.contains("courtyard"));
    settle(&mut harness);
    let problems: Vec<String> = harness.state().problems().into_iter().filter(|p| !p.starts_with("note:")).collect();
    assert!(problems.is_empty(), "{problems:?}");
    assert!(viewport_mean(&mut harness) > 20.0, "the sample is drawn");
    harness.render().unwrap().save(state_dir().join("sample.png")).unwrap();
}

/// File → Open sample lists every built-in sample by its title.
#[test]
fn the_file_menu_lists_every_sample() {
    let mut harness = default_harness();
    harness.get_by_label("File").click();
    harness.run_steps(2);
    harness.get_by_label_contains("Open sample").hover();
    harness.run_steps(4);
    let samples = crate::samples::list();
    assert!(samples.len() >= 6, "{samples:?}");
    for sample in samples {
        harness.get_by_label(&sample.title);
    }
}

/// File → Open sample → the sample whose name contains `name`, as a user picks it.
fn open_sample(harness: &mut Harness<'_, EditorApp>, name: &str) {
    harness.get_by_label("File").click();
    harness.run_steps(2);
    harness.get_by_label_contains("Open sample").hover();
    harness.run_steps(4);
    harness.get_by_label_contains(name).click();
    harness.run_steps(2);
}

/// Square lights as a user sets them up: add the decomposer from the Add menu, link the sky
/// into it and it into the Output from the inspector, pick the mode from the toolbar; the
/// viewport draws the rsl mode with the decomposer's previews, and changing K redraws it
/// without a new decomposition.
#[test]
fn square_lights_from_the_add_menu_to_the_viewport() {
    let mut harness = default_harness();
    let before: Vec<String> = harness.state().doc.project.nodes.iter().map(|n| n.id.clone()).collect();
    let added = add_from_menu(&mut harness, "RSL decomposer");
    assert_eq!(harness.state().selection, Selection::Node(added.clone()));
    // It lands clear of the other nodes, measured as drawn (with its previews it is wide).
    let rect = harness.state().graph.node_rect(&added).expect("drawn");
    for other in &before {
        let theirs = harness.state().graph.node_rect(other).expect("drawn");
        assert!(!rect.intersects(theirs), "{added} at {rect:?} covers {other} at {theirs:?}");
    }
    // Its previews evaluate first, so the inspector's layout holds still under the pointer.
    settle(&mut harness);
    pick(&mut harness, "environment (Environment)", "sky.environment");
    harness.state_mut().selection = Selection::Node("output".into());
    harness.run_steps(3);
    pick(&mut harness, "square_lights (SquareLights)", &format!("{added}.square_lights"));
    harness.key_press(egui::Key::Escape);
    harness.step();
    pick(&mut harness, "Mode", "Square lights, movable objects (rsl)");
    settle(&mut harness);
    let frame = harness.state().view.frame.clone().expect("a frame");
    assert_eq!(frame.mode, lightloom_nodes::kinds::output::Mode::Rsl, "pending: {:?}", frame.pending);
    assert!(harness.state().problems().iter().all(|p| !p.starts_with("error")), "{:?}", harness.state().problems());
    let lit = viewport_mean(&mut harness);
    assert!(lit > 20.0, "the rsl mode lights the scene (mean sRGB {lit:.1})");
    harness.render().unwrap().save(state_dir().join("square_lights.png")).expect("screenshot for a person to look at");

    // Fewer lights: a cut of the same merge sequence, redrawn.
    inspector::set_param(&mut harness.state_mut().doc, &added, "light_count", ParamValue::Int(8)).unwrap();
    harness.state_mut().doc.seal();
    settle(&mut harness);
    // The Output lights the sky's sun apart (its default): the lights of the sky without it.
    let ran = computed_stages(&harness);
    assert!(!ran.iter().any(|s| s.ends_with("merge_sequence")), "K is a cut, not a new decomposition: {ran:?}");
    assert!(ran.contains(&format!("{added}.residual_square_lights")), "{ran:?}");
    let fewer = viewport_mean(&mut harness);
    assert!((fewer - lit).abs() > 0.05, "the image changed with K: {lit:.2} vs {fewer:.2}");
}

/// Objects move with the pointer: a left drag that starts on an object moves it in the view
/// plane (it follows the pointer), Shift+drag turns it, each drag one undo step; in the rsl
/// mode the move recomputes only the per-vertex visibility.
#[test]
fn dragging_an_object_moves_it_and_shift_turns_it() {
    let mut harness = default_harness();
    settle(&mut harness);
    let spec = lightloom_nodes::kinds::kind("Scene").and_then(|k| k.param("objects")).unwrap();
    let objects = |h: &Harness<'_, EditorApp>| match inspector::param_value(&h.state().doc.project, "scene", spec) {
        ParamValue::Objects(o) => o,
        _ => panic!("the scene lists objects"),
    };
    let before = objects(&harness);
    let sphere = before.iter().position(|o| o.name == "sphere").expect("the default sphere");
    let rect = harness.state().viewport_rect;
    let camera = harness.state().viewport_camera(rect);
    let at = gizmos::screen_pos(&camera, rect, before[sphere].translation).expect("in front of the camera");
    pointer_drag(&mut harness, egui::PointerButton::Primary, at, at + egui::vec2(60.0, -20.0));
    let after = objects(&harness);
    let now = gizmos::screen_pos(&camera, rect, after[sphere].translation).unwrap();
    assert!((now - (at + egui::vec2(60.0, -20.0))).length() < 3.0, "the sphere follows the pointer: {at:?} → {now:?}");
    assert_eq!(harness.state().selection, Selection::Node("scene".into()));
    assert_eq!(harness.state().view.selected_object, Some(sphere), "the dragged object is selected");
    assert_eq!(after[sphere].rotation_deg, before[sphere].rotation_deg);
    assert_eq!(harness.state().doc.undo_label(), Some("Set scene.objects"));
    settle(&mut harness);

    // Shift+drag turns it about the vertical axis.
    let turn_from = gizmos::screen_pos(&camera, rect, after[sphere].translation).unwrap();
    let turn_to = turn_from + egui::vec2(40.0, 0.0);
    pointer_drag_with(&mut harness, egui::PointerButton::Primary, turn_from, turn_to, egui::Modifiers::SHIFT);
    let turned = objects(&harness);
    assert_eq!(turned[sphere].translation, after[sphere].translation, "a turn does not move it");
    assert!((turned[sphere].rotation_deg[1] - after[sphere].rotation_deg[1]).abs() > 5.0, "{:?}", turned[sphere]);
    // Undo twice: back where it was.
    harness.state_mut().undo();
    harness.state_mut().undo();
    assert_eq!(objects(&harness)[sphere].translation, before[sphere].translation);
}
