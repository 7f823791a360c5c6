//! The node graph, drawn with egui-snarl. The project is the source of truth: the widget's
//! graph is synced from it, and everything the user does in the widget comes back as a
//! [`GraphAction`] that the editor applies to the project as an undoable edit.

use super::jobs::NodeStatus;
use super::previews::Previews;
use eframe::egui::{self, Color32, RichText};
use egui_snarl::ui::{AnyPins, PinInfo, SnarlStyle, SnarlViewer, SnarlWidget};
use egui_snarl::{InPin, InPinId, NodeId, OutPin, OutPinId, Snarl};
use lightloom_nodes::engine::Evaluation;
use lightloom_nodes::engine::spec::{Availability, PortType};
use lightloom_nodes::kinds;
use lightloom_nodes::project::Project;
use std::collections::{HashMap, HashSet};

/// What the user asked the graph for.
#[derive(Clone, Debug, PartialEq)]
pub enum GraphAction {
    Add {
        kind: String,
        position: [f32; 2],
        link: Option<PendingLink>,
    },
    Connect {
        from: (String, String),
        to: (String, String),
    },
    Disconnect {
        from: (String, String),
        to: (String, String),
    },
    DisconnectPort {
        port: (String, String),
        input: bool,
    },
    Remove(Vec<String>),
    Duplicate(Vec<String>),
    Copy(Vec<String>),
    Rename(String),
    /// Nodes were dragged to new positions.
    Move(Vec<(String, [f32; 2])>),
    /// A link was refused: why.
    Refused(String),
}

/// A wire dropped on empty space: the new node gets linked to it.
#[derive(Clone, Debug, PartialEq)]
pub enum PendingLink {
    /// From this output to the new node's first input of the same type.
    FromOutput(String, String),
    /// From the new node's first output of the type into this input.
    ToInput(String, String),
}

/// The add-node popup opened by Shift+A.
struct AddMenu {
    screen_pos: egui::Pos2,
    graph_pos: [f32; 2],
    query: String,
}

pub struct GraphEditor {
    snarl: Snarl<String>,
    pub widget: SnarlWidget,
    add_menu: Option<AddMenu>,
    /// Screen → graph transform of the last frame.
    to_global: egui::emath::TSTransform,
    query: String,
    /// Nodes selected in the widget, by id.
    pub selected: Vec<String>,
    /// Whether `selected` changed this frame (a click in the graph; the inspector follows it
    /// only then, so a node chosen elsewhere stays chosen).
    pub selection_changed: bool,
    /// Fit the view to the nodes on the next frame (new document, Home).
    fit_pending: bool,
    /// A refused link or failed edit, shown over the graph for a few seconds.
    pub notice: Option<(String, std::time::Instant)>,
    /// The pass in which a right-click add menu was last shown (a menu not shown in the
    /// previous pass opens with an empty search).
    menu_pass: u64,
    /// Each node's rectangle on screen in the last frame.
    node_rects: HashMap<String, egui::Rect>,
    /// Whether the primary button went down on empty graph space (a box selection).
    press_on_background: bool,
}

pub fn port_color(ty: PortType) -> Color32 {
    match ty {
        PortType::Environment => Color32::from_rgb(230, 190, 60),
        PortType::Material => Color32::from_rgb(80, 190, 120),
        PortType::Scene => Color32::from_rgb(90, 150, 230),
        PortType::Medium => Color32::from_rgb(170, 170, 200),
        PortType::Lights => Color32::from_rgb(240, 130, 70),
        PortType::AreaLight => Color32::from_rgb(250, 200, 120),
        PortType::Blockers => Color32::from_rgb(150, 110, 90),
        PortType::SquareLights => Color32::from_rgb(200, 120, 200),
    }
}

fn status_color(status: Option<&NodeStatus>) -> (Color32, &'static str) {
    match status {
        Some(NodeStatus::UpToDate) => (Color32::from_rgb(90, 200, 90), "up to date"),
        Some(NodeStatus::Dirty) | None => (Color32::from_rgb(200, 200, 90), "dirty"),
        Some(NodeStatus::Running(..)) => (Color32::from_rgb(80, 160, 255), "running"),
        Some(NodeStatus::Error(_)) => (Color32::from_rgb(235, 70, 60), "error"),
    }
}

impl Default for GraphEditor {
    fn default() -> Self {
        let style = SnarlStyle { collapsible: Some(true), ..SnarlStyle::new() };
        Self {
            snarl: Snarl::new(),
            widget: SnarlWidget::new().id(egui::Id::new("lightloom-graph")).style(style),
            add_menu: None,
            to_global: Default::default(),
            selection_changed: false,
            query: String::new(),
            selected: Vec::new(),
            fit_pending: true,
            notice: None,
            menu_pass: 0,
            node_rects: HashMap::new(),
            press_on_background: false,
        }
    }
}

impl GraphEditor {
    /// Where a node of `kind` added from the menu bar goes: the middle of the visible graph
    /// (`view`, in screen space), moved down until it overlaps no node. Nodes are measured as
    /// last drawn (a node with previews is wider), and the new one by its previews.
    pub fn free_spot(&self, view: egui::Rect, project: &Project, kind: &str) -> [f32; 2] {
        let previews: f32 =
            lightloom_nodes::kinds::kind(kind).map_or(0.0, |k| k.previews.iter().map(|p| p.size[0] + 8.0).sum());
        let size = egui::vec2((previews + 130.0).max(190.0), 110.0);
        let to_graph = self.to_global.inverse();
        let occupied: Vec<egui::Rect> = project
            .nodes
            .iter()
            .map(|n| match self.node_rects.get(&n.id) {
                Some(r) => to_graph * *r,
                None => egui::Rect::from_min_size(egui::pos2(n.position[0], n.position[1]), egui::vec2(190.0, 110.0)),
            })
            .collect();
        let centre = to_graph * view.center();
        let mut spot = centre - size / 2.0;
        for _ in 0..64 {
            let candidate = egui::Rect::from_min_size(spot, size);
            if !occupied.iter().any(|r| r.intersects(candidate)) {
                break;
            }
            spot.y += size.y / 2.0;
        }
        [spot.x, spot.y]
    }

    /// Moves a node in the widget as a pointer drag does (UI tests).
    #[cfg(test)]
    pub fn move_in_widget(&mut self, id: &str, to: [f32; 2]) {
        let nid = self.snarl.node_ids().find(|(_, n)| n.as_str() == id).map(|(nid, _)| nid).expect("node in widget");
        self.snarl.get_node_info_mut(nid).expect("node info").pos = egui::pos2(to[0], to[1]);
    }

    /// A node's rectangle on screen in the last frame (UI tests).
    #[cfg(test)]
    pub fn node_rect(&self, id: &str) -> Option<egui::Rect> {
        self.node_rects.get(id).copied()
    }

    /// Blender's pointer bindings on top of egui-snarl's, whose are fixed: snarl selects on
    /// Shift+click, box-selects on Shift+drag and pans on any drag of empty space. Here a
    /// click selects one node (Shift+click adds, as in snarl), a click on empty space clears
    /// the selection, a left drag on empty space box-selects, a middle drag pans and a
    /// right-click on empty space opens the add menu. This
    /// sets the modifiers snarl reads for this frame; the caller restores the real ones.
    /// Returns the real modifiers when it changed them, and the pan to apply.
    fn blender_gestures(&mut self, ctx: &egui::Context, graph: egui::Rect) -> (Option<egui::Modifiers>, egui::Vec2) {
        let (pos, modifiers, pointer) = ctx.input(|i| (i.pointer.hover_pos(), i.modifiers, i.pointer.clone()));
        let over_node = pos.is_some_and(|p| self.node_rects.values().any(|r| r.contains(p)));
        let in_graph = pos.is_some_and(|p| {
            graph.contains(p) && ctx.layer_id_at(p).is_none_or(|layer| layer.order < egui::Order::Foreground)
        });
        if pointer.primary_pressed() {
            self.press_on_background = in_graph && !over_node;
        }
        // The right-click add menu is ours: a click on empty space does not reach snarl
        // while it listens for a box selection.
        // (Not while the primary button holds a wire: a right-click cancels the wire.)
        if pointer.secondary_clicked()
            && !pointer.primary_down()
            && in_graph
            && !over_node
            && let Some(pos) = pos
        {
            self.open_add_menu(pos);
        }
        let middle = pointer.button_down(egui::PointerButton::Middle);
        let pan = if middle && in_graph { pointer.delta() } else { egui::Vec2::ZERO };
        if modifiers.any() || !in_graph || middle || pointer.button_down(egui::PointerButton::Secondary) {
            return (None, pan);
        }
        let shift = egui::Modifiers::SHIFT;
        let injected = if pointer.primary_clicked() && over_node {
            // Snarl: Shift+Ctrl+click on a node selects only it.
            Some(shift | egui::Modifiers::COMMAND)
        } else if pointer.primary_released() {
            // A box selection ends without Shift: it replaces the selection (a click on empty
            // space is an empty box, which clears it).
            None
        } else if pointer.primary_down() {
            self.press_on_background.then_some(shift)
        } else {
            // Hovering empty space: snarl must already listen for a box selection when the
            // button goes down (egui picks the dragged widget from the previous frame).
            (!over_node).then_some(shift)
        };
        let Some(injected) = injected else { return (None, pan) };
        ctx.input_mut(|i| i.modifiers = injected);
        (Some(modifiers), pan)
    }

    /// Makes the widget's graph match the project: nodes, positions and wires. Nodes that
    /// stay keep their widget ids (and selection).
    pub fn sync(&mut self, project: &Project) {
        let present: HashMap<String, NodeId> = self.snarl.node_ids().map(|(nid, id)| (id.clone(), nid)).collect();
        let wanted: HashSet<&str> = project.nodes.iter().map(|n| n.id.as_str()).collect();
        for (id, nid) in &present {
            if !wanted.contains(id.as_str()) {
                self.snarl.remove_node(*nid);
            }
        }
        let mut ids = HashMap::new();
        for n in &project.nodes {
            let pos = egui::pos2(n.position[0], n.position[1]);
            let nid = match present.get(&n.id) {
                Some(&nid) => {
                    if let Some(info) = self.snarl.get_node_info_mut(nid) {
                        info.pos = pos;
                    }
                    nid
                }
                None => self.snarl.insert_node(pos, n.id.clone()),
            };
            ids.insert(n.id.as_str(), nid);
        }
        let mut desired = HashSet::new();
        for l in &project.links {
            let (Some(&a), Some(&b)) = (ids.get(l.from.0.as_str()), ids.get(l.to.0.as_str())) else { continue };
            let (Some(ka), Some(kb)) =
                (super::edits::kind_of(project, &l.from.0), super::edits::kind_of(project, &l.to.0))
            else {
                continue;
            };
            let (Some(o), Some(i)) =
                (ka.outputs.iter().position(|p| p.name == l.from.1), kb.inputs.iter().position(|p| p.name == l.to.1))
            else {
                continue;
            };
            desired.insert((OutPinId { node: a, output: o }, InPinId { node: b, input: i }));
        }
        let current: Vec<_> = self.snarl.wires().collect();
        for w in &current {
            if !desired.contains(w) {
                self.snarl.disconnect(w.0, w.1);
            }
        }
        for w in desired {
            self.snarl.connect(w.0, w.1);
        }
    }

    /// Draws the graph; returns what the user did.
    pub fn show(
        &mut self,
        ui: &mut egui::Ui,
        project: &Project,
        status: &HashMap<String, NodeStatus>,
        evaluation: Option<&Evaluation>,
        feeding: Option<&HashSet<String>>,
        previews: &mut Previews,
    ) -> Vec<GraphAction> {
        let rect = ui.available_rect_before_wrap();
        if ui.input(|i| i.key_pressed(egui::Key::Home)) && ui.rect_contains_pointer(rect) {
            self.fit_pending = true;
        }
        let fit = self.fit_pending.then(|| fit_transform(project, rect));
        self.fit_pending = false;
        let (real_modifiers, pan) = self.blender_gestures(ui.ctx(), rect);
        let mut viewer = Viewer {
            project,
            status,
            evaluation,
            feeding,
            previews,
            actions: Vec::new(),
            to_global: self.to_global,
            query: &mut self.query,
            menu_pass: &mut self.menu_pass,
            fit,
            pan,
            node_rects: HashMap::new(),
        };
        // Titles and port names are not selectable text: a drag on them moves the node.
        ui.style_mut().interaction.selectable_labels = false;
        let response = self.widget.show(&mut self.snarl, &mut viewer, ui);
        if let Some(modifiers) = real_modifiers {
            ui.ctx().input_mut(|i| i.modifiers = modifiers);
        }
        self.node_rects =
            viewer.node_rects.iter().map(|(id, r)| (id.clone(), viewer.to_global * r.expand(6.0))).collect();
        if let Some((text, at)) = &self.notice {
            if at.elapsed().as_secs_f32() < 6.0 {
                let pos = egui::pos2(rect.left() + 8.0, rect.bottom() - 8.0);
                let galley = ui.painter().layout(
                    text.clone(),
                    egui::FontId::proportional(14.0),
                    Color32::WHITE,
                    rect.width() - 16.0,
                );
                let bg = egui::Rect::from_min_size(pos - egui::vec2(0.0, galley.size().y), galley.size()).expand(4.0);
                ui.painter().rect_filled(bg, 4.0, Color32::from_rgb(140, 30, 30));
                ui.painter().galley(bg.min + egui::vec2(4.0, 4.0), galley, Color32::WHITE);
                ui.ctx().request_repaint_after(std::time::Duration::from_millis(500));
            } else {
                self.notice = None;
            }
        }
        self.to_global = viewer.to_global;
        let mut actions = std::mem::take(&mut viewer.actions);
        let selected: Vec<String> = self
            .widget
            .get_selected_nodes_at(ui.id(), ui.ctx())
            .into_iter()
            .filter_map(|nid| self.snarl.get_node(nid).cloned())
            .collect();
        self.selection_changed = selected != self.selected;
        self.selected = selected;

        // Moves: positions that differ from the project's.
        let moved: Vec<(String, [f32; 2])> = self
            .snarl
            .nodes_pos()
            .filter_map(|(pos, id)| {
                let n = super::edits::node(project, id)?;
                (n.position != [pos.x, pos.y]).then(|| (id.clone(), [pos.x, pos.y]))
            })
            .collect();
        if !moved.is_empty() {
            actions.push(GraphAction::Move(moved));
        }

        // Keyboard, while the pointer is over the graph and no text field has focus.
        let hovered = response.contains_pointer();
        let typing = ui.ctx().egui_wants_keyboard_input();
        if hovered && !typing {
            let (add, delete, duplicate, copy) = ui.input(|i| {
                (
                    i.modifiers.shift && i.key_pressed(egui::Key::A),
                    i.key_pressed(egui::Key::Delete) || (i.key_pressed(egui::Key::X) && !i.modifiers.any()),
                    (i.modifiers.command || i.modifiers.shift) && i.key_pressed(egui::Key::D),
                    i.events.iter().any(|e| matches!(e, egui::Event::Copy)),
                )
            });
            if add {
                let screen_pos = ui.input(|i| i.pointer.hover_pos()).unwrap_or(response.rect.center());
                self.open_add_menu(screen_pos);
            }
            if !self.selected.is_empty() {
                if delete {
                    actions.push(GraphAction::Remove(self.selected.clone()));
                }
                if duplicate {
                    actions.push(GraphAction::Duplicate(self.selected.clone()));
                }
                if copy {
                    actions.push(GraphAction::Copy(self.selected.clone()));
                }
            }
        }
        self.show_add_popup(ui.ctx(), &mut actions);
        actions
    }

    /// Opens the searchable add-node menu at a screen position (Shift+A).
    pub fn open_add_menu(&mut self, screen_pos: egui::Pos2) {
        let graph_pos = self.to_global.inverse() * screen_pos;
        self.add_menu = Some(AddMenu { screen_pos, graph_pos: [graph_pos.x, graph_pos.y], query: String::new() });
    }

    fn show_add_popup(&mut self, ctx: &egui::Context, actions: &mut Vec<GraphAction>) {
        let Some(menu) = self.add_menu.as_mut() else { return };
        let mut close = ctx.input(|i| i.key_pressed(egui::Key::Escape));
        let area = egui::Area::new(egui::Id::new("add-node-menu"))
            .order(egui::Order::Foreground)
            .fixed_pos(menu.screen_pos)
            .show(ctx, |ui| {
                egui::Frame::popup(ui.style()).show(ui, |ui| {
                    ui.label(RichText::new("Add node").strong());
                    if let Some(kind) = add_list(ui, &mut menu.query, None) {
                        actions.push(GraphAction::Add { kind, position: menu.graph_pos, link: None });
                        close = true;
                    }
                })
            });
        let clicked_outside = ctx.input(|i| i.pointer.any_pressed())
            && ctx.input(|i| i.pointer.interact_pos()).is_some_and(|p| !area.response.rect.contains(p));
        if close || clicked_outside {
            self.add_menu = None;
        }
    }
}

/// Graph → screen transform showing every node in `rect` (nodes taken as about 260×200).
fn fit_transform(project: &Project, rect: egui::Rect) -> egui::emath::TSTransform {
    let (node_w, node_h) = (260.0, 200.0);
    let mut lo = egui::pos2(f32::MAX, f32::MAX);
    let mut hi = egui::pos2(f32::MIN, f32::MIN);
    for n in &project.nodes {
        lo = lo.min(egui::pos2(n.position[0], n.position[1]));
        hi = hi.max(egui::pos2(n.position[0] + node_w, n.position[1] + node_h));
    }
    if project.nodes.is_empty() {
        return egui::emath::TSTransform::from_translation(rect.center().to_vec2());
    }
    let bounds = egui::Rect::from_min_max(lo, hi).expand(30.0);
    let scale = (rect.width() / bounds.width()).min(rect.height() / bounds.height()).clamp(0.3, 1.0);
    let translation = rect.center().to_vec2() - bounds.center().to_vec2() * scale;
    egui::emath::TSTransform::new(translation, scale)
}

/// A search field and the matching node kinds; returns the one clicked (or chosen with
/// Enter). `compatible` limits the list to kinds with a port of that type.
pub fn add_list(ui: &mut egui::Ui, query: &mut String, compatible: Option<(PortType, bool)>) -> Option<String> {
    let search = ui.add(egui::TextEdit::singleline(query).hint_text("search…").desired_width(200.0));
    if !search.has_focus() && query.is_empty() {
        search.request_focus();
    }
    let needle = query.to_lowercase();
    let matches: Vec<_> = kinds::registry()
        .iter()
        .filter(|k| {
            needle.is_empty()
                || k.label.to_lowercase().contains(&needle)
                || k.name.to_lowercase().contains(&needle)
                || k.doc.to_lowercase().contains(&needle)
        })
        .filter(|k| match compatible {
            None => true,
            // (type, the new node needs an input of it)
            Some((ty, true)) => k.inputs.iter().any(|p| p.ty == ty),
            Some((ty, false)) => k.outputs.iter().any(|p| p.ty == ty),
        })
        .collect();
    let enter = search.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter));
    if enter && let Some(first) = matches.first() {
        return Some(first.name.to_string());
    }
    let mut chosen = None;
    for k in &matches {
        let label = match k.availability {
            Availability::Ready => k.label.to_string(),
            Availability::Planned(missing) => format!("{} ({missing})", k.label),
        };
        if ui.button(label).on_hover_text(k.doc).clicked() {
            chosen = Some(k.name.to_string());
        }
    }
    if matches.is_empty() {
        ui.weak("no node kind matches");
    }
    chosen
}

struct Viewer<'a> {
    project: &'a Project,
    status: &'a HashMap<String, NodeStatus>,
    evaluation: Option<&'a Evaluation>,
    /// Nodes whose results reach an Output (`None`: not known yet).
    feeding: Option<&'a HashSet<String>>,
    previews: &'a mut Previews,
    actions: Vec<GraphAction>,
    to_global: egui::emath::TSTransform,
    query: &'a mut String,
    menu_pass: &'a mut u64,
    /// A transform to impose this frame (fit to view).
    fit: Option<egui::emath::TSTransform>,
    /// Screen-space pan to apply this frame (middle drag), unless snarl panned itself.
    pan: egui::Vec2,
    /// Each node's extent in graph space, gathered as its parts are drawn.
    node_rects: HashMap<String, egui::Rect>,
}

impl Viewer<'_> {
    /// The add menu's search, emptied when the menu opens anew (a search left from the last
    /// time could match nothing and hide every kind).
    fn fresh_query(&mut self, ctx: &egui::Context) -> &mut String {
        let pass = ctx.cumulative_pass_nr();
        if *self.menu_pass + 1 < pass {
            self.query.clear();
        }
        *self.menu_pass = pass;
        self.query
    }

    fn kind(&self, id: &str) -> Option<&'static lightloom_nodes::engine::spec::NodeKindSpec> {
        super::edits::kind_of(self.project, id)
    }

    /// Whether the node's results reach an Output (Outputs count as reached).
    fn feeds_output(&self, id: &str) -> bool {
        self.kind(id).is_some_and(|k| k.outputs.is_empty()) || self.feeding.is_none_or(|f| f.contains(id))
    }

    /// For a node that reaches no Output: which of its outputs to link where.
    fn link_hint(&self, id: &str) -> Option<String> {
        if self.feeds_output(id) {
            return None;
        }
        let kind = self.kind(id)?;
        let output = kinds::kind("Output")?;
        let hint = kind.outputs.iter().find_map(|out| {
            let input = output.inputs.iter().find(|i| i.ty == out.ty)?;
            Some(format!("not connected: link `{}` to the Output's `{}` input", out.name, input.name))
        });
        Some(hint.unwrap_or_else(|| "not connected to the Output: it is not evaluated".into()))
    }

    fn record_extent(&mut self, id: &str, rect: egui::Rect) {
        let extent = self.node_rects.entry(id.to_string()).or_insert(rect);
        *extent = extent.union(rect);
    }

    fn out_ref(&self, snarl: &Snarl<String>, pin: OutPinId) -> Option<(String, String)> {
        let id = snarl.get_node(pin.node)?;
        Some((id.clone(), self.kind(id)?.outputs.get(pin.output)?.name.to_string()))
    }

    fn in_ref(&self, snarl: &Snarl<String>, pin: InPinId) -> Option<(String, String)> {
        let id = snarl.get_node(pin.node)?;
        Some((id.clone(), self.kind(id)?.inputs.get(pin.input)?.name.to_string()))
    }
}

impl SnarlViewer<String> for Viewer<'_> {
    fn title(&mut self, node: &String) -> String {
        let n = super::edits::node(self.project, node);
        let label = n.map(|n| n.label.as_str()).filter(|l| !l.is_empty()).unwrap_or(node);
        match self.kind(node) {
            Some(k) => format!("{label} · {}", k.label),
            None => label.to_string(),
        }
    }

    fn show_header(&mut self, node: NodeId, _: &[InPin], _: &[OutPin], ui: &mut egui::Ui, snarl: &mut Snarl<String>) {
        let id = snarl[node].clone();
        let status = self.status.get(&id);
        let planned = self.kind(&id).and_then(|k| match k.availability {
            Availability::Planned(missing) => Some(missing),
            Availability::Ready => None,
        });
        let (color, word) = status_color(status);
        let feeds_output = self.feeds_output(&id);
        ui.horizontal(|ui| {
            let (rect, response) = ui.allocate_exact_size(egui::vec2(10.0, 10.0), egui::Sense::hover());
            ui.painter().circle_filled(rect.center(), 4.5, color);
            let hover = match (planned, status) {
                (_, Some(NodeStatus::Error(m))) => format!("error: {m}"),
                (_, Some(NodeStatus::Running(stage, f))) => format!("running {stage} ({:.0}%)", f * 100.0),
                _ => word.to_string(),
            };
            let hover = match planned {
                Some(missing) => format!("{hover}; {missing}"),
                None => hover,
            };
            response.on_hover_text(hover);
            let title = RichText::new(self.title(&id)).strong();
            ui.label(if feeds_output { title } else { title.weak() });
        });
        self.record_extent(&id, ui.min_rect());
    }

    fn inputs(&mut self, node: &String) -> usize {
        self.kind(node).map_or(0, |k| k.inputs.len())
    }

    fn outputs(&mut self, node: &String) -> usize {
        self.kind(node).map_or(0, |k| k.outputs.len())
    }

    #[allow(refining_impl_trait)]
    fn show_input(&mut self, pin: &InPin, ui: &mut egui::Ui, snarl: &mut Snarl<String>) -> PinInfo {
        let id = snarl[pin.id.node].clone();
        let Some(spec) = self.kind(&id).and_then(|k| k.inputs.get(pin.id.input)) else { return PinInfo::circle() };
        let text = if spec.many { format!("{} (many)", spec.name) } else { spec.name.to_string() };
        if spec.required && pin.remotes.is_empty() {
            ui.label(RichText::new(text).color(Color32::from_rgb(235, 90, 80)))
                .on_hover_text(format!("required {} input: link one", spec.ty));
        } else {
            ui.label(text).on_hover_text(spec.ty.to_string());
        }
        self.record_extent(&id, ui.min_rect());
        PinInfo::circle().with_fill(port_color(spec.ty))
    }

    #[allow(refining_impl_trait)]
    fn show_output(&mut self, pin: &OutPin, ui: &mut egui::Ui, snarl: &mut Snarl<String>) -> PinInfo {
        let id = snarl[pin.id.node].clone();
        let Some(spec) = self.kind(&id).and_then(|k| k.outputs.get(pin.id.output)) else { return PinInfo::circle() };
        ui.label(spec.name).on_hover_text(spec.ty.to_string());
        self.record_extent(&id, ui.min_rect());
        PinInfo::circle().with_fill(port_color(spec.ty))
    }

    fn has_body(&mut self, node: &String) -> bool {
        self.link_hint(node).is_some()
            || matches!(self.status.get(node), Some(NodeStatus::Error(_) | NodeStatus::Running(..)))
            || self.kind(node).is_some_and(super::previews::has_preview)
            || self.kind(node).is_some_and(|k| k.availability != Availability::Ready)
    }

    fn show_body(&mut self, node: NodeId, _: &[InPin], _: &[OutPin], ui: &mut egui::Ui, snarl: &mut Snarl<String>) {
        let id = snarl[node].clone();
        ui.vertical(|ui| {
            ui.set_max_width(220.0);
            match self.status.get(&id) {
                Some(NodeStatus::Error(message)) => {
                    ui.add(egui::Label::new(RichText::new(message).color(Color32::from_rgb(235, 90, 80))).wrap());
                }
                Some(NodeStatus::Running(stage, fraction)) => {
                    ui.add(egui::ProgressBar::new(*fraction).desired_width(200.0).text(stage.as_str()));
                }
                _ => {}
            }
            if let Some(hint) = self.link_hint(&id) {
                ui.add(egui::Label::new(RichText::new(hint).weak().italics()).wrap());
            }
            if let Some(kind) = self.kind(&id) {
                if let Availability::Planned(missing) = kind.availability {
                    ui.weak(missing);
                }
                if let Some(evaluation) = self.evaluation {
                    self.previews.show(ui, &id, kind, evaluation);
                }
            }
        });
        self.record_extent(&id, ui.min_rect());
    }

    fn has_node_menu(&mut self, _: &String) -> bool {
        true
    }

    fn show_node_menu(
        &mut self,
        node: NodeId,
        _: &[InPin],
        _: &[OutPin],
        ui: &mut egui::Ui,
        snarl: &mut Snarl<String>,
    ) {
        let id = snarl[node].clone();
        if ui.button("Rename…").clicked() {
            self.actions.push(GraphAction::Rename(id.clone()));
            ui.close();
        }
        if ui.button("Duplicate  (Shift+D)").clicked() {
            self.actions.push(GraphAction::Duplicate(vec![id.clone()]));
            ui.close();
        }
        if ui.button("Copy  (Ctrl+C)").clicked() {
            self.actions.push(GraphAction::Copy(vec![id.clone()]));
            ui.close();
        }
        if ui.button("Delete  (X, Delete)").clicked() {
            self.actions.push(GraphAction::Remove(vec![id]));
            ui.close();
        }
    }

    fn has_dropped_wire_menu(&mut self, _: AnyPins, _: &mut Snarl<String>) -> bool {
        true
    }

    fn show_dropped_wire_menu(&mut self, pos: egui::Pos2, ui: &mut egui::Ui, src: AnyPins, snarl: &mut Snarl<String>) {
        let (ty, link) = match src {
            AnyPins::Out(pins) => {
                let Some(r) = pins.first().and_then(|p| self.out_ref(snarl, *p)) else { return };
                let Some(ty) = self.kind(&r.0).and_then(|k| k.output(&r.1)).map(|p| p.ty) else { return };
                ((ty, true), PendingLink::FromOutput(r.0, r.1))
            }
            AnyPins::In(pins) => {
                let Some(r) = pins.first().and_then(|p| self.in_ref(snarl, *p)) else { return };
                let Some(ty) = self.kind(&r.0).and_then(|k| k.input(&r.1)).map(|p| p.ty) else { return };
                ((ty, false), PendingLink::ToInput(r.0, r.1))
            }
        };
        ui.label(RichText::new(format!("Add a node taking {}", ty.0)).strong());
        let query = self.fresh_query(ui.ctx());
        if let Some(kind) = add_list(ui, query, Some(ty)) {
            self.actions.push(GraphAction::Add { kind, position: [pos.x, pos.y], link: Some(link) });
            self.query.clear();
            ui.close();
        }
    }

    fn connect(&mut self, from: &OutPin, to: &InPin, snarl: &mut Snarl<String>) {
        let (Some(a), Some(b)) = (self.out_ref(snarl, from.id), self.in_ref(snarl, to.id)) else { return };
        match super::edits::check_link(self.project, &a, &b) {
            Ok(()) => self.actions.push(GraphAction::Connect { from: a, to: b }),
            Err(reason) => self.actions.push(GraphAction::Refused(reason)),
        }
    }

    fn disconnect(&mut self, from: &OutPin, to: &InPin, snarl: &mut Snarl<String>) {
        if let (Some(a), Some(b)) = (self.out_ref(snarl, from.id), self.in_ref(snarl, to.id)) {
            self.actions.push(GraphAction::Disconnect { from: a, to: b });
        }
    }

    fn drop_outputs(&mut self, pin: &OutPin, snarl: &mut Snarl<String>) {
        if let Some(port) = self.out_ref(snarl, pin.id) {
            self.actions.push(GraphAction::DisconnectPort { port, input: false });
        }
    }

    fn drop_inputs(&mut self, pin: &InPin, snarl: &mut Snarl<String>) {
        if let Some(port) = self.in_ref(snarl, pin.id) {
            self.actions.push(GraphAction::DisconnectPort { port, input: true });
        }
    }

    fn current_transform(&mut self, to_global: &mut egui::emath::TSTransform, _: &mut Snarl<String>) {
        if let Some(fit) = self.fit.take() {
            *to_global = fit;
        } else if *to_global == self.to_global {
            to_global.translation += self.pan;
        }
        self.to_global = *to_global;
    }
}
