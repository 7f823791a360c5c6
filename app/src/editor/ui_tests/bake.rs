//! File → Bake… as a user reaches it: the menu entry opens a folder dialog; a bake shows its
//! progress in the status bar, writes the same files as `lightloom bake`, and Cancel stops it
//! with nothing written.

use super::*;

fn wait_for_bake(harness: &mut Harness<'_, EditorApp>, mut during: impl FnMut(&mut Harness<'_, EditorApp>)) {
    let start = Instant::now();
    while harness.state().bake.is_some() {
        assert!(start.elapsed() < Duration::from_secs(240), "the bake finished");
        harness.step();
        during(harness);
        std::thread::sleep(Duration::from_millis(20));
    }
    harness.step();
}

#[test]
fn file_bake_writes_the_bake_and_cancel_writes_nothing() {
    let mut harness = default_harness();
    pick(&mut harness, "Mode", "Soft light, no shadows");
    settle(&mut harness);

    harness.get_by_label("File").click();
    harness.run_steps(2);
    harness.get_by_label("Bake…").click();
    harness.run_steps(2);
    assert!(harness.state().bake_dialog.is_some(), "Bake… opens the folder dialog");
    harness.state_mut().bake_dialog = None;

    let out = state_dir().join("baked");
    let _ = std::fs::remove_dir_all(&out);
    harness.state_mut().bake_to(out.clone());
    let mut saw_progress = false;
    wait_for_bake(&mut harness, |h| {
        saw_progress |= h.query_by_label("Cancel bake").is_some();
    });
    assert!(saw_progress, "the status bar shows the bake with a Cancel button");
    for file in ["scene.glb", "lightmap.exr", "bake.json"] {
        assert!(out.join(file).is_file(), "{file} was written");
    }
    let log = &harness.state().log;
    assert!(log.iter().any(|l| !l.error && l.text.starts_with("baked into")), "the log says so");
    let manifest: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("bake.json")).unwrap()).unwrap();
    assert_eq!(manifest["mode"], "sh_irradiance");

    // A denser lightmap (a new atlas and texels), cancelled while it runs: nothing is written.
    // The bake's thread waits for the click before it writes, however fast the bake was.
    inspector::set_param(&mut harness.state_mut().doc, "output", "bake_lightmap_density", ParamValue::Float(64.0))
        .unwrap();
    let cancelled = state_dir().join("cancelled");
    let _ = std::fs::remove_dir_all(&cancelled);
    let hold = std::sync::Arc::new(std::sync::Barrier::new(2));
    harness.state_mut().bake_hold = Some(hold.clone());
    harness.state_mut().bake_to(cancelled.clone());
    harness.run_steps(2);
    harness.get_by_label("Cancel bake").click();
    harness.run_steps(2);
    hold.wait();
    wait_for_bake(&mut harness, |_| {});
    assert!(!cancelled.join("scene.glb").exists(), "a cancelled bake writes nothing");
    let last = harness.state().log.last().unwrap();
    assert!(last.error && last.text.contains("cancelled"), "{}", last.text);
}

/// The bake's settings sit in the Output's inspector under a "Bake" header, folded at first,
/// so the shading settings come first; opening it shows them.
#[test]
fn bake_settings_fold_under_their_own_header() {
    let mut harness = default_harness();
    harness.get_by_role_and_label(Role::ComboBox, "Mode");
    assert!(harness.query_by_label("Lightmap texels per metre").is_none(), "folded at first");
    harness.get_by_label("Bake").click();
    harness.run_steps(3);
    for label in
        ["Lightmap texels per metre", "Lightmap padding", "Probe spacing", "Probe SH bands", "Specular cube size"]
    {
        harness.get_by_label(label);
    }
    if let Ok(path) = std::env::var("LIGHTLOOM_TEST_SCREENSHOT") {
        harness.render().expect("the UI renders through wgpu").save(path).unwrap();
    }
}
