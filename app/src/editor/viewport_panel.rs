//! The viewport panel: toolbar, Blender-style navigation, picking, the selection outline, and
//! drawing (approximation, or the background reference and its error map).

use super::*;

impl EditorApp {
    pub(super) fn viewport_panel(&mut self, ui: &mut egui::Ui) {
        // The panel as laid out: the view never reaches under the side panels, however wide
        // the toolbar would like to be.
        let panel = ui.max_rect();
        self.viewport_toolbar(ui);
        let available = egui::vec2((panel.right() - ui.cursor().left()).max(16.0), ui.available_height());
        let (rect, response) = ui.allocate_exact_size(available, egui::Sense::click_and_drag());
        self.viewport_rect = rect;
        self.navigate(ui, &response, rect);
        let dragging_gizmo = self.drag_gizmo(ui, &response, rect);
        let dragging_object = !dragging_gizmo && self.drag_object(ui, &response, rect);
        // While the view moves, draw at half resolution; the full frame follows on release.
        let moving = (response.dragged() && !dragging_gizmo && !dragging_object)
            || (response.hovered() && ui.input(|i| i.smooth_scroll_delta.y != 0.0));
        let scale = self.view.resolution_scale * ui.ctx().pixels_per_point() * if moving { 0.5 } else { 1.0 };
        let size = (((rect.width() * scale) as u32).clamp(16, 4096), ((rect.height() * scale) as u32).clamp(16, 4096));
        self.draw_viewport(ui.ctx(), size);
        let painter = ui.painter_at(rect);
        painter.rect_filled(rect, 0.0, Color32::from_gray(20));
        if let Some(id) = self.host.as_ref().and_then(ViewportHost::texture_id) {
            painter.image(
                id,
                rect,
                egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0)),
                Color32::WHITE,
            );
        }
        self.selection_overlay(&painter, rect);
        render_frame_overlay(&painter, rect, self.render_frame(rect), &self.doc.project.render);
        self.refresh_light_previews(ui.ctx());
        self.draw_gizmos(&painter, rect, response.hover_pos());
        let message = if let Some(e) = &self.host_error {
            Some(format!("viewport unavailable: {e}"))
        } else if let Some(e) = &self.view.frame_error {
            Some(e.clone())
        } else if self.view.frame.is_none() {
            Some("evaluating…".into())
        } else {
            None
        };
        if let Some(m) = message {
            painter.text(
                rect.center(),
                egui::Align2::CENTER_CENTER,
                m,
                egui::FontId::proportional(16.0),
                Color32::LIGHT_GRAY,
            );
        }
        if let Some(pending) = self.view.frame.as_ref().and_then(|f| f.pending.clone()) {
            let text = match &self.evaluator.progress {
                Some(p) => format!("{pending}\n{}", p.describe()),
                // Cancelled, or the mode's stages failed (see Problems): no refinement is coming.
                None => "unshadowed preview: evaluation stopped before the mode was ready (F5 re-evaluates)".into(),
            };
            let galley = painter.layout_no_wrap(text, egui::FontId::proportional(13.0), Color32::WHITE);
            let at = egui::pos2(rect.left() + 8.0, rect.bottom() - 8.0 - galley.size().y);
            painter.rect_filled(
                egui::Rect::from_min_size(at, galley.size()).expand(4.0),
                3.0,
                Color32::from_black_alpha(160),
            );
            painter.galley(at, galley, Color32::WHITE);
        }
        if let Some(error) = &self.view.error {
            let text = format!(
                "error vs reference: RMSE {:.4}, relative {:.1}%, PSNR {:.1} dB",
                error.rmse,
                error.relative_rmse * 100.0,
                error.psnr_db
            );
            let galley = painter.layout_no_wrap(text, egui::FontId::monospace(12.0), Color32::WHITE);
            let at = rect.left_top() + egui::vec2(8.0, 8.0);
            painter.rect_filled(
                egui::Rect::from_min_size(at, galley.size()).expand(4.0),
                3.0,
                Color32::from_black_alpha(170),
            );
            painter.galley(at, galley, Color32::WHITE);
        }
        if let Some(scale) = self.view.error_scale {
            error_legend(&painter, rect, scale);
        }
        if response.clicked()
            && let Some(pos) = response.interact_pointer_pos()
        {
            match self.gizmo_at(pos, rect) {
                Some(gizmo) => {
                    self.selection = Selection::Node(gizmo.node);
                    self.view.selected_object = None;
                }
                None => self.pick(pos, rect),
            }
        }
    }

    pub(super) fn viewport_toolbar(&mut self, ui: &mut egui::Ui) {
        let Some(output) = self.doc.project.nodes.iter().find(|n| n.kind == "Output").map(|n| n.id.clone()) else {
            ui.weak("no Output node: add one to see the scene");
            return;
        };
        let spec = lightloom_nodes::kinds::kind("Output").expect("Output kind");
        let value = |doc: &Document, name: &str| {
            inspector::param_value(&doc.project, &output, spec.param(name).expect("param"))
        };
        let mut changes: Vec<(&str, ParamValue)> = Vec::new();
        // Two rows (what is shown; the view), so the toolbar does not reflow as labels change;
        // each wraps only when the panel is too narrow for it.
        ui.horizontal_wrapped(|ui| {
            for (name, label) in [("view", "View"), ("mode", "Mode"), ("tonemap", "Tone map")] {
                let ParamValue::Choice(current) = value(&self.doc, name) else { continue };
                let lightloom_nodes::engine::spec::ParamKind::Choice { options, labels, .. } =
                    &spec.param(name).expect("param").kind
                else {
                    continue;
                };
                let l = ui.label(label);
                let mut chosen = current.clone();
                inspector::choice_combo(ui, ("viewport", name), options, labels, &mut chosen, true).labelled_by(l.id);
                if chosen != current {
                    changes.push((name, ParamValue::Choice(chosen)));
                }
            }
            if let ParamValue::Float(mut exposure) = value(&self.doc, "exposure") {
                let l = ui.label("Exposure");
                if ui
                    .add(egui::DragValue::new(&mut exposure).range(-20.0..=20.0).speed(0.05).suffix(" EV"))
                    .labelled_by(l.id)
                    .changed()
                {
                    changes.push(("exposure", ParamValue::Float(exposure)));
                }
            }
        });
        ui.horizontal_wrapped(|ui| {
            ui.label("Resolution");
            egui::ComboBox::from_id_salt("resolution")
                .selected_text(format!("{:.0}%", self.view.resolution_scale * 100.0))
                .show_ui(ui, |ui| {
                    for s in [0.25f32, 0.5, 0.75, 1.0] {
                        ui.selectable_value(&mut self.view.resolution_scale, s, format!("{:.0}%", s * 100.0));
                    }
                });
            if ui.button("Frame all").on_hover_text("Home").clicked() || ui.input(|i| i.key_pressed(egui::Key::Home)) {
                self.frame_all();
            }
            if ui.button("Reset view").on_hover_text("back to the project's camera").clicked() {
                let camera =
                    self.doc.project.camera(Some(&self.view.camera_name)).or_else(|_| self.doc.project.camera(None));
                if let Ok(c) = camera {
                    self.view.camera = OrbitCamera::from_camera(&c);
                }
            }
            if ui.button("Save view to camera").on_hover_text("store this view in the project's camera").clicked() {
                let camera = self.view.camera.to_camera(&self.view.camera_name);
                let result = self.doc.edit("Save view to camera", None, |p| {
                    match p.cameras.iter_mut().find(|c| c.name == camera.name) {
                        Some(c) => *c = camera.clone(),
                        None => p.cameras.insert(0, camera.clone()),
                    }
                    Ok(())
                });
                if let Err(e) = result {
                    self.log_error(e);
                }
            }
        });
        for (name, v) in changes {
            if let Err(e) = inspector::set_param(&mut self.doc, &output, name, v) {
                self.log_error(e);
            }
        }
    }

    /// The part of the viewport that `lightloom render` renders (as Blender's camera frame):
    /// the render size's aspect, as large as fits with a margin.
    pub(super) fn render_frame(&self, rect: egui::Rect) -> egui::Rect {
        let render = &self.doc.project.render;
        let aspect = render.width.max(1) as f32 / render.height.max(1) as f32;
        let inner = rect.shrink(rect.width().min(rect.height()) * 0.04);
        let size = if inner.width() > inner.height() * aspect {
            egui::vec2(inner.height() * aspect, inner.height())
        } else {
            egui::vec2(inner.width(), inner.width() / aspect)
        };
        egui::Rect::from_center_size(inner.center(), size)
    }

    /// The camera the viewport draws with: the view, widened so that the render frame shows
    /// exactly the camera's field of view.
    pub(super) fn viewport_camera(&self, rect: egui::Rect) -> OrbitCamera {
        let frame = self.render_frame(rect);
        self.view.camera.widened(f64::from(rect.height() / frame.height().max(1.0)))
    }

    pub(super) fn frame_all(&mut self) {
        if let Some(frame) = &self.view.frame
            && let Some(m) = frame.geometry.meshes.value.get::<lightloom_nodes::mesh::MeshSet>()
        {
            self.view.camera.frame(m.bounds());
        }
    }

    /// Blender-style: middle drag orbits, Shift+middle pans, Ctrl+middle or the wheel zooms;
    /// for trackpads, Alt+left drag orbits, Alt+Shift+left pans, pinch zooms; right drag
    /// also orbits.
    pub(super) fn navigate(&mut self, ui: &egui::Ui, response: &egui::Response, rect: egui::Rect) {
        let (delta, shift, ctrl, alt) =
            ui.input(|i| (i.pointer.delta(), i.modifiers.shift, i.modifiers.command, i.modifiers.alt));
        let delta = (f64::from(delta.x), f64::from(delta.y));
        // The camera's field of view spans the render frame's height.
        let height = f64::from(self.render_frame(rect).height());
        let middle = response.dragged_by(egui::PointerButton::Middle);
        let left_alt = response.dragged_by(egui::PointerButton::Primary) && alt;
        let right = response.dragged_by(egui::PointerButton::Secondary);
        if middle || left_alt || right {
            if shift {
                self.view.camera.pan(delta, height);
            } else if ctrl && middle {
                self.view.camera.zoom((delta.1 * 0.01).exp());
            } else {
                self.view.camera.orbit(delta, height);
            }
        }
        if response.hovered() {
            let (scroll, zoom) = ui.input(|i| (i.smooth_scroll_delta.y, i.zoom_delta()));
            if scroll != 0.0 {
                self.view.camera.zoom((-f64::from(scroll) * 0.002).exp());
            }
            if zoom != 1.0 {
                self.view.camera.zoom(1.0 / f64::from(zoom));
            }
        }
    }

    /// The Scene node and the index of the object under `pos`, or the mesh's name when it is
    /// part of no listed object.
    fn object_at(&self, pos: egui::Pos2, rect: egui::Rect) -> Option<Result<(String, usize), String>> {
        let frame = self.view.frame.as_ref()?;
        let local = pos - rect.min;
        let size = (rect.width().max(1.0) as usize, rect.height().max(1.0) as usize);
        let camera = self.viewport_camera(rect).pinhole();
        let mesh = frame.pick(&camera, (f64::from(local.x), f64::from(local.y)), size)?;
        let meshes = frame.geometry.meshes.value.get::<lightloom_nodes::mesh::MeshSet>()?;
        let name = meshes.meshes[mesh].name.split('/').next().unwrap_or_default().to_string();
        // The Scene node feeding the output, and the object with that name.
        let (_, graph) = self.evaluator.last.as_ref()?;
        let output = graph.nodes.iter().find(|n| n.kind.name == "Output")?;
        let scene = graph.upstream(&output.id, "scene")?;
        let Some(ParamValue::Objects(objects)) = scene.params.get("objects") else { return None };
        Some(match objects.iter().position(|o| o.name == name) {
            Some(index) => Ok((scene.id.clone(), index)),
            None => Err(meshes.meshes[mesh].name.clone()),
        })
    }

    /// A Scene node's object list (its default when the project does not set it).
    fn scene_objects(&self, scene: &str) -> Option<ParamValue> {
        let spec = lightloom_nodes::kinds::kind("Scene")?.param("objects")?;
        Some(inspector::param_value(&self.doc.project, scene, spec))
    }

    pub(super) fn pick(&mut self, pos: egui::Pos2, rect: egui::Rect) {
        if self.view.frame.is_none() {
            return;
        }
        match self.object_at(pos, rect) {
            Some(Ok((scene, index))) => {
                self.selection = Selection::Node(scene.clone());
                self.view.selected_object = Some(index);
                let name = match self.scene_objects(&scene) {
                    Some(ParamValue::Objects(objects)) => {
                        objects.get(index).map(|o| o.name.clone()).unwrap_or_default()
                    }
                    _ => String::new(),
                };
                self.log_info(format!("selected object `{name}` of {scene}"));
            }
            Some(Err(mesh)) => {
                self.view.selected_object = None;
                self.log_info(format!("`{mesh}` comes from the scene's file"));
            }
            None => self.view.selected_object = None,
        }
    }

    /// A primary drag that starts on an object moves it in the view plane (Shift turns it about
    /// the vertical axis), one undo step per drag; returns whether it did. Objects keep their
    /// precomputed transport in their own space, so in the `rsl` mode a move recomputes only
    /// the per-vertex visibility.
    pub(super) fn drag_object(&mut self, ui: &egui::Ui, response: &egui::Response, rect: egui::Rect) -> bool {
        let alt = ui.input(|i| i.modifiers.alt);
        if response.drag_started_by(egui::PointerButton::Primary) && !alt {
            let origin = ui.input(|i| i.pointer.press_origin());
            let hit = origin.and_then(|p| self.object_at(p, rect)).and_then(Result::ok);
            // Held by name: the list may change before the next evaluation.
            self.view.dragging_object = hit.and_then(|(scene, index)| match self.scene_objects(&scene) {
                Some(ParamValue::Objects(objects)) => objects.get(index).map(|o| (scene, o.name.clone())),
                _ => None,
            });
            if let Some((scene, index)) = hit_index(self, &self.view.dragging_object) {
                self.selection = Selection::Node(scene);
                self.view.selected_object = Some(index);
            }
        }
        // Alt hands the drag to navigation (orbit) for the rest of the press.
        if !response.dragged_by(egui::PointerButton::Primary) || alt {
            self.view.dragging_object = None;
            return false;
        }
        let Some((scene, name)) = self.view.dragging_object.clone() else { return false };
        let (delta, turn) = ui.input(|i| (i.pointer.delta(), i.modifiers.shift));
        if delta == egui::Vec2::ZERO {
            return true;
        }
        let Some(ParamValue::Objects(mut objects)) = self.scene_objects(&scene) else { return false };
        let Some(object) = objects.iter_mut().find(|o| o.name == name) else { return false };
        if turn {
            object.rotation_deg[1] = (object.rotation_deg[1] + f64::from(delta.x) * 0.5).rem_euclid(360.0);
        } else {
            let camera = self.viewport_camera(rect);
            let moved = camera.drag_point(
                glam::DVec3::from(object.translation),
                (f64::from(delta.x), f64::from(delta.y)),
                f64::from(rect.height()),
            );
            object.translation = moved.to_array();
        }
        if let Err(e) = inspector::set_param(&mut self.doc, &scene, "objects", ParamValue::Objects(objects)) {
            self.log_error(e);
        }
        true
    }

    /// Outlines the selected object's bounding box.
    pub(super) fn selection_overlay(&self, painter: &egui::Painter, rect: egui::Rect) {
        let (Some(index), Some(frame)) = (self.view.selected_object, &self.view.frame) else { return };
        let Selection::Node(scene_id) = &self.selection else { return };
        let Some(ParamValue::Objects(objects)) = self.scene_objects(scene_id) else { return };
        let Some(object) = objects.get(index) else { return };
        let Some(m) = frame.geometry.meshes.value.get::<lightloom_nodes::mesh::MeshSet>() else { return };
        let prefix = format!("{}/", object.name);
        let parts: Vec<_> = m.meshes.iter().filter(|x| x.name == object.name || x.name.starts_with(&prefix)).collect();
        if parts.is_empty() {
            return;
        }
        let (lo, hi) = lightloom_nodes::mesh::union_bounds(parts);
        let all = m.bounds();
        let view_proj = self.viewport_camera(rect).view().view_proj(rect.width() / rect.height().max(1.0), all);
        let corner = |i: usize| {
            glam::Vec3::new(
                if i & 1 == 0 { lo[0] } else { hi[0] },
                if i & 2 == 0 { lo[1] } else { hi[1] },
                if i & 4 == 0 { lo[2] } else { hi[2] },
            )
        };
        let project = |p: glam::Vec3| {
            let c = view_proj * p.extend(1.0);
            (c.w > 1e-4).then(|| {
                egui::pos2(
                    rect.left() + (c.x / c.w * 0.5 + 0.5) * rect.width(),
                    rect.top() + (0.5 - c.y / c.w * 0.5) * rect.height(),
                )
            })
        };
        let stroke = egui::Stroke::new(1.5, Color32::from_rgb(255, 200, 80));
        for (a, b) in [(0, 1), (2, 3), (4, 5), (6, 7), (0, 2), (1, 3), (4, 6), (5, 7), (0, 4), (1, 5), (2, 6), (3, 7)] {
            if let (Some(p), Some(q)) = (project(corner(a)), project(corner(b))) {
                painter.line_segment([p, q], stroke);
            }
        }
    }

    /// Shows frames the render thread finished, and asks it for a new one when the frame,
    /// camera, size or view changed; starts or shows reference renders. Never waits for the
    /// GPU: the last finished frame stays on screen while the next one renders.
    pub(super) fn draw_viewport(&mut self, ctx: &egui::Context, size: (u32, u32)) {
        let camera = self.viewport_camera(self.viewport_rect);
        let Some(host) = self.host.as_mut() else { return };
        match host.poll(ctx) {
            Some(Ok(done)) => {
                self.view.drawn = done.signature;
                if done.error.is_some() {
                    self.view.error = done.error;
                }
                self.view.error_scale = done.error_scale;
            }
            Some(Err(e)) => {
                self.view.frame_error = Some(e);
                self.view.drawn = host.shown.unwrap_or(0);
            }
            None => {}
        }
        if host.is_busy() {
            ctx.request_repaint_after(std::time::Duration::from_millis(15));
        }
        let Some(frame) = self.view.frame.clone() else { return };
        let settings = &frame.settings;
        let mut h = std::hash::DefaultHasher::new();
        use std::hash::{Hash, Hasher};
        self.view.frame_generation.hash(&mut h);
        format!("{camera:?}").hash(&mut h);
        size.hash(&mut h);
        let signature = h.finish();
        let render =
            |frame: &Arc<FrameInputs>| viewport::Job::Render { frame: frame.clone(), camera: camera.view(), size };
        if settings.view == View::Approximation {
            if let Some(job) = self.view.reference.take() {
                job.cancel();
            }
            self.view.error = None;
            if signature != self.view.drawn {
                host.request(signature, render(&frame));
                if host.shown == Some(signature) {
                    self.view.drawn = signature;
                }
            }
            return;
        }
        // Reference and error views: the reference is rendered in the background at the
        // viewport size; meanwhile the approximation stays on screen.
        let have = self.view.reference_image.as_ref().is_some_and(|(s, _)| *s == signature);
        let running = self.view.reference.as_ref().is_some_and(|j| j.signature == signature);
        if !have && !running {
            if let Some(old) = self.view.reference.take() {
                old.cancel();
            }
            self.view.reference = Some(ReferenceJob::spawn(frame.clone(), camera.pinhole(), size, signature));
            host.request(signature, render(&frame));
            return;
        }
        let Some((_, reference)) = self.view.reference_image.clone().filter(|(s, _)| *s == signature) else { return };
        let view_signature = signature
            ^ xxhash_rust::xxh3::xxh3_64(
                format!("{}{}{}", settings.view, settings.exposure, settings.tonemap).as_bytes(),
            );
        if view_signature != self.view.drawn {
            let job = viewport::Job::Compare {
                frame: frame.clone(),
                camera: camera.view(),
                size,
                reference,
                view: settings.view,
            };
            host.request(view_signature, job);
            if host.shown == Some(view_signature) {
                self.view.drawn = view_signature;
            }
        }
    }
}

/// The error view's colour scale: the heat map's ramp from no difference to `scale` (and
/// above), in linear radiance, on a dark backing at the viewport's bottom left.
fn error_legend(painter: &egui::Painter, rect: egui::Rect, scale: f64) {
    let (width, height) = (250.0, 12.0);
    let origin = rect.left_bottom() + egui::vec2(12.0, -44.0);
    let backing = egui::Rect::from_min_size(origin - egui::vec2(6.0, 20.0), egui::vec2(width + 12.0, 56.0));
    painter.rect_filled(backing, 4.0, Color32::from_black_alpha(190));
    painter.text(
        origin - egui::vec2(0.0, 4.0),
        egui::Align2::LEFT_BOTTOM,
        "|approx − reference|, linear radiance (RGB mean)",
        egui::FontId::proportional(11.0),
        Color32::WHITE,
    );
    let steps = 64;
    for i in 0..steps {
        let t = i as f64 / (steps - 1) as f64;
        let [r, g, b] = lightloom_nodes::reference::error_ramp(t).map(|c| (c * 255.0).round() as u8);
        let x = origin.x + width * i as f32 / steps as f32;
        let cell = egui::Rect::from_min_size(egui::pos2(x, origin.y), egui::vec2(width / steps as f32 + 0.5, height));
        painter.rect_filled(cell, 0.0, Color32::from_rgb(r, g, b));
    }
    for (t, label) in [(0.0, "0".to_string()), (0.5, format!("{:.3}", scale / 2.0)), (1.0, format!("≥ {scale:.3}"))] {
        let x = origin.x + width * t;
        let align = if t == 0.0 {
            egui::Align2::LEFT_TOP
        } else if t == 1.0 {
            egui::Align2::RIGHT_TOP
        } else {
            egui::Align2::CENTER_TOP
        };
        painter.text(
            egui::pos2(x, origin.y + height + 2.0),
            align,
            label,
            egui::FontId::monospace(11.0),
            Color32::WHITE,
        );
    }
}

/// Dims the viewport outside the render frame and names the render size.
fn render_frame_overlay(
    painter: &egui::Painter,
    rect: egui::Rect,
    frame: egui::Rect,
    render: &lightloom_nodes::project::RenderSettings,
) {
    let dim = Color32::from_black_alpha(110);
    painter.rect_filled(egui::Rect::from_min_max(rect.min, egui::pos2(rect.right(), frame.top())), 0.0, dim);
    painter.rect_filled(egui::Rect::from_min_max(egui::pos2(rect.left(), frame.bottom()), rect.max), 0.0, dim);
    let middle = |l: f32, r: f32| egui::Rect::from_min_max(egui::pos2(l, frame.top()), egui::pos2(r, frame.bottom()));
    painter.rect_filled(middle(rect.left(), frame.left()), 0.0, dim);
    painter.rect_filled(middle(frame.right(), rect.right()), 0.0, dim);
    painter.rect_stroke(frame, 0.0, egui::Stroke::new(1.0, Color32::from_gray(150)), egui::StrokeKind::Outside);
    painter.text(
        frame.right_bottom() + egui::vec2(0.0, 3.0),
        egui::Align2::RIGHT_TOP,
        format!("render {}×{}", render.width, render.height),
        egui::FontId::proportional(11.0),
        Color32::from_gray(170),
    );
}

/// The Scene node and current index of the object held by name.
fn hit_index(app: &EditorApp, held: &Option<(String, String)>) -> Option<(String, usize)> {
    let (scene, name) = held.as_ref()?;
    match app.scene_objects(scene)? {
        ParamValue::Objects(objects) => objects.iter().position(|o| &o.name == name).map(|i| (scene.clone(), i)),
        _ => None,
    }
}
