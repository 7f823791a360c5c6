//! `lightloom bake` through the real binary: every exported file passes the Khronos
//! glTF-Validator (npm `gltf-validator`, run with Node) with no errors or warnings; three.js
//! in headless Chromium draws the baked lighting as Lightloom's own picture of it; the same
//! project gives the same bytes; a failed or cancelled bake leaves the folder as it was.

use std::path::{Path, PathBuf};
use std::process::Command;

fn lightloom() -> Command {
    Command::new(env!("CARGO_BIN_EXE_lightloom"))
}

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("lightloom-bake-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn bake(project: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
    let mut command = lightloom();
    command.arg("bake").arg(project).arg("--out").arg(out).args(extra);
    command.output().unwrap()
}

/// The Node packages (validator, three.js, puppeteer-core), installed from
/// `tools/package.json` on first use (`.ci/run` installs them up front). Fails loudly without
/// Node or npm.
fn tools() -> PathBuf {
    static READY: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    READY
        .get_or_init(|| {
            let tools = repo().join("tools");
            let installed = ["gltf-validator", "three", "puppeteer-core"]
                .iter()
                .all(|p| tools.join("node_modules").join(p).exists());
            if !installed {
                let status = Command::new("npm")
                    .args(["ci", "--no-audit", "--no-fund", "--prefix"])
                    .arg(&tools)
                    .status()
                    .expect("npm is needed to install the glTF validator: install nodejs and npm (.ci/run does)");
                assert!(status.success(), "npm ci in tools/ failed");
            }
            tools
        })
        .clone()
}

/// The validator's report on `file`: (errors, warnings, messages that are errors or warnings).
fn validate(file: &Path) -> (u64, u64, Vec<String>) {
    let out = Command::new("node")
        .arg(tools().join("validate_gltf.mjs"))
        .arg(file)
        .output()
        .expect("node is needed to run the glTF validator: install nodejs (.ci/run does)");
    assert!(out.status.success(), "validator: {}", String::from_utf8_lossy(&out.stderr));
    let reports: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let issues = &reports[0]["issues"];
    let serious = issues["messages"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|m| m["severity"].as_u64().unwrap() < 2)
        .map(|m| format!("{} at {}: {}", m["code"], m["pointer"], m["message"]))
        .collect();
    (issues["numErrors"].as_u64().unwrap(), issues["numWarnings"].as_u64().unwrap(), serious)
}

/// The default scene (sky with a sun, wavelet per-pixel mode), the foggy street (point
/// lights, fog, SH transfer) and the square-light sample (its lights as directional lights):
/// valid glTF, and the same bytes from a second bake that computes everything again. The
/// engine model (a glTF import) is valid too.
#[test]
fn baked_scenes_pass_the_khronos_validator_and_are_deterministic() {
    let dir = temp_dir("valid");
    let street = repo().join("projects/samples/fog_street.ron");
    let default = repo().join("projects/default.ron");
    let squares = repo().join("projects/samples/square_lights.ron");
    for (name, project) in
        [("default", default.as_path()), ("street", street.as_path()), ("squares", squares.as_path())]
    {
        let first = dir.join(format!("{name}-1"));
        let out = bake(project, &first, &["--no-disk-cache"]);
        assert!(out.status.success(), "{name}: {}", String::from_utf8_lossy(&out.stderr));
        let (errors, warnings, messages) = validate(&first.join("scene.glb"));
        assert_eq!((errors, warnings), (0, 0), "{name}: {messages:#?}");
        let second = dir.join(format!("{name}-2"));
        let out = bake(project, &second, &["--no-disk-cache", "-q"]);
        assert!(out.status.success());
        for file in ["scene.glb", "bake.json", "lightmap.exr", "probes.json", "probes.bin"] {
            assert!(
                std::fs::read(first.join(file)).unwrap() == std::fs::read(second.join(file)).unwrap(),
                "{name}: {file} differs between two bakes"
            );
        }
    }
    // A glTF model without texture coordinates of its own (the lightmap's are its first set).
    let engine = dir.join("engine");
    let out = bake(&repo().join("projects/samples/engine.ron"), &engine, &["--no-disk-cache", "-q"]);
    assert!(out.status.success(), "engine: {}", String::from_utf8_lossy(&out.stderr));
    let (errors, warnings, messages) = validate(&engine.join("scene.glb"));
    assert_eq!((errors, warnings), (0, 0), "engine: {messages:#?}");

    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("street-1/bake.json")).unwrap()).unwrap();
    assert_eq!(manifest["point_lights"], 3);
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("squares-1/bake.json")).unwrap()).unwrap();
    assert_eq!(manifest["mode"], "rsl");
    assert!(manifest["square_lights"].as_u64().unwrap() >= 10, "{}", manifest["square_lights"]);
}

/// A bake that fails (a missing environment file) writes nothing and says why.
#[test]
fn a_failed_bake_leaves_the_folder_as_it_was() {
    let dir = temp_dir("failed");
    let out_dir = dir.join("out");
    std::fs::create_dir_all(&out_dir).unwrap();
    std::fs::write(out_dir.join("scene.glb"), b"previous").unwrap();
    let project = repo().join("projects/default.ron");
    let out =
        bake(&project, &out_dir, &["--no-disk-cache", "--set", "sky.source=file", "--set", "sky.file=missing.exr"]);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("missing.exr"), "{stderr}");
    let names: Vec<_> = std::fs::read_dir(&out_dir).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(names, ["scene.glb"]);
    assert_eq!(std::fs::read(out_dir.join("scene.glb")).unwrap(), b"previous");
}

/// Ctrl+C during the transport precompute: the bake stops, says it was cancelled, and writes
/// nothing.
#[cfg(unix)]
#[test]
fn ctrl_c_cancels_a_bake_and_writes_nothing() {
    let dir = temp_dir("cancel");
    let project = repo().join("projects/default.ron");
    let out_dir = dir.join("out");
    let child = lightloom()
        .arg("bake")
        .arg(&project)
        .arg("--out")
        .arg(&out_dir)
        .args(["--no-disk-cache", "--set", "output.mode=sh_prt", "--set", "scene.transport_rays=16384"])
        .stderr(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(1500));
    let status = Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap();
    assert!(status.success());
    let started = std::time::Instant::now();
    let out = child.wait_with_output().unwrap();
    assert!(started.elapsed().as_secs() < 20, "cancelling took {:?}", started.elapsed());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.contains("cancelled"), "{stderr}");
    assert!(!out_dir.join("scene.glb").exists());
}

/// Linear RGB pixels three.js drew (rows top to bottom) and which show a surface.
fn three_js_picture(bake: &Path, variant: &str, (w, h): (usize, usize)) -> (Vec<[f32; 3]>, Vec<bool>) {
    let out = Command::new("node")
        .arg(tools().join("threejs/shoot.mjs"))
        .arg(bake)
        .args([variant, &w.to_string(), &h.to_string()])
        .output()
        .expect("node is needed to drive three.js in Chromium: install nodejs and chromium (.ci/run does)");
    assert!(out.status.success(), "three.js in Chromium ({variant}): {}", String::from_utf8_lossy(&out.stderr));
    let result: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let bytes = base64::decode(result["pixels"].as_str().unwrap()).unwrap();
    let floats: Vec<f32> = bytes.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
    assert_eq!(floats.len(), w * h * 4);
    let mut pixels = vec![[0.0; 3]; w * h];
    let mut surface = vec![false; w * h];
    for y in 0..h {
        // WebGL reads rows bottom to top.
        for x in 0..w {
            let p = &floats[((h - 1 - y) * w + x) * 4..][..4];
            pixels[y * w + x] = [p[0], p[1], p[2]];
            surface[y * w + x] = p[3] > 0.5;
        }
    }
    (pixels, surface)
}

/// Relative RMSE `‖a − b‖ / ‖b‖` over pixels inside surfaces, leaving out silhouettes
/// against the background (a neighbour differs), where a rasteriser and a ray through the
/// pixel centre may see different things. Edges between two objects stay in: they are most of
/// the remaining error (the mean ratio of the pictures is 1.000).
fn relative_rmse(a: &[[f32; 3]], b: &[[f32; 3]], surface: &[bool], (w, h): (usize, usize)) -> (f64, usize) {
    let (mut diff, mut norm, mut count) = (0.0, 0.0, 0);
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let i = y * w + x;
            let inside = (-1i64..=1)
                .all(|dy| (-1i64..=1).all(|dx| surface[(y as i64 + dy) as usize * w + (x as i64 + dx) as usize]));
            if !inside {
                continue;
            }
            for c in 0..3 {
                diff += f64::from(a[i][c] - b[i][c]).powi(2);
                norm += f64::from(b[i][c]).powi(2);
            }
            count += 1;
        }
    }
    ((diff / norm).sqrt(), count)
}

/// three.js (npm `three`, GLTFLoader, in headless Chromium with SwiftShader) loads the baked
/// default scene and draws its baked lighting from the glTF camera, per vertex (`COLOR_0`) and
/// from the lightmap (the RGBM texture decoded in three's own lightmap path): both match
/// Lightloom's own picture of the same bake (`--preview`) within 2% relative RMSE over surface
/// pixels. The vertex and lightmap pictures differ from each other by far more, so the
/// metric sees which light was drawn.
#[test]
fn three_js_draws_the_bake_as_lightloom_does() {
    let dir = temp_dir("threejs");
    let size = (320, 180);
    let out = bake(&repo().join("projects/default.ron"), &dir, &["--no-disk-cache", "-q", "--preview", "320x180"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let ours = |name: &str| -> Vec<[f32; 3]> {
        let image = image::open(dir.join(name)).unwrap().into_rgb32f();
        image.as_raw().chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect()
    };
    let (vertex_ours, lightmap_ours) = (ours("preview_vertex.exr"), ours("preview_lightmap.exr"));
    let mut errors = Vec::new();
    for (variant, reference) in [("vertex", &vertex_ours), ("lightmap", &lightmap_ours)] {
        let (theirs, surface) = three_js_picture(&dir, variant, size);
        let (error, pixels) = relative_rmse(&theirs, reference, &surface, size);
        eprintln!("three.js {variant}: relative RMSE {error:.4} over {pixels} surface pixels");
        assert!(pixels > 20_000, "{variant}: only {pixels} surface pixels compared");
        assert!(error < 0.02, "{variant}: three.js differs from Lightloom's picture by {error:.4}");
        errors.push(error);
    }
    let surface = vec![true; size.0 * size.1];
    let (between, _) = relative_rmse(&vertex_ours, &lightmap_ours, &surface, size);
    eprintln!("vertex against lightmap: {between:.4}");
    assert!(
        between > 3.0 * errors[0].max(errors[1]),
        "the variants differ by {between}: the metric cannot tell them apart"
    );
}

/// The baked environment's SH (environment.json) against `lightloom sh` on the same HDRI, and
/// the specular cube's KTX2 header as a reader expects it.
#[test]
fn baked_environment_sh_matches_lightloom_sh() {
    let dir = temp_dir("environment");
    let project = repo().join("projects/samples/glossy_courtyard.ron");
    let out = bake(&project, &dir, &["-q", "--set", "output.mode=sh_irradiance"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let baked: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("environment.json")).unwrap()).unwrap();
    let hdri = repo().join("assets/envmaps/courtyard.hdr");
    let sh = lightloom().arg("sh").arg(&hdri).args(["--bands", "3", "--json"]).output().unwrap();
    assert!(sh.status.success(), "{}", String::from_utf8_lossy(&sh.stderr));
    let printed: serde_json::Value = serde_json::from_slice(&sh.stdout).unwrap();
    let (ours, theirs) = (baked["sh"]["coefficients"].as_array().unwrap(), printed["coefficients"].as_array().unwrap());
    assert_eq!(ours.len(), 9);
    let scale = theirs[0]["rgb"][1].as_f64().unwrap();
    for (a, b) in ours.iter().zip(theirs) {
        assert_eq!((&a["l"], &a["m"]), (&b["l"], &b["m"]));
        for c in 0..3 {
            let (x, y) = (a["rgb"][c].as_f64().unwrap(), b["rgb"][c].as_f64().unwrap());
            assert!((x - y).abs() < 0.005 * scale, "L{}{}: {x} vs {y}", a["l"], a["m"]);
        }
    }
    let ktx = std::fs::read(dir.join("environment_specular.ktx2")).unwrap();
    assert_eq!(&ktx[..12], &[0xAB, 0x4B, 0x54, 0x58, 0x20, 0x32, 0x30, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A]);
    assert_eq!(u32::from_le_bytes(ktx[12..16].try_into().unwrap()), 97, "VK_FORMAT_R16G16B16A16_SFLOAT");
    assert_eq!(u32::from_le_bytes(ktx[36..40].try_into().unwrap()), 6, "six faces");
}

/// three.js's `KTX2Loader` (in headless Chromium) reads the baked specular cube, and the GPU's
/// own cube lookup finds every texel where the file put it:
/// - the texels read back through `textureLod` at texel centres of every face and level equal
///   the file's half floats (as the `ktx2` crate reads them);
/// - the roughest level's luminance follows the environment's L2 SH (`environment.json`, a
///   separate code path) at the lookup directions, so faces and rows are the world's
///   (a flipped face or swapped pair drops the correlation far below).
///
/// three r181's loader returns a raw (not Basis) cube file as a 2D texture of six faces per
/// level; the page assembles the cube from three's decoded levels, as three does for Basis.
#[test]
fn three_js_reads_the_specular_cube() {
    let dir = temp_dir("ktx2");
    let out = bake(&repo().join("projects/default.ron"), &dir, &["--no-disk-cache", "-q"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let run = Command::new("node")
        .arg(tools().join("threejs/shoot.mjs"))
        .arg(&dir)
        .arg("ktx2")
        .output()
        .expect("node is needed to drive three.js in Chromium: install nodejs and chromium (.ci/run does)");
    assert!(run.status.success(), "three.js KTX2Loader: {}", String::from_utf8_lossy(&run.stderr));
    let result: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    let texture = &result["texture"];
    assert_eq!(texture["typeIsHalfFloat"], true, "{texture}");
    assert_eq!(texture["formatIsRGBA"], true, "{texture}");

    let bytes = std::fs::read(dir.join("environment_specular.ktx2")).unwrap();
    let reader = ktx2::Reader::new(&bytes[..]).expect("a valid KTX2 file");
    let size = reader.header().pixel_width as usize;
    let levels: Vec<&[u8]> = reader.levels().map(|l| l.data).collect();
    assert_eq!(result["levels"].as_u64().unwrap() as usize, levels.len());
    let samples = result["samples"].as_array().unwrap();
    assert!(samples.len() > 6 * levels.len() * 8, "{} samples", samples.len());
    let sh = read_sh(&dir.join("environment.json"));
    let (mut worst, mut roughest) = (0.0f64, Vec::new());
    for s in samples {
        let at = |k: &str| s[k].as_u64().unwrap() as usize;
        let (level, face, x, y) = (at("level"), at("face"), at("x"), at("y"));
        let n = (size >> level).max(1);
        let texel = &levels[level][((face * n + y) * n + x) * 8..][..8];
        let mut luminance = 0.0;
        for c in 0..4 {
            let file = f64::from(half::f16::from_le_bytes([texel[c * 2], texel[c * 2 + 1]]).to_f32());
            let read = s["rgba"][c].as_f64().unwrap();
            worst = worst.max((read - file).abs() / file.abs().max(1e-3));
            luminance += if c < 3 { read } else { 0.0 };
        }
        if level + 1 == levels.len() {
            roughest.push((luminance, sh_radiance(&sh, gl_direction(face, x, y, n))));
        }
    }
    let correlation = pearson(&roughest);
    eprintln!(
        "three.js read {} texels: worst relative difference {worst:.2e}; roughest level against the SH r = {correlation:.3}",
        samples.len()
    );
    assert!(worst < 1e-3, "texels differ from the file by up to {worst}");
    assert!(correlation > 0.8, "the roughest level does not follow the environment's SH (r = {correlation})");
}

/// `environment.json`'s L2 radiance SH, luminance summed over RGB, by index `l(l+1)+m`.
fn read_sh(path: &Path) -> Vec<f64> {
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap();
    json["sh"]["coefficients"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["rgb"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).sum())
        .collect()
}

/// The real SH of the file's stated convention (no Condon-Shortley phase), up to l = 2.
fn sh_radiance(coefficients: &[f64], [x, y, z]: [f64; 3]) -> f64 {
    let basis = [
        0.282095,
        0.488603 * y,
        0.488603 * z,
        0.488603 * x,
        1.092548 * x * y,
        1.092548 * y * z,
        0.315392 * (3.0 * z * z - 1.0),
        1.092548 * x * z,
        0.546274 * (x * x - y * y),
    ];
    coefficients.iter().zip(basis).map(|(c, b)| c * b).sum()
}

/// The direction of texel `(x, y)` of `face` at `n` texels a side, by the OpenGL/Vulkan table
/// that KTX2 cube maps follow (faces +X −X +Y −Y +Z −Z, row 0 first in the file).
fn gl_direction(face: usize, x: usize, y: usize, n: usize) -> [f64; 3] {
    let u = 2.0 * (x as f64 + 0.5) / n as f64 - 1.0;
    let v = 2.0 * (y as f64 + 0.5) / n as f64 - 1.0;
    let d = [[1.0, -v, -u], [-1.0, -v, u], [u, 1.0, v], [u, -1.0, -v], [u, -v, 1.0], [-u, -v, -1.0]][face];
    let length = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    d.map(|c| c / length)
}

fn pearson(pairs: &[(f64, f64)]) -> f64 {
    let n = pairs.len() as f64;
    let (ma, mb) = (pairs.iter().map(|p| p.0).sum::<f64>() / n, pairs.iter().map(|p| p.1).sum::<f64>() / n);
    let cov: f64 = pairs.iter().map(|p| (p.0 - ma) * (p.1 - mb)).sum();
    let va: f64 = pairs.iter().map(|p| (p.0 - ma).powi(2)).sum();
    let vb: f64 = pairs.iter().map(|p| (p.1 - mb).powi(2)).sum();
    cov / (va * vb).sqrt()
}

/// The viewport's SH irradiance shader (per pixel, on the GPU) against the bake's CPU twin of
/// it (per vertex, `--preview`'s albedo × baked light) from the same camera: the same light
/// wherever a pixel lies inside a triangle. Silhouette pixels (coverage and interpolation
/// differ there) are the top few percent, so the 95th percentile is what is bounded.
#[test]
fn the_viewport_sh_irradiance_is_the_cpu_irradiance() {
    let dir = temp_dir("irradiance");
    let project = repo().join("projects/default.ron");
    // The SH shader alone: the sun stays in the environment's SH (lit apart, the viewport
    // shadows it per pixel and the bake per vertex).
    let mode = ["--set", "output.mode=sh_irradiance", "--set", "output.sun=in_environment"];
    let out = bake(&project, &dir.join("bake"), &[&mode[..], &["--preview", "320x180", "-q"]].concat());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let render = dir.join("render.exr");
    let out = lightloom()
        .args(["render", project.to_str().unwrap(), "-o", render.to_str().unwrap(), "-q"])
        .args(mode)
        .args(["--set", "output.background=false", "--width", "320", "--height", "180"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let gpu = image::open(&render).unwrap().into_rgb32f();
    let cpu = image::open(dir.join("bake/preview_vertex.exr")).unwrap().into_rgb32f();
    let mut errors: Vec<f64> = gpu
        .pixels()
        .zip(cpu.pixels())
        .filter(|(g, c)| g.0.iter().sum::<f32>() > 0.0 && c.0.iter().sum::<f32>() > 0.0)
        .map(|(g, c)| {
            let norm = |v: [f64; 3]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
            let (g, c) = (g.0.map(f64::from), c.0.map(f64::from));
            norm([g[0] - c[0], g[1] - c[1], g[2] - c[2]]) / norm(c)
        })
        .collect();
    assert!(errors.len() > 320 * 180 / 3, "{} surface pixels", errors.len());
    errors.sort_by(f64::total_cmp);
    let (median, p95) = (errors[errors.len() / 2], errors[errors.len() * 95 / 100]);
    assert!(median < 0.002 && p95 < 0.01, "per-pixel relative error: median {median}, 95th percentile {p95}");
}
