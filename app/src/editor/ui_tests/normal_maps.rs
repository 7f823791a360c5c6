//! Normal maps as a user reaches them: a sample that has one, and a glTF model's normal
//! texture typed into the BRDF node's "Normal map" field.

use super::*;

/// A normal map as a user meets it: the hammered-metal sample opens from the file menu and
/// draws; its BRDF node shows the map's preview beside the lobe plot; picking another filter in
/// the inspector redraws the viewport without reloading the map or rebuilding its pyramids.
#[test]
fn a_normal_mapped_sample_previews_its_map_and_filters_from_the_inspector() {
    let mut harness = default_harness();
    open_sample(&mut harness, "hammered metal");
    settle(&mut harness);
    let problems: Vec<String> = harness.state().problems().into_iter().filter(|p| p.starts_with("error")).collect();
    assert!(problems.is_empty(), "{problems:?}");
    assert!(harness.state().previews.shows_image("hammered", 1), "the normal-map preview is drawn");
    let vmf = viewport_mean(&mut harness);
    assert!(vmf > 20.0, "the sample is drawn (mean sRGB {vmf:.1})");
    harness.render().unwrap().save(state_dir().join("normal_map_sample.png")).expect("screenshot for a person");

    harness.state_mut().selection = Selection::Node("hammered".into());
    harness.run_steps(3);
    pick(&mut harness, "Normal filtering", "None (averaged normals)");
    settle(&mut harness);
    let ran = computed_stages(&harness);
    assert!(ran.contains(&"hammered.normal_settings".to_string()), "{ran:?}");
    assert!(!ran.iter().any(|s| s.ends_with(".normal_map") || s.ends_with(".ndf_moments")), "{ran:?}");
    let averaged = viewport_mean(&mut harness);
    assert!((averaged - vmf).abs() > 0.05, "the filter changes the picture: {vmf:.2} vs {averaged:.2}");
    harness.render().unwrap().save(state_dir().join("normal_map_averaged.png")).expect("screenshot for a person");
}

/// A glTF model's normal texture as a user picks it: the model's path typed into the BRDF
/// node's "Normal map" field, a key a frame, and used once Enter ends the editing. The material named like the node being absent, the first with a
/// normal texture gives it, and the node says which; its preview shows the map, the viewport
/// redraws with it, and nothing fails.
#[test]
fn a_gltf_models_normal_texture_is_typed_into_the_normal_map_field() {
    let model =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/gltf/assimp-glTF2/ClearCoat-glTF/ClearCoatTest.gltf");
    let mut harness = default_harness();
    settle(&mut harness);
    let before = viewport_mean(&mut harness);
    harness.state_mut().selection = Selection::Node("material".into());
    harness.run_steps(2);
    harness.get_by_role_and_label(Role::TextInput, "Normal map").click();
    harness.run_steps(1);
    // Typed a key a frame, as a person types: a half-typed path is never used.
    let path = model.display().to_string();
    for (i, c) in path.chars().enumerate() {
        harness.get_by_role_and_label(Role::TextInput, "Normal map").type_text(&c.to_string());
        harness.step();
        if i % 16 == 0 {
            let node = harness.state().doc.project.nodes.iter().find(|n| n.id == "material").unwrap().clone();
            let used = matches!(node.params.get("normal_map"), Some(ParamValue::Path(p)) if !p.is_empty());
            assert!(!used, "a half-typed path was used: {:?}", node.params);
        }
    }
    harness.key_press(egui::Key::Enter);
    harness.run_steps(2);
    settle(&mut harness);
    let problems: Vec<String> = harness.state().problems().into_iter().filter(|p| p.starts_with("error")).collect();
    assert!(problems.is_empty(), "{problems:?}");
    let report = &harness.state().evaluator.last.as_ref().expect("an evaluation").0.report;
    let loaded = report.stages.iter().find(|s| s.node == "material" && s.stage == "normal_map").expect("loaded");
    assert!(
        loaded
            .info
            .iter()
            .any(|i| i.contains("glTF material `BaseNorm_Base` (the first with one: no material is named `material`")),
        "the node says which material gave the map: {:?}",
        loaded.info
    );
    let frame = harness.state().view.frame.clone().expect("a frame");
    assert!(frame.materials[0].normal.is_some(), "the frame shades with the map");
    assert!(harness.state().previews.shows_image("material", 1), "the normal-map preview is drawn");
    let after = viewport_mean(&mut harness);
    assert!((after - before).abs() > 0.05, "the map changes the picture: {before:.2} vs {after:.2}");
    harness.render().unwrap().save(state_dir().join("gltf_normal_texture.png")).expect("screenshot for a person");

    // A file that is not there: said once as the load's error and once as a missing asset (and
    // the frame's note), not again for each stage it blocks.
    inspector::set_param(&mut harness.state_mut().doc, "material", "normal_map", ParamValue::Path("gone.gltf".into()))
        .unwrap();
    harness.state_mut().doc.seal();
    settle(&mut harness);
    let problems: Vec<String> = harness.state().problems().into_iter().filter(|p| p.contains("gone.gltf")).collect();
    assert!(problems.iter().any(|p| p.starts_with("material.normal_map:")), "{problems:?}");
    assert!(problems.len() <= 3, "{problems:?}");
}
