//! The area light's painting canvas in the inspector: the light's texture as the engine
//! rendered it, a round brush (radius, hardness, colour, intensity, blend), and whole-texture
//! operations. A stroke is collected while the pointer is down and appended to the node's
//! paint log when it is released: one undo step per stroke. The canvas only records what the
//! user did; the texture itself is the engine's `texture` stage.

use super::document::Document;
use super::edits;
use eframe::egui::{self, Color32, Stroke};
use lightloom_nodes::engine::spec::ParamValue;
use lightloom_nodes::engine::{Evaluation, key::Key};
use lightloom_nodes::light_texture::{Blend, LightTexture, PaintOp, Shape};

/// Canvas side in points.
const CANVAS: f32 = 240.0;

#[derive(Clone, Copy, PartialEq, Eq)]
pub enum Tool {
    Paint,
    Erase,
}

/// The brush and the stroke under way (editor state, not saved).
pub struct PaintCanvas {
    pub tool: Tool,
    pub radius: f64,
    pub hardness: f64,
    pub colour: [f32; 3],
    pub intensity: f64,
    pub blend: Blend,
    pub blur: f64,
    /// Points of the stroke being drawn, in light coordinates.
    pub stroke: Vec<[f64; 2]>,
    /// The texture on screen and the stage key it came from.
    shown: Option<(Key, egui::TextureHandle)>,
    /// Where the canvas was last drawn (tests drive the pointer there).
    pub last_rect: Option<egui::Rect>,
}

impl Default for PaintCanvas {
    fn default() -> Self {
        Self {
            tool: Tool::Paint,
            radius: 0.06,
            hardness: 0.5,
            colour: [1.0, 0.85, 0.6],
            intensity: 4.0,
            blend: Blend::Mix,
            blur: 0.01,
            stroke: Vec::new(),
            shown: None,
            last_rect: None,
        }
    }
}

/// Appends `op` to `node`'s paint log as one undo step.
pub fn append(doc: &mut Document, node: &str, label: &str, op: PaintOp) -> Result<(), String> {
    doc.edit(label.to_string(), None, |p| {
        op.check()?;
        let n = p.nodes.iter_mut().find(|n| n.id == node).ok_or_else(|| format!("no node `{node}`"))?;
        let mut ops = match n.params.get("paint") {
            Some(ParamValue::Paint(ops)) => ops.clone(),
            _ => Vec::new(),
        };
        if ops.len() >= lightloom_nodes::paint::MAX_OPERATIONS {
            return Err(format!("the light holds {} paint operations already; clear or blur it into fewer", ops.len()));
        }
        ops.push(op);
        n.params.insert("paint".into(), ParamValue::Paint(ops));
        Ok(())
    })
}

impl PaintCanvas {
    /// The brush settings, the canvas and the whole-texture operations for `node`.
    pub fn show(
        &mut self,
        ui: &mut egui::Ui,
        doc: &mut Document,
        node: &str,
        evaluation: Option<&Evaluation>,
    ) -> Vec<String> {
        let mut errors = Vec::new();
        let count = match edits::node(&doc.project, node).and_then(|n| n.params.get("paint")) {
            Some(ParamValue::Paint(ops)) => ops.len(),
            _ => 0,
        };
        ui.separator();
        let plural = if count == 1 { "" } else { "s" };
        ui.label(egui::RichText::new(format!("Paint: {count} operation{plural}")).strong());
        ui.horizontal(|ui| {
            ui.selectable_value(&mut self.tool, Tool::Paint, "Brush");
            ui.selectable_value(&mut self.tool, Tool::Erase, "Erase");
            egui::ComboBox::from_id_salt(("blend", node)).selected_text(format!("{:?}", self.blend)).show_ui(
                ui,
                |ui| {
                    for blend in [Blend::Mix, Blend::Add, Blend::Multiply] {
                        ui.selectable_value(&mut self.blend, blend, format!("{blend:?}"));
                    }
                },
            );
        });
        ui.horizontal(|ui| {
            ui.add(egui::DragValue::new(&mut self.radius).range(0.005..=0.5).speed(0.002).prefix("radius "));
            ui.add(egui::DragValue::new(&mut self.hardness).range(0.0..=1.0).speed(0.01).prefix("hardness "));
        });
        ui.horizontal(|ui| {
            ui.color_edit_button_rgb(&mut self.colour);
            ui.add(egui::DragValue::new(&mut self.intensity).range(0.0..=1e4).speed(0.05).prefix("intensity "));
        });
        self.canvas(ui, doc, node, evaluation, &mut errors);
        ui.horizontal_wrapped(|ui| {
            let colour = self.colour.map(f64::from);
            let mut op = None;
            if ui.button("Fill").on_hover_text("the whole light in the brush colour").clicked() {
                op = Some(("Fill light", PaintOp::Fill { colour, intensity: self.intensity }));
            }
            ui.add(egui::DragValue::new(&mut self.blur).range(0.001..=0.2).speed(0.001).prefix("σ "));
            if ui.button("Blur").clicked() {
                op = Some(("Blur light", PaintOp::Blur { sigma: self.blur }));
            }
            if ui.button("Disc").on_hover_text("emit only inside the inscribed disc").clicked() {
                op = Some(("Reshape light", PaintOp::Reshape { shape: Shape::Disc }));
            }
            if let Some((label, op)) = op
                && let Err(e) = append(doc, node, label, op)
            {
                errors.push(e);
            }
            if ui.button("Clear").on_hover_text("back to a white light (undoable)").clicked() {
                let result = doc.edit("Clear paint", None, |p| {
                    let n = p.nodes.iter_mut().find(|n| n.id == node).ok_or("no such node")?;
                    n.params.insert("paint".into(), ParamValue::Paint(Vec::new()));
                    Ok(())
                });
                if let Err(e) = result {
                    errors.push(e);
                }
            }
        });
        errors
    }

    fn canvas(
        &mut self,
        ui: &mut egui::Ui,
        doc: &mut Document,
        node: &str,
        evaluation: Option<&Evaluation>,
        errors: &mut Vec<String>,
    ) {
        let (rect, response) = ui.allocate_exact_size(egui::vec2(CANVAS, CANVAS), egui::Sense::click_and_drag());
        self.last_rect = Some(rect);
        let painter = ui.painter_at(rect);
        painter.rect_filled(rect, 0.0, Color32::from_gray(20));
        if let Some(stage) = evaluation.and_then(|e| e.get(node, "texture")) {
            let texture = stage.value.as_ref().ok().and_then(|v| v.expect::<LightTexture>().ok());
            if let Some(texture) = texture.filter(|_| self.shown.as_ref().is_none_or(|(key, _)| *key != stage.key)) {
                let image = canvas_image(texture);
                let handle = ui.ctx().load_texture(format!("paint-{node}"), image, egui::TextureOptions::NEAREST);
                self.shown = Some((stage.key, handle));
            }
        }
        if let Some((_, handle)) = &self.shown {
            let uv = egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0));
            painter.image(handle.id(), rect, uv, Color32::WHITE);
        }
        let to_light = |p: egui::Pos2| -> [f64; 2] {
            [f64::from((p.x - rect.left()) / rect.width()), f64::from((p.y - rect.top()) / rect.height())]
        };
        // A stroke starts where the button went down; a stroke left over from a drag that
        // ended elsewhere (the canvas scrolled away) is dropped.
        if response.drag_started() {
            self.stroke.clear();
            if let Some(origin) = ui.input(|i| i.pointer.press_origin()) {
                self.stroke.push(to_light(origin));
            }
        }
        if response.clicked()
            && let Some(at) = response.interact_pointer_pos()
        {
            self.stroke = vec![to_light(at)];
        }
        if let Some(pointer) = response.interact_pointer_pos()
            && self.stroke.len() < lightloom_nodes::paint::MAX_DABS
        {
            let at = to_light(pointer);
            // Dabs a quarter radius apart, filled in along fast moves.
            let spacing = self.radius / 4.0;
            let at = at.map(|c| c.clamp(-self.radius, 1.0 + self.radius));
            if response.dragged() {
                match self.stroke.last().copied() {
                    None => self.stroke.push(at),
                    Some(last) => {
                        let distance = (at[0] - last[0]).hypot(at[1] - last[1]);
                        let steps = if distance < spacing { 0 } else { (distance / spacing).ceil() as usize };
                        let room = lightloom_nodes::paint::MAX_DABS - self.stroke.len();
                        for k in 1..=steps.min(room) {
                            let t = k as f64 / steps as f64;
                            self.stroke.push([last[0] + t * (at[0] - last[0]), last[1] + t * (at[1] - last[1])]);
                        }
                    }
                }
            }
        }
        let brush = self.radius as f32 * rect.width();
        let outline = Stroke::new(1.0, Color32::from_rgba_unmultiplied(255, 255, 255, 160));
        for p in &self.stroke {
            painter.circle_stroke(rect.min + egui::vec2(p[0] as f32, p[1] as f32) * rect.width(), brush, outline);
        }
        if let Some(hover) = response.hover_pos() {
            painter.circle_stroke(hover, brush, Stroke::new(1.0, Color32::from_gray(200)));
        }
        if (response.drag_stopped() || response.clicked()) && !self.stroke.is_empty() {
            let points = std::mem::take(&mut self.stroke);
            let (label, op) = match self.tool {
                Tool::Paint => (
                    "Paint stroke",
                    PaintOp::Stroke {
                        points,
                        radius: self.radius,
                        hardness: self.hardness,
                        colour: self.colour.map(f64::from),
                        intensity: self.intensity,
                        blend: self.blend,
                    },
                ),
                Tool::Erase => {
                    ("Erase stroke", PaintOp::Erase { points, radius: self.radius, hardness: self.hardness })
                }
            };
            if let Err(e) = append(doc, node, label, op) {
                errors.push(e);
            }
        }
        response.on_hover_text("drag to paint; the light as seen from below, x to the right, z down");
    }
}

/// The light as the viewport previews it on its rectangle: the canvas's colours, with the
/// masked-out texels transparent.
pub fn preview_image(texture: &LightTexture) -> egui::ColorImage {
    display_image(texture, |_| Color32::TRANSPARENT)
}

/// The texture's emission for display: auto-exposed sRGB, the masked-off part checkered.
fn canvas_image(texture: &LightTexture) -> egui::ColorImage {
    let n = texture.side;
    display_image(texture, |k| {
        let grey = if ((k % n) / 4 + (k / n) / 4).is_multiple_of(2) { 40 } else { 60 };
        Color32::from_rgb(grey, grey, grey)
    })
}

/// The emission auto-exposed to sRGB, with `masked(k)` wherever texel `k` is masked off.
fn display_image(texture: &LightTexture, masked: impl Fn(usize) -> Color32) -> egui::ColorImage {
    let emission = texture.emission();
    let scale = lightloom_nodes::preview::auto_scale(emission.iter().copied());
    let pixels = emission
        .iter()
        .zip(&texture.mask)
        .enumerate()
        .map(|(k, (c, m))| {
            if *m <= 0.0 {
                return masked(k);
            }
            let [r, g, b, _] = lightloom_nodes::preview::display_rgb8(*c, scale);
            Color32::from_rgb(r, g, b)
        })
        .collect();
    egui::ColorImage::new([texture.side, texture.side], pixels)
}
