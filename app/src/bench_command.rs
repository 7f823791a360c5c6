//! `lightloom bench`: prints the relighting figures (the numbers behind the speed claims).
//! Benchmarks print; tests never time anything.
//!
//! * Visibility rays (`bench_rays`): one at a time and in bundles, beside Embree's rate.
//! * Edit-to-new-frame latency for a BRDF edit on the default project, per relighting mode
//!   (evaluate the changed stages, upload, draw, wait for the GPU).
//! * Frame time of the default project at 1280×720 per mode (nothing re-uploaded).
//! * A 100k-vertex sphere: the CPU cost of a lighting change (SH incident radiance at 6 and 8
//!   bands, local-frame products at 80 and 320 cells) and the GPU frame time in each mode. Its
//!   transport is synthetic (random coefficients of the right shape): costs do not depend on
//!   the values, and real transport for 100k vertices takes minutes (see `--bench transport`).
//! * Fog (the street lamps of `tests/projects/fog_lamps.ron`): frame time at 1280×720, and what
//!   moving a light or changing β costs (no table is recomputed).
//! * RSL decomposition (Xu et al. 2006 §4.1) of the default procedural sky: the merge sequence
//!   at 6×16², 6×32² and 6×64², and the cut at K = 30 (the paper: about 2 minutes at 6×32²).
//! * The `rsl` mode on a 60k-vertex torus with one moving occluder and 30 square lights:
//!   BRDF table builds, self-visibility and occluder-field precompute and their memory, the
//!   CPU cost of a move (per-vertex visibility) and the GPU frame, beside the paper's Table 1.
//! * Blocker spheres (`bench_blockers`): the thesis's Fig. 5.5 speed-up table and its scenes'
//!   update rates, on the CPU.

use crate::project_commands::{evaluate, fail_on_errors, output_request, upstream_of};
use anyhow::{Result, anyhow};
use clap::Args;
use lightloom_nodes::engine::spec::ParamValue;
use lightloom_nodes::engine::{CancelToken, Engine, Graph, StageValue};
use lightloom_nodes::frame::{
    Background, FrameInputs, FrameMaterial, Geometry, IrradianceSurfaces, Keyed, MediumFrame, PrtSurfaces, Surfaces,
    WaveletLighting, WaveletSurfaces,
};
use lightloom_nodes::kinds::output::{Mode, Tonemap, View};
use lightloom_nodes::transport::{Receivers, ShTransport, SphericalTransport};
use lightloom_nodes::wavelet::SparseVector;
use lightloom_render::{CameraView, GpuContext, ViewportRenderer};
use rand::{Rng, SeedableRng};
use std::sync::Arc;
use std::time::Instant;

#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Vertices of the synthetic relighting mesh.
    #[arg(long, default_value_t = 100_000)]
    pub vertices: usize,
    /// Frames timed per figure (the median is printed).
    #[arg(long, default_value_t = 5)]
    pub frames: usize,
    /// Only these sections (rays, default, fog, rsl, blockers, adaptive, area, normal_maps,
    /// synthetic; all when empty).
    #[arg(long, value_delimiter = ',')]
    pub only: Vec<String>,
    /// Also write the rays section's mesh and rays into this folder, for
    /// `tools/rays/compare_mitsuba.py` to trace the same rays with Mitsuba 3 (Embree).
    #[arg(long, value_name = "DIR")]
    pub rays_dump: Option<std::path::PathBuf>,
}

/// The view of the synthetic meshes: a unit object at the origin from 3 m.
fn bench_view() -> CameraView {
    CameraView::from_project(&lightloom_nodes::project::Camera {
        name: "bench".into(),
        position: [0.0, 0.5, 3.0],
        target: [0.0; 3],
        fov_y_deg: 45.0,
    })
}

pub(crate) fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Evaluates what drawing Output `output` needs and gathers the frame: the frame, the CPU
/// milliseconds it took and how many stages computed.
pub(crate) fn evaluate_frame(engine: &Arc<Engine>, graph: &Graph, output: &str) -> Result<(FrameInputs, f64, usize)> {
    let start = Instant::now();
    let evaluation = evaluate(engine.clone(), graph, output_request(graph, output), true);
    fail_on_errors(&evaluation, &upstream_of(graph, output))?;
    let frame = FrameInputs::gather(&evaluation, graph, output).map_err(|e| anyhow!(e))?;
    if std::env::var_os("LIGHTLOOM_BENCH_STAGES").is_some() {
        for s in evaluation.report.stages.iter().filter(|s| s.ms > 1.0) {
            eprintln!("    {}.{}: {:.1} ms {:?}", s.node, s.stage, s.ms, s.reasons);
        }
        eprintln!("    total with the gather: {:.1} ms", start.elapsed().as_secs_f64() * 1e3);
    }
    Ok((frame, start.elapsed().as_secs_f64() * 1e3, evaluation.report.computed().len()))
}

/// Draws and waits until the GPU has finished the frame.
pub(crate) fn timed_frame(
    gpu: &GpuContext,
    renderer: &mut ViewportRenderer,
    frame: &FrameInputs,
    view: &CameraView,
    size: (u32, u32),
) -> Result<f64> {
    let start = Instant::now();
    renderer.render(gpu, frame, view, size.0, size.1)?;
    gpu.wait()?;
    Ok(start.elapsed().as_secs_f64() * 1e3)
}

pub fn run(args: &BenchArgs) -> Result<()> {
    let wanted = |section: &str| args.only.is_empty() || args.only.iter().any(|s| s == section);
    if wanted("rays") {
        crate::bench_rays::ray_figures(args.rays_dump.as_deref())?;
        if args.only.iter().all(|s| s == "rays") && !args.only.is_empty() {
            return Ok(());
        }
    }
    let gpu = GpuContext::headless()?;
    println!("device: {}", gpu.describe());
    if wanted("default") {
        default_project_figures(args, &gpu)?;
    }
    if wanted("fog") {
        fog_figures(args, &gpu)?;
    }
    if wanted("rsl") {
        rsl_figures();
        rsl_mode_figures(args, &gpu)?;
    }
    if wanted("blockers") {
        crate::bench_blockers::blocker_figures(&gpu);
    }
    if wanted("adaptive") {
        crate::bench_adaptive::adaptive_figures();
    }
    if wanted("area") {
        crate::bench_area::area_light_figures();
        crate::bench_area::area_sample_figures(args, &gpu)?;
    }
    if wanted("normal_maps") {
        crate::bench_normal_maps::normal_map_figures(args, &gpu)?;
    }
    if wanted("synthetic") {
        synthetic_figures(args, &gpu)?;
    }
    Ok(())
}

fn rsl_figures() {
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
fn rsl_mode_figures(args: &BenchArgs, gpu: &GpuContext) -> Result<()> {
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
        let sat = BrdfSat::build(&lightloom_nodes::brdf::Brdf::from_material(&material), &cancel)
            .map_err(|e| anyhow!("{e}"))?;
        println!("  BRDF summed-area tables, {label}: {:.1} ms ({} view slices)", ms(start), sat.lobes.len());
    }
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
    for face in [8, 16] {
        let start = Instant::now();
        let field = Ovdf::compute(
            &lightloom_nodes::raycast::RayScene::build(&occluder),
            bounding_sphere(&occluder),
            face,
            VDT_SIZE,
            &cancel,
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
    let keyed = |key: u128, value: StageValue| Keyed { key, value: Arc::new(value) };
    let geometry = Geometry { meshes: keyed(1, StageValue::new(receiver.clone())), mesh_materials: vec![0, 0] };
    let surfaces = lightloom_nodes::frame::RslSurfaces::new(
        &lights,
        2,
        keyed(3, StageValue::new(visibility.expect("at least one frame"))),
        &[keyed(4, StageValue::new(sat))],
        None,
        &geometry,
    )
    .map_err(|e| anyhow!(e))?;
    let materials = vec![FrameMaterial { node: "bench".into(), material, normal: None }];
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
        crate::bench_anchors::XU_TABLE_1.beside(rate),
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
    let frame_of = |graph: &Graph| evaluate_frame(&engine, graph, "output");
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

fn fog_figures(args: &BenchArgs, gpu: &GpuContext) -> Result<()> {
    let path = std::path::Path::new("fog_lamps.ron");
    let project =
        lightloom_nodes::project::Project::from_ron(include_str!("../../tests/projects/fog_lamps.ron"), path)?;
    let view = CameraView::from_project(&project.camera(None).map_err(|e| anyhow!(e))?);
    let mut graph = project.graph(path).map_err(|e| anyhow!("{e:?}"))?;
    // The default table resolution (the project uses a smaller one to keep tests quick).
    graph.set_param("fog", "table_resolution", ParamValue::Choice("512".into()))?;
    let engine = Arc::new(Engine::in_memory());
    let mut renderer = ViewportRenderer::new(gpu);
    let frame_of = |graph: &Graph| evaluate_frame(&engine, graph, "output");
    let (frame, tables_ms, _) = frame_of(&graph)?;
    timed_frame(gpu, &mut renderer, &frame, &view, (1280, 720))?;
    let frames: Vec<f64> =
        (0..args.frames).map(|_| timed_frame(gpu, &mut renderer, &frame, &view, (1280, 720))).collect::<Result<_>>()?;
    println!(
        "
fog: two street lamps over a wet street, 1280x720 (tables 512² F, 128² × 49 G: {tables_ms:.0} ms once)"
    );
    println!("{:<28} {:>16} {:>12}", "edit", "edit stages ms", "frame ms");
    println!("{:<28} {:>16} {:>12.1}", "(none)", "-", median(frames));
    for (label, node, param, values) in [
        ("move a lamp", "lamp1", "position", [[-3.0, 4.0, -9.0], [-2.0, 4.0, -9.0], [-2.0, 5.0, -8.0]]),
        ("change β", "fog", "beta", [[0.05, 0.05, 0.05], [0.08, 0.08, 0.1], [0.02, 0.03, 0.04]]),
    ] {
        let (mut stages, mut frames) = (Vec::new(), Vec::new());
        for v in values {
            let value = if param == "beta" { ParamValue::Color(v) } else { ParamValue::Vec3(v) };
            graph.set_param(node, param, value)?;
            let (frame, ms, _) = frame_of(&graph)?;
            stages.push(ms);
            frames.push(timed_frame(gpu, &mut renderer, &frame, &view, (1280, 720))?);
        }
        println!("{label:<28} {:>16.1} {:>12.1}", median(stages), median(frames));
    }
    Ok(())
}

fn default_project_figures(args: &BenchArgs, gpu: &GpuContext) -> Result<()> {
    let project = lightloom_nodes::project::default_project();
    let camera = project.camera(None).map_err(|e| anyhow!(e))?;
    let view = CameraView::from_project(&camera);
    let base = project.graph(std::path::Path::new("default.ron")).map_err(|e| anyhow!("{e:?}"))?;
    println!(
        "\ndefault project, glossy Phong material, 1280x720: edit→frame after a BRDF edit (exponent), an \
         environment rotation (yaw) and a sun move (the procedural sky's elevation: a new environment)"
    );
    println!(
        "{:<18} {:<15} {:>15} {:>14} {:>15} {:>14} {:>14} {:>13} {:>9}",
        "mode",
        "sun",
        "BRDF stages ms",
        "BRDF→frame ms",
        "turn stages ms",
        "turn→frame ms",
        "sun stages ms",
        "sun→frame ms",
        "frame ms"
    );
    let modes = ["sh_irradiance", "sh_prt", "wavelet_vertex", "wavelet_pixel"];
    for (mode, sun) in modes.iter().flat_map(|m| ["separate", "in_environment"].map(|s| (*m, s))) {
        let mut graph = base.clone();
        graph.set_param("output", "mode", ParamValue::Choice(mode.into()))?;
        graph.set_param("output", lightloom_nodes::kinds::output::SUN, ParamValue::Choice(sun.into()))?;
        graph.set_param("material", "model", ParamValue::Choice("phong".into()))?;
        graph.set_param("material", "f0", ParamValue::Float(0.3))?;
        let engine = Arc::new(Engine::in_memory());
        let mut renderer = ViewportRenderer::new(gpu);
        let frame_of = |graph: &Graph| evaluate_frame(&engine, graph, "output").map(|(frame, _, _)| frame);
        let frame = frame_of(&graph)?;
        timed_frame(gpu, &mut renderer, &frame, &view, (1280, 720))?;
        // Median evaluation time and edit-to-frame time over `args.frames` edits.
        let mut latency = |graph: &mut Graph, edit: &dyn Fn(&mut Graph, usize) -> Result<()>| -> Result<(f64, f64)> {
            let (mut latencies, mut stages) = (Vec::new(), Vec::new());
            for i in 0..args.frames {
                edit(graph, i)?;
                let start = Instant::now();
                let frame = frame_of(graph)?;
                stages.push(start.elapsed().as_secs_f64() * 1e3);
                timed_frame(gpu, &mut renderer, &frame, &view, (1280, 720))?;
                latencies.push(start.elapsed().as_secs_f64() * 1e3);
            }
            Ok((median(stages), median(latencies)))
        };
        let brdf = latency(&mut graph, &|g, i| {
            Ok(g.set_param("material", "exponent", ParamValue::Float(10.0 + 7.0 * i as f64))?)
        })?;
        let turn = latency(&mut graph, &|g, i| {
            Ok(g.set_param("sky", "rotation", ParamValue::Vec3([10.0 + 13.0 * i as f64, 0.0, 0.0]))?)
        })?;
        let sun_move = latency(&mut graph, &|g, i| {
            Ok(g.set_param("sky", "sun_elevation", ParamValue::Float(30.0 + 3.0 * i as f64))?)
        })?;
        let frame = frame_of(&graph)?;
        let frames: Vec<f64> = (0..args.frames)
            .map(|_| timed_frame(gpu, &mut renderer, &frame, &view, (1280, 720)))
            .collect::<Result<_>>()?;
        println!(
            "{mode:<18} {sun:<15} {:>15.1} {:>14.1} {:>15.1} {:>14.1} {:>14.1} {:>13.1} {:>9.1}",
            brdf.0,
            brdf.1,
            turn.0,
            turn.1,
            sun_move.0,
            sun_move.1,
            median(frames)
        );
    }
    Ok(())
}

fn synthetic_figures(args: &BenchArgs, gpu: &GpuContext) -> Result<()> {
    let segments = ((args.vertices as f64 / 2.0).sqrt()).round().max(4.0) as usize;
    let mesh = lightloom_nodes::mesh::sphere(1.0, segments);
    let meshes = lightloom_nodes::mesh::MeshSet { meshes: vec![mesh] };
    let n = meshes.meshes[0].positions.len();
    let receivers = Receivers::from_meshes(&meshes);
    let bandwidth = crate::bench_anchors::copy_bandwidth();
    println!(
        "\nsynthetic sphere: {n} vertices, 1280x720; memory bandwidth {:.1} GB/s (parallel copy, read + write); \
         \"bound\": the least time to read and write a relight's bytes per vertex at that bandwidth",
        bandwidth / 1e9
    );
    println!("{:<24} {:>22} {:>14}  against the anchors", "mode", "lighting change ms", "frame ms");
    let mut rng = rand::rngs::SmallRng::seed_from_u64(7);
    let view = bench_view();
    let environment = lightloom_nodes::cubemap::CubeMap::from_fn(64, 1, |d| [1.0 + d.y, 0.8, 0.5 + d.x.abs()]);
    let light = lightloom_nodes::sh::project_samples(8, environment.samples());
    let keyed = |key: u128, value: StageValue| Keyed { key, value: Arc::new(value) };
    let base_settings = lightloom_nodes::kinds::output::OutputSettings {
        mode: Mode::ShIrradiance,
        exposure: 0.0,
        tonemap: Tonemap::Aces,
        background: true,
        view: View::Approximation,
        reference_samples: 1,
        separate_sun: false,
        wavelet_details: 0,
    };
    let material = lightloom_nodes::brdf::Material {
        model: lightloom_nodes::brdf::Model::Phong,
        exponent: 20.0,
        f0: 0.3,
        ..Default::default()
    };
    let materials = vec![FrameMaterial { node: "bench".into(), material: material.clone(), normal: None }];
    let geometry = Geometry { meshes: keyed(1, StageValue::new(meshes.clone())), mesh_materials: vec![0] };
    let frame_with = |mode: Mode, surfaces: Surfaces| FrameInputs {
        geometry: geometry.clone(),
        ray_scene: None,
        mode,
        pending: None,
        settings: lightloom_nodes::kinds::output::OutputSettings { mode, ..base_settings.clone() },
        ignored_inputs: Vec::new(),
        lobe_limits: Vec::new(),
        materials: materials.clone(),
        background: Background { radiance: Some(keyed(4, StageValue::new(environment.clone()))), visible: true },
        surfaces,
        medium: MediumFrame::new(Vec::new(), &materials, None),
        area_lights: None,
        blockers: None,
        sun: None,
        normal_maps: Default::default(),
    };
    let mut renderer = ViewportRenderer::new(gpu);
    let frame_times = |renderer: &mut ViewportRenderer, frame: &FrameInputs| -> Result<f64> {
        timed_frame(gpu, renderer, frame, &view, (1280, 720))?;
        let times: Vec<f64> =
            (0..args.frames).map(|_| timed_frame(gpu, renderer, frame, &view, (1280, 720))).collect::<Result<_>>()?;
        Ok(median(times))
    };
    let irradiance = IrradianceSurfaces::new(Some(&light), None, &materials);
    let frame = frame_with(Mode::ShIrradiance, Surfaces::Irradiance(irradiance));
    println!("{:<24} {:>22} {:>14.1}", "sh_irradiance", "-", frame_times(&mut renderer, &frame)?);
    for bands in [6usize, 8] {
        let count = n * bands * bands;
        let random = |rng: &mut rand::rngs::SmallRng| (0..count).map(|_| rng.random::<f32>() * 0.1).collect::<Vec<_>>();
        let transport = ShTransport { bands, rays: 0, visibility: random(&mut rng), transfer: random(&mut rng) };
        let start = Instant::now();
        let incident = lightloom_nodes::prt::incident_radiance(&light, &transport, &CancelToken::default())
            .map_err(|e| anyhow!("{e}"))?;
        let change_ms = start.elapsed().as_secs_f64() * 1e3;
        let surfaces = PrtSurfaces::new(
            keyed(10 + bands as u128, StageValue::new(transport)),
            keyed(20 + bands as u128, StageValue::new(incident)),
            Some(&light),
            None,
            &materials,
            vec![lightloom_nodes::prt::glossy_lobe(&material, lightloom_nodes::prt::LOBE_BANDS)],
            n,
        )
        .map_err(|e| anyhow!(e))?;
        let frame = frame_with(Mode::ShPrt, Surfaces::Prt(surfaces));
        let ms = frame_times(&mut renderer, &frame)?;
        // The relight reads each vertex's visibility and writes its RGB incident radiance (f32).
        let bytes = 4 * bands * bands * 4;
        let bound = crate::bench_anchors::bandwidth_bound_ms(n, bytes, bandwidth);
        println!(
            "{:<24} {:>22.1} {:>14.1}  {:.1}× the bandwidth bound ({bound:.1} ms for {bytes} B per vertex)",
            format!("sh_prt {bands} bands"),
            change_ms,
            ms,
            change_ms / bound
        );
    }
    let table = {
        let grid = lightloom_nodes::triple_product::CellGrid::for_coefficients(320).map_err(|e| anyhow!(e))?;
        let brdf = lightloom_nodes::brdf::Brdf::from_material(&material);
        let start = Instant::now();
        let table = lightloom_nodes::triple_product::tabulate_brdf(&brdf, grid, &CancelToken::default())
            .map_err(|e| anyhow!("{e}"))?;
        println!(
            "(BRDF table, 320 cells and their two finer levels × {} outgoing directions: {:.1} ms)",
            lightloom_nodes::triple_product::THETA_STEPS * lightloom_nodes::triple_product::PHI_STEPS,
            start.elapsed().as_secs_f64() * 1e3
        );
        table
    };
    for terms in [80usize, 320] {
        let depth = if terms == 80 { 2 } else { 3 };
        let cells = 20usize << (2 * depth);
        let basis = lightloom_nodes::wavelet::spherical::SphericalHaar::new(depth);
        let visibility = (0..n)
            .map(|_| {
                let dense: Vec<f64> = (0..cells).map(|_| if rng.random::<f64>() < 0.7 { 1.0 } else { 0.0 }).collect();
                SparseVector::largest(&basis.forward(&dense), terms, |_| 1.0)
            })
            .collect();
        let transport = SphericalTransport { depth, keep: terms, visibility };
        let grid = lightloom_nodes::triple_product::CellGrid::for_coefficients(terms).map_err(|e| anyhow!(e))?;
        let cell_visibility =
            lightloom_nodes::triple_product::local_visibility(grid, &transport, &CancelToken::default())
                .map_err(|e| anyhow!("{e}"))?;
        let visibility = keyed(30 + terms as u128, StageValue::new(cell_visibility));
        let receivers_keyed = keyed(3, StageValue::new(receivers.clone()));
        // A new environment: prefiltering on the CPU, then the relight kernel in the next frame.
        let start = Instant::now();
        let prefiltered = lightloom_nodes::triple_product::prefiltered(&environment, grid);
        let prefilter_ms = start.elapsed().as_secs_f64() * 1e3;
        let surfaces = |rotation: glam::DMat3, environment_key: u128, details: usize| -> Result<WaveletSurfaces> {
            let lighting = WaveletLighting {
                visibility: visibility.clone(),
                receivers: receivers_keyed.clone(),
                environment: keyed(environment_key, StageValue::new(prefiltered.clone())),
                rotation,
            };
            WaveletSurfaces::new(
                lighting,
                &[keyed(40, StageValue::new(table.clone()))],
                None,
                None,
                &geometry,
                &materials,
                details,
            )
            .map_err(|e| anyhow!(e))
        };
        // The first frame after a change rebuilds P and E (on the GPU, or on the CPU and
        // uploaded); the rebuild's cost is that frame's excess over a steady frame.
        // Ma's top-only products (the anchor), then with 32 detail terms per vertex.
        for (on, details) in [
            (lightloom_render::RelightOn::Cpu, 0),
            (lightloom_render::RelightOn::Gpu, 0),
            (lightloom_render::RelightOn::Cpu, 32),
            (lightloom_render::RelightOn::Gpu, 32),
        ] {
            renderer.set_relight_on(on);
            let label = format!(
                "wavelet_vertex {terms}{} ({})",
                if details > 0 { format!("+{details}") } else { String::new() },
                if on == lightloom_render::RelightOn::Cpu { "CPU" } else { "GPU" }
            );
            let key = |k: u128| 100_000 * details as u128 + 1000 * (on as u128 + 1) + 10 * terms as u128 + k;
            let first = frame_with(
                Mode::WaveletVertex,
                Surfaces::Wavelet(Box::new(surfaces(glam::DMat3::IDENTITY, key(1), details)?)),
            );
            let steady = match frame_times(&mut renderer, &first) {
                Ok(ms) => ms,
                Err(e) => {
                    println!("{label:<24} {:>22}   not drawn: {e}", "-");
                    continue;
                }
            };
            let mut changed = |rotation: glam::DMat3, environment_key: u128| -> Result<f64> {
                let frame = frame_with(
                    Mode::WaveletVertex,
                    Surfaces::Wavelet(Box::new(surfaces(rotation, environment_key, details)?)),
                );
                Ok(timed_frame(gpu, &mut renderer, &frame, &view, (1280, 720))? - steady)
            };
            let new_environment = changed(glam::DMat3::IDENTITY, key(2))? + prefilter_ms;
            let rotation = changed(glam::DMat3::from_rotation_y(0.7), key(2))?;
            // Ma recomputes every product every frame: its fps is a rotation's edit-to-frame rate.
            let rate = n as f64 / (rotation + steady) / 1e3;
            let ma = match details {
                0 => crate::bench_anchors::ma_interpolated(terms).map_or(String::new(), |a| a.beside(rate)),
                _ => "(no anchor: Ma keeps top-only coefficients)".to_string(),
            };
            // The relight reads each vertex's frame (32 B) and f16 visibility cells and writes its
            // RGB9E5 products and diffuse transfer (16 B), and its detail terms (20 B each), as the
            // GPU kernel stores them. The bound is host memory's: it says nothing of the kernel on
            // a GPU's own memory.
            let bound = if on == lightloom_render::RelightOn::Cpu {
                let bytes = 32 + 2 * terms + 4 * terms + 16 + 20 * details;
                let ms = crate::bench_anchors::bandwidth_bound_ms(n, bytes, bandwidth);
                format!("rotation {:.1}× the bandwidth bound ({ms:.1} ms for {bytes} B per vertex); ", rotation / ms)
            } else {
                String::new()
            };
            println!(
                "{label:<24} {:>22} {steady:>14.1}  {bound}rotation to frame {rate:.2} M vertices/s = {ma}",
                format!("{new_environment:.1} (rotation {rotation:.0})"),
            );
        }
    }
    Ok(())
}
