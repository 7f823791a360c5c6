//! Light gizmos in the viewport: every point light drawn where it is (filled when it lights
//! the output, hollow when it is not linked), clicked to select its node, dragged to move it
//! in the view plane (one undo step per drag).

use super::*;

/// Pointer distance, in points, within which a gizmo is hit.
const HIT_RADIUS: f32 = 12.0;

pub(super) struct LightGizmo {
    pub id: String,
    pub position: [f64; 3],
    /// The light's colour at full brightness.
    pub colour: Color32,
    /// Whether it reaches the Output (else it lights nothing).
    pub linked: bool,
}

/// Where world point `p` is in the viewport `rect` seen by `camera`, if in front of it.
pub(super) fn screen_pos(camera: &OrbitCamera, rect: egui::Rect, p: [f64; 3]) -> Option<egui::Pos2> {
    let ((x, y), _) = camera.project(glam::DVec3::from(p), (rect.width().into(), rect.height().into()))?;
    Some(rect.min + egui::vec2(x as f32, y as f32))
}

impl EditorApp {
    /// The project's point lights.
    pub(super) fn light_gizmos(&self) -> Vec<LightGizmo> {
        let spec = lightloom_nodes::kinds::kind("PointLight").expect("PointLight kind");
        let graph = self.evaluator.last.as_ref().map(|(_, g)| g);
        self.doc
            .project
            .nodes
            .iter()
            .filter(|n| n.kind == "PointLight")
            .filter_map(|n| {
                let value = |name: &str| spec.param(name).map(|s| inspector::param_value(&self.doc.project, &n.id, s));
                let (Some(ParamValue::Vec3(position)), Some(ParamValue::Color(intensity))) =
                    (value("position"), value("intensity"))
                else {
                    return None;
                };
                let peak = intensity.iter().cloned().fold(1e-9, f64::max);
                let [r, g, b] = intensity.map(|c| (c / peak * 255.0).round().clamp(0.0, 255.0) as u8);
                Some(LightGizmo {
                    id: n.id.clone(),
                    position,
                    colour: Color32::from_rgb(r, g, b),
                    linked: graph.is_some_and(|g| g.feeds_sink(&n.id)),
                })
            })
            .collect()
    }

    /// The light whose gizmo is under `pos`.
    pub(super) fn gizmo_at(&self, pos: egui::Pos2, rect: egui::Rect) -> Option<String> {
        let camera = self.viewport_camera(rect);
        self.light_gizmos()
            .into_iter()
            .filter_map(|g| Some((screen_pos(&camera, rect, g.position)?.distance(pos), g.id)))
            .filter(|(d, _)| *d <= HIT_RADIUS)
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .map(|(_, id)| id)
    }

    pub(super) fn draw_gizmos(&self, painter: &egui::Painter, rect: egui::Rect, hover: Option<egui::Pos2>) {
        let camera = self.viewport_camera(rect);
        let selected = match &self.selection {
            Selection::Node(id) => Some(id.as_str()),
            _ => None,
        };
        for g in self.light_gizmos() {
            let Some(at) = screen_pos(&camera, rect, g.position) else { continue };
            if !rect.contains(at) {
                continue;
            }
            let outline =
                if selected == Some(g.id.as_str()) { Color32::from_rgb(255, 200, 80) } else { Color32::BLACK };
            for i in 0..8 {
                let angle = i as f32 * std::f32::consts::FRAC_PI_4;
                let dir = egui::vec2(angle.cos(), angle.sin());
                painter.line_segment([at + dir * 8.0, at + dir * 12.0], egui::Stroke::new(2.0, g.colour));
            }
            painter.circle_stroke(at, 6.5, egui::Stroke::new(2.0, outline));
            if g.linked {
                painter.circle_filled(at, 5.5, g.colour);
            } else {
                painter.circle_stroke(at, 5.0, egui::Stroke::new(1.5, g.colour));
            }
            let hovered = hover.is_some_and(|p| p.distance(at) <= HIT_RADIUS);
            if hovered || selected == Some(g.id.as_str()) {
                let text = if g.linked { g.id.clone() } else { format!("{} (not linked: lights nothing)", g.id) };
                let galley = painter.layout_no_wrap(text, egui::FontId::proportional(12.0), Color32::WHITE);
                let corner = at + egui::vec2(14.0, -8.0);
                painter.rect_filled(
                    egui::Rect::from_min_size(corner, galley.size()).expand(3.0),
                    3.0,
                    Color32::from_black_alpha(170),
                );
                painter.galley(corner, galley, Color32::WHITE);
            }
        }
    }

    /// A primary drag that starts on a gizmo moves its light; returns whether it did.
    pub(super) fn drag_gizmo(&mut self, ui: &egui::Ui, response: &egui::Response, rect: egui::Rect) -> bool {
        let alt = ui.input(|i| i.modifiers.alt);
        if response.drag_started_by(egui::PointerButton::Primary) && !alt {
            let origin = ui.input(|i| i.pointer.press_origin());
            self.view.dragging_light = origin.and_then(|p| self.gizmo_at(p, rect));
            if let Some(id) = &self.view.dragging_light {
                self.selection = Selection::Node(id.clone());
            }
        }
        if !response.dragged_by(egui::PointerButton::Primary) {
            self.view.dragging_light = None;
            return false;
        }
        let Some(id) = self.view.dragging_light.clone() else { return false };
        let delta = ui.input(|i| i.pointer.delta());
        let Some(gizmo) = self.light_gizmos().into_iter().find(|g| g.id == id) else { return false };
        let camera = self.viewport_camera(rect);
        let moved = camera.drag_point(
            glam::DVec3::from(gizmo.position),
            (f64::from(delta.x), f64::from(delta.y)),
            f64::from(rect.height()),
        );
        if delta != egui::Vec2::ZERO
            && let Err(e) = inspector::set_param(&mut self.doc, &id, "position", ParamValue::Vec3(moved.to_array()))
        {
            self.log_error(e);
        }
        true
    }
}
