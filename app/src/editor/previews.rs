//! Node previews: the pictures each kind declares ([`PreviewSpec`]), made by
//! `lightloom_nodes::preview` from the node's stages and shown here. They are cached by the
//! stages' keys, so they are rebuilt only when a stage changes.

use eframe::egui::{self, Color32, Stroke};
use lightloom_nodes::brdf::LobePreview;
use lightloom_nodes::engine::spec::{NodeKindSpec, PreviewSpec};
use lightloom_nodes::engine::{Evaluation, key::Key};
use lightloom_nodes::picture::Preview;
use std::collections::HashMap;

/// Kinds that show a preview.
pub fn has_preview(kind: &NodeKindSpec) -> bool {
    !kind.previews.is_empty()
}

/// The stages a kind's previews read (requested from the engine while they show).
pub fn preview_stages(kind: &NodeKindSpec) -> impl Iterator<Item = &'static str> + '_ {
    kind.previews.iter().flat_map(|p| p.stages.iter().copied())
}

/// A preview as shown: an uploaded image, or the curves to plot.
enum Shown {
    Texture(egui::TextureHandle),
    Lobe(LobePreview),
}

#[derive(Default)]
pub struct Previews {
    /// Per node and preview index: the stages' combined key and what it made.
    shown: HashMap<(String, usize), (Key, Option<Shown>)>,
}

impl Previews {
    /// Draws the node's previews whose stages have values.
    pub fn show(&mut self, ui: &mut egui::Ui, node: &str, kind: &NodeKindSpec, evaluation: &Evaluation) {
        ui.horizontal(|ui| {
            for (index, spec) in kind.previews.iter().enumerate() {
                self.show_one(ui, node, index, spec, evaluation);
            }
        });
    }

    /// Whether preview `index` of `node` is an image on screen now.
    #[cfg(test)]
    pub fn shows_image(&self, node: &str, index: usize) -> bool {
        matches!(self.shown.get(&(node.to_string(), index)), Some((_, Some(Shown::Texture(_)))))
    }

    fn show_one(&mut self, ui: &mut egui::Ui, node: &str, index: usize, spec: &PreviewSpec, evaluation: &Evaluation) {
        let mut key: Key = 0;
        let mut values = Vec::new();
        for stage in spec.stages {
            let Some(Ok(value)) = evaluation.get(node, stage).map(|r| {
                key = key.rotate_left(13) ^ r.key;
                &r.value
            }) else {
                return;
            };
            values.push(value.as_ref());
        }
        let slot = (node.to_string(), index);
        if self.shown.get(&slot).is_none_or(|(cached, _)| *cached != key) {
            let shown = (spec.make)(&values).map(|preview| match preview {
                Preview::Image(image) => {
                    let size = [image.width, image.height];
                    let color = egui::ColorImage::from_rgba_unmultiplied(size, image.rgba.as_flattened());
                    let name = format!("preview-{node}-{index}");
                    Shown::Texture(ui.ctx().load_texture(name, color, egui::TextureOptions::LINEAR))
                }
                Preview::Lobe(lobe) => Shown::Lobe(lobe),
            });
            self.shown.insert(slot.clone(), (key, shown));
        }
        let size = egui::vec2(spec.size[0], spec.size[1]);
        match &self.shown[&slot].1 {
            Some(Shown::Texture(t)) => {
                ui.image((t.id(), size)).on_hover_text(spec.caption);
            }
            Some(Shown::Lobe(lobe)) => lobe_plot(ui, lobe, size, spec.caption),
            None => {}
        }
    }
}

/// Polar plot of `f·cos θ_i` in the plane of incidence, one curve per outgoing angle,
/// each normalised to its own peak; the legend gives the directional albedos.
fn lobe_plot(ui: &mut egui::Ui, lobe: &LobePreview, size: egui::Vec2, caption: &str) {
    let (rect, response) = ui.allocate_exact_size(size, egui::Sense::hover());
    let painter = ui.painter_at(rect);
    let origin = egui::pos2(rect.center().x, rect.bottom() - 4.0);
    let radius = (rect.height() - 8.0).min(rect.width() / 2.0 - 4.0);
    painter.line_segment(
        [egui::pos2(rect.left(), origin.y), egui::pos2(rect.right(), origin.y)],
        Stroke::new(1.0, Color32::GRAY),
    );
    painter.circle_stroke(origin, radius, Stroke::new(0.5, Color32::from_gray(70)));
    let colors = [Color32::from_rgb(120, 200, 255), Color32::from_rgb(255, 200, 90), Color32::from_rgb(255, 110, 110)];
    for (k, curve) in lobe.curves.iter().enumerate() {
        let peak = curve.iter().copied().fold(0.0f32, f32::max).max(1e-12);
        let points: Vec<egui::Pos2> = curve
            .iter()
            .enumerate()
            .map(|(i, v)| {
                let angle = (i as f32 - 90.0).to_radians();
                let r = radius * v / peak;
                egui::pos2(origin.x + r * angle.sin(), origin.y - r * angle.cos())
            })
            .collect();
        let color = colors[k % colors.len()];
        painter.add(egui::Shape::line(points, Stroke::new(1.5, color)));
        // The outgoing direction (mirror side: negative angles are where light comes from).
        let theta = lobe.theta_out_deg[k].to_radians() as f32;
        let tip = egui::pos2(origin.x + radius * theta.sin(), origin.y - radius * theta.cos());
        painter.line_segment([origin, tip], Stroke::new(0.8, color.gamma_multiply(0.5)));
    }
    let legend: Vec<String> = lobe
        .theta_out_deg
        .iter()
        .zip(&lobe.directional_albedo)
        .map(|(t, a)| format!("θo = {t:.0}°: albedo {a:.3}"))
        .collect();
    response.on_hover_text(format!("{caption}\n{}", legend.join("\n")));
}
