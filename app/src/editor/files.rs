//! Files: save, save as, open, new, the file dialog, the unsaved-changes and recovery
//! questions, closing, autosave, and `--screenshot`.

use super::*;

/// A copy of the built-in sample `stem` (File → Open sample, or `sample:NAME` on the command
/// line): untitled, with its asset paths made to resolve from the current folder, so Save asks
/// where to put it. Also the path of the sample's project file.
pub fn sample_copy(stem: &str) -> anyhow::Result<(Document, PathBuf)> {
    let path = crate::samples::project(stem)?;
    let sample = Document::open(&path)?;
    let mut project = sample.project.clone();
    let cwd = std::env::current_dir().unwrap_or_default();
    project.rebase_paths(&sample.project_dir(), &cwd);
    Ok((Document::new(project, None), path))
}

/// `x0,y0,x1,y1` of `rect` in window pixels (the layout `--screenshot` and `--status-file`
/// report).
fn window_pixels(ctx: &egui::Context, rect: egui::Rect) -> String {
    let ppp = ctx.pixels_per_point();
    format!("{:.0},{:.0},{:.0},{:.0}", rect.left() * ppp, rect.top() * ppp, rect.right() * ppp, rect.bottom() * ppp)
}

/// A background job's result once it has arrived; until then `None`, and the UI polls again.
pub(super) fn finished<T>(
    result: &std::sync::mpsc::Receiver<Result<T, String>>,
    ctx: &egui::Context,
    what: &str,
) -> Option<Result<T, String>> {
    match result.try_recv() {
        Ok(outcome) => Some(outcome),
        Err(std::sync::mpsc::TryRecvError::Empty) => {
            ctx.request_repaint_after(std::time::Duration::from_millis(200));
            None
        }
        Err(std::sync::mpsc::TryRecvError::Disconnected) => Some(Err(format!("{what} stopped unexpectedly"))),
    }
}

/// A render of the view to an image file, on its own thread.
pub(super) struct ImageRender {
    pub path: PathBuf,
    pub started: std::time::Instant,
    result: std::sync::mpsc::Receiver<Result<(u32, u32), String>>,
}

impl EditorApp {
    pub(super) fn save(&mut self) {
        match self.doc.path.clone() {
            Some(path) => self.save_to(&path),
            None => self.save_as_dialog(false),
        }
    }

    pub(super) fn save_as_dialog(&mut self, then_close: bool) {
        self.file_action = Some(FileAction::SaveAs { then_close });
        self.file_dialog.save_file();
    }

    /// Saves to `path` (atomic, with a `.bak` of the previous file), with the view on screen.
    pub fn save_to(&mut self, path: &std::path::Path) {
        self.doc.project.view = Some(self.view.camera.to_camera("view"));
        match self.doc.save_as(path) {
            Ok(()) => {
                document::remember_recent(path);
                self.action_errors.clear();
                self.log_info(format!("saved {}", path.display()));
                if let Some(status) = self.options.status_file.clone() {
                    self.append_status(&status, &format!("saved {}", path.display()));
                }
            }
            Err(e) => self.log_file_error(format!("{e:#}")),
        }
    }

    /// Asks first when there are unsaved changes.
    pub(super) fn request(&mut self, what: Pending) {
        if self.doc.is_dirty() {
            self.pending = Some(what);
        } else {
            self.perform(what);
        }
    }

    pub(super) fn perform(&mut self, what: Pending) {
        match what {
            Pending::Open(path) => self.open(&path),
            Pending::OpenSample(stem) => self.open_sample(&stem),
            Pending::New => {
                self.doc.discard_recovery();
                self.replace_document(Document::new(default_project(), None));
            }
            Pending::Close => {
                self.close_confirmed = true;
            }
            Pending::Recover(..) | Pending::Rename { .. } => {}
        }
    }

    /// Opens a project file (errors go to the log; the current document stays).
    pub fn open(&mut self, path: &std::path::Path) {
        match Document::open(path) {
            Ok(doc) => {
                self.doc.discard_recovery();
                document::remember_recent(path);
                self.action_errors.clear();
                self.log_info(format!("opened {}", path.display()));
                self.replace_document(doc);
                if let Some((p, at)) = document::pending_recovery(self.doc.path.as_deref()) {
                    self.pending = Some(Pending::Recover(p, at));
                }
            }
            Err(e) => self.log_file_error(format!("{e:#}")),
        }
    }

    pub(super) fn render_image_dialog(&mut self) {
        let mut dialog = egui_file_dialog::FileDialog::new()
            .add_save_extension("PNG image (tone-mapped)", "png")
            .add_save_extension("OpenEXR image (linear radiance)", "exr")
            .default_save_extension("PNG image (tone-mapped)")
            .default_file_name("render.png")
            .initial_directory(std::path::absolute(self.doc.project_dir()).unwrap_or_default());
        dialog.save_file();
        self.image_dialog = Some(dialog);
    }

    /// Renders what the viewport's render frame shows (the view, at the project's render
    /// size) to `path` as `lightloom render` does, on its own thread, sharing the editor's
    /// engine and its caches.
    pub fn render_image_to(&mut self, path: PathBuf) {
        let extension = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        if !matches!(extension.as_deref(), Some("png" | "exr")) {
            self.log_file_error(format!(
                "{}: choose a .png (tone-mapped) or .exr (linear radiance) file",
                path.display()
            ));
            return;
        }
        let mut project = self.doc.project.clone();
        project.view = Some(self.view.camera.to_camera("view"));
        let graph = match project.graph(&self.doc.project_dir()) {
            Ok(graph) => graph,
            Err(errors) => {
                let text: Vec<String> = errors.iter().map(ToString::to_string).collect();
                self.log_error(format!("cannot render {}: {}", path.display(), text.join("; ")));
                return;
            }
        };
        let engine = self.evaluator.engine.clone();
        let (send, result) = std::sync::mpsc::channel();
        let target = path.clone();
        let spawned = std::thread::Builder::new().name("lightloom-render-image".into()).spawn(move || {
            let rendered =
                crate::project_commands::render_project(&project, &graph, engine, None, None, (None, None), true)
                    .and_then(|r| {
                        crate::project_commands::write_image(&r.frame, &target)
                            .map(|()| (r.frame.width, r.frame.height))
                    })
                    .map_err(|e| format!("{e:#}"));
            let _ = send.send(rendered);
        });
        match spawned {
            Ok(_) => self.image_render = Some(ImageRender { path, started: std::time::Instant::now(), result }),
            Err(e) => self.log_file_error(format!("cannot start rendering {}: {e}", path.display())),
        }
    }

    pub(super) fn poll_image_render(&mut self, ctx: &egui::Context) {
        let Some(job) = &self.image_render else { return };
        let Some(outcome) = finished(&job.result, ctx, "the render") else { return };
        let job = self.image_render.take().expect("checked above");
        let took = crate::project_commands::duration_text(job.started.elapsed().as_secs_f64());
        match outcome {
            Ok((w, h)) => self.log_info(format!("rendered {} ({w}×{h}) in {took}", job.path.display())),
            Err(e) => self.log_file_error(format!("render to {} failed: {e}", job.path.display())),
        }
    }

    /// Edits the object list of Scene node `node` as one undo step.
    fn edit_objects(
        &mut self,
        node: &str,
        label: &str,
        f: impl FnOnce(&mut Vec<lightloom_nodes::kinds::scene::SceneObject>) -> Result<(), String>,
    ) -> Result<(), String> {
        let spec = edits::kind_of(&self.doc.project, node)
            .and_then(|k| k.param("objects"))
            .ok_or_else(|| format!("node `{node}` has no object list"))?;
        let ParamValue::Objects(mut objects) = inspector::param_value(&self.doc.project, node, spec) else {
            return Err(format!("node `{node}` has no object list"));
        };
        f(&mut objects)?;
        self.doc.edit(label, None, |p| {
            spec.check(&ParamValue::Objects(objects.clone()))?;
            let n = p.nodes.iter_mut().find(|n| n.id == node).ok_or_else(|| format!("no node `{node}`"))?;
            n.params.insert("objects".into(), ParamValue::Objects(objects));
            Ok(())
        })
    }

    /// Adds the glTF model `file` (relative to the project) to Scene node `node` as an object
    /// resting on the floor at the origin, selects it and frames the view on it.
    pub fn import_model(&mut self, node: &str, file: &str) -> Result<(), String> {
        let path = self.doc.project_dir().join(file);
        let imported = lightloom_nodes::gltf_import::import(&path)?;
        let (lo, hi) = lightloom_nodes::mesh::union_bounds(&imported.meshes);
        if lo[0] > hi[0] {
            return Err(format!("{}: the model has no triangles", path.display()));
        }
        for warning in &imported.warnings {
            self.log_info(format!("{}: {warning}", path.display()));
        }
        let stem = std::path::Path::new(file).file_stem().map_or("model".into(), |s| s.to_string_lossy().into_owned());
        let centre = [0, 1, 2].map(|a| (f64::from(lo[a]) + f64::from(hi[a])) / 2.0);
        let mut index = 0;
        self.edit_objects(node, &format!("Import {stem}"), |objects| {
            let mut name = stem.clone();
            let mut n = 2;
            while objects.iter().any(|o| o.name == name) {
                name = format!("{stem}{n}");
                n += 1;
            }
            let mut model = lightloom_nodes::kinds::scene::SceneObject::new(
                &name,
                lightloom_nodes::kinds::scene::Shape::Gltf { file: file.to_string() },
            );
            // (+ 0.0: no "-0" in the inspector)
            model.translation = [-centre[0] + 0.0, -f64::from(lo[1]) + 0.0, -centre[2] + 0.0];
            objects.push(model);
            index = objects.len() - 1;
            Ok(())
        })?;
        self.selection = Selection::Node(node.to_string());
        self.view.selected_object = Some(index);
        let half = [0, 1, 2].map(|a| (hi[a] - lo[a]) / 2.0);
        self.view.camera.frame(([-half[0], 0.0, -half[2]], [half[0], hi[1] - lo[1], half[2]]));
        self.log_info(format!(
            "imported {file}: {:.2} × {:.2} × {:.2} m, placed on the floor at the origin",
            hi[0] - lo[0],
            hi[1] - lo[1],
            hi[2] - lo[2]
        ));
        Ok(())
    }

    /// Opens a copy of the built-in sample `stem` (see [`sample_copy`]).
    pub fn open_sample(&mut self, stem: &str) {
        match sample_copy(stem) {
            Ok((copy, path)) => {
                self.doc.discard_recovery();
                self.action_errors.clear();
                self.replace_document(copy);
                self.log_info(format!("opened a copy of the sample {}", path.display()));
            }
            Err(e) => self.log_file_error(format!("{e:#}")),
        }
    }

    pub(super) fn replace_document(&mut self, doc: Document) {
        self.doc = doc;
        self.selection = Selection::None;
        self.view.selected_object = None;
        self.view.frame = None;
        self.view.reference_image = None;
        (self.view.camera, self.view.camera_name) = initial_view(&self.doc.project);
        self.request_evaluation();
        self.graph = GraphEditor::default();
        self.graph_revision = u64::MAX;
    }

    pub(super) fn dialogs(&mut self, ctx: &egui::Context) {
        if let Some(path) = self.image_dialog.as_mut().and_then(|d| d.update(ctx).picked().map(PathBuf::from)) {
            self.image_dialog = None;
            self.render_image_to(path);
        }
        if let Some(path) = self.bake_dialog.as_mut().and_then(|d| d.update(ctx).picked().map(PathBuf::from)) {
            self.bake_dialog = None;
            self.bake_to(path);
        }
        self.file_dialog.update(ctx);
        let asset = self.asset_dialog.as_mut().and_then(|d| d.update(ctx).picked().map(PathBuf::from));
        if let Some(path) = self.file_dialog.take_picked().or(asset) {
            self.asset_dialog = None;
            match self.file_action.take() {
                Some(FileAction::Open) => self.request(Pending::Open(path)),
                Some(FileAction::SaveAs { then_close }) => {
                    self.save_to(&path);
                    if then_close && !self.doc.is_dirty() {
                        self.close_confirmed = true;
                        ctx.send_viewport_cmd(egui::ViewportCommand::Close);
                    }
                }
                Some(FileAction::Browse { node, target }) => {
                    let dir = std::path::absolute(self.doc.project_dir()).unwrap_or_default();
                    let value = path.strip_prefix(&dir).map_or(path.clone(), PathBuf::from).display().to_string();
                    let result = match target {
                        inspector::FileTarget::Param(param) => {
                            inspector::set_param(&mut self.doc, &node, &param, ParamValue::Path(value))
                        }
                        inspector::FileTarget::NewModel => self.import_model(&node, &value),
                        inspector::FileTarget::Model(index) => {
                            self.edit_objects(&node, "Choose model file", |objects| {
                                match objects.get_mut(index).map(|o| &mut o.shape) {
                                    Some(lightloom_nodes::kinds::scene::Shape::Gltf { file }) => {
                                        *file = value.clone();
                                        Ok(())
                                    }
                                    _ => Err(format!("object {index} is not a glTF model")),
                                }
                            })
                        }
                    };
                    if let Err(e) = result {
                        self.log_error(e);
                    }
                    self.doc.seal();
                }
                None => {}
            }
        }
        let Some(pending) = self.pending.clone() else { return };
        let modal = egui::Modal::new(egui::Id::new("pending")).show(ctx, |ui| {
            ui.set_max_width(420.0);
            match &pending {
                Pending::Recover(path, at) => {
                    let age = at.elapsed().map_or(0, |d| d.as_secs());
                    ui.heading("Recover unsaved work?");
                    ui.label(format!(
                        "Lightloom did not close cleanly. Autosaved changes from {} minute(s) ago are in {}.",
                        age / 60,
                        path.display()
                    ));
                    ui.horizontal(|ui| {
                        if ui.button("Recover").clicked() {
                            match Document::open(path) {
                                Ok(recovered) => {
                                    let project = recovered.project;
                                    let _ = self.doc.edit("Recover autosaved changes", None, |p| {
                                        *p = project;
                                        Ok(())
                                    });
                                    self.log_info(format!("recovered {}", path.display()));
                                }
                                Err(e) => self.log_error(format!("{e:#}")),
                            }
                            self.pending = None;
                        }
                        if ui.button("Discard").clicked() {
                            let _ = std::fs::remove_file(path);
                            self.pending = None;
                        }
                    });
                }
                Pending::Rename { node, text } => {
                    ui.heading(format!("Rename {node}"));
                    let mut text = text.clone();
                    let r = ui.text_edit_singleline(&mut text);
                    r.request_focus();
                    let done = ui.input(|i| i.key_pressed(egui::Key::Enter));
                    self.pending = Some(Pending::Rename { node: node.clone(), text: text.clone() });
                    ui.horizontal(|ui| {
                        if ui.button("Rename").clicked() || done {
                            let node = node.clone();
                            let result = self.doc.edit(format!("Rename {node}"), None, |p| {
                                let n = p.nodes.iter_mut().find(|n| n.id == node).ok_or("node vanished")?;
                                n.label = text.trim().to_string();
                                Ok(())
                            });
                            if let Err(e) = result {
                                self.log_error(e);
                            }
                            self.pending = None;
                        }
                        if ui.button("Cancel").clicked() {
                            self.pending = None;
                        }
                    });
                }
                what => {
                    ui.heading("Save changes?");
                    ui.label(format!(
                        "{} has unsaved changes.",
                        self.doc.path.as_ref().map_or("This project".into(), |p| p.display().to_string())
                    ));
                    ui.horizontal(|ui| {
                        if ui.button("Save").clicked() {
                            self.pending = None;
                            match self.doc.path.clone() {
                                Some(p) => {
                                    self.save_to(&p);
                                    if !self.doc.is_dirty() {
                                        self.perform(what.clone());
                                    }
                                }
                                None => self.save_as_dialog(matches!(what, Pending::Close)),
                            }
                        }
                        if ui.button("Discard changes").clicked() {
                            self.pending = None;
                            self.doc.discard_recovery();
                            self.perform(what.clone());
                        }
                        if ui.button("Cancel").clicked() {
                            self.pending = None;
                        }
                    });
                }
            }
        });
        if modal.should_close() && !matches!(pending, Pending::Recover(..)) {
            self.pending = None;
        }
        if self.close_confirmed && matches!(pending, Pending::Close) {
            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
        }
    }

    pub(super) fn handle_close(&mut self, ctx: &egui::Context) {
        if ctx.input(|i| i.viewport().close_requested()) && !self.close_confirmed && self.doc.is_dirty() {
            ctx.send_viewport_cmd(egui::ViewportCommand::CancelClose);
            self.pending = Some(Pending::Close);
        }
    }

    pub(super) fn autosave(&mut self) {
        if self.close_confirmed {
            return;
        }
        match self.doc.autosave(AUTOSAVE_INTERVAL) {
            Ok(Some(path)) => self.log_info(format!("autosaved to {}", path.display())),
            Ok(None) => {}
            Err(e) => self.log_file_error(format!("autosave failed: {e:#}")),
        }
    }

    /// With `--screenshot`: once the first evaluation is on screen, capture the window, save
    /// it, and close.
    /// `--status-file`: a line each time the view settles (evaluated, drawn, not a preview)
    /// or the document is saved: what, seconds since start, and the layout in window pixels.
    pub(super) fn report_status(&mut self, ctx: &egui::Context) {
        let Some(path) = self.options.status_file.clone() else { return };
        let settled = self.view.frame.as_ref().is_some_and(|f| f.pending.is_none())
            && self.view.drawn != 0
            && !self.evaluator.is_running()
            && !self.host.as_ref().is_some_and(|h| h.is_busy());
        let state = if settled {
            format!(
                "settled revision={} mode={}",
                self.doc.revision(),
                self.view.frame.as_ref().map_or("none".into(), |f| f.mode.to_string())
            )
        } else {
            String::new()
        };
        if state.is_empty() || state == self.last_status {
            return;
        }
        self.last_status = state.clone();
        let px = |r| window_pixels(ctx, r);
        let line =
            format!("{state} viewport={} frame={}", px(self.viewport_rect), px(self.render_frame(self.viewport_rect)));
        self.append_status(&path, &line);
    }

    fn append_status(&self, path: &std::path::Path, line: &str) {
        use std::io::Write;
        let line = format!("{line} t={:.2}\n", self.started.elapsed().as_secs_f64());
        let written = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)
            .and_then(|mut f| f.write_all(line.as_bytes()));
        if let Err(e) = written {
            eprintln!("cannot write the status file {}: {e}", path.display());
        }
    }

    pub(super) fn screenshot(&mut self, ctx: &egui::Context) {
        match self.screenshot_state {
            ScreenshotState::Waiting
                if self.view.frame.is_some()
                    && self.view.drawn != 0
                    && !self.evaluator.is_running()
                    && !self.host.as_ref().is_some_and(|h| h.is_busy()) =>
            {
                ctx.send_viewport_cmd(egui::ViewportCommand::Screenshot(egui::UserData::default()));
                self.screenshot_state = ScreenshotState::Requested;
            }
            ScreenshotState::Requested => {
                let image = ctx.input(|i| {
                    i.events.iter().find_map(|e| match e {
                        egui::Event::Screenshot { image, .. } => Some(image.clone()),
                        _ => None,
                    })
                });
                if let Some(image) = image {
                    let path = self.options.screenshot.clone().expect("screenshot path");
                    let saved =
                        image::RgbaImage::from_raw(image.size[0] as u32, image.size[1] as u32, image.as_raw().to_vec())
                            .ok_or_else(|| "bad screenshot size".to_string())
                            .and_then(|img| img.save(&path).map_err(|e| e.to_string()));
                    let px = |r| window_pixels(ctx, r);
                    let problems = self.problems();
                    match saved {
                        Ok(()) => println!(
                            "screenshot: {} ({}x{}); graph {}; viewport {}; frame {}; project {:?}; problems {}{}",
                            path.display(),
                            image.size[0],
                            image.size[1],
                            px(self.graph_rect),
                            px(self.viewport_rect),
                            px(self.render_frame(self.viewport_rect)),
                            self.doc.project.name,
                            problems.len(),
                            problems.iter().map(|p| format!("\n  problem: {p}")).collect::<String>()
                        ),
                        Err(e) => eprintln!("screenshot failed: {e}"),
                    }
                    self.screenshot_state = ScreenshotState::Done;
                    self.close_confirmed = true;
                    ctx.send_viewport_cmd(egui::ViewportCommand::Close);
                }
                ctx.request_repaint();
            }
            ScreenshotState::Waiting => ctx.request_repaint_after(Duration::from_millis(100)),
            _ => {}
        }
    }
}
