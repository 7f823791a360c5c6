//! The wavelet modes as a user meets them: chosen from the mode list, they draw; on a CPU
//! adapter the engine relights the receivers (the viewport only uploads), and turning the sky
//! relights from the cached visibility.

use super::*;
use lightloom_nodes::frame::Surfaces;

/// The frame on screen's engine relight, if it brings one.
fn relit(harness: &Harness<'_, EditorApp>) -> Option<Vec<u32>> {
    let frame = harness.state().view.frame.as_ref().expect("a frame");
    let Surfaces::Wavelet(data) = &frame.surfaces else { panic!("not a wavelet frame") };
    let relit = data.relit.as_ref()?;
    let relit = relit.vertices.value.get::<lightloom_nodes::triple_product::relight::RelitReceivers>()?;
    Some(relit.products.to_vec())
}

#[test]
fn turning_the_sky_in_a_wavelet_mode_relights_from_the_cached_visibility() {
    let mut harness = default_harness();
    inspector::set_param(&mut harness.state_mut().doc, "scene", "tessellation", ParamValue::Int(24)).unwrap();
    harness.state_mut().doc.seal();
    pick(&mut harness, "Mode", "Sharp shadows, per vertex");
    settle(&mut harness);
    assert!(harness.state().problems().iter().all(|p| !p.starts_with("error")), "{:?}", harness.state().problems());
    let on_cpu = harness.state().host.as_ref().expect("a viewport").relights_on_cpu();
    let before = relit(&harness);
    assert_eq!(
        before.is_some(),
        on_cpu,
        "frames bring the engine's relight exactly where the viewport relights on the CPU"
    );
    harness.render().unwrap().save(state_dir().join("wavelet-vertex.png")).expect("screenshot for a person to look at");
    inspector::set_param(&mut harness.state_mut().doc, "sky", "rotation", ParamValue::Vec3([0.0, 90.0, 0.0])).unwrap();
    harness.state_mut().doc.seal();
    settle(&mut harness);
    let computed = computed_stages(&harness);
    for cached in ["output.local_visibility", "scene.transport_local"] {
        assert!(!computed.iter().any(|s| s == cached), "a turn recomputed {cached}: {computed:?}");
    }
    if on_cpu {
        assert!(computed.iter().any(|s| s == "output.wavelet_residual_relit"), "{computed:?}");
        assert_ne!(relit(&harness), before, "the turned sky relit the products");
    }
    assert!(harness.state().view.drawn != 0, "the turned frame is drawn");
    harness.render().unwrap().save(state_dir().join("wavelet-vertex-turned.png")).unwrap();
}
