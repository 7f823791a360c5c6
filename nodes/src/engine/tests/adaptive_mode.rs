//! The `sh_adaptive` mode through the engine: the frame it draws, its PSNR report, what a
//! threshold edit and an environment turn recompute, and the hysteresis across evaluations.

use super::*;
use crate::adaptive_sh::AdaptiveIncident;
use crate::kinds::AdaptiveError;
use crate::prt::IncidentSh;

/// The default project in `sh_adaptive` at level 7 (8 bands everywhere; the sky's sun lit
/// apart, so the stages are the residual sky's) with a Phong material,
/// and a second (Lambert) material linked that no mesh names, so every mesh keeps the first.
fn adaptive_graph(threshold: f64) -> Graph {
    let mut graph = default_graph_with("gloss", "BrdfEditor", &[("gloss", "material", "output", "material")]);
    graph.set_param("material", "model", ParamValue::Choice("phong".into())).unwrap();
    graph.set_param("sky", "sh_bands", ParamValue::Int(8)).unwrap();
    graph.set_param("scene", "transport_bands", ParamValue::Int(8)).unwrap();
    graph.set_param("scene", "transport_rays", ParamValue::Int(64)).unwrap();
    graph.set_param("scene", "tessellation", ParamValue::Int(24)).unwrap();
    graph.set_param("output", "mode", ParamValue::Choice("sh_adaptive".into())).unwrap();
    graph.set_param("output", "adaptive_level", ParamValue::Int(7)).unwrap();
    graph.set_param("output", "adaptive_threshold", ParamValue::Float(threshold)).unwrap();
    graph
}

fn info<'a>(eval: &'a Evaluation, stage: &str) -> &'a [String] {
    &eval.report.stages.iter().find(|s| s.node == "output" && s.stage == stage).expect("in the report").info
}

/// At threshold 0 the adaptive product equals `sh_prt`'s independent Gaunt product (f64,
/// `prt::incident_radiance`) and its PSNR is unbounded; the frame draws it.
#[test]
fn threshold_zero_equals_the_gaunt_product_of_sh_prt() {
    let engine = Engine::in_memory();
    let graph = adaptive_graph(0.0);
    let eval = evaluate_frame(&engine, &graph);
    let adaptive = value_of::<AdaptiveIncident>(&eval, "output", "adaptive_residual_incident");
    assert_eq!(adaptive.incident.bands, 8);
    assert_eq!(adaptive.stats.glossy, adaptive.levels.len(), "every mesh takes the first (glossy) material");
    let error = value_of::<AdaptiveError>(&eval, "output", "adaptive_residual_error");
    assert!(error.psnr_db > 90.0, "{error:?}");
    assert!(
        info(&eval, "adaptive_residual_error").iter().any(|l| l.contains("PSNR")),
        "{:?}",
        info(&eval, "adaptive_residual_error")
    );
    let frame = crate::frame::FrameInputs::gather(&eval, &graph, "output").unwrap();
    assert!(matches!(frame.surfaces, crate::frame::Surfaces::Prt(_)));
    let prt = adaptive_graph(0.0);
    let mut prt = prt;
    prt.set_param("output", "mode", ParamValue::Choice("sh_prt".into())).unwrap();
    // Both light the sky's sun apart: their products are of the sky without it.
    let gaunt = value_of::<IncidentSh>(&evaluate_frame(&engine, &prt), "output", "incident_residual_sh");
    let scale = gaunt.coeffs.iter().fold(0.0f32, |m, x| m.max(x.abs()));
    let worst = adaptive.incident.coeffs.iter().zip(&gaunt.coeffs).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
    assert!(worst < 1e-4 * scale, "largest difference {worst} (scale {scale})");
}

/// A threshold edit reruns only the adaptive product and its error; a positive threshold does
/// less work at a finite PSNR; turning the environment then reuses the previous levels
/// (hysteresis) and counts the changes.
#[test]
fn threshold_edits_rerun_only_the_product_and_a_turn_reports_level_changes() {
    let engine = Engine::in_memory();
    let mut graph = adaptive_graph(0.0);
    evaluate_frame(&engine, &graph);
    graph.set_param("output", "adaptive_threshold", ParamValue::Float(0.02)).unwrap();
    let eval = evaluate_frame(&engine, &graph);
    assert_eq!(ran(&eval.report), set(&["output.adaptive_residual_incident", "output.adaptive_residual_error"]));
    let adaptive = value_of::<AdaptiveIncident>(&eval, "output", "adaptive_residual_incident");
    assert!(adaptive.stats.macs < adaptive.stats.full_macs, "{:?}", adaptive.stats);
    let error = value_of::<AdaptiveError>(&eval, "output", "adaptive_residual_error");
    assert!(error.psnr_db.is_finite() && error.psnr_db > 20.0, "{error:?}");
    assert!(info(&eval, "adaptive_residual_incident").iter().any(|l| l.contains("full product's work")));
    graph.set_param("sky", "rotation", ParamValue::Vec3([20.0, 0.0, 0.0])).unwrap();
    let turned = value_of::<AdaptiveIncident>(&evaluate_frame(&engine, &graph), "output", "adaptive_residual_incident");
    assert!(turned.stats.flips.is_some(), "the previous levels were read");
}

/// Without hysteresis (1) the mode keeps no state: after an environment turn the result equals
/// a fresh engine's. With hysteresis the turn starts from the previous levels.
#[test]
fn without_hysteresis_a_turn_equals_a_fresh_evaluation() {
    let mut graph = adaptive_graph(0.02);
    graph.set_param("output", "adaptive_hysteresis", ParamValue::Float(1.0)).unwrap();
    let engine = Engine::in_memory();
    evaluate_frame(&engine, &graph);
    graph.set_param("sky", "rotation", ParamValue::Vec3([35.0, 0.0, 0.0])).unwrap();
    let turned = value_of::<AdaptiveIncident>(&evaluate_frame(&engine, &graph), "output", "adaptive_residual_incident");
    let fresh = value_of::<AdaptiveIncident>(
        &evaluate_frame(&Engine::in_memory(), &graph),
        "output",
        "adaptive_residual_incident",
    );
    assert_eq!(turned.stats.flips, None, "no previous levels were read");
    assert_eq!(turned.levels, fresh.levels);
    assert_eq!(turned.incident, fresh.incident);
}

/// The sharpness warning judges the adaptive mode by the bands it draws: the environment's
/// two bands here, though the scene's transport has eight.
#[test]
fn the_sharpness_warning_counts_the_environments_bands() {
    let mut graph = adaptive_graph(0.0);
    graph.set_param("sky", "sh_bands", ParamValue::Int(2)).unwrap();
    let eval = evaluate_frame(&Engine::in_memory(), &graph);
    let frame = crate::frame::FrameInputs::gather(&eval, &graph, "output").unwrap();
    assert!(frame.lobe_limits.iter().any(|(_, m)| m.contains("than 2 SH bands")), "{:?}", frame.lobe_limits);
}

/// An edit of one of several linked materials is reported once, as the `material` input.
#[test]
fn an_edit_of_one_linked_material_is_one_reason() {
    let mut graph = adaptive_graph(0.02);
    let engine = Engine::in_memory();
    evaluate_frame(&engine, &graph);
    graph.set_param("gloss", "albedo", ParamValue::Color([0.2, 0.3, 0.4])).unwrap();
    let eval = evaluate_frame(&engine, &graph);
    let reasons = &eval
        .report
        .stages
        .iter()
        .find(|s| s.node == "output" && s.stage == "adaptive_residual_incident")
        .unwrap()
        .reasons;
    assert_eq!(reasons.iter().filter(|r| r.contains("material")).count(), 1, "{reasons:?}");
}
