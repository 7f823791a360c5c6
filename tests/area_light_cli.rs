//! The painted area light through the real binary: the sample renders, and its near-field
//! relighting agrees with the Monte Carlo reference (which samples the painted texture on the
//! turned rectangle with shadow rays, independently of the wavelet path).

use std::path::{Path, PathBuf};
use std::process::Command;

fn lightloom() -> Command {
    Command::new(env!("CARGO_BIN_EXE_lightloom"))
}

/// The area-light sample without its environment: everything the image shows comes from the
/// painted panel.
fn panel_only_project(dir: &Path) -> PathBuf {
    let sample = Path::new(env!("CARGO_MANIFEST_DIR")).join("../projects/samples/area_light.ron");
    let text = std::fs::read_to_string(sample).unwrap();
    let start = text.find("        (\n            id: \"sky\"").expect("the sample has a sky node");
    let end = text.find("        (\n            id: \"scene\"").unwrap();
    let text = format!("{}{}", &text[..start], &text[end..])
        .replace("        (from: (\"sky\", \"environment\"), to: (\"out\", \"environment\")),\n", "");
    let path = dir.join("panel_only.ron");
    std::fs::write(&path, text).unwrap();
    path
}

/// Relative RMSE over surface pixels of the unshadowed-environment mode (here: the area light
/// alone) against the reference, and the reference's own noise.
fn accuracy(project: &Path, sets: &[&str]) -> (f64, f64) {
    let sets = [&["out.mode=sh_irradiance", "scene.tessellation=128"][..], sets].concat();
    sh_irradiance_error(project, 1024, (128, 72), &sets)
}

/// `lightloom accuracy` of `project` at `samples` per pixel and `width × height` with `sets`
/// applied: the `sh_irradiance` row's relative RMSE, and the reference's noise.
fn sh_irradiance_error(project: &Path, samples: usize, (width, height): (u32, u32), sets: &[&str]) -> (f64, f64) {
    let mut command = lightloom();
    command.args(["accuracy", project.to_str().unwrap(), "--json", "--samples", &samples.to_string()]);
    command.args(["--width", &width.to_string(), "--height", &height.to_string()]);
    command.args(["--bands", "2", "--wavelets", "--adaptive", "--no-disk-cache"]);
    for set in sets {
        command.args(["--set", set]);
    }
    let out = command.output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let rows = report["rows"].as_array().unwrap();
    let row = rows.iter().find(|r| r["mode"].as_str().unwrap().starts_with("sh_irradiance")).unwrap();
    (row["relative_rmse"].as_f64().unwrap(), report["reference_noise"]["relative_rmse"].as_f64().unwrap())
}

/// Per setting, the error against the reference: the defaults (2% of the texture, 30% of each
/// top face) within 12%; keeping everything no worse than the defaults by more than the
/// noise; and a face of 2, whose Haar products miss the light's grazing reach, no worse than 4
/// by more than the noise either, since the part of the light beyond the face is added in
/// closed form (it was 1.5× worse before).
#[test]
fn painted_area_light_matches_the_monte_carlo_reference() {
    let dir = std::env::temp_dir().join(format!("lightloom-area-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let project = panel_only_project(&dir);
    let (defaults, noise) = accuracy(&project, &[]);
    let (full, _) = accuracy(&project, &["panel.source_keep=100", "panel.target_keep=100"]);
    let (narrow, _) = accuracy(&project, &["panel.face_size=2"]);
    eprintln!("relative RMSE: defaults {defaults:.4}, keep all {full:.4}, face 2 {narrow:.4}; noise {noise:.4}");
    assert!(noise < 0.05, "the reference is too noisy to judge: {noise}");
    assert!(defaults < 0.12, "defaults: {defaults}");
    assert!(full < defaults + noise, "keeping everything: {full} against {defaults}");
    assert!(narrow < defaults + noise, "face 2: {narrow} against {defaults} at face 4");
}

/// Sun 2008 §4.9 through the binary: the panel over a glossy (Phong) floor, sphere and box, its
/// highlights reflected toward the render camera, against the reference (which evaluates the
/// full BRDF for each light sample). The same scene in Lambert sets the diffuse error.
#[test]
fn glossy_highlights_match_the_monte_carlo_reference() {
    let dir = std::env::temp_dir().join(format!("lightloom-area-gloss-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let project = panel_only_project(&dir);
    let text = std::fs::read_to_string(&project).unwrap();
    let gloss = "        (\n            id: \"gloss\",\n            kind: \"BrdfEditor\",\n            position: (0.0, 600.0),\n            \
                 params: {\"model\": Choice(\"phong\"), \"exponent\": Float(30.0), \"f0\": Float(0.3), \"albedo\": Color((0.5, 0.5, 0.5))},\n        ),\n";
    let text = text.replacen("        (id: \"out\"", &format!("{gloss}        (id: \"out\""), 1).replacen(
        "        (from: (\"panel\", \"area_light\"), to: (\"out\", \"area_lights\")),\n",
        "        (from: (\"panel\", \"area_light\"), to: (\"out\", \"area_lights\")),\n        (from: (\"gloss\", \"material\"), to: (\"out\", \"material\")),\n",
        1,
    );
    assert!(text.contains("(\"gloss\", \"material\")"), "the material is linked");
    let glossy = dir.join("glossy.ron");
    std::fs::write(&glossy, text).unwrap();
    let (with_highlights, noise) = accuracy(&glossy, &[]);
    let (lambert, _) = accuracy(&glossy, &["gloss.model=lambert"]);
    eprintln!("relative RMSE: glossy {with_highlights:.4}, the same in Lambert {lambert:.4}; noise {noise:.4}");
    assert!(noise < 0.05, "the reference is too noisy to judge: {noise}");
    assert!(with_highlights < 0.15, "glossy: {with_highlights}");
}

/// A 2 × 2 m textured panel 2.5 m up over a sphere (r 0.6) on a 20 m floor, without an
/// environment: the floor's vertices (1.25 m apart: a plane takes a quarter of the tessellation's
/// segments, 16 at 64) cannot hold the
/// sphere's shadow, which per-vertex shading smears and displaces; with a visibility texture
/// on the floor the lights are shaded per texel there, and the shadow sits under the sphere.
fn sphere_on_a_floor(dir: &Path, texture: bool) -> PathBuf {
    let floor_texture = if texture { ", visibility_texture: true" } else { "" };
    let text = format!(
        r#"(
    version: 4,
    name: "area light over a sphere on a wide floor",
    cameras: [(name: "main", position: (0.0, 3.0, 6.0), target: (0.0, 0.5, 0.0), fov_y_deg: 45.0)],
    nodes: [
        (id: "scene", kind: "Scene", params: {{
            "objects": Objects([
                (name: "floor", shape: Plane(size: 20.0){floor_texture}),
                (name: "sphere", shape: Sphere(radius: 0.6), translation: (0.7, 0.6, -0.3)),
            ]),
            "tessellation": Int(64),
            "visibility_texture_size": Choice("256"),
        }}),
        (id: "panel", kind: "AreaLightPainter", params: {{
            "paint": Paint([
                Fill(colour: (1.0, 1.0, 1.0), intensity: 1.0),
                Stroke(points: [(0.1, 0.3), (0.5, 0.35), (0.9, 0.3)], radius: 0.12, hardness: 0.6, colour: (1.0, 0.8, 0.5), intensity: 3.0, blend: Mix),
            ]),
            "position": Vec3((0.0, 2.5, 0.0)),
            "width": Float(2.0),
            "depth": Float(2.0),
            "intensity": Float(1.0),
        }}),
        (id: "out", kind: "Output", params: {{"mode": Choice("sh_irradiance"), "background": Bool(false)}}),
    ],
    links: [
        (from: ("scene", "scene"), to: ("out", "scene")),
        (from: ("panel", "area_light"), to: ("out", "area_lights")),
    ],
)"#
    );
    let path = dir.join(if texture { "floor_texture.ron" } else { "floor_vertices.ron" });
    std::fs::write(&path, text).unwrap();
    path
}

/// The relative RMSE of `project` against its reference at 320 × 180 and 512 samples, and the
/// reference's noise.
fn accuracy_at_tessellation(project: &Path) -> (f64, f64) {
    sh_irradiance_error(project, 512, (320, 180), &[])
}

/// Per texel on a visibility-textured floor, the area light's shadow and falloff follow the
/// reference within 5% once its noise is taken out; per vertex on the same floor it is over
/// twice as far.
#[test]
fn a_shadow_on_a_coarse_floor_follows_the_reference_per_texel() {
    let dir = std::env::temp_dir().join(format!("lightloom-area-floor-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (texels, noise) = accuracy_at_tessellation(&sphere_on_a_floor(&dir, true));
    let (vertices, _) = accuracy_at_tessellation(&sphere_on_a_floor(&dir, false));
    eprintln!("relative RMSE: per texel {texels:.4}, per vertex {vertices:.4}; noise {noise:.4}");
    assert!(noise < 0.05, "the reference is too noisy to judge: {noise}");
    let bias = (texels * texels - noise * noise).max(0.0).sqrt();
    assert!(bias < 0.05, "per texel: {texels} with the reference's noise {noise}");
    assert!(vertices > 2.0 * texels, "per vertex: {vertices} against {texels} per texel");
}

/// Relative RMSE of `ours` against `truth` over the pixels either lights (the camera does not
/// see the panel; beyond the floor both are black).
fn relative_rmse_over_surfaces(ours: &image::Rgb32FImage, truth: &image::Rgb32FImage, least: usize) -> f64 {
    let (mut squared, mut sum, mut count) = (0.0, 0.0, 0usize);
    for (a, b) in ours.pixels().zip(truth.pixels()) {
        if a.0.iter().chain(&b.0).sum::<f32>() > 0.0 {
            for c in 0..3 {
                squared += f64::from(a.0[c] - b.0[c]).powi(2);
                sum += f64::from(b.0[c]);
            }
            count += 3;
        }
    }
    assert!(count > 3 * least, "only {} surface pixels", count / 3);
    (squared / count as f64).sqrt() / (sum / count as f64)
}

/// `project` rendered at 320 × 180 from `camera` with `sets` applied, as linear radiance, and
/// what the command printed.
fn render_exr(project: &Path, exr: &Path, camera: &str, sets: &[&str]) -> (image::Rgb32FImage, String) {
    let mut command = lightloom();
    command.args(["render", project.to_str().unwrap(), "-o", exr.to_str().unwrap(), "--camera", camera]);
    command.args(["--width", "320", "--height", "180", "--no-disk-cache"]);
    for set in sets {
        command.args(["--set", set]);
    }
    let out = command.output().unwrap();
    let log = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{log}");
    (image::open(exr).unwrap().into_rgb32f(), log)
}

/// Against Mitsuba 3 (tests/projects/mitsuba/area_sphere_floor, made by
/// tools/mitsuba/area_light.py at 4096 samples): the painted panel's light and the shadow of
/// the sphere (off the panel's axis, so a flipped or transposed texel layout would misplace
/// it) on the wide floor, shaded per texel there, within 6%; per vertex on the same floor, far
/// off. From the "far" camera, the floor 5–10 m away, beyond the reach of the light's top face
/// (lit there only by the part beyond the face), within 6% too.
#[test]
fn the_area_light_matches_mitsuba_on_a_wide_floor() {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/projects/mitsuba/area_sphere_floor");
    let truth = image::open(scene.join("mitsuba.exr")).unwrap().into_rgb32f();
    let dir = std::env::temp_dir().join(format!("lightloom-area-mitsuba-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let render = |project: &Path, name: &str, camera: &str| render_exr(project, &dir.join(name), camera, &[]);
    let (image, log) = render(&scene.join("project.ron"), "texels.exr", "main");
    let texels = relative_rmse_over_surfaces(&image, &truth, 30_000);
    assert!(!log.contains("coarse"), "a floor shaded per texel is not called coarse: {log}");
    let far_truth = image::open(scene.join("mitsuba_far.exr")).unwrap().into_rgb32f();
    let far = relative_rmse_over_surfaces(&render(&scene.join("project.ron"), "far.exr", "far").0, &far_truth, 20_000);
    // The same floor without its visibility texture.
    let text = std::fs::read_to_string(scene.join("project.ron")).unwrap();
    assert!(text.contains(", visibility_texture: true"));
    std::fs::write(dir.join("project.ron"), text.replace(", visibility_texture: true", "")).unwrap();
    std::fs::copy(scene.join("panel.png"), dir.join("panel.png")).unwrap();
    let (image, log) = render(&dir.join("project.ron"), "vertices.exr", "main");
    let vertices = relative_rmse_over_surfaces(&image, &truth, 30_000);
    // The user is told why, and what to turn on.
    assert!(
        log.contains("`floor` (triangle edges 1.42 m on average): coarse") && log.contains("visibility texture"),
        "{log}"
    );
    eprintln!(
        "relative RMSE against Mitsuba: per texel {texels:.4}, per vertex {vertices:.4}; beyond the face {far:.4}"
    );
    assert!(texels < 0.06, "per texel: {texels}");
    assert!(far < 0.06, "beyond the top face: {far}");
    assert!(vertices > 3.0 * texels, "per vertex: {vertices} against {texels} per texel");
}

/// Against Mitsuba 3 (tests/projects/mitsuba/area_tilted, made by tools/mitsuba/area_light.py
/// area_tilted at 4096 samples): a 2 × 1 m panel turned −90° and tilted 50°, lighting a sphere,
/// a box and the floor from the side (the sphere's shadow falls long across the floor), within
/// 5% (the issue's goal is 6%). The same panel level, or tilted the other way, is far from the truth: the tilt is what
/// puts the light where Mitsuba has it.
#[test]
fn a_tilted_area_light_matches_mitsuba() {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/projects/mitsuba/area_tilted");
    let truth = image::open(scene.join("mitsuba.exr")).unwrap().into_rgb32f();
    let dir = std::env::temp_dir().join(format!("lightloom-area-tilted-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let project = scene.join("project.ron");
    let error = |name: &str, sets: &[&str]| {
        relative_rmse_over_surfaces(&render_exr(&project, &dir.join(name), "main", sets).0, &truth, 20_000)
    };
    let tilted = error("tilted.exr", &[]);
    let level = error("level.exr", &["panel.tilt=0"]);
    let mirrored = error("mirrored.exr", &["panel.tilt=-50"]);
    eprintln!(
        "relative RMSE against Mitsuba: tilted {tilted:.4}; level {level:.4}, tilted the other way {mirrored:.4}"
    );
    // 4.3% (4.8%, and banded, with one ray per top-face cell on the silhouettes too).
    assert!(tilted < 0.05, "tilted: {tilted}");
    assert!(level > 4.0 * tilted && mirrored > 4.0 * tilted, "level {level}, mirrored {mirrored}, tilted {tilted}");
}
