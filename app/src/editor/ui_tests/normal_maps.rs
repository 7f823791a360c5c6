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
/// node's "Normal map" field. The material named like the node being absent, the first with a
/// normal texture gives it, and the node says which; its preview shows the map, the viewport
/// redraws with it, and nothing fails.
#[test]
fn a_gltf_models_normal_texture_is_typed_into_the_normal_map_field() {
    let model = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../shared/assets/gltf/assimp-glTF2/ClearCoat-glTF/ClearCoatTest.gltf");
    let mut harness = default_harness();
    settle(&mut harness);
    let before = viewport_mean(&mut harness);
    harness.state_mut().selection = Selection::Node("material".into());
    harness.run_steps(2);
    harness.get_by_role_and_label(Role::TextInput, "Normal map").click();
    harness.run_steps(1);
    harness.get_by_role_and_label(Role::TextInput, "Normal map").type_text(&model.display().to_string());
    harness.key_press(egui::Key::Enter);
    harness.run_steps(2);
    settle(&mut harness);
    let problems: Vec<String> = harness.state().problems().into_iter().filter(|p| p.starts_with("error")).collect();
    assert!(problems.is_empty(), "{problems:?}");
    let report = &harness.state().evaluator.last.as_ref().expect("an evaluation").0.report;
    let loaded = report.stages.iter().find(|s| s.node == "material" && s.stage == "normal_map").expect("loaded");
    assert!(
        loaded.info.iter().any(|i| i.contains("glTF material `BaseNorm_Base`")),
        "the node says which material gave the map: {:?}",
        loaded.info
    );
    let frame = harness.state().view.frame.clone().expect("a frame");
    assert!(frame.materials[0].normal.is_some(), "the frame shades with the map");
    assert!(harness.state().previews.shows_image("material", 1), "the normal-map preview is drawn");
    let after = viewport_mean(&mut harness);
    assert!((after - before).abs() > 0.05, "the map changes the picture: {before:.2} vs {after:.2}");
    harness.render().unwrap().save(state_dir().join("gltf_normal_texture.png")).expect("screenshot for a person");
}
