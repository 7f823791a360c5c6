//! The area light painter through the engine: what each kind of edit reruns (the notes' §6
//! dirty rules), and an imported image.

use super::*;
use crate::kinds::area_light::AreaLight;
use crate::light_texture::{Blend, LightTexture, PaintOp};

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
    assert_eq!(area_stages(&first), set(&["area.texture", "area.source", "area.placement", "area.light"]));
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

/// An image imported into the light (a shared environment map) is resampled over the texture;
/// a missing one fails the texture stage with the file named.
#[test]
fn an_imported_image_paints_the_light() {
    let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/assets/envmaps");
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
