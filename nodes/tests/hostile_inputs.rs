//! Hostile inputs replayed through every loader, as the fuzz targets feed them
//! (`lightloom_nodes::fuzzing`): the mutation classes that once crashed, hung or exhausted
//! memory (byte flips, truncation, dropped and duplicated lines, extreme numbers, wrong enum
//! names, duplicate ids, node DAGs, special-file URIs, huge declared sizes), generated from real
//! files with a fixed seed, and the committed corpus under `fuzz/`. Each input must return,
//! error or not, without a panic.

use lightloom_nodes::fuzzing;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use std::path::{Path, PathBuf};

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn assets() -> PathBuf {
    let dir = workspace().join("assets");
    assert!(dir.is_dir(), "the repository's assets/ folder is expected at {}", dir.display());
    dir
}

/// Runs `target` on every input; panics are collected and reported with the input's name.
fn replay(target: fn(&[u8]), inputs: impl IntoIterator<Item = (String, Vec<u8>)>) -> usize {
    // Panics print as they happen (the panic hook is process-wide: tests running beside this
    // one must keep theirs).
    let mut panics = Vec::new();
    let mut count = 0;
    for (name, bytes) in inputs {
        count += 1;
        if std::panic::catch_unwind(|| target(&bytes)).is_err() {
            panics.push(name);
        }
    }
    assert!(panics.is_empty(), "{} of {count} inputs panicked: {:?}", panics.len(), &panics[..panics.len().min(20)]);
    count
}

/// Byte-level mutants of `seed`: flips, truncations, insertions of extreme bytes.
fn byte_mutants(name: &str, seed: &[u8], count: usize, rng: &mut SmallRng) -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    for i in 0..count {
        let mut bytes = seed.to_vec();
        match i % 4 {
            0 => {
                for _ in 0..rng.random_range(1..8) {
                    let at = rng.random_range(0..bytes.len().max(1));
                    if let Some(b) = bytes.get_mut(at) {
                        *b ^= 1 << rng.random_range(0..8);
                    }
                }
            }
            1 => bytes.truncate(rng.random_range(0..bytes.len().max(1))),
            2 => {
                let at = rng.random_range(0..bytes.len().max(1));
                let run = [0x00, 0xff, 0x7f, 0x80][rng.random_range(0..4)];
                bytes.splice(at..at, std::iter::repeat_n(run, rng.random_range(1..16)));
            }
            _ => {
                // Overwrite a 4-byte field with an extreme value (sizes, counts, offsets).
                if bytes.len() >= 4 {
                    let at = rng.random_range(0..bytes.len() - 3);
                    let v: u32 = [u32::MAX, 0x7fff_ffff, 100_000_000, 0][rng.random_range(0..4)];
                    bytes[at..at + 4].copy_from_slice(&v.to_le_bytes());
                }
            }
        }
        out.push((format!("{name} mutant {i}"), bytes));
    }
    out
}

/// Line- and token-level mutants of a text file.
fn text_mutants(name: &str, text: &str, count: usize, rng: &mut SmallRng) -> Vec<(String, Vec<u8>)> {
    let lines: Vec<&str> = text.lines().collect();
    let numbers = ["1e308", "-1e308", "1e400", "NaN", "inf", "-0", "4294967296", "99999999999999999999", "0"];
    let mut out = Vec::new();
    for i in 0..count {
        let mut l: Vec<String> = lines.iter().map(|s| s.to_string()).collect();
        let at = rng.random_range(0..l.len().max(1)).min(l.len().saturating_sub(1));
        let mutated = match i % 6 {
            0 => {
                l.remove(at);
                l.join("\n")
            }
            1 => {
                let line = l[at].clone();
                l.insert(at, line);
                l.join("\n")
            }
            2 => {
                // An extreme number in place of every number on the line.
                let n = numbers[rng.random_range(0..numbers.len())];
                let re: String = l[at]
                    .split(|c: char| c.is_ascii_digit() || c == '.')
                    .filter(|s| !s.is_empty())
                    .collect::<Vec<_>>()
                    .join(n);
                l[at] = if re.is_empty() { n.to_string() } else { re };
                l.join("\n")
            }
            3 => l.join("\n").replace(&format!("\"{}", pick_word(&l[at], rng)), "\"bogus_name"),
            4 => {
                let joined = l.join("\n");
                let mut end = rng.random_range(0..joined.len().max(1));
                while !joined.is_char_boundary(end) {
                    end -= 1;
                }
                joined[..end].to_string()
            }
            _ => {
                let joined = l.join("\n").into_bytes();
                let mut b = joined;
                let at = rng.random_range(0..b.len().max(1));
                if let Some(x) = b.get_mut(at) {
                    let tokens = b"(){}[],:\"\\0x";
                    *x = tokens[rng.random_range(0..tokens.len())];
                }
                String::from_utf8_lossy(&b).into_owned()
            }
        };
        out.push((format!("{name} mutant {i}"), mutated.into_bytes()));
    }
    out
}

fn pick_word(line: &str, rng: &mut SmallRng) -> String {
    let words: Vec<&str> = line.split('"').skip(1).step_by(2).collect();
    if words.is_empty() { "\u{0}".into() } else { words[rng.random_range(0..words.len())].to_string() }
}

/// Files of one fuzz target's committed corpus (`fuzz/corpus/<target>`, `fuzz/regressions/<target>`).
fn committed(target: &str) -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    for folder in ["corpus", "regressions"] {
        let dir = workspace().join("fuzz").join(folder).join(target);
        let Ok(entries) = std::fs::read_dir(&dir) else { continue };
        for entry in entries.flatten() {
            out.push((entry.path().display().to_string(), std::fs::read(entry.path()).unwrap()));
        }
    }
    out
}

#[test]
fn projects_mutated_every_way_never_panic() {
    let mut rng = SmallRng::seed_from_u64(1);
    let mut inputs = committed("project");
    let mut sources = vec![workspace().join("projects/default.ron")];
    for dir in [workspace().join("tests/projects"), workspace().join("tests/malformed")] {
        sources.extend(std::fs::read_dir(dir).unwrap().flatten().map(|e| e.path()).filter(|p| p.is_file()));
    }
    for path in &sources {
        let bytes = std::fs::read(path).unwrap();
        let name = path.display().to_string();
        inputs.extend(text_mutants(&name, &String::from_utf8_lossy(&bytes), 150, &mut rng));
        inputs.extend(byte_mutants(&name, &bytes, 30, &mut rng));
        inputs.push((name, bytes));
    }
    // Duplicate ids and a dense DAG of links (every node feeding every later one).
    inputs.push((
        "duplicate ids".into(),
        br#"(version: 2, nodes: [(id: "a", kind: "Scene"), (id: "o", kind: "Output"), (id: "o", kind: "Output")], links: [(from: ("a", "scene"), to: ("o", "scene"))])"#.to_vec(),
    ));
    let nodes: Vec<String> = (0..200).map(|i| format!(r#"(id: "l{i}", kind: "PointLight")"#)).collect();
    let links: Vec<String> = (0..200)
        .flat_map(|i| {
            (i + 1..200).step_by(7).map(move |j| format!(r#"(from: ("l{i}", "lights"), to: ("l{j}", "lights"))"#))
        })
        .collect();
    inputs.push((
        "dense DAG".into(),
        format!("(version: 3, nodes: [{}], links: [{}])", nodes.join(","), links.join(",")).into_bytes(),
    ));
    let n = replay(fuzzing::project, inputs);
    assert!(n > 1500, "{n} inputs");
}

#[test]
fn gltf_files_mutated_every_way_never_panic() {
    let mut rng = SmallRng::seed_from_u64(2);
    let base = assets().join("gltf/assimp-glTF2");
    let mut inputs = committed("gltf");
    for rel in [
        "BoxTextured-glTF-Binary/BoxTextured.glb",
        "BoxTextured-glTF-Embedded/BoxTextured.gltf",
        "BoxBadNormals-glTF-Binary/BoxBadNormals.glb",
        "BoxWithInfinites-glTF-Binary/BoxWithInfinites.glb",
    ] {
        let bytes = std::fs::read(base.join(rel)).unwrap();
        inputs.extend(byte_mutants(rel, &bytes, 200, &mut rng));
        if rel.ends_with(".gltf") {
            inputs.extend(text_mutants(rel, &String::from_utf8_lossy(&bytes), 200, &mut rng));
        }
    }
    // Special files and huge declared sizes as buffers.
    // not-a-checkout-path: buffers that try to climb out to a device.
    for uri in ["/dev/zero", "file:///dev/urandom", "/proc/self/mem", "../../../../../../dev/zero"] {
        inputs.push((
            format!("buffer {uri}"),
            format!(r#"{{"asset":{{"version":"2.0"}},"buffers":[{{"byteLength":36,"uri":"{uri}"}}]}}"#).into_bytes(),
        ));
    }
    inputs.push((
        "huge byteLength".into(),
        br#"{"asset":{"version":"2.0"},"buffers":[{"byteLength":99999999999,"uri":"data:application/octet-stream;base64,AAAA"}]}"#.to_vec(),
    ));
    let n = replay(fuzzing::gltf, inputs);
    assert!(n > 1000, "{n} inputs");
}

#[test]
fn environment_maps_mutated_every_way_never_panic() {
    let mut rng = SmallRng::seed_from_u64(3);
    let dir = std::env::temp_dir().join(format!("lightloom-hostile-envmaps-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let exr_path = dir.join("small.exr");
    exr::prelude::write_rgb_file(&exr_path, 64, 32, |x, y| (x as f32 / 64.0, y as f32 / 32.0, 0.5)).unwrap();
    let exr = std::fs::read(&exr_path).unwrap();
    let mut hdr = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 32 +X 64\n".to_vec();
    for i in 0..64 * 32 {
        hdr.extend([(i % 256) as u8, 128, 64, 129]);
    }
    let mut inputs = committed("envmap");
    for (name, format, bytes) in [("small.exr", 0u8, &exr), ("small.hdr", 1, &hdr)] {
        for (label, mutant) in byte_mutants(name, bytes, 400, &mut rng) {
            inputs.push((label, [vec![format], mutant].concat()));
        }
    }
    // Declared sizes far beyond the limit.
    for header in ["-Y 100000 +X 100000", "-Y 100000000 +X 32", "-Y 0 +X 0", "+Y 5 -X 99999999999"] {
        let mut bytes = vec![1u8];
        bytes.extend(format!("#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n{header}\n").into_bytes());
        bytes.extend([1u8, 2, 3, 4].repeat(16));
        inputs.push((header.into(), bytes));
    }
    let n = replay(fuzzing::envmap, inputs);
    assert!(n > 800, "{n} inputs");
}

#[test]
fn disk_cache_entries_mutated_every_way_never_panic() {
    use lightloom_nodes::engine::{Codec, StageValue};
    let mut rng = SmallRng::seed_from_u64(4);
    let dir = std::env::temp_dir().join(format!("lightloom-hostile-cache-{}", std::process::id()));
    let cache = lightloom_nodes::engine::cache::DiskCache::new(&dir);
    let transport = lightloom_nodes::transport::ShTransport {
        bands: 2,
        rays: 16,
        visibility: vec![0.5; 16],
        transfer: vec![0.25; 16],
    };
    cache.store(0x5eed, &StageValue::new(transport), &Codec::of::<lightloom_nodes::transport::ShTransport>()).unwrap();
    let entry = std::fs::read(cache.path_for(0x5eed)).unwrap();
    let mut inputs = committed("disk_entry");
    for (label, mutant) in byte_mutants("SH transport entry", &entry, 600, &mut rng) {
        inputs.push((label, [vec![0u8], mutant].concat()));
    }
    let n = replay(fuzzing::disk_entry, inputs);
    assert!(n > 500, "{n} inputs");
}

#[test]
fn painted_lights_mutated_every_way_never_panic() {
    let mut rng = SmallRng::seed_from_u64(5);
    let mut inputs = committed("light_texture");
    let log = r#"[Fill(colour: (1.0, 0.5, 0.2), intensity: 3.0), Stroke(points: [(0.2, 0.3), (0.5, 0.5)], radius: 0.1, hardness: 0.5, colour: (4.0, 4.0, 1.0), intensity: 2.0, blend: Add), Erase(points: [(0.9, 0.9)], radius: 0.05, hardness: 1.0), Blur(sigma: 0.02), Warp(offset: (0.1, 0.0), scale: 0.8, angle: 30.0), Reshape(shape: Disc)]"#;
    for (label, mutant) in text_mutants("paint log", log, 300, &mut rng) {
        inputs.push((label, [vec![0u8], mutant].concat()));
    }
    // Logs within every per-operation bound whose replay would take too long, and values that
    // would overflow.
    let heavy = format!("[{}]", vec!["Blur(sigma: 1.0)"; 400].join(", "));
    let overflow = format!("[{}]", ["Fill(colour: (1e300, 1.0, 1.0), intensity: 1e6)"; 3].join(", "));
    let multiply = format!(
        "[{}]",
        vec!["Stroke(points: [(0.5, 0.5)], radius: 0.1, hardness: 1.0, colour: (1e6, 1e6, 1e6), intensity: 1e6, blend: Multiply)"; 20]
            .join(", ")
    );
    for text in [heavy, overflow, multiply] {
        inputs.push((text.chars().take(40).collect(), [vec![0u8], text.into_bytes()].concat()));
    }
    // Images: a small PNG, mutated, and the environment maps' formats.
    let mut png = Vec::new();
    let image = image::RgbImage::from_fn(16, 8, |x, y| image::Rgb([(x * 16) as u8, (y * 32) as u8, 128]));
    image.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png).unwrap();
    for (label, mutant) in byte_mutants("light.png", &png, 200, &mut rng) {
        inputs.push((label, [vec![1u8], mutant].concat()));
    }
    inputs.push(("png".into(), [vec![1u8], png].concat()));
    let n = replay(fuzzing::light_texture, inputs);
    assert!(n > 500, "{n} inputs");
}

#[test]
fn normal_maps_mutated_every_way_never_panic() {
    let mut rng = SmallRng::seed_from_u64(6);
    let mut inputs = committed("normal_map");
    let png = std::fs::read(assets().join("gltf/assimp-glTF2/ClearCoat-glTF/RibsNormal.png")).unwrap();
    for (label, mutant) in byte_mutants("RibsNormal.png", &png, 300, &mut rng) {
        inputs.push((label, [vec![0u8], mutant].concat()));
    }
    // A small PNG of the same texels, mutated (its pyramid is built when it loads).
    let mut small = Vec::new();
    image::RgbImage::from_fn(16, 16, |x, y| image::Rgb([(x * 16) as u8, (y * 16) as u8, 200]))
        .write_to(&mut std::io::Cursor::new(&mut small), image::ImageFormat::Png)
        .unwrap();
    for (label, mutant) in byte_mutants("16x16 png", &small, 200, &mut rng) {
        inputs.push((label, [vec![0u8], mutant].concat()));
    }
    // The same image as a glTF material's normal texture: in a data URI (text-mutated) and in
    // a GLB's buffer view (byte-mutated).
    let material =
        r#""materials":[{"name":"normals","normalTexture":{"index":0,"scale":2}}],"textures":[{"source":0}]"#;
    let data_uri = format!(
        r#"{{"asset":{{"version":"2.0"}},"images":[{{"uri":"data:image/png;base64,{}","mimeType":"image/png"}}],{material}}}"#,
        base64::encode(&small)
    );
    for (label, mutant) in text_mutants("data-URI glTF", &data_uri, 200, &mut rng) {
        inputs.push((label, [vec![2u8], mutant].concat()));
    }
    let glb = fuzzing::glb(
        &format!(
            r#"{{"asset":{{"version":"2.0"}},"buffers":[{{"byteLength":{0}}}],"bufferViews":[{{"buffer":0,"byteLength":{0}}}],"images":[{{"bufferView":0,"mimeType":"image/png"}}],{material}}}"#,
            small.len()
        ),
        &small,
    );
    for (label, mutant) in byte_mutants("GLB", &glb, 200, &mut rng) {
        inputs.push((label, [vec![3u8], mutant].concat()));
    }
    inputs.push(("data-URI glTF".into(), [vec![2u8], data_uri.into_bytes()].concat()));
    inputs.push(("GLB".into(), [vec![3u8], glb].concat()));
    inputs.push(("16x16 png".into(), [vec![0u8], small].concat()));
    let n = replay(fuzzing::normal_map, inputs);
    assert!(n > 500, "{n} inputs");
}

/// The fuzz target's check: a file that reads gives finite, non-negative candela everywhere.
fn ies(bytes: &[u8]) {
    if let Ok(photometry) = lightloom_nodes::ies::Photometry::parse(bytes) {
        for k in 0..64 {
            let value = photometry.candela(f64::from(k) * 3.0, f64::from(k) * 11.0);
            assert!(value.is_finite() && value >= 0.0, "candela {value}");
        }
    }
}

#[test]
fn ies_profiles_mutated_every_way_never_panic() {
    let mut rng = SmallRng::seed_from_u64(7);
    let mut inputs = committed("ies");
    assert!(inputs.len() >= 5, "the committed IES corpus");
    for (name, bytes) in committed("ies") {
        let text = String::from_utf8_lossy(&bytes).into_owned();
        inputs.extend(text_mutants(&name, &text, 300, &mut rng));
        inputs.extend(byte_mutants(&name, &bytes, 100, &mut rng));
    }
    // Counts that would allocate without bound if trusted.
    inputs.push(("huge counts".into(), b"TILT=NONE\n1 -1 1 4096 4096 1 2 0 0 0\n1 1 1\n0 90".to_vec()));
    inputs.push(("huge tilt".into(), b"TILT=INCLUDE\n1 999999999\n".to_vec()));
    let n = replay(ies, inputs);
    assert!(n > 2000, "{n} inputs");
}
