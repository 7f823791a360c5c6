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

/// A model exported without texture coordinates, as a user meets it under a normal map: the
/// frame's note says the map does not apply to it and names box UVs; ticking "Box UVs" on the
/// object (one undo step) projects coordinates, the map applies and the note goes.
#[test]
fn box_uvs_give_a_model_without_texture_coordinates_its_normal_map() {
    let dir = tempfile::tempdir().unwrap();
    // A 1 m box without TEXCOORD_0: each face its own four vertices.
    let mut positions: Vec<[f32; 3]> = Vec::new();
    let mut normals: Vec<[f32; 3]> = Vec::new();
    let mut indices: Vec<u16> = Vec::new();
    for axis in 0..3 {
        for side in [-1.0f32, 1.0] {
            let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
            let base = positions.len() as u16;
            for (u, v) in [(-0.5f32, -0.5f32), (0.5, -0.5), (0.5, 0.5), (-0.5, 0.5)] {
                let mut p = [0.0f32; 3];
                p[axis] = 0.5 * side;
                p[a] = u;
                p[b] = v;
                positions.push(p);
                let mut n = [0.0f32; 3];
                n[axis] = side;
                normals.push(n);
            }
            let quad = if side > 0.0 { [0, 1, 2, 0, 2, 3] } else { [0, 2, 1, 0, 3, 2] };
            indices.extend(quad.map(|i| base + i));
        }
    }
    let floats = |v: &[[f32; 3]]| v.iter().flatten().flat_map(|f| f.to_le_bytes()).collect::<Vec<u8>>();
    let mut bin = floats(&positions);
    bin.extend(floats(&normals));
    bin.extend(indices.iter().flat_map(|i| i.to_le_bytes()));
    std::fs::write(dir.path().join("box.bin"), &bin).unwrap();
    let n = positions.len();
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"NORMAL":1}},"indices":2}}]}}],
        "buffers":[{{"byteLength":{len},"uri":"box.bin"}}],
        "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":{p}}},{{"buffer":0,"byteOffset":{p},"byteLength":{p}}},
                       {{"buffer":0,"byteOffset":{i0},"byteLength":{il}}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":{n},"type":"VEC3","min":[-0.5,-0.5,-0.5],"max":[0.5,0.5,0.5]}},
                     {{"bufferView":1,"componentType":5126,"count":{n},"type":"VEC3"}},
                     {{"bufferView":2,"componentType":5123,"count":{ni},"type":"SCALAR"}}]}}"#,
        len = bin.len(),
        p = n * 12,
        i0 = n * 24,
        il = indices.len() * 2,
        ni = indices.len(),
    );
    let model = dir.path().join("box.gltf");
    std::fs::write(&model, json).unwrap();
    let map = Path::new(env!("CARGO_MANIFEST_DIR")).join("../projects/samples/textures/bumps.png");

    let mut harness = default_harness();
    settle(&mut harness);
    inspector::set_param(
        &mut harness.state_mut().doc,
        "material",
        "normal_map",
        ParamValue::Path(map.display().to_string()),
    )
    .unwrap();
    harness.state_mut().doc.seal();
    harness.state_mut().import_model("scene", &model.display().to_string()).unwrap();
    settle(&mut harness);
    let note = |h: &Harness<'_, EditorApp>| {
        h.state().view.frame.as_ref().unwrap().lobe_limits.iter().any(|(_, why)| why.contains("no texture coordinates"))
    };
    assert!(note(&harness), "the frame says the map does not apply to the box");
    let limits = harness.state().view.frame.as_ref().unwrap().lobe_limits.clone();
    assert!(limits.iter().any(|(_, why)| why.contains("box_uvs")), "the note names box UVs: {limits:?}");

    harness.state_mut().selection = Selection::Node("scene".into());
    harness.run_steps(3);
    harness.get_by_role_and_label(Role::CheckBox, "Box UVs").click();
    harness.run_steps(2);
    settle(&mut harness);
    let objects = match edits::node(&harness.state().doc.project, "scene").and_then(|n| n.params.get("objects")) {
        Some(ParamValue::Objects(o)) => o.clone(),
        _ => panic!("the scene lists objects"),
    };
    assert_eq!(objects.last().unwrap().box_uvs, Some(1.0));
    assert!(harness.state().doc.undo_label().is_some());
    assert!(!note(&harness), "the map applies once the box has coordinates");
    harness.render().unwrap().save(state_dir().join("box_uvs.png")).expect("screenshot for a person");
    harness.state_mut().undo();
    settle(&mut harness);
    assert!(note(&harness), "one undo step takes the coordinates away again");
}
