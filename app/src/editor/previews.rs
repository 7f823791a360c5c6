//! Node previews: environment thumbnail and SH lighting sphere (images made by
//! `lightloom_nodes::preview`), the BRDF lobe plot (drawn from the BRDF editor's `preview`
//! stage). Textures are cached by stage key, so they are rebuilt only when the stage changes.

use eframe::egui::{self, Color32, Stroke};
use lightloom_nodes::brdf::LobePreview;
use lightloom_nodes::cubemap::CubeMap;
use lightloom_nodes::engine::{Evaluation, StageValue, key::Key};
use lightloom_nodes::kinds::fog::Medium;
use lightloom_nodes::preview::{self, PreviewImage};
use lightloom_nodes::sh::ShRgb;
use lightloom_nodes::single_scattering::FTable;
use std::collections::HashMap;

/// Kinds that show a preview.
pub fn has_preview(kind: &str) -> bool {
    !preview_stages(kind).is_empty()
}

/// The stages a kind's preview reads (requested from the engine while the preview shows).
pub fn preview_stages(kind: &str) -> &'static [&'static str] {
    match kind {
        "EnvironmentMap" => &["rotated_radiance", "sh"],
        "BrdfEditor" => &["preview"],
        "FogMedium" => &["medium", "f_tables"],
        _ => &[],
    }
}

#[derive(Default)]
pub struct Previews {
    textures: HashMap<(String, &'static str), (Key, egui::TextureHandle)>,
}

impl Previews {
    fn texture(
        &mut self,
        ctx: &egui::Context,
        evaluation: &Evaluation,
        node: &str,
        stage: &'static str,
        make: impl FnOnce(&StageValue) -> Option<PreviewImage>,
    ) -> Option<egui::TextureHandle> {
        let result = evaluation.get(node, stage)?;
        let value = result.value.as_ref().ok()?;
        self.keyed_texture(ctx, node, stage, result.key, || make(value))
    }

    /// A texture made by `make`, rebuilt only when `key` changes.
    fn keyed_texture(
        &mut self,
        ctx: &egui::Context,
        node: &str,
        stage: &'static str,
        key: Key,
        make: impl FnOnce() -> Option<PreviewImage>,
    ) -> Option<egui::TextureHandle> {
        let slot = (node.to_string(), stage);
        if let Some((cached, handle)) = self.textures.get(&slot)
            && *cached == key
        {
            return Some(handle.clone());
        }
        let image = make()?;
        let color = egui::ColorImage::from_rgba_unmultiplied([image.width, image.height], image.rgba.as_flattened());
        let handle = ctx.load_texture(format!("preview-{node}-{stage}"), color, egui::TextureOptions::LINEAR);
        self.textures.insert(slot, (key, handle.clone()));
        Some(handle)
    }

    /// Draws the node's preview (if its kind has one and its stage has a value).
    pub fn show(&mut self, ui: &mut egui::Ui, node: &str, kind: &str, evaluation: &Evaluation) {
        match kind {
            "EnvironmentMap" => {
                ui.horizontal(|ui| {
                    let thumb = self.texture(ui.ctx(), evaluation, node, "rotated_radiance", |v| {
                        v.get::<CubeMap>().map(|c| preview::environment_thumbnail(c, 192, 96))
                    });
                    if let Some(t) = thumb {
                        ui.image((t.id(), egui::vec2(128.0, 64.0))).on_hover_text("environment (auto-exposed)");
                    }
                    let sphere = self.texture(ui.ctx(), evaluation, node, "sh", |v| {
                        v.get::<ShRgb>().map(|sh| preview::sh_lighting_sphere(sh, 96))
                    });
                    if let Some(t) = sphere {
                        ui.image((t.id(), egui::vec2(64.0, 64.0)))
                            .on_hover_text("SH lighting on a white diffuse sphere (auto-exposed)");
                    }
                });
            }
            "FogMedium" => {
                let (Some(medium), Some(tables)) = (evaluation.get(node, "medium"), evaluation.get(node, "f_tables"))
                else {
                    return;
                };
                let (Ok(m), Ok(t)) = (&medium.value, &tables.value) else { return };
                let (Some(m), Some(t)) = (m.get::<Medium>(), t.get::<Vec<FTable>>()) else { return };
                let key = medium.key ^ tables.key.rotate_left(1);
                let glow = self.keyed_texture(ui.ctx(), node, "glow", key, || {
                    let phase = if m.phase == "polynomial" {
                        lightloom_nodes::single_scattering::Phase::polynomial(&m.phase_coefficients)?
                    } else {
                        lightloom_nodes::single_scattering::Phase::isotropic()
                    };
                    Some(preview::fog_glow(m.beta, &phase, t, 64))
                });
                if let Some(t) = glow {
                    ui.image((t.id(), egui::vec2(80.0, 80.0)))
                        .on_hover_text("a point light 10 m away seen through this fog (airlight, eq. 3.16)");
                }
            }
            "BrdfEditor" => {
                if let Some(Ok(value)) = evaluation.get(node, "preview").map(|r| &r.value)
                    && let Some(lobe) = value.get::<LobePreview>()
                {
                    lobe_plot(ui, lobe);
                }
            }
            _ => {}
        }
    }
}

/// Polar plot of `f·cos θ_i` in the plane of incidence, one curve per outgoing angle,
/// each normalised to its own peak; the legend gives the directional albedos.
fn lobe_plot(ui: &mut egui::Ui, lobe: &lightloom_nodes::brdf::LobePreview) {
    let size = egui::vec2(200.0, 104.0);
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
    response.on_hover_text(format!(
        "f·cos θi in the plane of incidence (each curve scaled to its peak)\n{}",
        legend.join("\n")
    ));
}
