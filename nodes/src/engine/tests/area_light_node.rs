//! The area light painter through the engine: what each kind of edit reruns (the notes' §6
//! dirty rules), and an imported image.

use super::*;
use crate::kinds::area_light::AreaLight;
use crate::light_texture::{Blend, LightTexture, PaintOp};
use glam::DVec3;

fn area_stages(eval: &Evaluation) -> BTreeSet<String> {
    ran(&eval.report).into_iter().filter(|s| s.starts_with("area.")).collect()
}

/// A stroke reruns the texture and its coefficients, a move only the placement, intensity and
/// tint only the final scale; the white default light keeps all its energy in one coefficient.
#[test]
fn edits_rerun_only_their_stages() {
    let engine = Engine::in_memory();
    let mut graph = default_graph_with("area", "AreaLightPainter", &[]);
    let cancel = CancelToken::default();
    let first = engine.evaluate(&graph, &cancel, None);
    assert_eq!(area_stages(&first), set(&["area.texture", "area.source", "area.placement", "area.face", "area.light"]));
    let light = value_of::<AreaLight>(&first, "area", "light");
    assert!((light.source.retained_energy - 1.0).abs() < 1e-12);
    assert_eq!(light.source.coefficients.len(), 1, "a constant light is its DC coefficient");
    assert_eq!(light.scale, [10.0; 3]);

    let stroke = PaintOp::Stroke {
        points: vec![[0.3, 0.3], [0.4, 0.35]],
        radius: 0.1,
        hardness: 0.5,
        colour: [1.0, 0.5, 0.2],
        intensity: 4.0,
        blend: Blend::Mix,
    };
    graph.set_param("area", "paint", ParamValue::Paint(vec![stroke])).unwrap();
    let painted = engine.evaluate(&graph, &cancel, None);
    assert_eq!(area_stages(&painted), set(&["area.texture", "area.source", "area.light"]));
    let light = value_of::<AreaLight>(&painted, "area", "light");
    assert!(light.source.coefficients.len() > 1 && light.source.retained_energy < 1.0);
    let info = &painted.report.stages.iter().find(|s| s.node == "area" && s.stage == "source").unwrap().info;
    assert!(info.iter().any(|l| l.contains("of 4096 coefficients kept per channel")), "{info:?}");

    graph.set_param("area", "position", ParamValue::Vec3([1.0, 2.5, -0.5])).unwrap();
    let moved = engine.evaluate(&graph, &cancel, None);
    assert_eq!(area_stages(&moved), set(&["area.placement", "area.light"]));
    let light = value_of::<AreaLight>(&moved, "area", "light");
    assert_eq!((light.placement.height, light.placement.corner), (2.5, [0.5, -1.0]));

    graph.set_param("area", "tint", ParamValue::Color([1.0, 0.5, 0.25])).unwrap();
    let tinted = engine.evaluate(&graph, &cancel, None);
    assert_eq!(area_stages(&tinted), set(&["area.light"]));
    assert_eq!(value_of::<AreaLight>(&tinted, "area", "light").scale, [10.0, 5.0, 2.5]);

    // A quarter turn of a 2 × 1 light: the rectangle it spans is 1 × 2.
    graph.set_param("area", "width", ParamValue::Float(2.0)).unwrap();
    graph.set_param("area", "angle", ParamValue::Float(90.0)).unwrap();
    let turned = engine.evaluate(&graph, &cancel, None);
    let extent = value_of::<AreaLight>(&turned, "area", "light").placement.extent;
    assert!((extent[0] - 1.0).abs() < 1e-12 && (extent[1] - 2.0).abs() < 1e-12, "{extent:?}");
}

/// An image imported into the light (an environment map from assets/) is resampled over the texture;
/// a missing one fails the texture stage with the file named.
#[test]
fn an_imported_image_paints_the_light() {
    let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/envmaps");
    let engine = Engine::in_memory();
    let mut graph = default_graph_with("area", "AreaLightPainter", &[]);
    let import =
        |file: &str| PaintOp::Import { path: assets.join(file).to_string_lossy().into_owned(), intensity: 1.0 };
    graph.set_param("area", "paint", ParamValue::Paint(vec![import("sunset.hdr")])).unwrap();
    let eval = engine.evaluate(&graph, &CancelToken::default(), None);
    let texture = value_of::<LightTexture>(&eval, "area", "texture");
    let lum: Vec<f64> = texture.radiance.iter().map(|c| c[0] + c[1] + c[2]).collect();
    let (lo, hi) = lum.iter().fold((f64::MAX, 0f64), |(a, b), v| (a.min(*v), b.max(*v)));
    assert!(hi > 2.0 * lo && lo >= 0.0, "the sunset varies over the light: {lo}..{hi}");

    graph.set_param("area", "paint", ParamValue::Paint(vec![import("no-such-image.exr")])).unwrap();
    let eval = engine.evaluate(&graph, &CancelToken::default(), None);
    let failed = eval.report.failed();
    let texture = failed.iter().find(|s| s.node == "area" && s.stage == "texture").expect("the texture fails");
    assert!(format!("{:?}", texture).contains("no-such-image.exr"), "{texture:?}");
}

/// A 4 m floor with a sphere of radius 0.5 resting at the origin, under white 1 × 1 lights
/// (`area`, then `area1`, …) at height 2 linked to the Output, drawn in `sh_irradiance` (the
/// cheapest mode).
fn lit_floor_graph(lights: usize) -> Graph {
    let mut project = default_project();
    for l in 0..lights {
        let id = if l == 0 { "area".to_string() } else { format!("area{l}") };
        project.nodes.push(ProjectNode {
            id: id.clone(),
            kind: "AreaLightPainter".into(),
            label: String::new(),
            position: [0.0; 2],
            params: BTreeMap::new(),
        });
        project
            .links
            .push(ProjectLink { from: (id, "area_light".into()), to: ("output".into(), "area_lights".into()) });
    }
    let mut graph = project.graph(Path::new("p.ron")).unwrap();
    let objects = vec![
        SceneObject::new("floor", Shape::Plane { size: 4.0 }),
        SceneObject::new("ball", Shape::Sphere { radius: 0.5 }).at([0.0, 0.5, 0.0]),
    ];
    graph.set_param("scene", "objects", ParamValue::Objects(objects)).unwrap();
    graph.set_param("scene", "tessellation", ParamValue::Int(96)).unwrap();
    graph.set_param("output", "mode", ParamValue::Choice("sh_irradiance".into())).unwrap();
    graph
}

/// Irradiance at floor point `x` from a constant light of radiance `radiance` on the square
/// `[c − w/2, c + w/2]²` at height `h`, with the sphere (centre `s`, radius `r`) blocking, by
/// a midpoint rule over the light's surface: `E = ∫ L cos θ cos θ' V / d² dA`.
fn direct_irradiance(x: DVec3, light: (f64, [f64; 2], f64), radiance: f64, sphere: (DVec3, f64)) -> f64 {
    direct_integral(x, light, radiance, sphere, |_| 1.0)
}

/// [`direct_irradiance`]'s midpoint rule with a per-direction factor: `∫ L factor(ω) cos θ cos θ' V / d² dA`.
fn direct_integral(
    x: DVec3,
    (h, c, w): (f64, [f64; 2], f64),
    radiance: f64,
    (s, r): (DVec3, f64),
    factor: impl Fn(DVec3) -> f64,
) -> f64 {
    let n = 160;
    let da = (w / n as f64).powi(2);
    let mut e = 0.0;
    for i in 0..n * n {
        let p = DVec3::new(
            c[0] - w / 2.0 + (i % n) as f64 * w / n as f64 + w / (2 * n) as f64,
            h,
            c[1] - w / 2.0 + (i / n) as f64 * w / n as f64 + w / (2 * n) as f64,
        );
        let d = p - x;
        let dist2 = d.length_squared();
        let dir = d / dist2.sqrt();
        // The segment x → p misses the sphere when its closest approach is beyond r.
        let t = (s - x).dot(dir).clamp(0.0, dist2.sqrt());
        if (x + dir * t - s).length() < r {
            continue;
        }
        e += radiance * factor(dir) * dir.y * dir.y / dist2 * da;
    }
    e
}

/// The viewport's area-light path through the engine: floor vertices against direct
/// integration over the light (with the sphere's shadow), and the notes' §6 dirty rules: a
/// stroke casts no ray and reruns only the propagation, a move also only the rays to the light
/// beyond the top faces; intensity rescales exactly
/// from the memoised sums; a second light with the same face shares the traced transport; the
/// incremental result equals a from-scratch evaluation bit for bit.
#[test]
fn area_lights_light_the_floor_like_direct_integration() {
    use crate::kinds::output::area::{AreaIrradiance, AreaTransport};
    let engine = Engine::in_memory();
    let mut graph = lit_floor_graph(1);
    let first = evaluate_frame(&engine, &graph);
    assert!(ran(&first.report).contains("output.area_transport"));
    let receivers = value_of::<crate::transport::Receivers>(&first, "scene", "receivers");
    let e = value_of::<AreaIrradiance>(&first, "output", "area_irradiance").irradiance;
    assert_eq!(e.len(), receivers.len());
    // Floor vertices (the first mesh) within 1.5 m of the centre, against direct integration.
    let floor = receivers.mesh_offsets[1];
    let ball = (DVec3::new(0.0, 0.5, 0.0), 0.5);
    let (mut err2, mut ref2, mut checked) = (0.0, 0.0, 0);
    for i in 0..floor {
        let (x, _) = receivers.point(i);
        // The vertex at the ball's contact point lies inside the faceted ball: skipped.
        if x.x.abs() > 1.5 || x.z.abs() > 1.5 || x.length() < 0.05 {
            continue;
        }
        let reference = direct_irradiance(x, (2.0, [0.0, 0.0], 1.0), 10.0, ball);
        let ours = f64::from(e[i][0]);
        assert!((e[i][0] - e[i][2]).abs() <= 1e-6 * e[i][0].abs().max(1.0), "a white light is grey");
        err2 += (ours - reference).powi(2);
        ref2 += reference * reference;
        checked += 1;
    }
    let relative = (err2 / ref2).sqrt();
    assert!(checked > 50, "{checked} floor vertices checked");
    // One ray per top-face cell: 2.9% here (4 rays per cell: 1.2%).
    assert!(relative < 0.04, "relative L2 error {relative:.4} against direct integration");
    // A vertex under the ball is in full shadow; one at 1 m from it is lit.
    let nearest = |p: DVec3| {
        (0..floor)
            .min_by(|&a, &b| (receivers.point(a).0 - p).length().total_cmp(&(receivers.point(b).0 - p).length()))
            .unwrap()
    };
    assert!(e[nearest(DVec3::new(0.15, 0.0, 0.0))][0] < 0.02 * e[nearest(DVec3::new(1.0, 0.0, 0.0))][0]);
    // The ball's underside (normal down) gets nothing from a light above.
    let underside = (floor..receivers.len()).find(|&i| receivers.point(i).1.y < -0.9).unwrap();
    assert_eq!(e[underside], [0.0; 3]);
    // A ceiling above the light casts no shadow (rays end at the light's plane), and gets
    // nothing itself.
    let mut roofed = graph.clone();
    let ParamValue::Objects(mut objects) = graph.node("scene").unwrap().params["objects"].clone() else { panic!() };
    objects.push(SceneObject::new("ceiling", Shape::Plane { size: 4.0 }).at([0.0, 3.0, 0.0]));
    roofed.set_param("scene", "objects", ParamValue::Objects(objects)).unwrap();
    let under_roof = value_of::<AreaIrradiance>(&evaluate_frame(&engine, &roofed), "output", "area_irradiance");
    assert_eq!(&under_roof.irradiance[..receivers.len()], &e[..], "the ceiling changes nothing below the light");
    assert!(under_roof.irradiance[receivers.len()..].iter().all(|c| *c == [0.0; 3]));

    // A move reruns only the placement, the unshadowed preview and the propagation.
    graph.set_param("area", "position", ParamValue::Vec3([0.5, 2.0, 0.0])).unwrap();
    let moved = evaluate_frame(&engine, &graph);
    let reran: BTreeSet<String> = ran(&moved.report);
    assert_eq!(
        reran,
        set(&[
            "area.placement",
            "area.light",
            "output.area_preview",
            "output.area_transport",
            "output.area_irradiance",
            "output.area_texel_transport",
            "output.area_texel_irradiance",
            "output.area_highlights"
        ])
    );
    // The transport reruns to see the light's plane is unchanged: the top face's rays are
    // reused, and only the light's part beyond the faces is traced again (one ray per quadrant).
    let report = moved.report.stages.iter().find(|s| s.stage == "area_transport").unwrap();
    assert!(report.reasons.iter().any(|r| r.contains("1 part(s) computed, 2 reused")), "{:?}", report.reasons);

    // Doubling the intensity doubles the light, reusing the memoised sum.
    let before = value_of::<AreaIrradiance>(&moved, "output", "area_irradiance").irradiance;
    graph.set_param("area", "intensity", ParamValue::Float(20.0)).unwrap();
    let brighter = evaluate_frame(&engine, &graph);
    let report = brighter.report.stages.iter().find(|s| s.stage == "area_irradiance").unwrap();
    assert!(report.reasons.iter().any(|r| r.contains("0 part(s) computed, 1 reused")), "{:?}", report.reasons);
    let after = value_of::<AreaIrradiance>(&brighter, "output", "area_irradiance").irradiance;
    assert!(before.iter().zip(&after).all(|(b, a)| (2.0 * b[1] - a[1]).abs() <= 1e-6 * a[1].abs().max(1e-3)));

    // A stroke computes only the responses of the coefficients the light newly keeps (the
    // white light's one coefficient is reused), and gives the bits of evaluating afresh.
    let stroke = PaintOp::Stroke {
        points: vec![[0.2, 0.3], [0.6, 0.4]],
        radius: 0.15,
        hardness: 0.5,
        colour: [1.0, 0.3, 0.0],
        intensity: 2.0,
        blend: Blend::Mix,
    };
    graph.set_param("area", "paint", ParamValue::Paint(vec![stroke])).unwrap();
    let painted = evaluate_frame(&engine, &graph);
    let (computed, reused) = memo_parts(&painted, "output", "area_irradiance");
    assert!(reused >= 1 && computed >= 2, "{computed} computed, {reused} reused");
    let incremental = value_of::<AreaIrradiance>(&painted, "output", "area_irradiance").irradiance;
    let fresh = value_of::<AreaIrradiance>(&evaluate_frame(&Engine::in_memory(), &graph), "output", "area_irradiance");
    assert!(fresh.irradiance.iter().zip(&incremental).all(|(a, b)| a.map(f32::to_bits) == b.map(f32::to_bits)));
    assert!(incremental.iter().zip(&after).any(|(p, a)| p[2] < 0.9 * a[2]), "the orange stroke takes blue away");

    // A second light with the same face: the transport stage reruns (its inputs changed) but
    // traces only the new light's part beyond the face; the face's rays and the first light's
    // are reused.
    let mut two_lights = lit_floor_graph(2);
    for id in ["area", "area1"] {
        two_lights.set_param(id, "position", ParamValue::Vec3([0.5, 2.0, 0.0])).unwrap();
        two_lights.set_param(id, "intensity", ParamValue::Float(20.0)).unwrap();
    }
    two_lights.set_param("area1", "position", ParamValue::Vec3([-1.0, 1.5, 0.5])).unwrap();
    let two = evaluate_frame(&engine, &two_lights);
    let report = two.report.stages.iter().find(|s| s.stage == "area_transport").unwrap();
    assert!(report.reasons.iter().any(|r| r.contains("1 part(s) computed, 3 reused")), "{:?}", report.reasons);
    assert_eq!(value_of::<AreaTransport>(&two, "output", "area_transport").faces.len(), 1);
    let both = value_of::<AreaIrradiance>(&two, "output", "area_irradiance").irradiance;
    let peak = after.iter().map(|a| a[0]).fold(0.0, f32::max);
    let lowest = both.iter().zip(&after).map(|(b, a)| b[0] - a[0]).fold(f32::MAX, f32::min);
    assert!(lowest > -0.01 * peak, "a second light darkens a vertex by {lowest} (peak {peak})");
    assert!(both.iter().zip(&after).any(|(b, a)| b[0] > 1.5 * a[0] + 1.0));
    // Incremental evaluation after the edit sequence equals evaluating from scratch, bit for bit.
    let fresh = evaluate_frame(&Engine::in_memory(), &two_lights);
    let scratch = value_of::<AreaIrradiance>(&fresh, "output", "area_irradiance").irradiance;
    assert!(scratch.iter().zip(&both).all(|(a, b)| a.map(f32::to_bits) == b.map(f32::to_bits)));
}

/// The unshadowed preview (closed form, no ray) comes in a tier before the traced transport,
/// the frame draws it until then, and it is the traced light without its shadows: within 3% of
/// it on floor vertices the ball cannot shadow, and far above it under the ball.
#[test]
fn the_unshadowed_preview_comes_first_and_agrees_where_nothing_shadows() {
    use crate::kinds::output::area::AreaIrradiance;
    let engine = Engine::in_memory();
    let graph = lit_floor_graph(1);
    let request = crate::frame::frame_request(&graph, "output", false);
    let tier_of = |stage: &str| request.tiers.iter().position(|t| t.stages.iter().any(|s| s.stage == stage)).unwrap();
    assert!(tier_of("area_preview") < tier_of("area_irradiance"));
    assert!(tier_of("area_preview") > 0, "the mode's own frame comes first");
    let first = evaluate_frame(&engine, &graph);
    let receivers = value_of::<crate::transport::Receivers>(&first, "scene", "receivers");
    let preview = value_of::<AreaIrradiance>(&first, "output", "area_preview").irradiance;
    let traced = value_of::<AreaIrradiance>(&first, "output", "area_irradiance").irradiance;
    let floor = receivers.mesh_offsets[1];
    let (mut err2, mut ref2) = (0.0, 0.0);
    for i in 0..floor {
        let (x, _) = receivers.point(i);
        if x.x.abs().max(x.z.abs()) > 1.5 {
            err2 += f64::from(preview[i][0] - traced[i][0]).powi(2);
            ref2 += f64::from(traced[i][0]).powi(2);
        }
    }
    assert!(ref2 > 0.0 && (err2 / ref2).sqrt() < 0.03, "unshadowed floor: {:.4}", (err2 / ref2).sqrt());
    let under = (0..floor)
        .min_by(|&a, &b| {
            let d = |i: usize| (receivers.point(i).0 - DVec3::new(0.15, 0.0, 0.0)).length();
            d(a).total_cmp(&d(b))
        })
        .unwrap();
    assert!(preview[under][0] > 10.0 * traced[under][0].max(1e-6));
    // A frame gathered from the tiers up to the preview draws the preview.
    let partial = engine.evaluate_request(
        &graph,
        &crate::engine::Request { tiers: request.tiers[..=tier_of("area_preview")].to_vec() },
        &CancelToken::default(),
        None,
        &|_, _| {},
    );
    let frame = crate::frame::FrameInputs::gather(&partial, &graph, "output").unwrap();
    let area = frame.area_lights.expect("the preview is drawn");
    assert_eq!(area.irradiance.value.expect::<AreaIrradiance>().unwrap().irradiance, preview);
}

/// Radiance a glossy floor point `x` reflects toward `eye` from the light of
/// [`direct_irradiance`] (same rule and blocker), the lobe before the specular colour.
fn direct_highlight(x: DVec3, eye: DVec3, brdf: &crate::brdf::Brdf, radiance: f64, sphere: (DVec3, f64)) -> f64 {
    let to_local = crate::rsl::shade::shading_frame(DVec3::Y, DVec3::X).transpose();
    let wo = to_local * (eye - x).normalize();
    direct_integral(x, (2.0, [0.0, 0.0], 1.0), radiance, sphere, |d| brdf.lobe_value(to_local * d, wo))
}

/// Sun 2008 §4.9 through the engine: a glossy floor's highlights from the painted light toward
/// the render camera, against direct integration over the light with the ball's shadow; moving
/// the viewpoint reruns only the highlights (the visibility is kept: no ray), and moves them.
#[test]
fn glossy_highlights_follow_the_view_like_direct_integration() {
    use crate::kinds::output::HIGHLIGHT_EYE;
    use crate::kinds::output::area::AreaHighlights;
    let engine = Engine::in_memory();
    let mut graph = lit_floor_graph(1);
    graph.set_param("material", "model", ParamValue::Choice("phong".into())).unwrap();
    graph.set_param("material", "exponent", ParamValue::Float(12.0)).unwrap();
    graph.set_param("material", "f0", ParamValue::Float(0.5)).unwrap();
    graph.set_param("material", "specular", ParamValue::Color([1.0, 0.8, 0.6])).unwrap();
    let ParamValue::Vec3(eye) = graph.node("output").unwrap().params[HIGHLIGHT_EYE] else { panic!("an eye") };
    assert_eq!(eye, default_project().cameras[0].position, "the render camera's viewpoint");
    let first = evaluate_frame(&engine, &graph);
    let receivers = value_of::<crate::transport::Receivers>(&first, "scene", "receivers");
    let material = value_of::<crate::brdf::Material>(&first, "material", "material");
    let brdf = crate::brdf::Brdf::from_material(&material);
    let highlights = value_of::<AreaHighlights>(&first, "output", "area_highlights").radiance;
    assert_eq!(highlights.len(), receivers.len());
    let floor = receivers.mesh_offsets[1];
    let ball = (DVec3::new(0.0, 0.5, 0.0), 0.5);
    let compare = |radiance: &[[f32; 3]], eye: [f64; 3]| {
        let (mut err2, mut ref2, mut checked) = (0.0, 0.0, 0);
        for i in 0..floor {
            let (x, _) = receivers.point(i);
            if x.x.abs() > 1.5 || x.z.abs() > 1.5 || x.length() < 0.05 {
                continue;
            }
            let reference = direct_highlight(x, DVec3::from(eye), &brdf, 10.0, ball);
            // Tinted by the specular colour.
            assert!((f64::from(radiance[i][2]) - 0.6 * f64::from(radiance[i][0])).abs() <= 1e-4 * reference.max(1.0));
            err2 += (f64::from(radiance[i][0]) - reference).powi(2);
            ref2 += reference * reference;
            checked += 1;
        }
        assert!(checked > 50);
        (err2 / ref2).sqrt()
    };
    let error = compare(&highlights, eye);
    eprintln!("highlights from the render camera: {error:.4} relative L2 against direct integration");
    assert!(error < 0.05, "relative L2 error {error:.4} of the highlights against direct integration");

    // Another viewpoint: only the highlights rerun, reusing the traced visibility.
    let side = [3.0, 1.5, 0.5];
    graph.set_param("output", HIGHLIGHT_EYE, ParamValue::Vec3(side)).unwrap();
    let moved = evaluate_frame(&engine, &graph);
    assert_eq!(ran(&moved.report), set(&["output.area_highlights"]));
    let seen = value_of::<AreaHighlights>(&moved, "output", "area_highlights").radiance;
    let error = compare(&seen, side);
    eprintln!("highlights from the side: {error:.4}");
    assert!(error < 0.05, "relative L2 error {error:.4} from the side");
    let brightest = |r: &[[f32; 3]]| (0..floor).max_by(|&a, &b| r[a][0].total_cmp(&r[b][0])).unwrap();
    let (before, after) = (receivers.point(brightest(&highlights)).0, receivers.point(brightest(&seen)).0);
    assert!(after.x > before.x + 0.3, "the highlight moves toward the new eye: {before} -> {after}");
}

/// Irradiance at floor point `x` (normal +y) from a constant `width × depth` light of radiance
/// `radiance` centred at `centre`, its light coordinates turned into the world by
/// `orientation` (facing `orientation · −y`), with the sphere blocking, by a midpoint rule over
/// the light's surface in the world: `E = ∫ L cos θ cos θ' V / d² dA`.
fn oriented_irradiance(x: DVec3, light: (DVec3, glam::DMat3, f64, f64), radiance: f64, sphere: (DVec3, f64)) -> f64 {
    oriented_integral(x, light, radiance, sphere, |_| 1.0)
}

/// [`oriented_irradiance`]'s midpoint rule with a per-direction factor.
fn oriented_integral(
    x: DVec3,
    (centre, orientation, width, depth): (DVec3, glam::DMat3, f64, f64),
    radiance: f64,
    (s, r): (DVec3, f64),
    factor: impl Fn(DVec3) -> f64,
) -> f64 {
    let n = 160;
    let facing = orientation * DVec3::NEG_Y;
    let da = width * depth / (n * n) as f64;
    let mut e = 0.0;
    for i in 0..n * n {
        let (a, b) = (((i % n) as f64 + 0.5) / n as f64 - 0.5, ((i / n) as f64 + 0.5) / n as f64 - 0.5);
        let p = centre + orientation * DVec3::new(a * width, 0.0, b * depth);
        let d = p - x;
        let dist2 = d.length_squared();
        let dir = d / dist2.sqrt();
        let (cos_receiver, cos_light) = (dir.y, -dir.dot(facing));
        if cos_receiver <= 0.0 || cos_light <= 0.0 {
            continue;
        }
        let t = (s - x).dot(dir).clamp(0.0, dist2.sqrt());
        if (x + dir * t - s).length() < r {
            continue;
        }
        e += radiance * factor(dir) * cos_receiver * cos_light / dist2 * da;
    }
    e
}

/// A light turned 30° and tilted 40° toward the ball lights the floor like direct integration
/// over its tilted rectangle in the world, the ball's shadow included (the light is computed in
/// its own frame, where it lies level). A move within its own plane traces no top face again;
/// a second light in the same frame shares the traced transport, a level one does not.
#[test]
fn a_tilted_light_lights_the_floor_like_direct_integration() {
    use crate::kinds::output::area::{AreaIrradiance, AreaTransport};
    let engine = Engine::in_memory();
    let mut graph = lit_floor_graph(2);
    let (angle, tilt, centre) = (30.0f64, 40.0f64, DVec3::new(0.8, 1.6, 1.2));
    let orientation =
        glam::DMat3::from_rotation_y(angle.to_radians()) * glam::DMat3::from_rotation_x(tilt.to_radians());
    for id in ["area", "area1"] {
        graph.set_param(id, "angle", ParamValue::Float(angle)).unwrap();
        graph.set_param(id, "tilt", ParamValue::Float(tilt)).unwrap();
        graph.set_param(id, "position", ParamValue::Vec3(centre.to_array())).unwrap();
    }
    // The second light starts dark, beside the first in its plane.
    let beside = centre + orientation * DVec3::new(-1.2, 0.0, 0.3);
    graph.set_param("area1", "position", ParamValue::Vec3(beside.to_array())).unwrap();
    graph.set_param("area1", "intensity", ParamValue::Float(0.0)).unwrap();
    let first = evaluate_frame(&engine, &graph);
    assert_eq!(value_of::<AreaTransport>(&first, "output", "area_transport").faces.len(), 1, "one frame, one face");
    let receivers = value_of::<crate::transport::Receivers>(&first, "scene", "receivers");
    let e = value_of::<AreaIrradiance>(&first, "output", "area_irradiance").irradiance;
    let floor = receivers.mesh_offsets[1];
    let ball = (DVec3::new(0.0, 0.5, 0.0), 0.5);
    let (mut err2, mut ref2, mut checked, mut shadowed) = (0.0, 0.0, 0, 0);
    for i in 0..floor {
        let (x, _) = receivers.point(i);
        if x.x.abs() > 1.5 || x.z.abs() > 1.5 || x.length() < 0.05 {
            continue;
        }
        let reference = oriented_irradiance(x, (centre, orientation, 1.0, 1.0), 10.0, ball);
        err2 += (f64::from(e[i][0]) - reference).powi(2);
        ref2 += reference * reference;
        checked += 1;
        let unshadowed = oriented_irradiance(x, (centre, orientation, 1.0, 1.0), 10.0, (ball.0, 0.0));
        shadowed += usize::from(reference < 0.5 * unshadowed);
    }
    let relative = (err2 / ref2).sqrt();
    eprintln!("tilted light against direct integration: {relative:.4} over {checked} floor vertices");
    assert!(checked > 50 && shadowed > 10, "{checked} floor vertices checked, {shadowed} in the ball's shadow");
    // 0.8% here (1.4% with one ray per top-face cell on the ball's silhouette too).
    assert!(relative < 0.012, "relative L2 error {relative:.4} against direct integration");

    // A move within the light's own plane reuses the top face's rays: only its part beyond
    // the face is traced again.
    let moved = centre + orientation * DVec3::new(0.3, 0.0, -0.2);
    graph.set_param("area", "position", ParamValue::Vec3(moved.to_array())).unwrap();
    let after = evaluate_frame(&engine, &graph);
    let report = after.report.stages.iter().find(|s| s.stage == "area_transport").unwrap();
    assert!(report.reasons.iter().any(|r| r.contains("1 part(s) computed, 3 reused")), "{:?}", report.reasons);
    // A level light beside it has a frame of its own.
    graph.set_param("area1", "tilt", ParamValue::Float(0.0)).unwrap();
    let level = evaluate_frame(&engine, &graph);
    assert_eq!(value_of::<AreaTransport>(&level, "output", "area_transport").faces.len(), 2);

    // The unshadowed preview (closed form in the light's frame) and a glossy floor's highlights
    // toward the render camera (the lobe turned back out of the light's frame), against the
    // same integral over the moved light, alone.
    use crate::kinds::output::{HIGHLIGHT_EYE, area::AreaHighlights};
    graph.set_param("area1", "intensity", ParamValue::Float(0.0)).unwrap();
    graph.set_param("area1", "tilt", ParamValue::Float(tilt)).unwrap();
    graph.set_param("material", "model", ParamValue::Choice("phong".into())).unwrap();
    graph.set_param("material", "exponent", ParamValue::Float(12.0)).unwrap();
    graph.set_param("material", "f0", ParamValue::Float(0.5)).unwrap();
    let glossy = evaluate_frame(&engine, &graph);
    let ParamValue::Vec3(eye) = graph.node("output").unwrap().params[HIGHLIGHT_EYE] else { panic!("an eye") };
    let brdf = crate::brdf::Brdf::from_material(&value_of::<crate::brdf::Material>(&glossy, "material", "material"));
    let preview = value_of::<AreaIrradiance>(&glossy, "output", "area_preview").irradiance;
    let highlights = value_of::<AreaHighlights>(&glossy, "output", "area_highlights").radiance;
    let light = (moved, orientation, 1.0, 1.0);
    let to_local = crate::rsl::shade::shading_frame(DVec3::Y, DVec3::X).transpose();
    let [(mut p_err, mut p_ref), (mut h_err, mut h_ref)] = [(0.0, 0.0); 2];
    for i in 0..floor {
        let (x, _) = receivers.point(i);
        if x.x.abs() > 1.5 || x.z.abs() > 1.5 || x.length() < 0.05 {
            continue;
        }
        let open = oriented_irradiance(x, light, 10.0, (ball.0, 0.0));
        p_err += (f64::from(preview[i][0]) - open).powi(2);
        p_ref += open * open;
        let wo = to_local * (DVec3::from(eye) - x).normalize();
        let lobe = oriented_integral(x, light, 10.0, ball, |d| brdf.lobe_value(to_local * d, wo));
        h_err += (f64::from(highlights[i][0]) - lobe).powi(2);
        h_ref += lobe * lobe;
    }
    let (preview, highlights) = ((p_err / p_ref).sqrt(), (h_err / h_ref).sqrt());
    eprintln!(
        "tilted light: unshadowed preview {preview:.4}, glossy highlights {highlights:.4} against direct integration"
    );
    assert!(preview < 0.02, "the preview: {preview:.4}");
    assert!(highlights < 0.05, "the highlights: {highlights:.4}");
}
