//! Gizmos in the viewport: every light whose kind declares a light gizmo
//! ([`GizmoSpec::Light`]) drawn where it is (filled when it lights the output, hollow when it
//! is not linked; a spot with a line along its aim), every blocker sphere as its outline, and every
//! painted area light as its rectangle with a centre handle and four edge handles. A click
//! selects the node; a drag moves the light or the sphere in the view plane and the area light in
//! its own plane (with Shift, along its normal only), and an edge handle resizes the area light
//! about its centre (one undo step per drag).

use super::*;
use lightloom_nodes::engine::spec::GizmoSpec;

/// Pointer distance, in points, within which a light's gizmo (or a sphere's centre) is hit.
const HIT_RADIUS: f32 = 12.0;
/// Distance from a sphere's outline, in points, within which it is hit.
const RING_HIT: f32 = 5.0;
/// Pointer distance, in points, within which an area light's edge handle is hit.
const EDGE_HIT: f32 = 7.0;

/// What a gizmo stands for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum GizmoTarget {
    /// A light; dragging sets its `position` parameter. `aim`: the way it shines, if it has one.
    Light { position: &'static str, aim: Option<[f64; 3]> },
    /// A painted area light's rectangle (metres), tilted by `tilt` degrees about its width axis
    /// and turned by `angle` degrees about the vertical.
    AreaLight { width: f64, depth: f64, angle: f64, tilt: f64 },
    /// Sphere `index` of a blocker set, of `radius` metres; `fitted` when the set is fitted to a
    /// model (its spheres come from the fit, and a drag moves the whole set).
    Sphere { index: usize, radius: f64, fitted: bool },
}

pub(super) struct Gizmo {
    pub id: String,
    pub target: GizmoTarget,
    /// World position (a sphere's centre with its set's offset).
    pub position: [f64; 3],
    /// The light's colour at full brightness; the blocker port's colour for spheres.
    pub colour: Color32,
    /// Whether it reaches the Output (else it lights or shadows nothing).
    pub linked: bool,
}

/// A gizmo by its node and, for a blocker set, which sphere; for an area light, which edge
/// handle (none: the centre).
#[derive(Clone, Debug, PartialEq)]
pub(super) struct GizmoId {
    pub node: String,
    pub sphere: Option<usize>,
    pub edge: Option<Edge>,
}

/// An area light's edge handle: the two along its width (±), then the two along its depth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Edge {
    Width(f64),
    Depth(f64),
}

impl Edge {
    const ALL: [Edge; 4] = [Edge::Width(1.0), Edge::Width(-1.0), Edge::Depth(1.0), Edge::Depth(-1.0)];

    fn param(self) -> &'static str {
        match self {
            Edge::Width(_) => "width",
            Edge::Depth(_) => "depth",
        }
    }
}

/// A `width × depth` area light tilted by `tilt` degrees about its width axis, then turned by
/// `angle` degrees about the vertical (both right-handed, as the light's texture turns).
type LightShape = (f64, f64, f64, f64);

/// The world point at light coordinates `(u, v) ∈ [−1, 1]²` of a light centred at `p`.
fn on_area_light(p: [f64; 3], (width, depth, angle, tilt): LightShape, (u, v): (f64, f64)) -> [f64; 3] {
    let offset = lightloom_nodes::near_field::light_orientation(angle, tilt)
        * glam::DVec3::new(u * width / 2.0, 0.0, v * depth / 2.0);
    (glam::DVec3::from(p) + offset).to_array()
}

/// Texels per side of the grid the light's preview is drawn on: egui maps a texture affinely
/// per triangle, so a finer grid keeps the texture where perspective puts it.
const PREVIEW_GRID: usize = 8;

/// The selected light's painted texture on its rectangle, over the view (in light coordinates,
/// as the canvas shows it); nothing when part of it is behind the camera.
fn preview_light(
    painter: &egui::Painter,
    camera: &OrbitCamera,
    rect: egui::Rect,
    texture: egui::TextureId,
    position: [f64; 3],
    shape: LightShape,
) {
    let mut mesh = egui::Mesh::with_texture(texture);
    let n = PREVIEW_GRID;
    for j in 0..=n {
        for i in 0..=n {
            let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
            let Some(pos) = screen_pos(camera, rect, on_area_light(position, shape, (2.0 * u - 1.0, 2.0 * v - 1.0)))
            else {
                return;
            };
            mesh.vertices.push(egui::epaint::Vertex {
                pos,
                uv: egui::pos2(u as f32, v as f32),
                color: Color32::from_white_alpha(230),
            });
        }
    }
    let at = |i: usize, j: usize| (j * (n + 1) + i) as u32;
    for j in 0..n {
        for i in 0..n {
            mesh.add_triangle(at(i, j), at(i + 1, j), at(i + 1, j + 1));
            mesh.add_triangle(at(i, j), at(i + 1, j + 1), at(i, j + 1));
        }
    }
    painter.add(egui::Shape::mesh(mesh));
}

impl Gizmo {
    fn gizmo_id(&self) -> GizmoId {
        let sphere = match self.target {
            GizmoTarget::Light { .. } | GizmoTarget::AreaLight { .. } => None,
            GizmoTarget::Sphere { index, .. } => Some(index),
        };
        GizmoId { node: self.id.clone(), sphere, edge: None }
    }

    /// An area light's edge handles: which edge, and its world point.
    pub(super) fn edges(&self) -> Vec<(Edge, [f64; 3])> {
        let GizmoTarget::AreaLight { width, depth, angle, tilt } = self.target else { return Vec::new() };
        Edge::ALL
            .iter()
            .map(|&e| {
                let uv = match e {
                    Edge::Width(s) => (s, 0.0),
                    Edge::Depth(s) => (0.0, s),
                };
                (e, on_area_light(self.position, (width, depth, angle, tilt), uv))
            })
            .collect()
    }

    /// The sphere's outline radius in points (0 for a light).
    fn screen_radius(&self, camera: &OrbitCamera, rect: egui::Rect) -> f32 {
        let GizmoTarget::Sphere { radius, .. } = self.target else { return 0.0 };
        let Some((_, depth)) =
            camera.project(glam::DVec3::from(self.position), (rect.width().into(), rect.height().into()))
        else {
            return 0.0;
        };
        let tan = (camera.fov_y_deg.to_radians() / 2.0).tan();
        (radius / (depth * tan) * f64::from(rect.height()) / 2.0) as f32
    }
}

/// Where world point `p` is in the viewport `rect` seen by `camera`, if in front of it.
pub(super) fn screen_pos(camera: &OrbitCamera, rect: egui::Rect, p: [f64; 3]) -> Option<egui::Pos2> {
    let ((x, y), _) = camera.project(glam::DVec3::from(p), (rect.width().into(), rect.height().into()))?;
    Some(rect.min + egui::vec2(x as f32, y as f32))
}

/// A light's colour scaled so its brightest channel is full.
fn full_brightness(rgb: [f64; 3]) -> Color32 {
    let peak = rgb.iter().cloned().fold(1e-9, f64::max);
    let [r, g, b] = rgb.map(|c| (c / peak * 255.0).round().clamp(0.0, 255.0) as u8);
    Color32::from_rgb(r, g, b)
}

/// The blocker port's colour in the graph.
const SPHERE_COLOUR: Color32 = Color32::from_rgb(230, 170, 120);

impl EditorApp {
    /// The project's point lights and blocker spheres.
    pub(super) fn gizmos(&self) -> Vec<Gizmo> {
        let graph = self.evaluator.last.as_ref().map(|(_, g)| g);
        let linked = |id: &str| graph.is_some_and(|g| g.feeds_sink(id));
        let mut out = Vec::new();
        for n in &self.doc.project.nodes {
            let Some(spec) = lightloom_nodes::kinds::kind(&n.kind) else { continue };
            let value = |name: &str| spec.param(name).map(|s| inspector::param_value(&self.doc.project, &n.id, s));
            if let GizmoSpec::Light { position, colour, aim } = spec.gizmo {
                let (Some(ParamValue::Vec3(at)), Some(ParamValue::Color(rgb))) = (value(position), value(colour))
                else {
                    continue;
                };
                let aim = aim.and_then(|name| match value(name) {
                    Some(ParamValue::Vec3(aim)) => Some(aim),
                    _ => None,
                });
                out.push(Gizmo {
                    id: n.id.clone(),
                    target: GizmoTarget::Light { position, aim },
                    position: at,
                    colour: full_brightness(rgb),
                    linked: linked(&n.id),
                });
                continue;
            }
            match n.kind.as_str() {
                "AreaLightPainter" => {
                    let (Some(ParamValue::Vec3(position)), Some(ParamValue::Color(tint))) =
                        (value("position"), value("tint"))
                    else {
                        continue;
                    };
                    let float = |name: &str| match value(name) {
                        Some(ParamValue::Float(v)) => v,
                        _ => 0.0,
                    };
                    out.push(Gizmo {
                        id: n.id.clone(),
                        target: GizmoTarget::AreaLight {
                            width: float("width"),
                            depth: float("depth"),
                            angle: float("angle"),
                            tilt: float("tilt"),
                        },
                        position,
                        colour: full_brightness(tint),
                        linked: linked(&n.id),
                    });
                }
                "BlockerSpheres" => {
                    let (Some(ParamValue::Spheres(hand)), Some(transform)) =
                        (value("spheres"), self.sphere_transform(&n.id))
                    else {
                        continue;
                    };
                    // A set fitted to a model shows the fitted spheres of the last evaluation.
                    let fitted = matches!(value("fit_model"), Some(ParamValue::Path(p)) if !p.is_empty());
                    let spheres = if fitted {
                        self.evaluator
                            .last
                            .as_ref()
                            .and_then(|(e, _)| e.value(&n.id, "fitted").ok())
                            .and_then(|v| {
                                v.get::<lightloom_nodes::sphere_set::SphereSetFit>().map(|f| f.spheres.clone())
                            })
                            .unwrap_or_default()
                    } else {
                        hand
                    };
                    for (index, (centre, radius)) in spheres.iter().enumerate() {
                        out.push(Gizmo {
                            id: n.id.clone(),
                            target: GizmoTarget::Sphere { index, radius: radius * transform.scale, fitted },
                            position: transform.to_world(*centre).to_array(),
                            colour: SPHERE_COLOUR,
                            linked: linked(&n.id),
                        });
                    }
                }
                _ => {}
            }
        }
        out
    }

    /// Where blocker set `node` puts its spheres (its offset, rotation and scale).
    fn sphere_transform(&self, node: &str) -> Option<lightloom_nodes::kinds::blockers::SetTransform> {
        let spec = lightloom_nodes::kinds::kind("BlockerSpheres")?;
        let value = |name: &str| spec.param(name).map(|p| inspector::param_value(&self.doc.project, node, p));
        let (Some(ParamValue::Vec3(offset)), Some(ParamValue::Vec3(rotation)), Some(ParamValue::Float(scale))) =
            (value("offset"), value("rotation"), value("scale"))
        else {
            return None;
        };
        Some(lightloom_nodes::kinds::blockers::SetTransform::new(offset, rotation, scale))
    }

    /// The gizmo under `pos`: an area light's edge handle, a light within reach of its marker,
    /// a sphere near its centre or its outline (the nearest wins).
    pub(super) fn gizmo_at(&self, pos: egui::Pos2, rect: egui::Rect) -> Option<GizmoId> {
        let camera = self.viewport_camera(rect);
        let gizmos = self.gizmos();
        let edge = gizmos
            .iter()
            .flat_map(|g| g.edges().into_iter().map(move |(e, p)| (g, e, p)))
            .filter_map(|(g, e, p)| {
                let d = screen_pos(&camera, rect, p)?.distance(pos);
                (d <= EDGE_HIT).then(|| (d, GizmoId { edge: Some(e), ..g.gizmo_id() }))
            })
            .min_by(|a, b| a.0.total_cmp(&b.0));
        gizmos
            .into_iter()
            .filter_map(|g| {
                let d = screen_pos(&camera, rect, g.position)?.distance(pos);
                let hit = match g.target {
                    GizmoTarget::Light { .. } | GizmoTarget::AreaLight { .. } => d <= HIT_RADIUS,
                    // A sphere by its centre or its outline, so the objects it stands in for
                    // stay pickable; never from inside it.
                    GizmoTarget::Sphere { radius, .. } => {
                        let inside = (camera.position() - glam::DVec3::from(g.position)).length() <= radius;
                        !inside && (d <= HIT_RADIUS || (d - g.screen_radius(&camera, rect)).abs() <= RING_HIT)
                    }
                };
                hit.then(|| (d, g.gizmo_id()))
            })
            .chain(edge)
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .map(|(_, id)| id)
    }

    /// Keeps each area light's preview texture in step with its last evaluated `texture` stage.
    pub(super) fn refresh_light_previews(&mut self, ctx: &egui::Context) {
        let lights: Vec<String> =
            self.doc.project.nodes.iter().filter(|n| n.kind == "AreaLightPainter").map(|n| n.id.clone()).collect();
        self.light_previews.retain(|id, _| lights.contains(id));
        let Some((evaluation, _)) = &self.evaluator.last else { return };
        for id in lights {
            let Some(stage) = evaluation.get(&id, "texture") else { continue };
            if self.light_previews.get(&id).is_some_and(|(key, _)| *key == stage.key) {
                continue;
            }
            let Some(texture) =
                stage.value.as_ref().ok().and_then(|v| v.expect::<lightloom_nodes::light_texture::LightTexture>().ok())
            else {
                continue;
            };
            let image = super::paint_canvas::preview_image(texture);
            let handle = ctx.load_texture(format!("light-preview-{id}"), image, egui::TextureOptions::LINEAR);
            self.light_previews.insert(id, (stage.key, handle));
        }
    }

    pub(super) fn draw_gizmos(&self, painter: &egui::Painter, rect: egui::Rect, hover: Option<egui::Pos2>) {
        let camera = self.viewport_camera(rect);
        let selected = match &self.selection {
            Selection::Node(id) => Some(id.as_str()),
            _ => None,
        };
        let hovered_id = hover.and_then(|p| self.gizmo_at(p, rect));
        for g in self.gizmos() {
            let Some(at) = screen_pos(&camera, rect, g.position) else { continue };
            if !rect.contains(at) {
                continue;
            }
            let is_selected = selected == Some(g.id.as_str());
            let outline = if is_selected { Color32::from_rgb(255, 200, 80) } else { Color32::BLACK };
            let label = match g.target {
                GizmoTarget::Light { aim, .. } => {
                    // A spot's aim: a line half a metre along it.
                    let aimed = aim.and_then(|aim| {
                        let aim = glam::DVec3::from(aim).try_normalize()?;
                        screen_pos(&camera, rect, (glam::DVec3::from(g.position) + aim * 0.5).to_array())
                    });
                    if let Some(to) = aimed {
                        painter.line_segment([at, to], egui::Stroke::new(2.0, g.colour));
                        painter.circle_filled(to, 2.5, g.colour);
                    }
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
                    if g.linked { g.id.clone() } else { format!("{} (not linked: lights nothing)", g.id) }
                }
                GizmoTarget::AreaLight { width, depth, angle, tilt } => {
                    let shape = (width, depth, angle, tilt);
                    let corners: Option<Vec<egui::Pos2>> = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
                        .iter()
                        .map(|&uv| screen_pos(&camera, rect, on_area_light(g.position, shape, uv)))
                        .collect();
                    let colour = if is_selected { outline } else { g.colour };
                    if is_selected && let Some((_, texture)) = self.light_previews.get(&g.id) {
                        preview_light(painter, &camera, rect, texture.id(), g.position, shape);
                    }
                    if let Some(mut corners) = corners {
                        corners.push(corners[0]);
                        painter.add(egui::Shape::line(corners.clone(), egui::Stroke::new(3.0, Color32::BLACK)));
                        painter.add(egui::Shape::line(corners, egui::Stroke::new(1.5, colour)));
                    }
                    let handle = egui::Rect::from_center_size(at, egui::vec2(9.0, 9.0));
                    painter.rect_filled(handle.expand(1.5), 1.0, Color32::BLACK);
                    painter.rect_filled(handle, 1.0, colour);
                    for (edge, p) in g.edges() {
                        let Some(at) = screen_pos(&camera, rect, p) else { continue };
                        let hot = hovered_id.as_ref().is_some_and(|h| h.node == g.id && h.edge == Some(edge));
                        painter.circle_filled(at, if hot { 6.0 } else { 4.5 }, Color32::BLACK);
                        painter.circle_filled(at, if hot { 4.5 } else { 3.0 }, colour);
                    }
                    match hovered_id.as_ref().and_then(|h| h.edge) {
                        Some(edge) => format!("{} · drag to resize its {}", g.id, edge.param()),
                        None if g.linked => format!("{} · {width:.2} × {depth:.2} m area light", g.id),
                        None => format!("{} · {width:.2} × {depth:.2} m area light (not linked: lights nothing)", g.id),
                    }
                }
                GizmoTarget::Sphere { index, radius, fitted } => {
                    let r = g.screen_radius(&camera, rect).max(3.0);
                    let colour = if is_selected { outline } else { g.colour };
                    let stroke = if g.linked {
                        egui::Stroke::new(1.5, colour)
                    } else {
                        egui::Stroke::new(1.0, colour.gamma_multiply(0.5))
                    };
                    painter.circle_stroke(at, r + 1.0, egui::Stroke::new(1.0, Color32::from_black_alpha(140)));
                    painter.circle_stroke(at, r, stroke);
                    painter.circle_filled(at, 2.5, colour);
                    let state = if g.linked { "" } else { " (not linked: shadows nothing)" };
                    let what = if fitted { "fitted sphere" } else { "sphere" };
                    format!("{} {what} {} · r {radius:.2} m{state}", g.id, index + 1)
                }
            };
            let hovered = hovered_id.as_ref().is_some_and(|h| h.node == g.id && h.sphere == g.gizmo_id().sphere);
            if hovered || (is_selected && matches!(g.target, GizmoTarget::Light { .. })) {
                let galley = painter.layout_no_wrap(label, egui::FontId::proportional(12.0), Color32::WHITE);
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

    /// A primary drag that starts on a gizmo moves its light or sphere; returns whether it did.
    pub(super) fn drag_gizmo(&mut self, ui: &egui::Ui, response: &egui::Response, rect: egui::Rect) -> bool {
        let alt = ui.input(|i| i.modifiers.alt);
        if response.drag_started_by(egui::PointerButton::Primary) && !alt {
            let origin = ui.input(|i| i.pointer.press_origin());
            self.view.dragging_gizmo = origin.and_then(|p| self.gizmo_at(p, rect));
            if let Some(id) = &self.view.dragging_gizmo {
                self.selection = Selection::Node(id.node.clone());
            }
        }
        if !response.dragged_by(egui::PointerButton::Primary) {
            self.view.dragging_gizmo = None;
            return false;
        }
        let Some(id) = self.view.dragging_gizmo.clone() else { return false };
        let delta = ui.input(|i| i.pointer.delta());
        let Some(gizmo) = self.gizmos().into_iter().find(|g| g.gizmo_id() == GizmoId { edge: None, ..id.clone() })
        else {
            return false;
        };
        if delta == egui::Vec2::ZERO {
            return true;
        }
        let camera = self.viewport_camera(rect);
        let drag = (f64::from(delta.x), f64::from(delta.y));
        let from = glam::DVec3::from(gizmo.position);
        let moved = match gizmo.target {
            // An area light slides in its own plane; with Shift it moves along its normal only.
            GizmoTarget::AreaLight { angle, tilt, .. } if ui.input(|i| i.modifiers.shift) => {
                let normal = lightloom_nodes::near_field::light_orientation(angle, tilt) * glam::DVec3::Y;
                let lifted = camera.drag_point(from, drag, f64::from(rect.height()));
                from + normal * (lifted - from).dot(normal)
            }
            GizmoTarget::AreaLight { angle, tilt, .. } => {
                let normal = lightloom_nodes::near_field::light_orientation(angle, tilt) * glam::DVec3::Y;
                camera.drag_point_in_plane(from, normal, drag, f64::from(rect.height()))
            }
            _ => camera.drag_point(from, drag, f64::from(rect.height())),
        }
        .to_array();
        let change = match (id.sphere, id.edge) {
            (_, Some(edge)) => {
                // The edge follows the pointer in the view plane; its distance from the centre
                // along the light's own axis is half the new size.
                let Some((_, at)) = gizmo.edges().into_iter().find(|(e, _)| *e == edge) else { return true };
                let moved = camera.drag_point(
                    glam::DVec3::from(at),
                    (f64::from(delta.x), f64::from(delta.y)),
                    f64::from(rect.height()),
                );
                let axis = glam::DVec3::from(at) - glam::DVec3::from(gizmo.position);
                let half = (moved - glam::DVec3::from(gizmo.position)).dot(axis.normalize_or_zero());
                Some((edge.param(), ParamValue::Float((2.0 * half).clamp(0.01, 1e3))))
            }
            (None, None) => match gizmo.target {
                GizmoTarget::Light { position, .. } => Some((position, ParamValue::Vec3(moved))),
                _ => Some(("position", ParamValue::Vec3(moved))),
            },
            (Some(_), None) if matches!(gizmo.target, GizmoTarget::Sphere { fitted: true, .. }) => {
                // A fitted sphere moves its whole set.
                self.sphere_transform(&id.node).map(|t| {
                    let offset = t.offset + glam::DVec3::from(moved) - glam::DVec3::from(gizmo.position);
                    ("offset", ParamValue::Vec3(offset.to_array()))
                })
            }
            (Some(index), None) => {
                let spec = lightloom_nodes::kinds::kind("BlockerSpheres").expect("BlockerSpheres kind");
                let spheres =
                    inspector::param_value(&self.doc.project, &id.node, spec.param("spheres").expect("param"));
                match (spheres, self.sphere_transform(&id.node)) {
                    (ParamValue::Spheres(mut spheres), Some(transform)) if index < spheres.len() => {
                        spheres[index].0 = transform.to_set(glam::DVec3::from(moved));
                        Some(("spheres", ParamValue::Spheres(spheres)))
                    }
                    _ => None,
                }
            }
        };
        if let Some((name, value)) = change
            && let Err(e) = inspector::set_param(&mut self.doc, &id.node, name, value)
        {
            self.log_error(e);
        }
        true
    }
}
