//! The graph panel and the inspector: user actions applied to the project as edits.

use super::*;

impl EditorApp {
    // ----- graph -----

    pub(super) fn graph_panel(&mut self, ui: &mut egui::Ui) {
        self.graph_rect = ui.max_rect();
        if self.graph_revision != self.doc.revision() {
            self.graph.sync(&self.doc.project);
            self.graph_revision = self.doc.revision();
        }
        let evaluation = self.evaluator.last.as_ref().map(|(e, _)| e.clone());
        let feeding: Option<std::collections::HashSet<String>> = self
            .built_graph
            .as_ref()
            .map(|g| g.nodes.iter().filter(|n| g.feeds_sink(&n.id)).map(|n| n.id.clone()).collect());
        let actions = self.graph.show(
            ui,
            &self.doc.project,
            &self.evaluator.status,
            evaluation.as_deref(),
            feeding.as_ref(),
            &mut self.previews,
        );
        if self.graph.selection_changed
            && let [id] = self.graph.selected.as_slice()
            && self.selection != Selection::Node(id.clone())
        {
            self.selection = Selection::Node(id.clone());
            self.view.selected_object = None;
        }
        if ui.input(|i| i.key_pressed(egui::Key::F2))
            && !ui.ctx().egui_wants_keyboard_input()
            && let [id] = self.graph.selected.as_slice()
        {
            self.pending = Some(Pending::Rename { node: id.clone(), text: id.clone() });
        }
        self.apply(actions);
    }

    /// Applies graph actions to the document (each an undoable edit).
    pub fn apply(&mut self, actions: Vec<GraphAction>) {
        for action in actions {
            let result: Result<(), String> = match action {
                GraphAction::Add { kind, position, link } => {
                    let result = self.doc.edit(format!("Add {kind}"), None, |p| {
                        let id = edits::add_node(p, &kind, position)?;
                        let spec = edits::kind_of(p, &id).expect("just added");
                        match link {
                            Some(PendingLink::FromOutput(node, port)) => {
                                let ty = edits::kind_of(p, &node).and_then(|k| k.output(&port)).map(|o| o.ty);
                                if let Some(input) = spec.inputs.iter().find(|i| Some(i.ty) == ty) {
                                    edits::connect(p, &(node, port), &(id.clone(), input.name.into()))?;
                                }
                            }
                            Some(PendingLink::ToInput(node, port)) => {
                                let ty = edits::kind_of(p, &node).and_then(|k| k.input(&port)).map(|o| o.ty);
                                if let Some(output) = spec.outputs.iter().find(|o| Some(o.ty) == ty) {
                                    edits::connect(p, &(id.clone(), output.name.into()), &(node, port))?;
                                }
                            }
                            None => {}
                        }
                        Ok(id)
                    });
                    result.map(|id| {
                        self.selection = Selection::Node(id);
                    })
                }
                GraphAction::Connect { from, to } => {
                    self.doc.edit(format!("Link {}.{} → {}.{}", from.0, from.1, to.0, to.1), None, |p| {
                        edits::connect(p, &from, &to)
                    })
                }
                GraphAction::Disconnect { from, to } => {
                    self.doc.edit(format!("Unlink {}.{} → {}.{}", from.0, from.1, to.0, to.1), None, |p| {
                        edits::disconnect(p, &from, &to);
                        Ok(())
                    })
                }
                GraphAction::DisconnectPort { port, input } => {
                    self.doc.edit(format!("Unlink {}.{}", port.0, port.1), None, |p| {
                        edits::disconnect_port(p, &port, input);
                        Ok(())
                    })
                }
                GraphAction::Remove(ids) => {
                    if ids.iter().any(|id| matches!(&self.selection, Selection::Node(s) if s == id)) {
                        self.selection = Selection::None;
                    }
                    self.doc.edit(format!("Delete {}", ids.join(", ")), None, |p| {
                        edits::remove_nodes(p, &ids);
                        Ok(())
                    })
                }
                GraphAction::Duplicate(ids) => {
                    let clipboard = edits::Clipboard::copy(&self.doc.project, &ids);
                    self.doc
                        .edit(format!("Duplicate {}", ids.join(", ")), None, |p| {
                            edits::paste(p, &clipboard, [40.0, 40.0])
                        })
                        .map(|_| ())
                }
                GraphAction::Copy(ids) => {
                    let clipboard = edits::Clipboard::copy(&self.doc.project, &ids);
                    self.graph_copy_text(&clipboard);
                    self.clipboard = Some(clipboard);
                    Ok(())
                }
                GraphAction::Rename(id) => {
                    let text = edits::node(&self.doc.project, &id).map(|n| n.label.clone()).unwrap_or_default();
                    self.pending = Some(Pending::Rename { node: id, text });
                    Ok(())
                }
                GraphAction::Move(moves) => self.doc.edit("Move nodes", Some("move nodes"), |p| {
                    for (id, pos) in &moves {
                        if let Some(n) = p.nodes.iter_mut().find(|n| &n.id == id) {
                            n.position = *pos;
                        }
                    }
                    Ok(())
                }),
                GraphAction::Refused(reason) => Err(reason),
            };
            if let Err(e) = result {
                self.graph.notice = Some((e.clone(), Instant::now()));
                self.log_error(e);
            }
        }
    }

    pub(super) fn graph_copy_text(&mut self, clipboard: &edits::Clipboard) {
        self.copy_request = Some(clipboard.to_text());
    }

    pub(super) fn paste(&mut self, text: Option<&str>) {
        let clipboard = text.and_then(edits::Clipboard::from_text).or_else(|| self.clipboard.clone());
        let Some(clipboard) = clipboard else { return };
        let result = self.doc.edit("Paste nodes", None, |p| edits::paste(p, &clipboard, [60.0, 60.0]));
        if let Err(e) = result {
            self.log_error(e);
        }
    }

    // ----- inspector -----

    pub(super) fn inspector(&mut self, ui: &mut egui::Ui) {
        let Selection::Node(id) = self.selection.clone() else {
            ui.weak("Select a node to edit it, or click an object in the viewport.");
            return;
        };
        if edits::node(&self.doc.project, &id).is_none() {
            self.selection = Selection::None;
            return;
        }
        let frame_meshes = self.view.frame.clone();
        let mut inspector = inspector::Inspector {
            doc: &mut self.doc,
            status: self.evaluator.status.get(&id),
            report: self.evaluator.last.as_ref().map(|(e, _)| &e.report),
            selected_object: &mut self.view.selected_object,
            meshes: frame_meshes.as_ref().and_then(|f| f.geometry.meshes.value.get::<lightloom_nodes::mesh::MeshSet>()),
            limits: frame_meshes
                .as_ref()
                .map(|f| f.lobe_limits.iter().filter(|(n, _)| *n == id).map(|(_, m)| m.clone()).collect())
                .unwrap_or_default(),
            requests: Vec::new(),
            errors: Vec::new(),
            canvas: &mut self.paint_canvas,
            evaluation: self.evaluator.last.as_ref().map(|(e, _)| e.as_ref()),
        };
        inspector.show(ui, &id);
        let (requests, errors) = (inspector.requests, inspector.errors);
        for e in errors {
            self.log_error(e);
        }
        for r in requests {
            let inspector::InspectorRequest::Browse { node, target, extensions } = r;
            self.file_action = Some(FileAction::Browse { node, target });
            // Its own dialog, filtered to the parameter's file types (the project dialog keeps
            // its .ron filter).
            let mut dialog = egui_file_dialog::FileDialog::new()
                .add_file_filter_extensions("Supported files", extensions.to_vec())
                .default_file_filter("Supported files")
                .initial_directory(std::path::absolute(self.doc.project_dir()).unwrap_or_default());
            dialog.pick_file();
            self.asset_dialog = Some(dialog);
        }
    }
}
