//! Command-line tests: run the real `lightloom` binary.

use std::path::{Path, PathBuf};
use std::process::Command;

fn lightloom() -> Command {
    Command::new(env!("CARGO_BIN_EXE_lightloom"))
}

fn assets() -> PathBuf {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets");
    assert!(dir.is_dir(), "the repository's assets/ folder is expected at {}", dir.display());
    dir
}

fn sh_json(args: &[&str]) -> serde_json::Value {
    let out = lightloom().arg("sh").args(args).arg("--json").output().expect("run lightloom");
    assert!(out.status.success(), "lightloom sh {args:?} failed: {}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).expect("valid JSON")
}

fn irradiance(report: &serde_json::Value, axis: &str) -> [f64; 3] {
    let entry = report["irradiance"].as_array().unwrap().iter().find(|e| e["axis"] == axis).unwrap();
    let rgb = entry["rgb"].as_array().unwrap();
    [0, 1, 2].map(|c| rgb[c].as_f64().unwrap())
}

fn write_hdr(path: &Path, width: u32, height: u32, f: impl Fn(u32, u32) -> [f32; 3]) {
    let pixels: Vec<image::Rgb<f32>> = (0..width * height).map(|i| image::Rgb(f(i % width, i / width))).collect();
    let file = std::fs::File::create(path).unwrap();
    image::codecs::hdr::HdrEncoder::new(file).encode(&pixels, width as usize, height as usize).unwrap();
}

#[test]
fn constant_environment_gives_pi_times_radiance_everywhere() {
    let dir = tempdir("constant");
    let path = dir.join("grey.hdr");
    write_hdr(&path, 256, 128, |_, _| [0.5, 1.0, 2.0]);
    let report = sh_json(&[path.to_str().unwrap(), "--bands", "3"]);
    let l00 = report["coefficients"][0]["rgb"][1].as_f64().unwrap();
    assert!((l00 - (4.0 * std::f64::consts::PI).sqrt()).abs() < 1e-4, "L00 = {l00}");
    for axis in ["+X", "-X", "+Y", "-Y", "+Z", "-Z"] {
        let e = irradiance(&report, axis);
        for (c, radiance) in [0.5, 1.0, 2.0].iter().enumerate() {
            assert!((e[c] - std::f64::consts::PI * radiance).abs() < 1e-3, "{axis}: {e:?}");
        }
    }
}

#[test]
fn bright_upper_hemisphere_lights_plus_y() {
    // Radiance 1 above the horizon, 0 below: E(+Y) = π exactly, E(-Y) = 0, E(±X) = π/2;
    // 3-band SH gets within the known 9-coefficient error of a step function.
    let dir = tempdir("hemisphere");
    let path = dir.join("half.hdr");
    write_hdr(&path, 512, 256, |_, y| if y < 128 { [1.0; 3] } else { [0.0; 3] });
    let report = sh_json(&[path.to_str().unwrap(), "--bands", "3"]);
    let pi = std::f64::consts::PI;
    assert!((irradiance(&report, "+Y")[0] - pi).abs() < 0.1 * pi);
    assert!(irradiance(&report, "-Y")[0].abs() < 0.1 * pi);
    assert!((irradiance(&report, "+X")[0] - pi / 2.0).abs() < 1e-3);
    assert!((irradiance(&report, "-Z")[0] - pi / 2.0).abs() < 1e-3);
}

#[test]
fn real_environment_maps_agree_across_formats() {
    // The same HDRI as ZIP EXR, DWAB EXR and Radiance HDR gives the same SH within the
    // formats' quantisation.
    let envmaps = assets().join("envmaps");
    let exr = sh_json(&[envmaps.join("courtyard.exr").to_str().unwrap(), "--bands", "4"]);
    let hdr = sh_json(&[envmaps.join("courtyard.hdr").to_str().unwrap(), "--bands", "4"]);
    let dwab = sh_json(&[envmaps.join("dwab/courtyard.exr").to_str().unwrap(), "--bands", "4"]);
    let coeffs = |r: &serde_json::Value| -> Vec<f64> {
        r["coefficients"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(|c| (0..3).map(move |k| c["rgb"][k].as_f64().unwrap()))
            .collect()
    };
    let (a, b, c) = (coeffs(&exr), coeffs(&hdr), coeffs(&dwab));
    let scale = a[0].abs();
    for i in 0..a.len() {
        assert!((a[i] - b[i]).abs() < 0.02 * scale, "coefficient {i}: EXR {} vs HDR {}", a[i], b[i]);
        assert!((a[i] - c[i]).abs() < 0.02 * scale, "coefficient {i}: EXR {} vs DWAB {}", a[i], c[i]);
    }
    assert_eq!(exr["coefficients"].as_array().unwrap().len(), 16);
}

#[test]
fn bad_input_gives_a_clear_error_and_exit_code_two() {
    let dir = tempdir("bad");
    let broken = dir.join("broken.exr");
    std::fs::write(&broken, b"not an exr at all").unwrap();
    for (args, needle) in [
        (vec!["sh".to_string(), "/no/such/sky.hdr".to_string()], "/no/such/sky.hdr"),
        (vec!["sh".to_string(), broken.display().to_string()], "broken.exr"),
        (vec!["sh".to_string(), "--builtin-sky".to_string(), "--window".to_string(), "boxcar".to_string()], "boxcar"),
    ] {
        let out = lightloom().args(&args).output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(needle), "{args:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
    }
    // Absurd band counts are refused by the argument parser (exit 2, names the option).
    let out = lightloom().args(["sh", "--builtin-sky", "--bands", "1000"]).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--bands"));
}

#[test]
fn default_job_renders_the_builtin_project() {
    let dir = tempdir("default-job");
    let out = lightloom().current_dir(&dir).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("rendered 960x540"), "{text}");
    let image = image::open(dir.join("lightloom-default.png")).unwrap().into_rgb8();
    // Not blank: the image has both dark and bright regions and many distinct colours.
    let lum: Vec<u32> = image.pixels().map(|p| p[0] as u32 + p[1] as u32 + p[2] as u32).collect();
    let (lo, hi) = (lum.iter().min().unwrap(), lum.iter().max().unwrap());
    assert!(hi - lo > 200, "contrast {lo}..{hi}");
    let distinct: std::collections::HashSet<_> = image.pixels().map(|p| p.0).collect();
    assert!(distinct.len() > 1000, "{} colours", distinct.len());
}

fn tempdir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("lightloom-cli-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

#[test]
fn malformed_projects_fail_with_clear_errors_and_exit_code_two() {
    // (file, text the error must contain)
    let corpus = [
        ("truncated.ron", "truncated.ron:6:"),
        ("binary.ron", "not a text file"),
        ("wrong_types.ron", "line 4: node `sky` parameter `exposure`: expected Float, found Int"),
        ("unknown_kind.ron", "node `pot`: unknown node kind `Teapot`"),
        ("dangling_link.ron", "node `sky` port `environment`: link refers to a node that does not exist"),
        ("cycle.ron", "links form a cycle"),
        ("absurd_numbers.ron", "1e300 EV is outside -20..=20"),
        ("not_a_number.ron", "object `ball` has a size outside"),
        ("missing_asset.ron", "no/such/sky.exr does not exist"),
        ("missing_version.ron", "missing `version` field"),
        ("future_version.ron", "version 99 is newer"),
        ("unknown_field.ron", "Unexpected field named `colour`"),
        ("missing_output_input.ron", "node `out` port `scene`: required Scene input is not connected"),
        ("duplicate_ids.ron", "node `o`: duplicate node id"),
        ("no_output.ron", "no_output.ron: the project has no Output node"),
    ];
    let dir = workspace().join("tests/malformed");
    let listed: Vec<&str> = corpus.iter().map(|c| c.0).collect();
    for entry in std::fs::read_dir(&dir).unwrap() {
        let name = entry.unwrap().file_name().to_string_lossy().to_string();
        assert!(listed.contains(&name.as_str()), "{name} is in the corpus but not in this table");
    }
    let out_png = tempdir("malformed").join("x.png");
    for (file, needle) in corpus {
        let path = dir.join(file);
        for args in [
            vec!["info"],
            vec!["render", "-o", out_png.to_str().unwrap(), "--no-disk-cache"],
            vec!["eval", "--no-disk-cache"],
        ] {
            let out = lightloom().args(&args[..1]).arg(&path).args(&args[1..]).output().unwrap();
            let stderr = String::from_utf8_lossy(&out.stderr);
            assert_eq!(out.status.code(), Some(2), "{file} {args:?}: {stderr}");
            assert!(stderr.contains(needle), "{file} {args:?}: expected {needle:?} in {stderr}");
            assert!(!stderr.contains("panicked"), "{file}: {stderr}");
        }
    }
}

#[test]
fn white_furnace_in_the_square_light_mode() {
    // The same furnace drawn by the GPU pass of the `rsl` mode: a constant environment as 30
    // square lights, each light's ρ̄ from the summed-area tables and V̄ from the distance
    // tables (here only the horizon). What remains is the square-versus-region mismatch at the
    // horizon (notes §9: no tolerance given; set by measurement).
    let dir = tempdir("furnace-rsl");
    write_hdr(&dir.join("grey.hdr"), 128, 64, |_, _| [0.25, 0.5, 1.0]);
    let project = r#"(
        version: 4,
        cameras: [(name: "c", position: (0.0, 0.0, 4.0), target: (0.0, 0.0, 0.0), fov_y_deg: 30.0)],
        render: (width: 64, height: 64),
        nodes: [
            (id: "env", kind: "EnvironmentMap", params: {"source": Choice("file"), "file": Path("grey.hdr")}),
            (id: "lights", kind: "RslDecomposer", params: {"cube_resolution": Choice("16")}),
            (id: "scene", kind: "Scene", params: {
                "objects": Objects([(name: "s", shape: Sphere(radius: 1.0), color: (1.0, 1.0, 1.0))]),
            }),
            (id: "white", kind: "BrdfEditor", params: {"albedo": Color((1.0, 1.0, 1.0))}),
            (id: "out", kind: "Output", params: {"mode": Choice("rsl")}),
        ],
        links: [
            (from: ("env", "environment"), to: ("out", "environment")),
            (from: ("env", "environment"), to: ("lights", "environment")),
            (from: ("lights", "square_lights"), to: ("out", "square_lights")),
            (from: ("scene", "scene"), to: ("out", "scene")),
            (from: ("white", "material"), to: ("out", "material")),
        ],
    )"#;
    let path = dir.join("furnace-rsl.ron");
    std::fs::write(&path, project).unwrap();
    let exr = dir.join("furnace-rsl.exr");
    let out = lightloom()
        .args(["render", path.to_str().unwrap(), "-o", exr.to_str().unwrap(), "--no-disk-cache", "-q"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let image = image::open(&exr).unwrap().into_rgb32f();
    let (mut worst, mut sum, mut count) = (0.0f32, 0.0f32, 0);
    // The background shows the environment itself, so edge pixels need no mask.
    for p in image.pixels() {
        for (c, want) in [0.25f32, 0.5, 1.0].iter().enumerate() {
            let e = (p[c] - want).abs() / want;
            worst = worst.max(e);
            sum += e;
            count += 1;
        }
    }
    let mean = sum / count as f32;
    println!("rsl furnace: mean {:.2}%, worst {:.2}%", mean * 100.0, worst * 100.0);
    // Measured: mean 0.89%, worst 3.9% over all pixels (with the horizon also stored as
    // occluded in the distance tables it was 3.9% and 9.8%: counted twice).
    assert!(mean < 0.015 && worst < 0.06, "rsl furnace violated: mean {mean:.4}, worst {worst:.4}");
}

#[test]
fn square_light_images_approach_the_monte_carlo_reference_as_lights_are_added() {
    // A glossy GGX sphere under the courtyard HDRI in the `rsl` mode, against the Monte Carlo
    // reference of the same scene (independent: BRDF sampling and MIS on the BVH), for two
    // light counts: the GPU pass's glossy lookups must converge towards the reference.
    let dir = tempdir("rsl-reference");
    let hdr = assets().join("envmaps/courtyard.hdr");
    let project = format!(
        r#"(
        version: 4,
        cameras: [(name: "c", position: (0.0, 0.5, 3.2), target: (0.0, 0.0, 0.0), fov_y_deg: 40.0)],
        render: (width: 64, height: 64),
        nodes: [
            (id: "env", kind: "EnvironmentMap", params: {{"source": Choice("file"), "file": Path("{}")}}),
            (id: "lights", kind: "RslDecomposer"),
            (id: "scene", kind: "Scene", params: {{
                "objects": Objects([(name: "s", shape: Sphere(radius: 1.0), color: (1.0, 1.0, 1.0))]),
            }}),
            (id: "gloss", kind: "BrdfEditor", params: {{
                "model": Choice("ggx"), "roughness": Float(0.45), "f0": Float(0.5), "albedo": Color((0.4, 0.4, 0.4)),
            }}),
            (id: "out", kind: "Output", params: {{"mode": Choice("rsl"), "reference_samples": Int(1024)}}),
        ],
        links: [
            (from: ("env", "environment"), to: ("out", "environment")),
            (from: ("env", "environment"), to: ("lights", "environment")),
            (from: ("lights", "square_lights"), to: ("out", "square_lights")),
            (from: ("scene", "scene"), to: ("out", "scene")),
            (from: ("gloss", "material"), to: ("out", "material")),
        ],
    )"#,
        hdr.display()
    );
    let path = dir.join("rsl.ron");
    std::fs::write(&path, project).unwrap();
    let error_at = |k: usize| -> f64 {
        let png = dir.join(format!("error-{k}.png"));
        let out = lightloom()
            .args(["render", path.to_str().unwrap(), "-o", png.to_str().unwrap(), "--no-disk-cache"])
            .args(["--set", "out.view=error", "--set", &format!("lights.light_count={k}")])
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let text = String::from_utf8_lossy(&out.stdout).to_string();
        let relative = text.split("(relative ").nth(1).and_then(|t| t.split('%').next()).expect("an error line");
        relative.trim().parse::<f64>().unwrap() / 100.0
    };
    let (few, many) = (error_at(10), error_at(100));
    println!("rsl against the reference: K=10 {:.1}%, K=100 {:.1}%", few * 100.0, many * 100.0);
    assert!(many < few, "more lights, no closer: {few} -> {many}");
    assert!(many < 0.12, "K=100 is {:.1}% from the reference", many * 100.0);
}

#[test]
fn white_furnace_through_the_whole_pipeline() {
    // A white Lambert object under a constant environment with no occluders reflects exactly
    // the environment radiance: E = πL, L_out = albedo·E/π = L. The EXR is linear radiance.
    // Per-pixel irradiance, per-vertex shadowed transfer (whose 1024-ray Fibonacci quadrature
    // of the clamped cosine is good to a fraction of a percent) and the local-frame triple
    // product.
    let dir = tempdir("furnace");
    write_hdr(&dir.join("grey.hdr"), 128, 64, |_, _| [0.25, 0.5, 1.0]);
    for (mode, transport) in [("sh_irradiance", "none"), ("sh_prt", "sh"), ("wavelet_vertex", "sh_and_wavelets")] {
        let project = format!(
            r#"(
            version: 2,
            cameras: [(name: "c", position: (0.0, 0.0, 4.0), target: (0.0, 0.0, 0.0), fov_y_deg: 30.0)],
            render: (width: 64, height: 64),
            nodes: [
                (id: "env", kind: "EnvironmentMap", params: {{"source": Choice("file"), "file": Path("grey.hdr")}}),
                (id: "scene", kind: "Scene", params: {{
                    "objects": Objects([(name: "s", shape: Sphere(radius: 1.0), color: (1.0, 1.0, 1.0))]),
                    "transport": Choice("{transport}"),
                    "transport_rays": Int(1024),
                }}),
                (id: "white", kind: "BrdfEditor", params: {{"albedo": Color((1.0, 1.0, 1.0))}}),
                (id: "out", kind: "Output", params: {{"mode": Choice("{mode}")}}),
            ],
            links: [
                (from: ("env", "environment"), to: ("out", "environment")),
                (from: ("scene", "scene"), to: ("out", "scene")),
                (from: ("white", "material"), to: ("out", "material")),
            ],
        )"#
        );
        let path = dir.join(format!("furnace-{mode}.ron"));
        std::fs::write(&path, project).unwrap();
        let exr = dir.join(format!("furnace-{mode}.exr"));
        let out = lightloom()
            .args(["render", path.to_str().unwrap(), "-o", exr.to_str().unwrap(), "--no-disk-cache", "-q"])
            .output()
            .unwrap();
        assert!(out.status.success(), "{mode}: {}", String::from_utf8_lossy(&out.stderr));
        let image = image::open(&exr).unwrap().into_rgb32f();
        // Every pixel, sphere or background, is the environment radiance (half-float precision).
        let mut worst: f32 = 0.0;
        for p in image.pixels() {
            for (c, want) in [0.25f32, 0.5, 1.0].iter().enumerate() {
                worst = worst.max((p[c] - want).abs() / want);
            }
        }
        // Measured worst: 0.05% (irradiance), 0.1% (PRT), 0.5% (triple product: its top-only
        // cells straddling the horizon hold partial visibility).
        assert!(worst < 0.01, "{mode}: white furnace violated by {worst:.4} relative");
        // The PNG is tone-mapped and not blank.
        let png = dir.join(format!("furnace-{mode}.png"));
        let out = lightloom()
            .args(["render", path.to_str().unwrap(), "-o", png.to_str().unwrap(), "--no-disk-cache", "-q"])
            .output()
            .unwrap();
        assert!(out.status.success());
        assert_eq!(image::open(&png).unwrap().into_rgb8().dimensions(), (64, 64));
    }
}

#[test]
fn eval_reports_that_rotating_the_environment_recomputes_no_projection() {
    let project = workspace().join("projects/default.ron");
    let out = lightloom()
        .args([
            "eval",
            project.to_str().unwrap(),
            "--set",
            "sky.rotation=30,0,0",
            "--report",
            "json",
            "--no-disk-cache",
        ])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let recomputed: Vec<&str> = report["recomputed"].as_array().unwrap().iter().map(|v| v.as_str().unwrap()).collect();
    // Only what the Output's mode (wavelet_pixel) and its unshadowed preview read follow the
    // rotation: the rotation itself and the rotated SH and cube map (of the whole sky and of
    // the sky without its sun, which the viewport lights apart and turns as a uniform). The
    // wavelet products are rebuilt from the rotation by the renderer; no transport, projection
    // or product stage runs, and stages the mode does not read (the Haar projection, sh_prt's
    // incident radiance) do not run.
    assert_eq!(recomputed, ["sky.rotation", "sky.rotated_radiance", "sky.sh", "sky.residual_sh"]);
    let sh = report["after_overrides"]["stages"]
        .as_array()
        .unwrap()
        .iter()
        .find(|s| s["node"] == "sky" && s["stage"] == "sh")
        .unwrap();
    assert_eq!(sh["reasons"][0], "parameter `rotation` changed");
    // A bad override is a clear error.
    let out = lightloom().args(["eval", project.to_str().unwrap(), "--set", "sky.rotation=sideways"]).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("sky.rotation=sideways"));
}

#[test]
fn replay_matches_every_golden() {
    // Every project in projects/ and tests/projects/ renders within tolerance of its golden.
    // Needs a wgpu adapter: lavapipe (mesa-vulkan-drivers) on machines without a GPU.
    let root = workspace();
    let mut projects: Vec<PathBuf> = Vec::new();
    for dir in ["projects", "tests/projects"] {
        for entry in std::fs::read_dir(root.join(dir)).unwrap() {
            let p = entry.unwrap().path();
            if p.extension().is_some_and(|e| e == "ron") {
                projects.push(p);
            }
        }
    }
    assert!(projects.len() >= 3);
    let out = lightloom().current_dir(&root).arg("replay").args(&projects).arg("--no-disk-cache").output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "replay failed:\n{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(stdout.lines().filter(|l| l.ends_with(" ok")).count(), projects.len(), "{stdout}");
}

#[test]
fn the_default_project_file_is_the_builtin_default() {
    let path = workspace().join("projects/default.ron");
    let text = std::fs::read_to_string(&path).unwrap();
    let project = lightloom_nodes::project::Project::from_ron(&text, &path).unwrap();
    assert_eq!(project, lightloom_nodes::project::default_project());
}

#[test]
fn rotating_environment_scene_and_camera_together_leaves_the_image_unchanged() {
    // Yaw everything by 90° (the cube map rotates by a face permutation): the shadowed PRT
    // image must not change beyond sampling (transport rays are fixed in world space).
    let dir = tempdir("rotation");
    write_hdr(&dir.join("sky.hdr"), 256, 128, |x, y| {
        let (u, v) = (x as f32 / 256.0, y as f32 / 128.0);
        let blob = if (u - 0.3).abs() < 0.05 && (v - 0.3).abs() < 0.06 { 40.0 } else { 0.0 };
        [0.3 + blob + u, 0.4 + blob * 0.8, 0.6 + (1.0 - v)]
    });
    let project = |mode: &str, yaw: f64, ball: [f64; 3], camera: [f64; 3]| {
        format!(
            r#"(
            version: 2,
            cameras: [(name: "c", position: ({}, {}, {}), target: (0.0, 0.3, 0.0), fov_y_deg: 40.0)],
            render: (width: 96, height: 64),
            nodes: [
                (id: "env", kind: "EnvironmentMap", params: {{
                    "source": Choice("file"), "file": Path("sky.hdr"), "rotation": Vec3(({yaw}, 0.0, 0.0)),
                }}),
                (id: "scene", kind: "Scene", params: {{
                    "objects": Objects([
                        (name: "floor", shape: Plane(size: 4.0), rotation_deg: (0.0, {yaw}, 0.0), color: (0.8, 0.8, 0.8)),
                        (name: "ball", shape: Sphere(radius: 0.5), translation: ({}, {}, {}), color: (0.9, 0.6, 0.4)),
                    ]),
                    "tessellation": Int(40),
                    "transport": Choice("sh_and_wavelets"),
                    "local_frame_depth": Int(2),
                    "transport_rays": Int(1024),
                }}),
                (id: "m", kind: "BrdfEditor", params: {{"model": Choice("phong"), "exponent": Float(6.0), "f0": Float(0.3)}}),
                (id: "out", kind: "Output", params: {{"mode": Choice("{mode}"), "background": Bool(false)}}),
            ],
            links: [
                (from: ("env", "environment"), to: ("out", "environment")),
                (from: ("scene", "scene"), to: ("out", "scene")),
                (from: ("m", "material"), to: ("out", "material")),
            ],
        )"#,
            camera[0], camera[1], camera[2], ball[0], ball[1], ball[2]
        )
    };
    let render = |name: &str, text: String| {
        let path = dir.join(format!("{name}.ron"));
        std::fs::write(&path, text).unwrap();
        let exr = dir.join(format!("{name}.exr"));
        let out = lightloom()
            .args(["render", path.to_str().unwrap(), "-o", exr.to_str().unwrap(), "--no-disk-cache", "-q"])
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        image::open(&exr).unwrap().into_rgb32f()
    };
    for mode in ["sh_prt", "wavelet_vertex"] {
        let a = render(&format!("{mode}-a"), project(mode, 0.0, [0.8, 0.5, 0.3], [0.0, 2.0, 4.0]));
        // Ry(90°): (x, y, z) -> (z, y, -x).
        let b = render(&format!("{mode}-b"), project(mode, 90.0, [0.3, 0.5, -0.8], [4.0, 2.0, 0.0]));
        let (mut sq, mut sum) = (0.0f64, 0.0f64);
        for (p, q) in a.pixels().zip(b.pixels()) {
            for c in 0..3 {
                sq += ((p[c] - q[c]) as f64).powi(2);
                sum += p[c] as f64;
            }
        }
        let n = (a.width() * a.height() * 3) as f64;
        let relative = (sq / n).sqrt() / (sum / n);
        assert!(sum > 0.0);
        assert!(
            relative < 0.03,
            "{mode}: rotating everything together changed the image by {relative:.4} relative RMSE"
        );
    }
}

#[test]
fn eval_reports_that_a_brdf_edit_recomputes_only_the_material() {
    let project = workspace().join("tests/projects/glossy.ron");
    let out = lightloom()
        .args(["eval", project.to_str().unwrap(), "--set", "gloss.exponent=30", "--report", "json", "--no-disk-cache"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let recomputed: Vec<&str> = report["recomputed"].as_array().unwrap().iter().map(|v| v.as_str().unwrap()).collect();
    // The material and its SH lobe; no lighting, transport or product stage. The mode is
    // sh_prt, so the local-frame table (wavelet modes) and the lobe plot (the editor's
    // preview) are not needed and do not run.
    assert_eq!(recomputed, ["gloss.material", "gloss.sh_lobe"]);
}

#[test]
fn each_object_is_shaded_by_its_own_material_in_every_mode() {
    // Two BRDF editors linked to the Output; the ball names `red`, the floor names nothing (so
    // takes the first linked, `green`). Under a constant sky every mode, and the reference,
    // must show a red ball on a green floor.
    let dir = tempdir("materials");
    write_hdr(&dir.join("white.hdr"), 64, 32, |_, _| [1.0, 1.0, 1.0]);
    let project = r#"(
        version: 2,
        cameras: [(name: "c", position: (0.0, 1.0, 3.0), target: (0.0, 0.3, 0.0), fov_y_deg: 40.0)],
        render: (width: 64, height: 48),
        nodes: [
            (id: "env", kind: "EnvironmentMap", params: {"source": Choice("file"), "file": Path("white.hdr")}),
            (id: "scene", kind: "Scene", params: {
                "objects": Objects([
                    (name: "floor", shape: Plane(size: 6.0), color: (1.0, 1.0, 1.0)),
                    (name: "ball", shape: Sphere(radius: 0.4), translation: (0.0, 0.4, 0.0), color: (1.0, 1.0, 1.0), material: "red"),
                ]),
                "transport": Choice("sh_and_wavelets"),
                "local_frame_depth": Int(2),
            }),
            (id: "green", kind: "BrdfEditor", params: {"albedo": Color((0.1, 0.8, 0.1))}),
            (id: "red", kind: "BrdfEditor", params: {"albedo": Color((0.8, 0.1, 0.1))}),
            (id: "out", kind: "Output", params: {"background": Bool(false), "reference_samples": Int(16)}),
        ],
        links: [
            (from: ("env", "environment"), to: ("out", "environment")),
            (from: ("scene", "scene"), to: ("out", "scene")),
            (from: ("green", "material"), to: ("out", "material")),
            (from: ("red", "material"), to: ("out", "material")),
        ],
    )"#;
    let path = dir.join("materials.ron");
    std::fs::write(&path, project).unwrap();
    let views = [
        ("sh_irradiance", "approximation"),
        ("sh_prt", "approximation"),
        ("wavelet_vertex", "approximation"),
        ("sh_irradiance", "reference"),
    ];
    for (mode, view) in views {
        let exr = dir.join(format!("{mode}-{view}.exr"));
        let out = lightloom()
            .args(["render", path.to_str().unwrap(), "-o", exr.to_str().unwrap(), "--no-disk-cache", "-q"])
            .args(["--set", &format!("out.mode={mode}"), "--set", &format!("out.view={view}")])
            .output()
            .unwrap();
        assert!(out.status.success(), "{mode}/{view}: {}", String::from_utf8_lossy(&out.stderr));
        let image = image::open(&exr).unwrap().into_rgb32f();
        // The ball fills the centre; the floor fills the bottom rows.
        let ball = image.get_pixel(32, 20);
        let floor = image.get_pixel(32, 46);
        assert!(ball[0] > 3.0 * ball[1], "{mode}/{view}: ball {ball:?} is not red");
        assert!(floor[1] > 3.0 * floor[0], "{mode}/{view}: floor {floor:?} is not green");
    }
}

#[test]
fn every_relighting_mode_computes_the_transport_it_reads() {
    // No transport switch to keep in step with the mode: each mode pulls what it reads, and
    // the report says why the rest did not run.
    let project = workspace().join("projects/default.ron");
    let dir = tempdir("mode-transport");
    let cheap = ["--set", "scene.tessellation=12", "--set", "scene.visibility_texture_size=16"];
    for (mode, transport, unneeded) in [
        ("sh_prt", "scene.transport_sh", "scene.transport_local"),
        ("wavelet_vertex", "scene.transport_local", "scene.transport_sh"),
        ("wavelet_pixel", "scene.transport_texels", "scene.transport_sh"),
    ] {
        let png = dir.join(format!("{mode}.png"));
        let out = lightloom()
            .args(["render", project.to_str().unwrap(), "-o", png.to_str().unwrap(), "-q", "--no-disk-cache"])
            .args(["--set", &format!("output.mode={mode}"), "--width", "32", "--height", "32"])
            .args(cheap)
            .output()
            .unwrap();
        assert!(out.status.success(), "{mode}: {}", String::from_utf8_lossy(&out.stderr));
        assert!(png.exists(), "{mode}");
        let out = lightloom()
            .args(["eval", project.to_str().unwrap(), "--report", "json", "--no-disk-cache"])
            .args(["--set", &format!("output.mode={mode}")])
            .args(cheap)
            .output()
            .unwrap();
        assert!(out.status.success(), "{mode}: {}", String::from_utf8_lossy(&out.stderr));
        let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        let status = |name: &str| {
            let stage = report["after_overrides"]["stages"]
                .as_array()
                .unwrap()
                .iter()
                .find(|s| format!("{}.{}", s["node"].as_str().unwrap(), s["stage"].as_str().unwrap()) == name)
                .unwrap_or_else(|| panic!("{mode}: no {name} in the report"))
                .clone();
            (stage["status"].as_str().unwrap().to_string(), stage["reasons"].clone())
        };
        let (ran, _) = status(transport);
        assert!(["computed", "memory_hit"].contains(&ran.as_str()), "{mode}: {transport} {ran}");
        let (not_run, reasons) = status(unneeded);
        assert_eq!(not_run, "not_needed", "{mode}: {unneeded}");
        assert!(reasons[0].as_str().unwrap().contains(&format!("mode {mode}")), "{mode}: {reasons}");
    }
}

/// The fog shader (GPU) against the same model on the CPU (`single_scattering::shade`) and
/// against the independent single-scattering reference (`shade_reference`: eq. 3.5 integrated
/// along every ray, eq. 3.22 over the hemisphere): street lamps over a wet (Phong) street.
#[test]
fn fog_render_matches_the_cpu_model_and_the_numerical_reference() {
    use lightloom_nodes::reference::PinholeCamera;
    use lightloom_nodes::single_scattering::{
        AirlightQuery, FTable, FogShadingPoint, FogTables, Interpolation, Phase, PhongGTables, airlight,
        airlight_reference, shade, shade_reference,
    };
    use std::f64::consts::PI;
    let dir = std::env::temp_dir().join(format!("lightloom-fog-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let exr = dir.join("fog.exr");
    let project = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/projects/fog_lamps.ron");
    let (width, height) = (160usize, 90usize);
    let out = lightloom()
        .args(["render", "--no-disk-cache", "--width", "160", "--height", "90", "-o"])
        .arg(&exr)
        .arg(&project)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let gpu = image::open(&exr).unwrap().to_rgb32f();

    // The same scene on the CPU: tables at the project's resolution (F 128², G 32²).
    let f = [FTable::new(0, 128)];
    let g = PhongGTables::new(32);
    let tables = FogTables { f: &f, g: &g };
    let beta = 0.04;
    let lights = [(glam::DVec3::new(-3.0, 4.0, -8.0), 400.0), (glam::DVec3::new(4.0, 4.0, -16.0), 400.0)];
    let camera = PinholeCamera {
        position: glam::DVec3::new(0.0, 1.7, 0.0),
        target: glam::DVec3::new(0.0, 0.8, -10.0),
        fov_y_deg: 50.0,
    };
    // The `asphalt` material: albedo 0.5 on a 0.8 grey plane; Phong exponent 24, f0 0.3.
    let (exponent, weight) = (24.0, 0.3);
    let point_at = |d: glam::DVec3| {
        let t = -camera.position.y / d.y;
        let p = camera.position + d * t;
        (p.x.abs() < 39.0 && p.z.abs() < 39.0 && t < 60.0).then(|| FogShadingPoint {
            viewer: camera.position,
            point: p,
            normal: glam::DVec3::Y,
            k_d: 0.5 * 0.8 / PI,
            k_s: weight * (exponent + 2.0) / (2.0 * PI) * (-d.y),
            exponent,
        })
    };
    let sky = |d: glam::DVec3, reference: bool| -> f64 {
        lights
            .iter()
            .map(|(pos, i0)| {
                let to = *pos - camera.position;
                let gamma = d.dot(to.normalize()).clamp(-1.0, 1.0).acos();
                let q = AirlightQuery { beta, d_sv: to.length(), d_vp: f64::INFINITY, gamma, i0: *i0 };
                if reference {
                    airlight_reference(&q, &Phase::isotropic())
                } else {
                    airlight(&q, &Phase::isotropic(), &f, Interpolation::Bilinear)
                }
            })
            .sum()
    };
    // Relative RMSE of the GPU image against a CPU evaluation over pixels (every `stride`-th).
    let compare = |stride: usize, reference: bool| {
        let (mut err2, mut ref2, mut compared) = (0.0, 0.0, 0);
        for y in (0..height).step_by(stride) {
            for x in (0..width).step_by(stride) {
                let d = camera.ray(x as f64 + 0.5, y as f64 + 0.5, width, height);
                let cpu = if d.y < -1e-3 {
                    // Skip the plane's far edge and the horizon (sub-pixel geometry).
                    let Some(point) = point_at(d) else { continue };
                    if reference {
                        shade_reference(&point, &lights, beta)
                    } else {
                        shade(&point, &lights, beta, &tables)
                    }
                } else {
                    sky(d, reference)
                };
                let gpu = f64::from(gpu.get_pixel(x as u32, y as u32)[1]);
                err2 += (gpu - cpu).powi(2);
                ref2 += cpu * cpu;
                compared += 1;
            }
        }
        ((err2 / ref2).sqrt(), compared)
    };
    let (model_error, compared) = compare(1, false);
    assert!(compared > width * height * 8 / 10, "{compared} pixels compared");
    let (reference_error, sampled) = compare(6, true);
    eprintln!(
        "GPU fog: relative RMSE {:.3}% against the CPU model ({compared} pixels), {:.3}% against the numerical \
         reference ({sampled} pixels)",
        model_error * 100.0,
        reference_error * 100.0
    );
    assert!(model_error < 0.005, "GPU fog vs CPU model: relative RMSE {:.2}%", model_error * 100.0);
    assert!(reference_error < 0.01, "GPU fog vs numerical reference: relative RMSE {:.2}%", reference_error * 100.0);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A render size within the project format's range but beyond what the GPU memory budget
/// allows is a clear error before anything is allocated (10000² once ran out of memory).
#[test]
fn render_sizes_beyond_the_gpu_budget_are_refused() {
    let out_png = tempdir("huge-render").join("x.png");
    let project = workspace().join("projects/default.ron");
    let out = lightloom()
        .args(["render"])
        .arg(&project)
        .args(["-o", out_png.to_str().unwrap(), "--width", "10000", "--height", "10000", "--no-disk-cache"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("render size 10000x10000 needs about") && !stderr.contains("panicked"), "{stderr}");
    assert!(!out_png.exists());
}

/// A camera looking straight down once rendered a uniform image (no up direction); cameras
/// at absurd coordinates are refused with the camera's name.
#[test]
fn a_camera_looking_straight_down_sees_the_scene_and_absurd_cameras_are_refused() {
    let dir = tempdir("straight-down");
    let default = std::fs::read_to_string(workspace().join("projects/default.ron")).unwrap();
    let down = default.replace("position: (0.0, 2.2, 5.5)", "position: (0.0, 6.0, 0.0)");
    assert_ne!(down, default, "the default camera moved; update this test");
    let project = dir.join("down.ron");
    std::fs::write(&project, down).unwrap();
    let png = dir.join("down.png");
    let out = lightloom()
        .arg("render")
        .arg(&project)
        .args(["-o", png.to_str().unwrap(), "--width", "96", "--height", "64", "--no-disk-cache"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let image = image::open(&png).unwrap().into_rgb8();
    let luma: Vec<f64> = image.pixels().map(|p| p.0.iter().map(|c| *c as f64).sum::<f64>() / 3.0).collect();
    let mean = luma.iter().sum::<f64>() / luma.len() as f64;
    let spread = (luma.iter().map(|l| (l - mean).powi(2)).sum::<f64>() / luma.len() as f64).sqrt();
    assert!(spread > 10.0, "a uniform image (std dev {spread:.2} of 255) from a camera looking down");
    let far = default.replace("position: (0.0, 2.2, 5.5)", "position: (0.0, 2.2, 1e30)");
    std::fs::write(&project, far).unwrap();
    let out = lightloom().arg("info").arg(&project).output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("camera 0 (`main`): needs coordinates within"), "{stderr}");
}

/// `info` says "valid" only when every file the project names loads: a broken glTF or
/// environment map is reported with its node and file, exit code 2.
#[test]
fn info_loads_every_asset_before_calling_a_project_valid() {
    let dir = tempdir("info-assets");
    let gltf = assets().join("gltf/assimp-glTF2/IndexOutOfRange/IndexOutOfRange.gltf");
    let truncated_hdr = dir.join("truncated.hdr");
    let hdr = std::fs::read(assets().join("envmaps/courtyard.hdr")).unwrap();
    std::fs::write(&truncated_hdr, &hdr[..hdr.len() / 3]).unwrap();
    let project = |scene_file: &Path, sky_file: &Path| {
        format!(
            r#"(version: 4, nodes: [
                (id: "scene", kind: "Scene", params: {{"objects": Objects([(name: "model", shape: Gltf(file: "{}"))])}}),
                (id: "sky", kind: "EnvironmentMap", params: {{"source": Choice("file"), "file": Path("{}")}}),
                (id: "out", kind: "Output"),
            ], links: [
                (from: ("scene", "scene"), to: ("out", "scene")),
                (from: ("sky", "environment"), to: ("out", "environment")),
            ])"#,
            scene_file.display(),
            sky_file.display()
        )
    };
    let good_gltf = assets().join("gltf/assimp-glTF2/BoxTextured-glTF/BoxTextured.gltf");
    let good_hdr = assets().join("envmaps/courtyard.hdr");
    for (scene_file, sky_file, needle) in [
        (&gltf, &good_hdr, "IndexOutOfRange.gltf"),
        (&good_gltf, &truncated_hdr, "truncated.hdr"),
        (&good_gltf, &good_hdr, ""),
    ] {
        let path = dir.join("p.ron");
        std::fs::write(&path, project(scene_file, sky_file)).unwrap();
        let out = lightloom().arg("info").arg(&path).env("XDG_CACHE_HOME", dir.join("cache")).output().unwrap();
        let (stdout, stderr) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
        if needle.is_empty() {
            assert!(out.status.success() && stdout.contains("valid: every asset loads"), "{stdout}{stderr}");
        } else {
            assert_eq!(out.status.code(), Some(2), "{needle}: {stdout}{stderr}");
            assert!(stderr.contains(needle) && !stdout.contains("valid"), "{needle}: {stderr}");
        }
    }
}

/// A node that feeds no output (here an RSL decomposer without its environment) does not
/// block a render: the CLI renders what the editor shows and warns about the node.
#[test]
fn an_unlinked_node_with_a_missing_input_is_a_warning_not_an_error() {
    let dir = tempdir("unlinked");
    let project = dir.join("p.ron");
    std::fs::write(
        &project,
        r#"(version: 3, nodes: [(id: "scene", kind: "Scene"), (id: "rsl", kind: "RslDecomposer"), (id: "out", kind: "Output")],
            links: [(from: ("scene", "scene"), to: ("out", "scene"))])"#,
    )
    .unwrap();
    let png = dir.join("p.png");
    let out = lightloom()
        .arg("render")
        .arg(&project)
        .args(["-o", png.to_str().unwrap(), "--width", "32", "--height", "24", "--no-disk-cache"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("warning:") && stderr.contains("node `rsl` port `environment`"), "{stderr}");
    assert!(png.exists());
}

/// The samples (File → Open sample) load with their assets, evaluate without errors and
/// render a lit picture through the CLI (small, with few transport rays, to stay quick).
#[test]
fn every_sample_renders() {
    let dir = tempdir("samples");
    let samples: Vec<PathBuf> = std::fs::read_dir(workspace().join("projects/samples"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "ron"))
        .collect();
    assert!(samples.len() >= 3, "{samples:?}");
    for sample in samples {
        let text = std::fs::read_to_string(&sample).unwrap();
        let project = lightloom_nodes::project::Project::from_ron(&text, &sample).unwrap();
        let scene = project.nodes.iter().find(|n| n.kind == "Scene").unwrap().id.clone();
        let out = dir.join(sample.with_extension("png").file_name().unwrap());
        let result = lightloom()
            .args(["render", sample.to_str().unwrap(), "-o", out.to_str().unwrap(), "--width", "160", "--height", "90"])
            .args(["--no-disk-cache", "--quiet", "--set", &format!("{scene}.transport_rays=32")])
            .output()
            .unwrap();
        assert!(result.status.success(), "{}: {}", sample.display(), String::from_utf8_lossy(&result.stderr));
        let image = image::open(&out).unwrap().to_rgb8();
        let mean = image.pixels().map(|p| p.0.iter().map(|&c| f64::from(c)).sum::<f64>()).sum::<f64>()
            / (3 * image.width() * image.height()) as f64;
        assert!(mean > 20.0 && mean < 250.0, "{}: mean sRGB {mean:.1}", sample.display());
    }
}
