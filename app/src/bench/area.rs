//! `lightloom bench --only area`: near-field relighting by a painted area light (Sun 2008
//! §4.5) on a 200 × 200 floor (40,000 receivers), order 32, face size 4:
//!
//! * vertex relights per second at keep 1% / 20% and 5% / 40% (thesis: about 1.5 M/s at 1% / 20%
//!   on 8 cores of 2008; our goal is 1.5 M/s on these 2 cores);
//! * a stroke to new shading: replaying the paint log, the Haar transform, the responses of the
//!   coefficients the stroke newly keeps and the sum (goal: under 100 ms of CPU work);
//! * a light move: the propagation alone;
//! * the transport precompute per vertex (unoccluded rays here: the time is the face sampling
//!   and the Haar transform, not ray casting) and its memory.

use super::common::{BenchArgs, evaluate_frame, median, timed_frame};
use anyhow::{Result, anyhow};
use glam::DVec3;
use lightloom_nodes::engine::spec::ParamValue;
use lightloom_nodes::engine::{Engine, Graph};
use lightloom_nodes::light_texture::{Blend, PaintOp, render};
use lightloom_nodes::near_field::{
    LightPlacement, TargetKeep, TopFace, face_transport, irradiance, light_source, responses, shade,
};
use lightloom_render::{CameraView, GpuContext, ViewportRenderer};
use std::sync::Arc;
use std::time::Instant;

pub fn area_light_figures() {
    let side = 200;
    let positions: Vec<DVec3> = (0..side * side)
        .map(|i| {
            DVec3::new(-3.0 + 6.0 * (i % side) as f64 / side as f64, 0.0, -3.0 + 6.0 * (i / side) as f64 / side as f64)
        })
        .collect();
    let normals = vec![DVec3::Y; positions.len()];
    let face = TopFace { order: 32, size: 4.0 };
    let start = Instant::now();
    let transport = face_transport(face, &positions, &normals, 1, |_, _| true);
    let precompute = start.elapsed().as_secs_f64();
    println!(
        "Area light, {} receivers, order 32 (thesis: ~1.5 M relights/s at 1%/20% on 8 cores, 2008; goal 1.5 M/s on 2 cores):",
        positions.len()
    );
    println!(
        "  transport: {:.1} us per vertex ({:.2} s), {} bytes per vertex (1024 coefficients, f32)",
        precompute / positions.len() as f64 * 1e6,
        precompute,
        face.order * face.order * 4
    );
    // A painted light: a warm fill, three coloured strokes, a soft blur, a disc.
    let stroke = |y: f64, colour: [f64; 3]| PaintOp::Stroke {
        points: (0..30).map(|i| [0.15 + 0.025 * i as f64, y + 0.1 * (i as f64 * 0.4).sin()]).collect(),
        radius: 0.06,
        hardness: 0.3,
        colour,
        intensity: 6.0,
        blend: Blend::Mix,
    };
    let mut ops = vec![
        PaintOp::Fill { colour: [1.0, 0.9, 0.7], intensity: 5.0 },
        stroke(0.3, [1.0, 0.3, 0.2]),
        stroke(0.5, [0.2, 1.0, 0.4]),
        stroke(0.7, [0.3, 0.4, 1.0]),
        PaintOp::Blur { sigma: 0.01 },
        PaintOp::Reshape { shape: lightloom_nodes::light_texture::Shape::Disc },
    ];
    let placement = LightPlacement::centred(2.0, [0.0, 0.0], [1.5, 1.0]);
    let mut no_files = |_: &str| Err("no files".to_string());
    for (source_pct, target_pct) in [(1.0, 20.0), (1.0, 100.0), (5.0, 40.0), (100.0, 100.0)] {
        let texture = render(&ops, 32, &mut no_files).expect("a valid log");
        let keep = (source_pct / 100.0 * 1024.0f64).ceil() as usize;
        let source = light_source(&texture.emission(), 32, keep);
        let target = if target_pct >= 100.0 { TargetKeep::All } else { TargetKeep::Predicted(target_pct / 100.0) };
        // The first relight at a placement also computes its couplings; the median of five is
        // what a repaint or a drag that returns to a placement sees.
        let times: Vec<f64> = (0..5)
            .map(|_| {
                let start = Instant::now();
                std::hint::black_box(irradiance(&source, &placement, &transport, &positions, target));
                start.elapsed().as_secs_f64()
            })
            .collect();
        let (first, seconds) = (times[0], median(times));
        let rate = positions.len() as f64 / seconds / 1e6;
        let anchors =
            super::anchors::sun_area_relights(source_pct, target_pct).map_or(String::new(), |(eight, one)| {
                format!(
                    "; {}; per thread {}",
                    eight.beside(rate),
                    one.beside(rate / rayon::current_num_threads() as f64)
                )
            });
        println!(
            "  keep {source_pct}% / {target_pct}%: {:.0} ms per relight (median of 5; first {:.0} ms) = {rate:.2} M \
             relights/s ({} source coefficients){anchors}",
            seconds * 1e3,
            first * 1e3,
            source.coefficients.len()
        );
    }
    // The other target heuristic: the largest propagated coefficients (1% / 20%).
    {
        let texture = render(&ops, 32, &mut no_files).expect("a valid log");
        let source = light_source(&texture.emission(), 32, 11);
        let start = Instant::now();
        std::hint::black_box(irradiance(&source, &placement, &transport, &positions, TargetKeep::Largest(0.2)));
        let seconds = start.elapsed().as_secs_f64();
        println!(
            "  keep 1% / 20% by the largest coefficients: {:.0} ms per relight = {:.2} M relights/s",
            seconds * 1e3,
            positions.len() as f64 / seconds / 1e6
        );
    }
    // A stroke: replay, transform, then shade with the responses of the coefficients the
    // light kept before (held from the last frame) and those it newly keeps (1% / 20%).
    let target = TargetKeep::Predicted(0.2);
    let before = light_source(&render(&ops, 32, &mut no_files).expect("a valid log").emission(), 32, 11);
    let old: Vec<(u16, u16)> = before.coefficients.iter().map(|c| c.0).collect();
    let held = responses(&old, &placement, &transport, &positions, target).expect("linear targets");
    ops.push(PaintOp::Stroke {
        points: (0..40).map(|i| [0.2 + 0.015 * i as f64, 0.4]).collect(),
        radius: 0.08,
        hardness: 0.4,
        colour: [0.2, 0.3, 1.0],
        intensity: 8.0,
        blend: Blend::Mix,
    });
    let start = Instant::now();
    let texture = render(&ops, 32, &mut no_files).expect("a valid log");
    let source = light_source(&texture.emission(), 32, 11); // 1%
    let texture_ms = start.elapsed().as_secs_f64() * 1e3;
    let added: Vec<(u16, u16)> = source.coefficients.iter().map(|c| c.0).filter(|i| !old.contains(i)).collect();
    let fresh = responses(&added, &placement, &transport, &positions, target).expect("linear targets");
    let column = |r: usize, index: (u16, u16)| match old.iter().position(|&i| i == index) {
        Some(j) => held[j][r],
        None => fresh[added.iter().position(|&i| i == index).expect("added")][r],
    };
    let indices: Vec<(u16, u16)> = source.coefficients.iter().map(|c| c.0).collect();
    let e = shade(&source, positions.len(), |r, j| column(r, indices[j]));
    let stroke_ms = start.elapsed().as_secs_f64() * 1e3;
    std::hint::black_box(e);
    let moved = LightPlacement::centred(2.2, [0.3, -0.2], [1.5, 1.0]);
    let start = Instant::now();
    std::hint::black_box(irradiance(&source, &moved, &transport, &positions, TargetKeep::Predicted(0.2)));
    let move_ms = start.elapsed().as_secs_f64() * 1e3;
    println!(
        "  stroke to new shading: {stroke_ms:.0} ms ({texture_ms:.1} ms replay and transform, {} of {} coefficients \
         new) (goal < 100 ms); light move: {move_ms:.0} ms",
        added.len(),
        indices.len()
    );
}

/// `paint` with the `k`th timed stroke added: a warm line of 20 points across the light.
fn with_stroke(paint: &[PaintOp], k: usize) -> Vec<PaintOp> {
    let mut ops = paint.to_vec();
    ops.push(PaintOp::Stroke {
        points: (0..20).map(|i| [0.2 + 0.03 * i as f64, 0.5 + 0.02 * k as f64]).collect(),
        radius: 0.06,
        hardness: 0.5,
        colour: [1.0, 0.4, 0.2],
        intensity: 5.0,
        blend: Blend::Mix,
    });
    ops
}

/// The area-light sample (`projects/samples/area_light.ron`) at a tessellation of about 40k
/// vertices, through the engine as the editor runs it: the first evaluation (the top-face
/// transport), then a stroke, a move, a resize and an intensity change, each as CPU stage time
/// and the frame drawn after it.
pub fn area_sample_figures(args: &BenchArgs, gpu: &GpuContext) -> Result<()> {
    let path = crate::samples::project("area_light")?;
    let (project, mut graph) = lightloom_nodes::project::Project::load(&path).map_err(|e| anyhow!("{e}"))?;
    graph.set_param("scene", "tessellation", ParamValue::Int(136))?;
    let view = CameraView::from_project(&project.camera(None).map_err(|e| anyhow!(e))?);
    let engine = Arc::new(Engine::in_memory());
    let mut renderer = ViewportRenderer::new(gpu);
    let frame_of = |graph: &Graph| evaluate_frame(&engine, graph, "out", gpu);
    let (frame, first_ms, _) = frame_of(&graph)?;
    let vertices = frame.geometry.vertex_count();
    timed_frame(gpu, &mut renderer, &frame, &view, (960, 540))?;
    println!(
        "\narea-light sample ({vertices} vertices, sh_prt plus one painted light), 960x540; first evaluation {:.1} s \
         ({:.0} us per vertex with the top-face transport, {} KB per vertex)",
        first_ms / 1e3,
        first_ms * 1e3 / vertices as f64,
        32 * 32 * 4 / 1024
    );
    println!("{:<34} {:>16} {:>12}", "edit (goal: stroke < 100 ms CPU)", "CPU stages ms", "frame ms");
    let ParamValue::Paint(paint) =
        graph.node("panel").and_then(|n| n.params.get("paint")).cloned().ok_or_else(|| anyhow!("paint"))?
    else {
        return Err(anyhow!("paint"));
    };
    type Edit = Box<dyn Fn(&mut Graph, usize) -> Result<()>>;
    let edits: Vec<(&str, Edit)> = vec![
        (
            "a stroke",
            Box::new(move |g, k| Ok(g.set_param("panel", "paint", ParamValue::Paint(with_stroke(&paint, k)))?)),
        ),
        (
            "move the light",
            Box::new(|g, k| {
                Ok(g.set_param("panel", "position", ParamValue::Vec3([0.1 * (k + 1) as f64, 2.0, 0.0]))?)
            }),
        ),
        (
            "resize the light",
            Box::new(|g, k| Ok(g.set_param("panel", "width", ParamValue::Float(1.6 + 0.1 * (k + 1) as f64))?)),
        ),
        ("intensity", Box::new(|g, k| Ok(g.set_param("panel", "intensity", ParamValue::Float(4.0 + (k + 1) as f64))?))),
    ];
    for (acc, name) in [("analytic", "exact couplings"), ("table256", "couplings from a 256-step table")] {
        graph.set_param("panel", "acc", ParamValue::Choice(acc.into()))?;
        let (_, switch_ms, _) = frame_of(&graph)?;
        println!("{name} (first evaluation {switch_ms:.0} ms):");
        for (label, edit) in &edits {
            let (mut stages, mut frames) = (Vec::new(), Vec::new());
            for k in 0..args.frames.max(1) {
                edit(&mut graph, k)?;
                let (frame, ms, _) = frame_of(&graph)?;
                stages.push(ms);
                frames.push(timed_frame(gpu, &mut renderer, &frame, &view, (960, 540))?);
            }
            println!("  {label:<32} {:>16.1} {:>12.1}", median(stages), median(frames));
        }
    }
    glossy_sample_figures(args, gpu, &project, &path, &view)
}

/// The sample with a glossy (Phong) material: the highlights' first evaluation, the view
/// resting somewhere new (the glossy transport and every response again, no ray), and a stroke.
fn glossy_sample_figures(
    args: &BenchArgs,
    gpu: &GpuContext,
    project: &lightloom_nodes::project::Project,
    path: &std::path::Path,
    view: &CameraView,
) -> Result<()> {
    use lightloom_nodes::project::{ProjectLink, ProjectNode};
    let mut glossy = project.clone();
    glossy.nodes.push(ProjectNode {
        id: "gloss".into(),
        kind: "BrdfEditor".into(),
        label: String::new(),
        position: [0.0; 2],
        params: [
            ("model".to_string(), ParamValue::Choice("phong".into())),
            ("exponent".to_string(), ParamValue::Float(30.0)),
            ("f0".to_string(), ParamValue::Float(0.3)),
        ]
        .into(),
    });
    glossy.links.push(ProjectLink { from: ("gloss".into(), "material".into()), to: ("out".into(), "material".into()) });
    let mut graph = glossy.graph(path).map_err(|e| anyhow!("{e:?}"))?;
    graph.set_param("scene", "tessellation", ParamValue::Int(136))?;
    let engine = Arc::new(Engine::in_memory());
    let mut renderer = ViewportRenderer::new(gpu);
    let (_, first_ms, _) = evaluate_frame(&engine, &graph, "out", gpu)?;
    println!("glossy floor, sphere and box (Phong 30), exact couplings (first evaluation {:.1} s):", first_ms / 1e3);
    let eye = glossy.camera(None).map_err(|e| anyhow!(e))?.position;
    let (mut stages, mut frames) = (Vec::new(), Vec::new());
    for k in 0..args.frames.max(1) {
        let turned = [eye[0] + 0.4 * (k + 1) as f64, eye[1], eye[2]];
        graph.set_param("out", lightloom_nodes::kinds::output::HIGHLIGHT_EYE, ParamValue::Vec3(turned))?;
        let (frame, ms, _) = evaluate_frame(&engine, &graph, "out", gpu)?;
        stages.push(ms);
        frames.push(timed_frame(gpu, &mut renderer, &frame, view, (960, 540))?);
    }
    println!("  {:<32} {:>16.1} {:>12.1}", "the view rests elsewhere", median(stages), median(frames));
    Ok(())
}

/// The engine sample (the 2CylinderEngine glTF, ~94k vertices, glossy GGX, a floor with a
/// visibility texture) with a painted panel linked as a user would, CPU stage times only (the
/// viewport's draw apart), each beside its goal: linking the light the first time (the engine's
/// own stages already evaluated), a stroke, a move in the light's plane, an intensity change,
/// and the view resting somewhere new (the highlights).
pub fn area_engine_figures(args: &BenchArgs) -> Result<()> {
    use crate::project_commands::{evaluate, output_request};
    use lightloom_nodes::project::{Project, ProjectLink, ProjectNode};
    let path = crate::samples::project("engine")?;
    let (mut project, _) = Project::load(&path).map_err(|e| anyhow!("{e}"))?;
    let area = Project::load(&crate::samples::project("area_light")?).map_err(|e| anyhow!("{e}"))?.0;
    let mut panel =
        area.nodes.iter().find(|n| n.id == "panel").cloned().ok_or_else(|| anyhow!("the area sample's panel"))?;
    panel.params.insert("position".into(), ParamValue::Vec3([0.1, 1.2, 0.0]));
    panel.params.insert("width".into(), ParamValue::Float(1.0));
    panel.params.insert("depth".into(), ParamValue::Float(0.6));
    project.nodes.push(ProjectNode { position: [0.0, 600.0], ..panel });
    let unlinked = project.graph(&path).map_err(|e| anyhow!("{e:?}"))?;
    project
        .links
        .push(ProjectLink { from: ("panel".into(), "area_light".into()), to: ("output".into(), "area_lights".into()) });
    let mut graph = project.graph(&path).map_err(|e| anyhow!("{e:?}"))?;
    let engine = Arc::new(Engine::in_memory());
    // CPU stage time of an evaluation: its total, and the area stages' own.
    type Timed = (f64, Vec<(String, f64)>);
    let run = |graph: &Graph| -> Result<Timed> {
        let start = Instant::now();
        let evaluation = evaluate(engine.clone(), graph, output_request(graph, "output", true), true);
        let total = start.elapsed().as_secs_f64() * 1e3;
        if let Some(failed) = evaluation.report.stages.iter().find(|s| s.error.is_some()) {
            return Err(anyhow!("{}.{}: {:?}", failed.node, failed.stage, failed.error));
        }
        let area = evaluation
            .report
            .stages
            .iter()
            .filter(|s| s.stage.starts_with("area_") && s.ms > 0.5)
            .map(|s| (s.stage.to_string(), s.ms))
            .collect();
        Ok((total, area))
    };
    let (warm, _) = run(&unlinked)?;
    let vertices = {
        let evaluation = evaluate(engine.clone(), &unlinked, output_request(&unlinked, "output", true), true);
        let frame =
            lightloom_nodes::frame::FrameInputs::gather(&evaluation, &unlinked, "output").map_err(|e| anyhow!(e))?;
        frame.geometry.vertex_count()
    };
    println!("\narea light on the engine sample ({vertices} vertices; the sample alone took {:.1} s):", warm / 1e3);
    let show = |label: &str, goal: &str, (total, area): Timed| {
        let parts: Vec<String> = area.iter().map(|(s, ms)| format!("{s} {ms:.0}")).collect();
        println!("  {label:<32} {total:>10.0} ms (goal {goal}): {}", parts.join(", "));
    };
    show("link the light (first time)", "< 10 s", run(&graph)?);
    // What the light's transports hold (the glossy one per view alike).
    let evaluation = evaluate(engine.clone(), &graph, output_request(&graph, "output", true), true);
    for stage in ["area_transport", "area_texel_transport"] {
        let bytes = evaluation.value("output", stage).map_err(|e| anyhow!("{e:?}"))?.approx_bytes();
        println!("  {stage:<32} {:>10.1} MiB", bytes as f64 / (1 << 20) as f64);
    }
    let ParamValue::Paint(paint) =
        graph.node("panel").and_then(|n| n.params.get("paint")).cloned().ok_or_else(|| anyhow!("paint"))?
    else {
        return Err(anyhow!("paint"));
    };
    let mut results: Vec<(&str, &str, Vec<Timed>)> =
        vec![("a stroke", "< 100 ms", vec![]), ("move in its plane", "< 300 ms", vec![]), ("intensity", "", vec![])];
    results.push(("the view rests elsewhere", "not from scratch", vec![]));
    let eye = project.camera(None).map_err(|e| anyhow!(e))?.position;
    for k in 0..args.frames.max(1) {
        graph.set_param("panel", "paint", ParamValue::Paint(with_stroke(&paint, k)))?;
        results[0].2.push(run(&graph)?);
        graph.set_param("panel", "position", ParamValue::Vec3([0.1 + 0.05 * (k + 1) as f64, 1.2, 0.0]))?;
        results[1].2.push(run(&graph)?);
        graph.set_param("panel", "intensity", ParamValue::Float(4.0 + (k + 1) as f64))?;
        results[2].2.push(run(&graph)?);
        let turned = [eye[0] + 0.2 * (k + 1) as f64, eye[1], eye[2]];
        graph.set_param("output", lightloom_nodes::kinds::output::HIGHLIGHT_EYE, ParamValue::Vec3(turned))?;
        results[3].2.push(run(&graph)?);
    }
    for (label, goal, mut runs) in results {
        runs.sort_by(|a, b| a.0.total_cmp(&b.0));
        let median = runs.swap_remove(runs.len() / 2);
        show(label, if goal.is_empty() { "-" } else { goal }, median);
    }
    Ok(())
}
