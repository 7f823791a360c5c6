//! The inspector: the selected node's name, status, stage timings, inputs and parameters
//! (typed widgets with ranges and units; object lists with transforms). Every change is an
//! undoable edit of the document; a drag is one undo step.

use super::document::Document;
use super::edits;
use super::jobs::NodeStatus;
use eframe::egui::{self, Color32, RichText};
use lightloom_nodes::engine::Report;
use lightloom_nodes::engine::spec::{ParamKind, ParamSpec, ParamValue};
use lightloom_nodes::kinds::scene::{SceneObject, Shape};
use lightloom_nodes::project::Project;

/// What a picked file is for.
#[derive(Clone, Debug, PartialEq)]
pub enum FileTarget {
    /// A file parameter.
    Param(String),
    /// A new glTF model object in the node's object list.
    NewModel,
    /// The file of the object at this index.
    Model(usize),
}

/// Something the inspector wants from the editor.
pub enum InspectorRequest {
    /// Pick a file with these extensions for `node`.
    Browse { node: String, target: FileTarget, extensions: &'static [&'static str] },
}

/// Lengths a model may have been authored in, as scales to metres.
pub const MODEL_UNITS: [(&str, f64); 5] =
    [("metres", 1.0), ("centimetres", 0.01), ("millimetres", 0.001), ("inches", 0.0254), ("feet", 0.3048)];

/// Sets one parameter after checking it against its spec; `merge` makes a drag one undo step.
pub fn set_param(doc: &mut Document, node: &str, name: &str, value: ParamValue) -> Result<(), String> {
    let key = format!("{node}.{name}");
    doc.edit(format!("Set {key}"), Some(&key), |p| {
        let kind = edits::kind_of(p, node).ok_or_else(|| format!("no node `{node}`"))?;
        let spec = kind.param(name).ok_or_else(|| format!("{} has no parameter `{name}`", kind.label))?;
        spec.check(&value).map_err(|e| format!("{key}: {e}"))?;
        // Picking a file means using it: the parameter it selects changes in the same step.
        let selects = match (&spec.kind, &value) {
            (ParamKind::Path { selects: Some((choice, option)), .. }, ParamValue::Path(v)) if !v.is_empty() => {
                Some((choice.to_string(), ParamValue::Choice(option.to_string())))
            }
            _ => None,
        };
        let n = p.nodes.iter_mut().find(|n| n.id == node).expect("node exists");
        n.params.insert(name.to_string(), value);
        if let Some((choice, option)) = selects {
            n.params.insert(choice, option);
        }
        Ok(())
    })
}

/// A menu of a choice parameter's options: each option's plain-language label (with its
/// name) and a tooltip saying what it does and costs, where the kind gives them. `compact`
/// shows only the option's name when closed (toolbars).
pub fn choice_combo(
    ui: &mut egui::Ui,
    id_salt: impl std::hash::Hash + std::fmt::Debug,
    options: &[&str],
    labels: &[(&str, &str)],
    value: &mut String,
    compact: bool,
) -> egui::Response {
    let text = |option: &str| match options.iter().position(|o| *o == option).and_then(|i| labels.get(i)) {
        Some((label, _)) => format!("{label} ({option})"),
        None => option.to_string(),
    };
    let selected = if compact { value.clone() } else { text(value) };
    let mut r = egui::ComboBox::from_id_salt(id_salt).selected_text(selected).show_ui(ui, |ui| {
        let mut changed = false;
        for (i, o) in options.iter().enumerate() {
            let mut item = ui.selectable_value(value, o.to_string(), text(o));
            if let Some((_, help)) = labels.get(i) {
                item = item.on_hover_text(*help);
            }
            changed |= item.changed();
        }
        changed
    });
    if r.inner == Some(true) {
        r.response.mark_changed();
    }
    let current = options.iter().position(|o| *o == value.as_str()).and_then(|i| labels.get(i));
    match current {
        Some((_, help)) => r.response.on_hover_text(*help),
        None => r.response,
    }
}

/// The value a node's parameter has (its default when the project does not set it).
pub fn param_value(project: &Project, node: &str, spec: &ParamSpec) -> ParamValue {
    edits::node(project, node).and_then(|n| n.params.get(spec.name).cloned()).unwrap_or_else(|| spec.default_value())
}

pub struct Inspector<'a> {
    pub doc: &'a mut Document,
    pub status: Option<&'a NodeStatus>,
    pub report: Option<&'a Report>,
    /// The object picked in the viewport (Scene nodes).
    pub selected_object: &'a mut Option<usize>,
    /// The meshes on screen (object sizes).
    pub meshes: Option<&'a lightloom_nodes::mesh::MeshSet>,
    /// What the viewport cannot show of this node, as drawn now (a material's highlight).
    pub limits: Vec<String>,
    pub requests: Vec<InspectorRequest>,
    pub errors: Vec<String>,
    /// The painting canvas (area lights) and the evaluation whose texture it shows.
    pub canvas: &'a mut super::paint_canvas::PaintCanvas,
    pub evaluation: Option<&'a lightloom_nodes::engine::Evaluation>,
}

impl Inspector<'_> {
    pub fn show(&mut self, ui: &mut egui::Ui, id: &str) {
        let Some(kind) = edits::kind_of(&self.doc.project, id) else {
            ui.weak(format!("node `{id}` has an unknown kind"));
            return;
        };
        ui.heading(kind.label);
        ui.add(egui::Label::new(RichText::new(kind.doc).weak()).wrap());
        ui.separator();
        let mut label = edits::node(&self.doc.project, id).map(|n| n.label.clone()).unwrap_or_default();
        ui.horizontal(|ui| {
            ui.label("Name");
            let response = ui.add(egui::TextEdit::singleline(&mut label).hint_text(id).desired_width(160.0));
            if response.changed() {
                let key = format!("{id}.label");
                let result = self.doc.edit(format!("Rename {id}"), Some(&key), |p| {
                    let n = p.nodes.iter_mut().find(|n| n.id == id).ok_or("node vanished")?;
                    n.label = label.clone();
                    Ok(())
                });
                self.note(result);
            }
            ui.weak(format!("id {id}"));
        });
        self.status_section(ui, id);
        for limit in &self.limits {
            ui.add(egui::Label::new(RichText::new(format!("⚠ {limit}")).color(Color32::from_rgb(240, 190, 80))).wrap());
        }
        self.inputs_section(ui, id, kind);
        ui.separator();
        let project = &self.doc.project;
        let value = |name: &str| kind.param(name).map(|p| param_value(project, id, p));
        let grouped = |name: &str| kind.groups.iter().any(|g| g.params.contains(&name));
        let shown: Vec<&ParamSpec> =
            kind.params.iter().filter(|p| (kind.relevant)(&value, p.name) && !grouped(p.name)).collect();
        self.param_grid(ui, id, ("params", id.to_string()), &shown);
        for group in kind.groups {
            let specs: Vec<&ParamSpec> = group.params.iter().filter_map(|name| kind.param(name)).collect();
            egui::CollapsingHeader::new(group.label)
                .id_salt(("group", id, group.label))
                .show(ui, |ui| {
                    ui.weak(group.doc);
                    self.param_grid(ui, id, ("group params", format!("{id}/{}", group.label)), &specs);
                })
                .header_response
                .on_hover_text(group.doc);
        }
        for spec in &kind.params {
            match spec.kind {
                ParamKind::Objects { .. } => self.objects_widget(ui, id, spec),
                ParamKind::Spheres { .. } => self.spheres_widget(ui, id, spec),
                ParamKind::Paint => {
                    let errors = self.canvas.show(ui, self.doc, id, self.evaluation);
                    self.errors.extend(errors);
                }
                _ => {}
            }
        }
    }

    /// One labelled widget per row for `specs` (list-valued parameters have widgets of their own).
    fn param_grid(
        &mut self,
        ui: &mut egui::Ui,
        id: &str,
        grid: impl std::hash::Hash + std::fmt::Debug,
        specs: &[&ParamSpec],
    ) {
        egui::Grid::new(grid).num_columns(2).striped(true).show(ui, |ui| {
            for spec in specs {
                if matches!(spec.kind, ParamKind::Objects { .. } | ParamKind::Spheres { .. } | ParamKind::Paint) {
                    continue;
                }
                let label = ui.label(spec.label).on_hover_text(spec.doc);
                self.param_widget(ui, id, spec, label.id);
                ui.end_row();
            }
        });
    }

    fn note(&mut self, result: Result<(), String>) {
        if let Err(e) = result {
            self.errors.push(e);
        }
    }

    fn status_section(&mut self, ui: &mut egui::Ui, id: &str) {
        match self.status {
            Some(NodeStatus::Error(m)) => {
                ui.add(egui::Label::new(RichText::new(format!("⚠ {m}")).color(Color32::from_rgb(235, 90, 80))).wrap());
            }
            Some(NodeStatus::Running(stage, f)) => {
                ui.add(egui::ProgressBar::new(*f).text(format!("running {stage}")));
            }
            Some(NodeStatus::Dirty) => {
                ui.weak("waiting for evaluation");
            }
            Some(NodeStatus::UpToDate) | None => {
                ui.weak("up to date");
            }
        }
        let Some(report) = self.report else { return };
        let stages: Vec<_> = report.stages.iter().filter(|s| s.node == id).collect();
        if stages.is_empty() {
            return;
        }
        egui::CollapsingHeader::new(format!("Stages ({:.1} ms)", stages.iter().map(|s| s.ms).sum::<f64>()))
            .id_salt(("stages", id))
            .show(ui, |ui| {
                egui::Grid::new(("stage-grid", id)).striped(true).show(ui, |ui| {
                    for s in stages {
                        ui.label(s.stage.as_ref());
                        ui.label(format!("{:?}", s.status).to_lowercase());
                        ui.label(format!("{:.1} ms", s.ms));
                        ui.label(s.reasons.join("; ")).on_hover_text(s.error.clone().unwrap_or_default());
                        ui.end_row();
                    }
                });
            });
        for s in report.stages.iter().filter(|s| s.node == id) {
            for line in &s.info {
                ui.add(egui::Label::new(RichText::new(line).weak()).wrap());
            }
            for w in &s.warnings {
                ui.add(egui::Label::new(RichText::new(format!("⚠ {w}")).color(Color32::from_rgb(230, 180, 60))).wrap());
            }
        }
    }

    fn inputs_section(
        &mut self,
        ui: &mut egui::Ui,
        id: &str,
        kind: &'static lightloom_nodes::engine::spec::NodeKindSpec,
    ) {
        if kind.inputs.is_empty() {
            return;
        }
        ui.separator();
        ui.label(RichText::new("Inputs").strong());
        for input in &kind.inputs {
            let to = (id.to_string(), input.name.to_string());
            let project = &self.doc.project;
            let linked: Vec<(String, String)> =
                project.links.iter().filter(|l| l.to == to).map(|l| l.from.clone()).collect();
            let candidates: Vec<(String, String)> = project
                .nodes
                .iter()
                .filter(|n| n.id != id)
                .flat_map(|n| {
                    let outputs = lightloom_nodes::kinds::kind(&n.kind).map(|k| k.outputs.as_slice()).unwrap_or(&[]);
                    outputs.iter().filter(|o| o.ty == input.ty).map(move |o| (n.id.clone(), o.name.to_string()))
                })
                .filter(|c| !linked.contains(c))
                .collect();
            ui.horizontal_wrapped(|ui| {
                let name = ui.label(format!("{} ({})", input.name, input.ty));
                for from in &linked {
                    let text = format!("{}.{}", from.0, from.1);
                    if ui.button(format!("{text} ✖")).on_hover_text("unlink").clicked() {
                        let result = self.doc.edit(format!("Unlink {text}"), None, |p| {
                            edits::disconnect(p, from, &to);
                            Ok(())
                        });
                        self.note(result);
                    }
                }
                if linked.is_empty() || input.many {
                    let mut chosen = None;
                    egui::ComboBox::from_id_salt(("link", id, input.name))
                        .selected_text(format!("link {}…", input.name))
                        .show_ui(ui, |ui| {
                            for c in &candidates {
                                if ui.selectable_label(false, format!("{}.{}", c.0, c.1)).clicked() {
                                    chosen = Some(c.clone());
                                }
                            }
                            if candidates.is_empty() {
                                ui.weak(format!("no {} output in the graph", input.ty));
                            }
                        })
                        .response
                        .labelled_by(name.id);
                    if let Some(from) = chosen {
                        let result =
                            self.doc.edit(format!("Link {}.{} → {id}.{}", from.0, from.1, input.name), None, |p| {
                                edits::connect(p, &from, &to)
                            });
                        self.note(result);
                    }
                }
                if input.required && linked.is_empty() {
                    ui.colored_label(Color32::from_rgb(235, 90, 80), "required");
                }
            });
        }
    }

    fn param_widget(&mut self, ui: &mut egui::Ui, id: &str, spec: &ParamSpec, label: egui::Id) {
        let current = param_value(&self.doc.project, id, spec);
        let mut value = current.clone();
        let suffix = if spec.unit.is_empty() { String::new() } else { format!(" {}", spec.unit) };
        let response = match (&spec.kind, &mut value) {
            (ParamKind::Float { min, max, .. }, ParamValue::Float(v)) => {
                let speed = ((max - min) / 500.0).clamp(1e-4, 10.0);
                ui.add(egui::DragValue::new(v).range(*min..=*max).speed(speed).suffix(suffix).max_decimals(4))
            }
            (ParamKind::Int { min, max, .. }, ParamValue::Int(v)) => {
                ui.add(egui::DragValue::new(v).range(*min..=*max).suffix(suffix))
            }
            (ParamKind::Bool { .. }, ParamValue::Bool(v)) => ui.checkbox(v, ""),
            (ParamKind::Vec3 { min, max, .. }, ParamValue::Vec3(v)) => vec3_widget(ui, v, *min, *max, &suffix),
            (ParamKind::Color { max, .. }, ParamValue::Color(v)) => color_widget(ui, v, *max),
            (ParamKind::Choice { options, labels, .. }, ParamValue::Choice(v)) => {
                choice_combo(ui, (id, spec.name), options, labels, v, false)
            }
            (ParamKind::Path { extensions, .. }, ParamValue::Path(v)) => {
                // What is typed is a draft until editing ends (Enter, or leaving the field): a
                // half-typed path is never loaded, nor its error shown under the pointer.
                let draft_id = egui::Id::new(("path draft", id, spec.name));
                let r = ui
                    .horizontal(|ui| {
                        let mut draft = ui.data(|d| d.get_temp::<String>(draft_id)).unwrap_or_else(|| v.clone());
                        let r = ui.add(egui::TextEdit::singleline(&mut draft).desired_width(150.0).hint_text("(none)"));
                        if r.has_focus() {
                            ui.data_mut(|d| d.insert_temp(draft_id, draft));
                        } else {
                            ui.data_mut(|d| d.remove::<String>(draft_id));
                            if r.lost_focus() {
                                *v = draft;
                            }
                        }
                        if ui.button("Browse…").clicked() {
                            self.requests.push(InspectorRequest::Browse {
                                node: id.into(),
                                target: FileTarget::Param(spec.name.into()),
                                extensions,
                            });
                        }
                        r
                    })
                    .inner;
                if !v.is_empty() {
                    let path = self.doc.project_dir().join(v.as_str());
                    if !path.exists() {
                        ui.colored_label(Color32::from_rgb(235, 90, 80), "missing")
                            .on_hover_text(format!("{} does not exist", path.display()));
                    }
                }
                r
            }
            _ => ui.label(current.to_string()),
        };
        let response = response.labelled_by(label).on_hover_text(spec.doc);
        if value != current {
            let result = set_param(self.doc, id, spec.name, value);
            self.note(result);
        }
        let _ = response;
    }

    fn objects_widget(&mut self, ui: &mut egui::Ui, id: &str, spec: &ParamSpec) {
        let ParamValue::Objects(current) = param_value(&self.doc.project, id, spec) else { return };
        let mut objects = current.clone();
        let materials: Vec<String> =
            self.doc.project.nodes.iter().filter(|n| n.kind == "BrdfEditor").map(|n| n.id.clone()).collect();
        ui.separator();
        ui.horizontal(|ui| {
            ui.label(RichText::new(format!("Objects ({})", objects.len())).strong());
            ui.menu_button("+ Add", |ui| {
                let shapes = [
                    ("Sphere", Shape::Sphere { radius: 0.5 }),
                    ("Box", Shape::Box { size: [1.0; 3] }),
                    ("Plane", Shape::Plane { size: 4.0 }),
                    ("Torus", Shape::Torus { major: 0.6, minor: 0.2 }),
                    ("Cornell box", Shape::CornellBox { size: 2.0 }),
                ];
                for (name, shape) in shapes {
                    if ui.button(name).clicked() {
                        let mut n = 1;
                        while objects.iter().any(|o| o.name == format!("{}{n}", name.to_lowercase())) {
                            n += 1;
                        }
                        objects.push(SceneObject::new(&format!("{}{n}", name.to_lowercase()), shape));
                        *self.selected_object = Some(objects.len() - 1);
                        ui.close();
                    }
                }
                ui.separator();
                if ui.button("glTF model…").on_hover_text("import a .gltf or .glb file as an object").clicked() {
                    self.requests.push(InspectorRequest::Browse {
                        node: id.into(),
                        target: FileTarget::NewModel,
                        extensions: &["gltf", "glb"],
                    });
                    ui.close();
                }
            });
        });
        let mut remove = None;
        let mut duplicate = None;
        let meshes = self.meshes;
        let project_dir = self.doc.project_dir();
        for (i, o) in objects.iter_mut().enumerate() {
            let selected = *self.selected_object == Some(i);
            let header = egui::CollapsingHeader::new(RichText::new(&o.name).color(if selected {
                Color32::from_rgb(255, 200, 80)
            } else {
                Color32::PLACEHOLDER
            }))
            .id_salt(("object", id, i))
            .open(selected.then_some(true))
            .show(ui, |ui| {
                egui::Grid::new(("object-grid", id, i)).num_columns(2).show(ui, |ui| {
                    ui.label("Name");
                    ui.text_edit_singleline(&mut o.name);
                    ui.end_row();
                    ui.label("Shape");
                    shape_widget(ui, &mut o.shape);
                    ui.end_row();
                    if let Shape::Gltf { file } = &mut o.shape {
                        ui.label("File");
                        ui.horizontal(|ui| {
                            ui.add(egui::TextEdit::singleline(file).desired_width(150.0).hint_text("(none)"));
                            if ui.button("Browse…").clicked() {
                                self.requests.push(InspectorRequest::Browse {
                                    node: id.into(),
                                    target: FileTarget::Model(i),
                                    extensions: &["gltf", "glb"],
                                });
                            }
                            if !file.is_empty() && !project_dir.join(file.as_str()).is_file() {
                                ui.colored_label(Color32::from_rgb(235, 90, 80), "missing");
                            }
                        });
                        ui.end_row();
                        model_units_rows(ui, o, meshes, (id, i));
                        box_uvs_row(ui, o);
                    }
                    ui.label("Translation");
                    vec3_widget(ui, &mut o.translation, -1e4, 1e4, " m");
                    ui.end_row();
                    ui.label("Rotation");
                    vec3_widget(ui, &mut o.rotation_deg, -360.0, 360.0, "°");
                    ui.end_row();
                    ui.label("Scale");
                    vec3_widget(ui, &mut o.scale, 1e-3, 1e3, "");
                    ui.end_row();
                    ui.label("Colour");
                    color_widget(ui, &mut o.color, 1.0);
                    ui.end_row();
                    ui.label("Material");
                    egui::ComboBox::from_id_salt(("material", id, i))
                        .selected_text(if o.material.is_empty() { "(first linked)" } else { o.material.as_str() })
                        .show_ui(ui, |ui| {
                            ui.selectable_value(&mut o.material, String::new(), "(first linked)");
                            for m in &materials {
                                ui.selectable_value(&mut o.material, m.clone(), m);
                            }
                        });
                    ui.end_row();
                    ui.label("Visibility texture");
                    ui.checkbox(&mut o.visibility_texture, "")
                        .on_hover_text("precompute per-texel visibility over the UVs: sharp shadows on coarse meshes");
                    ui.end_row();
                });
                ui.horizontal(|ui| {
                    if ui.button("Duplicate").clicked() {
                        duplicate = Some(i);
                    }
                    if ui.button("Remove").clicked() {
                        remove = Some(i);
                    }
                });
            });
            if header.header_response.clicked() {
                *self.selected_object = if selected { None } else { Some(i) };
            }
        }
        if let Some(i) = duplicate {
            let mut copy = objects[i].clone();
            copy.name = format!("{} copy", copy.name);
            copy.translation[0] += 0.5;
            objects.insert(i + 1, copy);
        }
        if let Some(i) = remove {
            objects.remove(i);
            *self.selected_object = None;
        }
        if objects != current {
            let result = set_param(self.doc, id, spec.name, ParamValue::Objects(objects));
            self.note(result);
        }
    }

    fn spheres_widget(&mut self, ui: &mut egui::Ui, id: &str, spec: &ParamSpec) {
        let ParamValue::Spheres(current) = param_value(&self.doc.project, id, spec) else { return };
        let mut spheres = current.clone();
        ui.separator();
        ui.horizontal(|ui| {
            ui.label(RichText::new(format!("{} ({})", spec.label, spheres.len())).strong());
            if ui.button("+ Add").clicked() {
                spheres.push(([0.0, 0.5, 0.0], 0.25));
            }
        });
        let mut remove = None;
        for (i, (centre, radius)) in spheres.iter_mut().enumerate() {
            ui.horizontal(|ui| {
                vec3_widget(ui, centre, -1e4, 1e4, " m");
                ui.add(egui::DragValue::new(radius).range(1e-3..=1e6).speed(0.01).prefix("r "));
                if ui.small_button("✖").clicked() {
                    remove = Some(i);
                }
            });
        }
        if let Some(i) = remove {
            spheres.remove(i);
        }
        if spheres != current {
            let result = set_param(self.doc, id, spec.name, ParamValue::Spheres(spheres));
            self.note(result);
        }
    }
}

fn vec3_widget(ui: &mut egui::Ui, v: &mut [f64; 3], min: f64, max: f64, suffix: &str) -> egui::Response {
    let speed = ((max - min) / 2000.0).clamp(1e-3, 1.0);
    ui.horizontal(|ui| {
        let mut response = ui.add(egui::DragValue::new(&mut v[0]).range(min..=max).speed(speed).max_decimals(3));
        response |= ui.add(egui::DragValue::new(&mut v[1]).range(min..=max).speed(speed).max_decimals(3));
        response |= ui.add(egui::DragValue::new(&mut v[2]).range(min..=max).speed(speed).max_decimals(3));
        if !suffix.is_empty() {
            ui.weak(suffix.trim());
        }
        response
    })
    .inner
}

/// Linear RGB: a colour button for values in 0..1, numbers for the rest (HDR tints).
fn color_widget(ui: &mut egui::Ui, v: &mut [f64; 3], max: f64) -> egui::Response {
    ui.horizontal(|ui| {
        let mut rgb = v.map(|c| c.clamp(0.0, 1.0) as f32);
        let mut response = ui.color_edit_button_rgb(&mut rgb);
        if response.changed() {
            *v = rgb.map(f64::from);
        }
        for c in v.iter_mut() {
            response |= ui.add(egui::DragValue::new(c).range(0.0..=max).speed(0.005).max_decimals(3));
        }
        response
    })
    .inner
}

fn shape_widget(ui: &mut egui::Ui, shape: &mut Shape) {
    ui.horizontal(|ui| {
        let name = match shape {
            Shape::Plane { .. } => "plane",
            Shape::Sphere { .. } => "sphere",
            Shape::Box { .. } => "box",
            Shape::Torus { .. } => "torus",
            Shape::CornellBox { .. } => "Cornell box",
            Shape::Gltf { .. } => "glTF model",
        };
        ui.label(name);
        match shape {
            Shape::Plane { size } | Shape::CornellBox { size } => {
                ui.add(egui::DragValue::new(size).range(1e-3..=1e4).speed(0.01).prefix("size "));
            }
            Shape::Sphere { radius } => {
                ui.add(egui::DragValue::new(radius).range(1e-3..=1e4).speed(0.01).prefix("radius "));
            }
            Shape::Box { size } => {
                vec3_widget(ui, size, 1e-3, 1e4, " m");
            }
            Shape::Torus { major, minor } => {
                ui.add(egui::DragValue::new(major).range(1e-3..=1e4).speed(0.01).prefix("R "));
                ui.add(egui::DragValue::new(minor).range(1e-3..=1e4).speed(0.01).prefix("r "));
            }
            Shape::Gltf { .. } => {}
        }
    });
}

/// Box-projected texture coordinates for a model's meshes that have none, so a normal map
/// applies to them: off, or one tile per so many metres.
fn box_uvs_row(ui: &mut egui::Ui, o: &mut SceneObject) {
    let label = ui.label("Box UVs");
    ui.horizontal(|ui| {
        let mut on = o.box_uvs.is_some();
        let checkbox = ui.checkbox(&mut on, "").labelled_by(label.id);
        // Named for assistive technology as the row is.
        checkbox.widget_info(|| egui::WidgetInfo::selected(egui::WidgetType::Checkbox, true, on, "Box UVs"));
        if checkbox
            .on_hover_text("project texture coordinates from the object's axes onto meshes without their own")
            .changed()
        {
            o.box_uvs = on.then_some(1.0);
        }
        if let Some(size) = &mut o.box_uvs {
            ui.add(egui::DragValue::new(size).range(1e-6..=1e6).speed(0.01).suffix(" m a unit")).on_hover_text(
                "metres on the object per unit of texture coordinate (the material's tiling repeats within it)",
            );
        }
    });
    ui.end_row();
}

/// A model's size on screen and the unit it was authored in (a uniform scale), with a hint
/// when the size is implausible for a scene measured in metres.
fn model_units_rows(
    ui: &mut egui::Ui,
    o: &mut SceneObject,
    meshes: Option<&lightloom_nodes::mesh::MeshSet>,
    id_salt: (&str, usize),
) {
    let prefix = format!("{}/", o.name);
    let size = meshes.map(|m| m.meshes.iter().filter(|x| x.name.starts_with(&prefix))).and_then(|parts| {
        let (lo, hi) = lightloom_nodes::mesh::union_bounds(parts);
        (lo[0] <= hi[0]).then(|| [0, 1, 2].map(|a| f64::from(hi[a] - lo[a])))
    });
    let label = ui.label("Units");
    let uniform = (o.scale[0] == o.scale[1] && o.scale[1] == o.scale[2]).then_some(o.scale[0]);
    let current = MODEL_UNITS.iter().find(|(_, s)| Some(*s) == uniform).map_or("custom scale", |(n, _)| n);
    egui::ComboBox::from_id_salt(("units", id_salt))
        .selected_text(current)
        .show_ui(ui, |ui| {
            for (name, scale) in MODEL_UNITS {
                if ui.selectable_label(uniform == Some(scale), name).clicked() {
                    o.scale = [scale; 3];
                }
            }
        })
        .response
        .labelled_by(label.id)
        .on_hover_text("the length unit the model was made in: sets a uniform scale to metres");
    ui.end_row();
    if let Some(size) = size {
        ui.label("Size");
        let largest = size.iter().cloned().fold(0.0, f64::max);
        ui.vertical(|ui| {
            ui.label(format!("{:.2} × {:.2} × {:.2} m", size[0], size[1], size[2]));
            if largest > 50.0 {
                ui.colored_label(
                    Color32::from_rgb(240, 190, 80),
                    "larger than a building: if it was made in centimetres or millimetres, set its units",
                );
            } else if largest < 0.05 {
                ui.colored_label(
                    Color32::from_rgb(240, 190, 80),
                    "smaller than a coin: if it was made in another unit, set its units or scale",
                );
            }
        });
        ui.end_row();
    }
}
