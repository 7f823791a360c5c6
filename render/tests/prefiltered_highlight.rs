//! The SH modes' environment highlight against the Monte Carlo reference: a GGX ball filling
//! the view, a bright window behind it. The per-vertex Phong lobe to a few SH bands rings the
//! window across the ball; once the GGX-prefiltered light is bound, each pixel draws the
//! material's true lobe from it (its albedo at the view, the light where its rays go), occluded
//! by the vertices' SH visibility through the lobe over the unoccluded one (1 on a convex ball,
//! whatever the bands ring), and the picture must come much nearer the reference.

use lightloom_nodes::engine::spec::ParamValue;
use lightloom_nodes::engine::{CancelToken, Engine, Graph};
use lightloom_nodes::frame::{FrameInputs, frame_request};
use lightloom_nodes::project::Project;
use lightloom_nodes::reference::{self, PinholeCamera};
use lightloom_render::{CameraView, GpuContext, ViewportRenderer};
use std::path::Path;

const SIZE: (u32, u32) = (96, 72);

/// A soft light behind the camera, 35° up (radiance 10 at its centre, falling off as a Gaussian of
/// 15°), over a dim sky (0.15) and a darker ground (0.05): the ball's front mirrors it.
fn soft_light_environment(dir: &Path) -> std::path::PathBuf {
    let (width, height) = (512u32, 256u32);
    let centre = glam::DVec3::new(0.0, 35f64.to_radians().sin(), 35f64.to_radians().cos());
    let texels: Vec<f32> = (0..width * height)
        .flat_map(|i| {
            let (x, y) = (i % width, i / width);
            let d = lightloom_nodes::cubemap::equirect_uv_to_dir(
                (f64::from(x) + 0.5) / f64::from(width),
                (f64::from(y) + 0.5) / f64::from(height),
            );
            let angle = d.dot(centre).clamp(-1.0, 1.0).acos() / 15f64.to_radians();
            let radiance = 10.0 * (-angle * angle).exp() + if d.y > 0.0 { 0.15 } else { 0.05 };
            [radiance as f32; 3]
        })
        .collect();
    let path = dir.join("soft.exr");
    image::Rgb32FImage::from_raw(width, height, texels).unwrap().save(&path).unwrap();
    path
}

fn project(dir: &Path, mode: &str) -> Graph {
    let text = format!(
        r#"(
            version: 4,
            name: "SH highlight",
            nodes: [
                (id: "sky", kind: "EnvironmentMap", position: (0.0, 0.0),
                 params: {{"source": Choice("file"), "file": Path("{}"), "sh_bands": Int(6)}}),
                (id: "scene", kind: "Scene", position: (0.0, 0.0),
                 params: {{"objects": Objects([
                     (name: "ball", shape: Sphere(radius: 0.5), translation: (0.0, 0.5, 0.0), color: (1.0, 1.0, 1.0)),
                 ]), "tessellation": Int(64)}}),
                (id: "metal", kind: "BrdfEditor", position: (0.0, 0.0),
                 params: {{"model": Choice("ggx"), "roughness": Float(0.4), "f0": Float(0.9), "albedo": Color((0.05, 0.05, 0.05))}}),
                (id: "output", kind: "Output", position: (0.0, 0.0),
                 params: {{"mode": Choice("{mode}"), "reference_samples": Int(64), "background": Bool(false), "sun": Choice("in_environment")}}),
            ],
            links: [
                (from: ("sky", "environment"), to: ("output", "environment")),
                (from: ("scene", "scene"), to: ("output", "scene")),
                (from: ("metal", "material"), to: ("output", "material")),
            ],
        )"#,
        soft_light_environment(dir).display()
    );
    let path = Path::new("highlight.ron");
    Project::from_ron(&text, path).unwrap().graph(path).unwrap()
}

fn frame(engine: &Engine, graph: &Graph) -> FrameInputs {
    let request = frame_request(graph, "output", true);
    let eval = engine.evaluate_request(graph, &request, &CancelToken::default(), None, &|_, _| {});
    assert!(eval.report.failed().is_empty(), "{:?}", eval.report.failed());
    FrameInputs::gather(&eval, graph, "output").unwrap()
}

/// Each 8 × 8 block's mean.
fn blocks(pixels: &[[f32; 3]]) -> Vec<[f32; 3]> {
    let (w, h) = (SIZE.0 as usize / 8, SIZE.1 as usize / 8);
    (0..w * h)
        .map(|i| {
            let (bx, by) = (i % w, i / w);
            let mut sum = [0.0f32; 3];
            for y in 0..8 {
                for (k, c) in pixels[(by * 8 + y) * SIZE.0 as usize + bx * 8..][..8].iter().flatten().enumerate() {
                    sum[k % 3] += c / 64.0;
                }
            }
            sum
        })
        .collect()
}

#[test]
fn the_sh_modes_draw_the_true_lobe_of_the_prefiltered_light() {
    let gpu = GpuContext::headless().expect("a wgpu device (lavapipe on machines without a GPU)");
    let mut renderer = ViewportRenderer::new(&gpu);
    let engine = Engine::in_memory();
    let dir = tempfile::tempdir().unwrap();
    let (position, target) = ([0.0, 0.75, 1.5], [0.0, 0.5, 0.0]);
    let pinhole = PinholeCamera { position: position.into(), target: target.into(), fov_y_deg: 45.0 };
    let view = CameraView {
        position: glam::DVec3::from(position).as_vec3(),
        target: glam::DVec3::from(target).as_vec3(),
        fov_y_deg: 45.0,
    };
    let size = (SIZE.0 as usize, SIZE.1 as usize);
    let mut truths: Vec<(f64, reference::HdrImage)> = Vec::new();
    // Roughness 0.4 and 0.7 (the Phong lobe's band-0 factor, (s + 2)/(s + 1), grows with it:
    // the prefiltered light is a mean, the albedo E's).
    for (mode, roughness) in [("sh_prt", 0.4), ("sh_adaptive", 0.4), ("sh_prt", 0.7)] {
        let mut graph = project(dir.path(), mode);
        graph.set_param("output", "mode", ParamValue::Choice(mode.into())).unwrap();
        graph.set_param("metal", "roughness", ParamValue::Float(roughness)).unwrap();
        let mode = format!("{mode}, roughness {roughness}");
        let prefiltered = frame(&engine, &graph);
        let highlight = prefiltered.normal_maps.vertex_highlight.as_ref().expect("the SH modes' highlight light");
        assert!(highlight.cube.is_some(), "{mode}: the prefiltered light is requested with the frame");
        if !truths.iter().any(|(r, _)| *r == roughness) {
            let image = prefiltered.render_reference(&pinhole, size, 1, &CancelToken::default(), &|_| {}).unwrap();
            truths.push((roughness, image));
        }
        let truth = &truths.iter().find(|(r, _)| *r == roughness).unwrap().1;
        // The frame as it shows before the prefiltered light is ready: the Phong lobe in SH.
        let mut phong = prefiltered.clone();
        phong.normal_maps.vertex_highlight.as_mut().unwrap().cube = None;
        let mut draw = |f: &FrameInputs| -> Vec<[f32; 3]> {
            let captured = renderer.render_offscreen(&gpu, f, &view, SIZE.0, SIZE.1).unwrap();
            captured.hdr.iter().map(|p| [p[0], p[1], p[2]]).collect()
        };
        let (now, before) = (draw(&prefiltered), draw(&phong));
        if let Ok(dump) = std::env::var("HIGHLIGHT_DUMP") {
            for (name, p) in [("truth", &truth.pixels), ("now", &now), ("before", &before)] {
                let flat: Vec<f32> = p.iter().flatten().copied().collect();
                image::Rgb32FImage::from_raw(SIZE.0, SIZE.1, flat)
                    .unwrap()
                    .save(Path::new(&dump).join(format!("{mode}_{name}.exr")))
                    .unwrap();
            }
        }
        // Blocks wholly on the ball.
        let covered: Vec<bool> =
            blocks(&truth.surface_mask().iter().map(|&c| [f32::from(u8::from(c)); 3]).collect::<Vec<_>>())
                .iter()
                .map(|b| b[0] >= 1.0)
                .collect();
        let error = |p: &[[f32; 3]]| {
            reference::compare(&blocks(p), &blocks(&truth.pixels), Some(&covered)).unwrap().relative_rmse
        };
        let mean = |p: &[[f32; 3]]| p.iter().map(|c| f64::from(c[1])).sum::<f64>();
        let energy = |p: &[[f32; 3]]| mean(p) / mean(&truth.pixels);
        println!(
            "{mode}: block error {:.1}% (Phong lobe in SH {:.1}%), energy {:.3} ({:.3})",
            100.0 * error(&now),
            100.0 * error(&before),
            energy(&now),
            energy(&before)
        );
        assert!(error(&now) < 0.6 * error(&before), "{mode}: the true lobe comes too little nearer the reference");
        assert!(error(&now) < 0.25, "{mode}: block error {}", error(&now));
        assert!((energy(&now) - 1.0).abs() < 0.1, "{mode}: energy {}", energy(&now));
    }
}
