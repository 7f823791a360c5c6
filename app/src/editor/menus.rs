//! Keyboard shortcuts, the menu bar, the status bar and the problems / log / timings panel.

use super::*;

impl EditorApp {
    pub(super) fn shortcuts(&mut self, ctx: &egui::Context) {
        use egui::{Key, KeyboardShortcut, Modifiers};
        let typing = ctx.egui_wants_keyboard_input();
        let pressed = |m: Modifiers, k: Key| ctx.input_mut(|i| i.consume_shortcut(&KeyboardShortcut::new(m, k)));
        if pressed(Modifiers::COMMAND | Modifiers::SHIFT, Key::Z) || pressed(Modifiers::COMMAND, Key::Y) {
            self.redo();
        } else if !typing && pressed(Modifiers::COMMAND, Key::Z) {
            self.undo();
        }
        if pressed(Modifiers::COMMAND | Modifiers::SHIFT, Key::S) {
            self.save_as_dialog(false);
        } else if pressed(Modifiers::COMMAND, Key::S) {
            self.save();
        }
        if pressed(Modifiers::COMMAND, Key::O) {
            self.file_action = Some(FileAction::Open);
            self.file_dialog.pick_file();
        }
        if pressed(Modifiers::COMMAND, Key::N) {
            self.request(Pending::New);
        }
        if pressed(Modifiers::NONE, Key::F12) && self.image_render.is_none() {
            self.render_image_dialog();
        }
        if !typing && pressed(Modifiers::NONE, Key::F5) {
            self.request_evaluation();
        }
        if !typing
            && let Some(text) = ctx.input(|i| {
                i.events.iter().find_map(|e| if let egui::Event::Paste(t) = e { Some(t.clone()) } else { None })
            })
        {
            self.paste(Some(&text));
        }
    }

    pub(super) fn undo(&mut self) {
        if let Some(label) = self.doc.undo_label().map(String::from)
            && self.doc.undo()
        {
            self.log_info(format!("undo: {label}"));
        }
    }

    pub(super) fn redo(&mut self) {
        if let Some(label) = self.doc.redo_label().map(String::from)
            && self.doc.redo()
        {
            self.log_info(format!("redo: {label}"));
        }
    }

    pub(super) fn menu_bar(&mut self, ui: &mut egui::Ui) {
        egui::MenuBar::new().ui(ui, |ui| {
            ui.menu_button("File", |ui| {
                if ui.button("New  (Ctrl+N)").clicked() {
                    self.request(Pending::New);
                    ui.close();
                }
                if ui.button("Open…  (Ctrl+O)").clicked() {
                    self.file_action = Some(FileAction::Open);
                    self.file_dialog.pick_file();
                    ui.close();
                }
                ui.menu_button("Open sample", |ui| {
                    if ui.button("Default: sphere and torus under a procedural sky").clicked() {
                        self.request(Pending::New);
                        ui.close();
                    }
                    for sample in crate::samples::list() {
                        if ui.button(sample.title).clicked() {
                            self.request(Pending::OpenSample(sample.stem.to_string()));
                            ui.close();
                        }
                    }
                });
                ui.menu_button("Open recent", |ui| {
                    let recent = document::recent_files();
                    if recent.is_empty() {
                        ui.weak("no recent projects");
                    }
                    for path in recent {
                        if ui.button(path.display().to_string()).clicked() {
                            self.request(Pending::Open(path));
                            ui.close();
                        }
                    }
                });
                ui.separator();
                if ui.button("Save  (Ctrl+S)").clicked() {
                    self.save();
                    ui.close();
                }
                if ui.button("Save As…  (Ctrl+Shift+S)").clicked() {
                    self.save_as_dialog(false);
                    ui.close();
                }
                ui.separator();
                let render = ui
                    .add_enabled(self.image_render.is_none(), egui::Button::new("Render image…  (F12)"))
                    .on_hover_text(
                        "render what the viewport's frame shows, at the project's render size, to PNG or EXR",
                    );
                if render.clicked() {
                    self.render_image_dialog();
                    ui.close();
                }
                let bake = ui.add_enabled(self.bake.is_none(), egui::Button::new("Bake…")).on_hover_text(
                    "bake the Output's lighting for game engines into a folder: scene.glb (light per vertex and \
                         a lightmap), lightmap.exr and bake.json",
                );
                if bake.clicked() {
                    self.bake_dialog();
                    ui.close();
                }
                ui.separator();
                if ui.button("Quit").clicked() {
                    ui.ctx().send_viewport_cmd(egui::ViewportCommand::Close);
                    ui.close();
                }
            });
            ui.menu_button("Edit", |ui| {
                let undo = self.doc.undo_label().map_or("Undo".to_string(), |l| format!("Undo {l}"));
                if ui
                    .add_enabled(self.doc.undo_label().is_some(), egui::Button::new(format!("{undo}  (Ctrl+Z)")))
                    .clicked()
                {
                    self.undo();
                    ui.close();
                }
                let redo = self.doc.redo_label().map_or("Redo".to_string(), |l| format!("Redo {l}"));
                if ui
                    .add_enabled(self.doc.redo_label().is_some(), egui::Button::new(format!("{redo}  (Ctrl+Shift+Z)")))
                    .clicked()
                {
                    self.redo();
                    ui.close();
                }
                ui.separator();
                let selected = self.graph.selected.clone();
                let any = !selected.is_empty();
                if ui.add_enabled(any, egui::Button::new("Copy  (Ctrl+C)")).clicked() {
                    self.apply(vec![GraphAction::Copy(selected.clone())]);
                    ui.close();
                }
                if ui.add_enabled(self.clipboard.is_some(), egui::Button::new("Paste  (Ctrl+V)")).clicked() {
                    self.paste(None);
                    ui.close();
                }
                if ui.add_enabled(any, egui::Button::new("Duplicate  (Shift+D)")).clicked() {
                    self.apply(vec![GraphAction::Duplicate(selected.clone())]);
                    ui.close();
                }
                if ui.add_enabled(any, egui::Button::new("Delete  (X)")).clicked() {
                    self.apply(vec![GraphAction::Remove(selected.clone())]);
                    ui.close();
                }
                if ui.add_enabled(selected.len() == 1, egui::Button::new("Rename…  (F2)")).clicked() {
                    self.apply(vec![GraphAction::Rename(selected[0].clone())]);
                    ui.close();
                }
            });
            ui.menu_button("Add", |ui| {
                let mut query = String::new();
                if let Some(kind) = graph_editor::add_list(ui, &mut query, None) {
                    let position = self.graph.free_spot(self.graph_rect, &self.doc.project, &kind);
                    self.apply(vec![GraphAction::Add { kind, position, link: None }]);
                    ui.close();
                }
            });
            ui.menu_button("Evaluate", |ui| {
                if ui.button("Re-evaluate  (F5)").clicked() {
                    self.request_evaluation();
                    ui.close();
                }
                if ui.add_enabled(self.evaluator.is_running(), egui::Button::new("Cancel evaluation")).clicked() {
                    self.evaluator.cancel();
                    ui.close();
                }
            });
        });
    }

    pub(super) fn status_bar(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            // First, so its Cancel stays put while the evaluation's status comes and goes.
            self.bake_status(ui);
            if let Some(p) = &self.evaluator.progress {
                let fraction = if p.total > 0 { p.done as f32 / p.total as f32 } else { 0.0 };
                let text = if p.total == 0 {
                    "evaluating: scheduling".to_string()
                } else {
                    format!("evaluating {}/{} {}", p.done, p.total, p.describe())
                };
                ui.add(egui::ProgressBar::new(fraction).desired_width(260.0).text(text));
                ui.label(crate::project_commands::duration_text(p.started.elapsed().as_secs_f64()));
                if ui.button("Cancel").clicked() {
                    self.evaluator.cancel();
                }
            } else if self.evaluator.cancelled_revision.is_some() {
                ui.label("evaluation cancelled — F5 re-evaluates");
            } else if let Some((evaluation, _)) = &self.evaluator.last {
                let took = crate::project_commands::duration_text(evaluation.report.total_ms / 1e3);
                ui.label(format!("evaluated in {took}"));
            }
            if let Some(job) = &self.image_render {
                ui.separator();
                ui.spinner();
                let took = crate::project_commands::duration_text(job.started.elapsed().as_secs_f64());
                ui.label(format!("rendering {} ({took})", job.path.display()));
            }
            if let Some(job) = &self.view.reference {
                ui.separator();
                ui.add(
                    egui::ProgressBar::new(job.fraction())
                        .desired_width(200.0)
                        .text(format!("reference {}x{}", job.size.0, job.size.1)),
                );
                if ui.button("Cancel reference").clicked() {
                    job.cancel();
                }
            }
            ui.with_layout(egui::Layout::right_to_left(egui::Align::Center), |ui| {
                let ui_ms = self.stats.frames.last().map_or(0.0, |f| f.ui_ms);
                let draw_ms = self.host.as_ref().map_or(0.0, |h| h.last_draw_ms);
                ui.weak(format!("UI {ui_ms:.1} ms · viewport draw {draw_ms:.0} ms"));
                if self.doc.is_dirty() {
                    ui.colored_label(Color32::from_rgb(230, 180, 60), "unsaved changes");
                }
            });
        });
    }

    pub(super) fn bottom_panel(&mut self, ui: &mut egui::Ui) {
        let problems = self.problems();
        ui.horizontal(|ui| {
            ui.selectable_value(&mut self.bottom_tab, BottomTab::Problems, format!("Problems ({})", problems.len()));
            ui.selectable_value(&mut self.bottom_tab, BottomTab::Log, "Log");
            ui.selectable_value(&mut self.bottom_tab, BottomTab::Timings, "Stage timings");
        });
        ui.separator();
        egui::ScrollArea::vertical().stick_to_bottom(self.bottom_tab == BottomTab::Log).show(ui, |ui| {
            match self.bottom_tab {
                BottomTab::Problems => {
                    if problems.is_empty() {
                        ui.weak("no problems");
                    }
                    for p in problems {
                        ui.colored_label(Color32::from_rgb(235, 90, 80), p);
                    }
                }
                BottomTab::Log => {
                    for line in &self.log {
                        let at = line.at.duration_since(SystemTime::UNIX_EPOCH).map_or(0, |d| d.as_secs());
                        let text = format!("{:02}:{:02}:{:02}  {}", at / 3600 % 24, at / 60 % 60, at % 60, line.text);
                        if line.error {
                            ui.colored_label(Color32::from_rgb(235, 90, 80), text);
                        } else {
                            ui.label(text);
                        }
                    }
                }
                BottomTab::Timings => self.timings(ui),
            }
        });
    }

    pub(super) fn problems(&self) -> Vec<String> {
        let revision = self.doc.revision();
        let mut out: Vec<String> = self
            .action_errors
            .iter()
            .filter(|(r, _)| r.is_none_or(|r| r == revision))
            .map(|(_, text)| text.clone())
            .collect();
        out.extend(self.graph_errors.iter().cloned());
        if let Some(e) = &self.host_error {
            out.push(format!("viewport: {e}"));
        }
        if let Some(e) = &self.view.frame_error {
            out.push(format!("viewport: {e}"));
        }
        if let Some((evaluation, _)) = &self.evaluator.last {
            // Stages blocked by a failure listed here add nothing to it.
            let failed = evaluation.report.failed();
            let any_own = failed.iter().any(|s| s.status != lightloom_nodes::engine::StageStatus::Blocked);
            for s in failed {
                if any_own && s.status == lightloom_nodes::engine::StageStatus::Blocked {
                    continue;
                }
                out.push(format!(
                    "{}.{}: {}",
                    s.node,
                    s.stage,
                    s.error.as_deref().unwrap_or("blocked by a failed input")
                ));
            }
            for s in &evaluation.report.stages {
                for w in &s.warnings {
                    out.push(format!("{}.{}: warning: {w}", s.node, s.stage));
                }
            }
        }
        for (node, _, path) in self.missing_assets() {
            out.push(format!("node `{node}`: file {} does not exist", path.display()));
        }
        if let Some(frame) = &self.view.frame {
            for (node, message) in &frame.lobe_limits {
                out.push(format!("note: material `{node}`: {message}"));
            }
        }
        // A stage read by several requests of one evaluation is reported by each.
        let mut seen = std::collections::HashSet::new();
        out.retain(|p| seen.insert(p.clone()));
        out
    }

    /// Asset files the current graph names that do not exist (checked on disk each frame, so
    /// a file that appears clears its problem).
    pub(super) fn missing_assets(&self) -> Vec<(String, String, PathBuf)> {
        self.built_graph.as_ref().map_or_else(Vec::new, |g| self.doc.project.missing_assets(g))
    }

    pub(super) fn timings(&self, ui: &mut egui::Ui) {
        let Some((evaluation, _)) = &self.evaluator.last else {
            ui.weak("nothing evaluated yet");
            return;
        };
        let report = &evaluation.report;
        ui.label(format!(
            "last evaluation: {:.1} ms, memory cache {:.1} MB",
            report.total_ms,
            report.memory_cache_bytes as f64 / 1e6
        ));
        egui::Grid::new("timings").striped(true).show(ui, |ui| {
            ui.strong("node");
            ui.strong("stage");
            ui.strong("status");
            ui.strong("ms");
            ui.strong("why");
            ui.end_row();
            let mut stages: Vec<_> = report.stages.iter().collect();
            stages.sort_by(|a, b| b.ms.total_cmp(&a.ms));
            for s in stages {
                ui.label(&s.node);
                ui.label(s.stage.as_ref());
                ui.label(format!("{:?}", s.status).to_lowercase());
                ui.label(format!("{:.2}", s.ms));
                ui.label(s.reasons.join("; "));
                ui.end_row();
            }
        });
    }
}
