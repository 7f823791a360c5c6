//! The square lights (Xu et al. 2006): the decomposition, the `rsl` mode on a moving scene, and
//! the square-lights sample.

use super::common::*;
use anyhow::{Result, anyhow};
use lightloom_nodes::engine::spec::ParamValue;
use lightloom_nodes::engine::{CancelToken, Engine, Graph, StageValue};
use lightloom_nodes::frame::{Background, FrameInputs, FrameMaterial, Geometry, Keyed, MediumFrame, Surfaces};
use lightloom_nodes::kinds::output::{Mode, Tonemap, View};
use lightloom_nodes::transport::Receivers;
use lightloom_render::{CameraView, GpuContext, ViewportRenderer};
use std::sync::Arc;
use std::time::Instant;

pub(super) fn rsl_figures() {
    use lightloom_nodes::rsl::MergeSequence;
    let sky = lightloom_nodes::sky::ProceduralSky::default();
    let image = lightloom_nodes::cubemap::Equirect::from_fn(512, 256, 3, |d| sky.radiance(d));
    println!("RSL decomposition of the default sky (paper anchor: about 2 min at 6x32^2, K = 30, 2006 CPU):");
    for size in [16, 32, 64] {
        let cube = image.to_cubemap(size);
        let start = Instant::now();
        let Ok(sequence) = MergeSequence::compute(&cube, &CancelToken::default(), &|_| {}) else { return };
        let merge_ms = start.elapsed().as_secs_f64() * 1e3;
        let start = Instant::now();
        let lights = sequence.cut(&cube, 30);
        let cut_ms = start.elapsed().as_secs_f64() * 1e3;
        println!(
            "  6x{size}^2: merge sequence {merge_ms:.0} ms ({} merges), cut at K = 30 and fit {cut_ms:.1} ms, {} lights",
            sequence.merges.len(),
            lights.lights.len()
        );
    }
}

/// The `rsl` mode at the paper's Table 1 scale: a 60k-vertex torus, a sphere occluder moving
/// around it, 30 square lights of the default sky.
pub(super) fn rsl_mode_figures(args: &BenchArgs, gpu: &GpuContext) -> Result<()> {
    use lightloom_nodes::rsl::brdf_sat::BrdfSat;
    use lightloom_nodes::rsl::ovdf::{ObjectOvdf, Ovdf, bounding_sphere};
    use lightloom_nodes::rsl::shade::light_visibility;
    use lightloom_nodes::rsl::vdt::{ObjectSvdf, Ramp, Svdf, VDT_SIZE};
    use lightloom_nodes::rsl::{MergeSequence, WorldLights};
    let cancel = CancelToken::default();
    let ms = |start: Instant| start.elapsed().as_secs_f64() * 1e3;
    println!(
        "\nrsl mode (paper, Table 1 on a GeForce 7800: robot 60k vertices 10.8 fps, Buddha 45k 27 fps = 36.5 M vertex-RSL/s):"
    );
    brdf_table_figures(&cancel)?;
    // A fat torus with a box through its rim shadows itself irregularly (a sphere's tables would
    // all be the same horizon, a lone torus's would repeat around its axis).
    let block = lightloom_nodes::mesh::cuboid([0.7, 1.4, 0.5], 4, false)
        .transformed(glam::DMat4::from_translation(glam::DVec3::new(1.0, 0.3, 0.0)));
    let receiver = lightloom_nodes::mesh::MeshSet { meshes: vec![lightloom_nodes::mesh::torus(1.0, 0.45, 172), block] };
    let occluder = lightloom_nodes::mesh::MeshSet {
        meshes: vec![lightloom_nodes::mesh::torus(0.4, 0.12, 32).transformed(glam::DMat4::from_rotation_x(1.0))],
    };
    let n: usize = receiver.meshes.iter().map(|m| m.positions.len()).sum();
    let start = Instant::now();
    let receivers = Receivers::from_meshes(&receiver);
    let svdf =
        Svdf::compute(&lightloom_nodes::raycast::RayScene::build(&receiver), &receivers, VDT_SIZE, &cancel, &|_| {})
            .map_err(|e| anyhow!("{e}"))?;
    println!(
        "  self-visibility tables: {n} vertices in {:.1} s; {} B per vertex (8-bit; the paper's FP32 is 4096 B, its \
         CPCA 1:17 about 240 B)",
        ms(start) / 1e3,
        svdf.bytes_per_vertex()
    );
    let start = Instant::now();
    let (compressed, error) = svdf.compressed(256, 8);
    println!(
        "  CPCA, 256 clusters x 8 directions: {:.1} s, {:.1} MiB for {n} vertices ({:.0} B per vertex; 1:{:.1} \
         against FP32, paper 1:17), relative error {:.2}%",
        ms(start) / 1e3,
        compressed.bytes() as f64 / (1 << 20) as f64,
        compressed.bytes() as f64 / n as f64,
        (n * VDT_SIZE * VDT_SIZE * 4) as f64 / compressed.bytes() as f64,
        error * 100.0
    );
    occluder_field_figures(&occluder, &cancel)?;
    let field = Ovdf::compute(
        &lightloom_nodes::raycast::RayScene::build(&occluder),
        bounding_sphere(&occluder),
        8,
        VDT_SIZE,
        &cancel,
        &|_| {},
    )
    .map_err(|e| anyhow!("{e}"))?;
    let sky = lightloom_nodes::sky::ProceduralSky::default();
    let cube = lightloom_nodes::cubemap::Equirect::from_fn(512, 256, 3, |d| sky.radiance(d)).to_cubemap(32);
    let sequence = MergeSequence::compute(&cube, &cancel, &|_| {}).map_err(|e| anyhow!(e))?;
    let lights = WorldLights { lights: sequence.cut(&cube, 30).lights };
    let objects =
        [ObjectSvdf { name: "receiver".into(), world_from_object: glam::DMat4::IDENTITY.to_cols_array(), svdf }];
    // The occluder circles the receiver: each frame is a move.
    let mut visibility_ms = Vec::new();
    let mut visibility = None;
    for frame in 0..args.frames.max(1) {
        let angle = frame as f64 * 0.3;
        let at = glam::DVec3::new(1.2 * angle.cos(), 0.9, 1.2 * angle.sin());
        let occluders = [
            ObjectOvdf {
                name: "receiver".into(),
                world_from_object: glam::DMat4::IDENTITY.to_cols_array(),
                ovdf: Ovdf::default(),
            },
            ObjectOvdf {
                name: "occluder".into(),
                world_from_object: glam::DMat4::from_translation(at).to_cols_array(),
                ovdf: field.clone(),
            },
        ];
        let start = Instant::now();
        visibility = Some(
            light_visibility(&objects, &occluders, &lights, Ramp::StraightEdge, &cancel).map_err(|e| anyhow!("{e}"))?,
        );
        visibility_ms.push(ms(start));
    }
    println!(
        "  CPU per move: per-vertex visibility of 30 lights with one moving occluder, {n} vertices: {:.0} ms",
        median(visibility_ms)
    );
    let material = lightloom_nodes::brdf::Material {
        model: lightloom_nodes::brdf::Model::Phong,
        exponent: 20.0,
        f0: 0.3,
        ..Default::default()
    };
    let sat =
        BrdfSat::build(&lightloom_nodes::brdf::Brdf::from_material(&material), &cancel).map_err(|e| anyhow!("{e}"))?;
    let frame = rsl_frame(&receiver, &lights, visibility.expect("at least one frame"), material, sat)?;
    let view = bench_view();
    let mut renderer = ViewportRenderer::new(gpu);
    timed_frame(gpu, &mut renderer, &frame, &view, (1280, 720))?;
    let times: Vec<f64> = (0..args.frames.max(1))
        .map(|_| timed_frame(gpu, &mut renderer, &frame, &view, (1280, 720)))
        .collect::<Result<_>>()?;
    let frame_ms = median(times);
    let rate = n as f64 * 30.0 / frame_ms / 1e3;
    println!(
        "  GPU frame at 1280x720, {n} vertices x 30 lights: {frame_ms:.1} ms = {rate:.1} M vertex-RSL/s, {} (this \
         device: {})",
        super::anchors::XU_TABLE_1.beside(rate),
        gpu.describe()
    );
    square_light_sample_figures(args, gpu)
}

/// Edits on the square-light sample (`projects/samples/square_lights.ron`, built in): what each
/// recomputes on the CPU and the frame after it, beside the targets: a BRDF edit within 100 ms
/// of CPU-side work; moves and environment turns without precomputation.
fn square_light_sample_figures(args: &BenchArgs, gpu: &GpuContext) -> Result<()> {
    let path = crate::samples::project("square_lights")?;
    let (project, mut graph) = lightloom_nodes::project::Project::load(&path).map_err(|e| anyhow!("{e}"))?;
    let view = CameraView::from_project(&project.camera(None).map_err(|e| anyhow!(e))?);
    let engine = Arc::new(Engine::in_memory());
    let mut renderer = ViewportRenderer::new(gpu);
    let frame_of = |graph: &Graph| evaluate_frame(&engine, graph, "output", gpu);
    let (frame, first_ms, _) = frame_of(&graph)?;
    let vertices = frame.geometry.vertex_count();
    timed_frame(gpu, &mut renderer, &frame, &view, (960, 540))?;
    println!(
        "\nsquare-light sample ({vertices} vertices, 30 lights, 3 objects), 960x540; first evaluation {:.1} s",
        first_ms / 1e3
    );
    println!("{:<30} {:>16} {:>8} {:>12}", "edit", "CPU stages ms", "stages", "frame ms");
    let ParamValue::Objects(objects) =
        graph.node("scene").and_then(|n| n.params.get("objects")).cloned().ok_or_else(|| anyhow!("objects"))?
    else {
        return Err(anyhow!("objects"));
    };
    type Edit = Box<dyn Fn(&mut Graph, usize) -> Result<()>>;
    let edits: Vec<(&str, Edit)> = vec![
        (
            "BRDF edit (gloss exponent)",
            Box::new(|g, k| Ok(g.set_param("gloss", "exponent", ParamValue::Float(20.0 + 3.0 * k as f64))?)),
        ),
        (
            "BRDF swap (gold: Ward/GGX aniso)",
            Box::new(|g, k| {
                let model = if k % 2 == 0 { "ward" } else { "ggx_anisotropic" };
                g.set_param("gold", "anisotropy", ParamValue::Float(0.5 + 0.01 * k as f64))?;
                Ok(g.set_param("gold", "model", ParamValue::Choice(model.into()))?)
            }),
        ),
        (
            "move the sphere",
            Box::new(move |g, k| {
                let mut moved = objects.clone();
                moved[1].translation[0] += 0.1 * (k + 1) as f64;
                moved[1].rotation_deg[1] += 7.0 * (k + 1) as f64;
                Ok(g.set_param("scene", "objects", ParamValue::Objects(moved))?)
            }),
        ),
        (
            "turn the environment",
            Box::new(|g, k| {
                Ok(g.set_param("courtyard", "rotation", ParamValue::Vec3([5.0 * (k + 1) as f64, 0.0, 0.0]))?)
            }),
        ),
        (
            "environment exposure",
            Box::new(|g, k| Ok(g.set_param("courtyard", "exposure", ParamValue::Float(0.25 * (k + 1) as f64))?)),
        ),
    ];
    for (label, edit) in edits {
        let (mut stages, mut frames, mut count) = (Vec::new(), Vec::new(), 0);
        for k in 0..args.frames.max(1) {
            edit(&mut graph, k)?;
            let (frame, ms, computed) = frame_of(&graph)?;
            stages.push(ms);
            count = count.max(computed);
            frames.push(timed_frame(gpu, &mut renderer, &frame, &view, (960, 540))?);
        }
        println!("{label:<30} {:>16.1} {:>8} {:>12.1}", median(stages), count, median(frames));
    }
    Ok(())
}

/// The BRDF summed-area tables' build time, isotropic and anisotropic.
fn brdf_table_figures(cancel: &CancelToken) -> Result<()> {
    use lightloom_nodes::rsl::brdf_sat::BrdfSat;
    let ms = |start: Instant| start.elapsed().as_secs_f64() * 1e3;
    for (label, model, anisotropy) in [("isotropic (Phong 20)", "phong", 0.0), ("anisotropic (Ward)", "ward", 0.6)] {
        let material = lightloom_nodes::brdf::Material {
            model: model.parse().unwrap(),
            exponent: 20.0,
            roughness: 0.5,
            anisotropy,
            f0: 0.3,
            ..Default::default()
        };
        let start = Instant::now();
        let sat = BrdfSat::build(&lightloom_nodes::brdf::Brdf::from_material(&material), cancel)
            .map_err(|e| anyhow!("{e}"))?;
        println!("  BRDF summed-area tables, {label}: {:.1} ms ({} view slices)", ms(start), sat.lobes.len());
    }
    Ok(())
}

/// The occluder field's precompute and memory at two face sizes, and its PCA.
fn occluder_field_figures(occluder: &lightloom_nodes::mesh::MeshSet, cancel: &CancelToken) -> Result<()> {
    use lightloom_nodes::rsl::ovdf::{Ovdf, bounding_sphere};
    use lightloom_nodes::rsl::vdt::VDT_SIZE;
    let ms = |start: Instant| start.elapsed().as_secs_f64() * 1e3;
    for face in [8, 16] {
        let start = Instant::now();
        let field = Ovdf::compute(
            &lightloom_nodes::raycast::RayScene::build(occluder),
            bounding_sphere(occluder),
            face,
            VDT_SIZE,
            cancel,
            &|_| {},
        )
        .map_err(|e| anyhow!("{e}"))?;
        println!(
            "  occluder field, 16 shells x 6x{face}^2: {:.1} s, {:.1} MiB per occluder (the paper at 6x32^2: 384 MiB FP32, \
             15 MiB with PCA)",
            ms(start) / 1e3,
            field.bytes() as f64 / (1 << 20) as f64
        );
        let (compressed, error) = field.compressed(8);
        println!(
            "    PCA per segment (384 x 8 directions): {:.1} MiB (1:{:.1} against FP32, paper 1:26), relative error \
             {:.2}%",
            compressed.bytes() as f64 / (1 << 20) as f64,
            (field.bytes() * 4) as f64 / compressed.bytes() as f64,
            error * 100.0
        );
    }
    Ok(())
}

/// The `rsl` frame of the receiver lit by `lights` with these per-vertex visibilities.
fn rsl_frame(
    receiver: &lightloom_nodes::mesh::MeshSet,
    lights: &lightloom_nodes::rsl::WorldLights,
    visibility: lightloom_nodes::rsl::shade::LightVisibility,
    material: lightloom_nodes::brdf::Material,
    sat: lightloom_nodes::rsl::brdf_sat::BrdfSat,
) -> Result<FrameInputs> {
    let keyed = |key: u128, value: StageValue| Keyed { key, value: Arc::new(value) };
    let geometry =
        Geometry::of_meshes(keyed(1, StageValue::new(receiver.clone())), vec![0, 0]).map_err(|e| anyhow!(e))?;
    let surfaces = lightloom_nodes::frame::RslSurfaces::new(
        lights,
        2,
        keyed(3, StageValue::new(visibility)),
        &[keyed(4, StageValue::new(sat))],
        None,
        &geometry,
    )
    .map_err(|e| anyhow!(e))?;
    let materials = vec![FrameMaterial::new("bench", material, None)];
    let frame = FrameInputs {
        geometry,
        ray_scene: None,
        mode: Mode::Rsl,
        pending: None,
        settings: lightloom_nodes::kinds::output::OutputSettings {
            mode: Mode::Rsl,
            exposure: 0.0,
            tonemap: Tonemap::Aces,
            background: false,
            view: View::Approximation,
            reference_samples: 1,
            separate_sun: false,
            wavelet_details: 0,
        },
        ignored_inputs: Vec::new(),
        lobe_limits: Vec::new(),
        materials: materials.clone(),
        background: Background { radiance: None, visible: false },
        surfaces: Surfaces::Rsl(surfaces),
        medium: MediumFrame::new(Vec::new(), &materials, None),
        area_lights: None,
        blockers: None,
        sun: None,
        normal_maps: Default::default(),
    };
    Ok(frame)
}

/// The engine sample (~85k vertices) with an RSL decomposer linked to its studio HDRI, as a
/// user builds it: the sample evaluated in its own mode, then the Output switched to `rsl`
/// cold (nothing of the square lights computed yet), CPU stage time on these 2 cores beside
/// the goal of 30 s. Every stage that runs long enough to show an estimate of its time left
/// (2 s on, as the editor and the CLI show it) has each estimate compared with the time it
/// then took: the worst ratio either way (both read in whole seconds, at least one), beside
/// the goal of 2.
pub(super) fn rsl_engine_figures() -> Result<()> {
    use lightloom_nodes::engine::EvalEvent;
    use lightloom_nodes::project::{Project, ProjectLink, ProjectNode};
    use std::collections::HashMap;
    let path = crate::samples::project("engine")?;
    let (mut project, _) = Project::load(&path).map_err(|e| anyhow!("{e}"))?;
    project.nodes.push(ProjectNode {
        id: "lights".into(),
        kind: "RslDecomposer".into(),
        label: String::new(),
        position: [300.0, 0.0],
        params: Default::default(),
    });
    let environment = project
        .links
        .iter()
        .find(|l| l.to == ("output".to_string(), "environment".to_string()))
        .map(|l| l.from.clone())
        .ok_or_else(|| anyhow!("the engine sample's environment"))?;
    project.links.push(ProjectLink { from: environment, to: ("lights".into(), "environment".into()) });
    project.links.push(ProjectLink {
        from: ("lights".into(), "square_lights".into()),
        to: ("output".into(), "square_lights".into()),
    });
    let mut graph = project.graph(&path).map_err(|e| anyhow!("{e:?}"))?;
    let engine = Arc::new(Engine::in_memory());
    let request = |graph: &Graph| crate::project_commands::output_request(graph, "output", true);
    let warm = Instant::now();
    crate::project_commands::evaluate(engine.clone(), &graph, request(&graph), true);
    let warm = warm.elapsed().as_secs_f64();
    graph.set_param("output", "mode", ParamValue::Choice("rsl".into()))?;
    let start = Instant::now();
    let job = engine.spawn_request(graph.clone(), request(&graph));
    // Per stage: when it started, its estimates (when made, seconds left) and when it ended.
    let mut started: HashMap<(String, String), Instant> = HashMap::new();
    let mut estimates: HashMap<(String, String), Vec<(Instant, f64)>> = HashMap::new();
    let mut long = Vec::new();
    for event in job.events.iter() {
        match event {
            EvalEvent::StageStarted { node, stage } => {
                started.insert((node, stage), Instant::now());
            }
            EvalEvent::StageProgress { node, stage, fraction } => {
                let key = (node, stage);
                let Some(begun) = started.get(&key) else { continue };
                let elapsed = begun.elapsed().as_secs_f64();
                if fraction > 0.01 && fraction < 1.0 && elapsed >= 2.0 {
                    estimates.entry(key).or_default().push((Instant::now(), elapsed * (1.0 - fraction) / fraction));
                }
            }
            EvalEvent::StageFinished { node, stage, ms, .. } => {
                let key = (node, stage);
                if let Some(made) = estimates.remove(&key) {
                    let end = Instant::now();
                    let worst = made
                        .iter()
                        .map(|(at, left)| {
                            // Shown in whole seconds: under a second reads as one.
                            let (actual, left) = ((end - *at).as_secs_f64().max(1.0), left.max(1.0));
                            (left / actual).max(actual / left)
                        })
                        .fold(1.0, f64::max);
                    long.push((format!("{}.{}", key.0, key.1), ms / 1e3, made.len(), worst));
                }
            }
            EvalEvent::Finished => break,
            _ => {}
        }
    }
    let evaluation = job.wait();
    if let Some(failed) = evaluation.report.stages.iter().find(|s| s.error.is_some()) {
        return Err(anyhow!("{}.{}: {:?}", failed.node, failed.stage, failed.error));
    }
    println!(
        "\nswitch to rsl on the engine sample (RSL decomposer on its HDRI; the sample alone took {warm:.1} s):\n  \
         cold switch {:>8.1} s (goal < 30 s)",
        start.elapsed().as_secs_f64()
    );
    for (stage, seconds, count, worst) in long {
        println!(
            "  {stage:<28} {seconds:>6.1} s: {count} estimates, worst {worst:.2}x of the time then taken (goal <= 2x)"
        );
    }
    Ok(())
}
