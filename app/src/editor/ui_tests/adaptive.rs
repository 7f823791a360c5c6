//! The high-order SH mode as a user meets it: chosen from the mode list, it draws and shows
//! its PSNR against the full computation on the Output; a coarser threshold lowers it.

use super::*;

fn psnr_line(harness: &Harness<'_, EditorApp>) -> Option<f64> {
    let report = &harness.state().evaluator.last.as_ref()?.0.report;
    // The default sky's sun is lit apart: the products take the sky without it.
    let stage = report.stages.iter().find(|s| s.node == "output" && s.stage == "adaptive_residual_error")?;
    let line = stage.info.iter().find(|l| l.starts_with("PSNR"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

#[test]
fn the_adaptive_sh_mode_shows_its_psnr_and_the_threshold_trades_it() {
    let mut harness = default_harness();
    // High order needs the environment's and the scene's SH bands raised, and a glossy material.
    for (node, name, value) in [
        ("sky", "sh_bands", ParamValue::Int(8)),
        ("scene", "transport_bands", ParamValue::Int(8)),
        ("scene", "transport_rays", ParamValue::Int(128)),
        ("material", "model", ParamValue::Choice("phong".into())),
        ("material", "roughness", ParamValue::Float(0.25)),
    ] {
        inspector::set_param(&mut harness.state_mut().doc, node, name, value).unwrap();
    }
    harness.state_mut().doc.seal();
    pick(&mut harness, "Mode", "Sharper gloss, adaptive SH");
    settle(&mut harness);
    assert!(harness.state().problems().iter().all(|p| !p.starts_with("error")), "{:?}", harness.state().problems());
    harness.state_mut().selection = Selection::Node("output".into());
    harness.run_steps(3);
    let fine = psnr_line(&harness).expect("the PSNR is reported");
    // The inspector shows it to the user, beside this mode's settings.
    harness.get_by_label_contains("PSNR");
    harness.get_by_label("Adaptive threshold");
    assert!(harness.query_by_label("Wavelet coefficients").is_none(), "the wavelet setting is hidden here");
    harness.render().unwrap().save(state_dir().join("adaptive-sh.png")).expect("screenshot for a person to look at");
    inspector::set_param(&mut harness.state_mut().doc, "output", "adaptive_threshold", ParamValue::Float(0.1)).unwrap();
    harness.state_mut().doc.seal();
    settle(&mut harness);
    harness.run_steps(3);
    let coarse = psnr_line(&harness).expect("the PSNR is reported again");
    assert!(coarse < fine, "a coarser threshold lowers the PSNR: {fine:.1} → {coarse:.1} dB");
    harness.render().unwrap().save(state_dir().join("adaptive-sh-coarse.png")).unwrap();
}
