use super::*;

fn assets() -> std::path::PathBuf {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/gltf/assimp-glTF2");
    assert!(dir.is_dir(), "the repository's glTF assets are expected at {}", dir.display());
    dir
}

/// Every .gltf/.glb file under the assets folder.
fn corpus() -> Vec<std::path::PathBuf> {
    let mut files = Vec::new();
    let mut stack = vec![assets()];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(dir).unwrap() {
            let p = entry.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|e| e == "gltf" || e == "glb") {
                files.push(p);
            }
        }
    }
    files.sort();
    files
}

#[test]
fn real_models_load() {
    let engine = import(&assets().join("2CylinderEngine-glTF-Binary/2CylinderEngine.glb")).unwrap();
    let triangles: usize = engine.meshes.iter().map(|m| m.triangle_count()).sum();
    assert!(triangles > 100_000, "{triangles} triangles");
    assert!(engine.meshes.iter().all(|m| m.normals.len() == m.positions.len()));
    let boxed = import(&assets().join("BoxTextured-glTF/BoxTextured.gltf")).unwrap();
    assert_eq!(boxed.meshes.iter().map(|m| m.triangle_count()).sum::<usize>(), 12);
    assert_eq!(boxed.meshes[0].uvs.len(), boxed.meshes[0].positions.len());
}

#[test]
fn every_broken_file_gives_an_error_or_a_documented_repair() {
    let files = corpus();
    assert!(files.len() > 20);
    for file in &files {
        // Must return (never panic or hang); errors name the file.
        match import(file) {
            Ok(scene) => {
                for m in &scene.meshes {
                    assert!(m.positions.iter().flatten().all(|v| v.is_finite()), "{}", file.display());
                    assert!(m.indices.iter().all(|i| (*i as usize) < m.positions.len()));
                }
            }
            Err(e) => assert!(e.contains(&file.display().to_string()), "{e}"),
        }
    }
    let expect_err = |rel: &str, needle: &str| {
        let e = import(&assets().join(rel)).unwrap_err();
        assert!(e.contains(needle), "{rel}: {e}");
    };
    expect_err("IndexOutOfRange/IndexOutOfRange.gltf", "out of range");
    expect_err("MissingBin/BoxTextured.gltf", "buffers");
    expect_err("wrongTypes/badNumber.gltf", "not a valid glTF");
    let infinites = import(&assets().join("BoxWithInfinites-glTF-Binary/BoxWithInfinites.glb"));
    match infinites {
        Ok(s) => assert!(s.warnings.iter().any(|w| w.contains("non-finite")), "{:?}", s.warnings),
        Err(e) => assert!(e.contains("BoxWithInfinites"), "{e}"),
    }
    let bad_normals = import(&assets().join("BoxBadNormals-glTF-Binary/BoxBadNormals.glb")).unwrap();
    assert!(
        bad_normals
            .meshes
            .iter()
            .all(|m| m.normals.iter().all(|n| (DVec3::from(n.map(f64::from)).length() - 1.0).abs() < 1e-4))
    );
}

/// Writes `json` as a .gltf in a fresh folder and imports it.
fn import_json(name: &str, json: &str) -> Result<ImportedScene, String> {
    let dir = std::env::temp_dir().join(format!("lightloom-gltf-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(format!("{name}.gltf"));
    std::fs::write(&path, json).unwrap();
    import(&path)
}

/// A base64 data URI of three vec3 positions (one triangle).
fn triangle_buffer(positions: [[f32; 3]; 3]) -> String {
    let bytes: Vec<u8> = positions.iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
    format!(r#"{{"byteLength":36,"uri":"data:application/octet-stream;base64,{}"}}"#, base64::encode(bytes))
}

#[test]
fn an_attribute_pointing_at_a_missing_accessor_is_an_error() {
    let json = r#"{"asset":{"version":"2.0"},"meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],"nodes":[{"mesh":0}],"scenes":[{"nodes":[0]}],"scene":0}"#;
    let e = import_json("missing-accessor", json).unwrap_err();
    assert!(e.contains("missing-accessor.gltf") && e.contains("refers to item 0, but there are only 0"), "{e}");
}

#[test]
fn a_stride_smaller_than_an_element_is_an_error() {
    let buffer = triangle_buffer([[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"buffers":[{buffer}],
            "bufferViews":[{{"buffer":0,"byteLength":36,"byteStride":4}}],
            "accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}}],
            "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}}}]}}],"nodes":[{{"mesh":0}}],"scenes":[{{"nodes":[0]}}],"scene":0}}"#
    );
    let e = import_json("small-stride", &json).unwrap_err();
    assert!(e.contains("byteStride 4 is smaller than one element (12 bytes)"), "{e}");
}

#[test]
fn node_hierarchies_that_multiply_are_capped() {
    // Each node lists the next one twice: 2^40 paths in a few hundred bytes.
    let buffer = triangle_buffer([[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
    let mut nodes: Vec<String> = (0..40).map(|i| format!(r#"{{"children":[{},{}]}}"#, i + 1, i + 1)).collect();
    nodes.push(r#"{"mesh":0}"#.into());
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"buffers":[{buffer}],"bufferViews":[{{"buffer":0,"byteLength":36}}],
            "accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}}],
            "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}}}]}}],"nodes":[{}],"scenes":[{{"nodes":[0]}}],"scene":0}}"#,
        nodes.join(",")
    );
    let e = import_json("dag", &json).unwrap_err();
    assert!(e.contains("mesh instances") || e.contains("expands to more than"), "{e}");
    // The same mesh listed as a root 200000 times.
    let roots = vec!["0"; 200_000].join(",");
    let json = json.replace(r#""scenes":[{"nodes":[0]}]"#, &format!(r#""scenes":[{{"nodes":[{roots}]}}]"#));
    let json = json.replacen(r#""nodes":[{"children":[1,1]}"#, r#""nodes":[{"mesh":0},{"children":[1,1]}"#, 1);
    let e = import_json("roots", &json).unwrap_err();
    assert!(e.contains("mesh instances"), "{e}");
}

#[test]
fn special_files_as_buffers_are_refused() {
    for uri in ["/dev/zero", "file:///dev/urandom"] {
        let json = format!(
            r#"{{"asset":{{"version":"2.0"}},"buffers":[{{"byteLength":36,"uri":"{uri}"}}],"meshes":[],"nodes":[]}}"#
        );
        let e = import_json("special", &json).unwrap_err();
        assert!(e.contains("not a regular file") || e.contains("unsupported URI"), "{uri}: {e}");
    }
    let dir = std::env::temp_dir().join(format!("lightloom-gltf-fifo-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let fifo = dir.join("buffer.bin");
    let _ = std::fs::remove_file(&fifo);
    if std::process::Command::new("mkfifo").arg(&fifo).status().is_ok_and(|s| s.success()) {
        let json = r#"{"asset":{"version":"2.0"},"buffers":[{"byteLength":36,"uri":"buffer.bin"}]}"#;
        std::fs::write(dir.join("fifo.gltf"), json).unwrap();
        let e = import(&dir.join("fifo.gltf")).unwrap_err();
        assert!(e.contains("not a regular file"), "{e}");
    }
}

/// A material's normal texture is the image its glTF names: by material name, else the
/// first material that has one; a material without one, or a texture on TEXCOORD_1, is a
/// named error.
#[test]
fn normal_textures_are_found_by_material() {
    let file = assets().join("ClearCoat-glTF/ClearCoatTest.gltf");
    let image = |name: &str| std::fs::read(assets().join("ClearCoat-glTF").join(name)).unwrap();
    let ribs = normal_texture(&file, "BaseNorm_Base").unwrap();
    assert_eq!((ribs.material.as_str(), ribs.scale), ("BaseNorm_Base", 1.0));
    assert!(ribs.image == image("RibsNormal.png"));
    let wrap = normal_texture(&file, "CoatNorm_Coating").unwrap();
    assert!(wrap.image == image("PlasticWrap_normals.jpg"));
    assert_eq!(normal_texture(&file, "no such material").unwrap().material, "BaseNorm_Base");
    let e = normal_texture(&file, "Simple_Base").unwrap_err();
    assert!(e.contains("ClearCoatTest.gltf") && e.contains("`Simple_Base` has no normal texture"), "{e}");
    let json = std::fs::read_to_string(&file).unwrap().replacen(
        r#""normalTexture" : {
                "index" : 3,
                "texCoord" : 0"#,
        r#""normalTexture" : {
                "index" : 3,
                "texCoord" : 1"#,
        1,
    );
    assert!(json.contains(r#""texCoord" : 1"#), "the asset's layout changed");
    let dir = std::env::temp_dir().join(format!("lightloom-gltf-texcoord-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("coat.gltf"), json).unwrap();
    let e = normal_texture(&dir.join("coat.gltf"), "BaseNorm_Base").unwrap_err();
    assert!(e.contains("TEXCOORD_1"), "{e}");
}

/// A GLB holding its image in a buffer view, a `data:` URI image, and the ways either can
/// be broken: each loads the same bytes or says what is wrong.
#[test]
fn embedded_normal_textures_load_and_broken_ones_are_named() {
    let png = std::fs::read(assets().join("ClearCoat-glTF/RibsNormal.png")).unwrap();
    let dir = std::env::temp_dir().join(format!("lightloom-gltf-embedded-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let glb = |json: &str, bin: &[u8]| {
        let path = dir.join("model.glb");
        std::fs::write(&path, crate::fuzzing::glb(json, bin)).unwrap();
        normal_texture(&path, "bumps")
    };
    let material =
        r#""materials":[{"name":"bumps","normalTexture":{"index":0,"scale":0.5}}],"textures":[{"source":0}]"#;
    let view = |offset: usize, length: usize| {
        format!(
            r#"{{"asset":{{"version":"2.0"}},"buffers":[{{"byteLength":{}}}],"bufferViews":[{{"buffer":0,"byteOffset":{offset},"byteLength":{length}}}],"images":[{{"bufferView":0,"mimeType":"image/png"}}],{material}}}"#,
            png.len() + 4
        )
    };
    let mut bin = vec![0u8; 4];
    bin.extend_from_slice(&png);
    let loaded = glb(&view(4, png.len()), &bin).unwrap();
    assert!(loaded.image == png && loaded.scale == 0.5);
    let e = glb(&view(4, png.len() + 64), &bin).unwrap_err();
    assert!(e.contains("model.glb") && e.contains("lies outside its buffer"), "{e}");
    let e = glb(&view(4, png.len()).replace(r#""index":0"#, r#""index":7"#), &bin).unwrap_err();
    assert!(e.contains("refers to item 7, but there are only 1"), "{e}");
    let data_uri = format!(
        r#"{{"asset":{{"version":"2.0"}},"images":[{{"uri":"data:image/png;base64,{}"}}],{material}}}"#,
        base64::encode(&png)
    );
    assert!(import_json_texture("data-uri", &data_uri).unwrap().image == png);
    let e = import_json_texture("bad-base64", &data_uri.replace("base64,", "base64,@@")).unwrap_err();
    assert!(e.contains("bad base64"), "{e}");
    let missing = data_uri.replace(&format!("data:image/png;base64,{}", base64::encode(&png)), "gone.png");
    let e = import_json_texture("missing-image", &missing).unwrap_err();
    assert!(e.contains("missing-image.gltf") && e.contains("missing file gone.png"), "{e}");
    let special = missing.replace("gone.png", "/dev/zero");
    let e = import_json_texture("special-image", &special).unwrap_err();
    assert!(e.contains("not a regular file"), "{e}");
    assert!(import_json_texture("data-uri", &data_uri).unwrap().warnings.is_empty());
    // What the map does not do is said: a texture transform, and edges that clamp.
    let asks_more = data_uri
        .replace(
            r#""index":0,"scale":0.5"#,
            r#""index":0,"scale":0.5,"extensions":{"KHR_texture_transform":{"scale":[4,4]}}"#,
        )
        .replace(
            r#""textures":[{"source":0}]"#,
            r#""textures":[{"source":0,"sampler":0}],"samplers":[{"wrapS":33071}]"#,
        );
    let warnings = import_json_texture("asks-more", &asks_more).unwrap().warnings;
    assert!(warnings.len() == 2 && warnings[0].contains("KHR_texture_transform"), "{warnings:?}");
    assert!(warnings[1].contains("clamps or mirrors"), "{warnings:?}");
}

/// Writes `json` as a .gltf in a fresh folder and reads material `bumps`'s normal texture.
fn import_json_texture(name: &str, json: &str) -> Result<NormalTexture, String> {
    let dir = std::env::temp_dir().join(format!("lightloom-gltf-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(format!("{name}.gltf"));
    std::fs::write(&path, json).unwrap();
    normal_texture(&path, "bumps")
}

/// Prints what happens to each asset (run with `--ignored --nocapture`).
#[test]
#[ignore]
fn print_corpus_outcomes() {
    for p in corpus() {
        match import(&p) {
            Ok(s) => println!(
                "OK   {} meshes, {} warnings {:?}: {}",
                s.meshes.len(),
                s.warnings.len(),
                s.warnings.first(),
                p.display()
            ),
            Err(e) => println!("ERR  {e}"),
        }
    }
}
