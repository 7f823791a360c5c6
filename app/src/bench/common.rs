//! What every bench section shares: its arguments, the synthetic view, medians, and timed
//! evaluations and frames.

use crate::project_commands::{evaluate, fail_on_errors, output_request, upstream_of};
use anyhow::{Result, anyhow};
use clap::Args;
use lightloom_nodes::engine::{Engine, Graph};
use lightloom_nodes::frame::FrameInputs;
use lightloom_render::{CameraView, GpuContext, ViewportRenderer};
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
    /// Only these sections (rays, default, fog, rsl, blockers, adaptive, area, area_engine,
    /// rsl_engine, normal_maps, synthetic; all when empty).
    #[arg(long, value_delimiter = ',')]
    pub only: Vec<String>,
    /// Also write the rays section's mesh and rays into this folder, for
    /// `tools/rays/compare_mitsuba.py` to trace the same rays with Mitsuba 3 (Embree).
    #[arg(long, value_name = "DIR")]
    pub rays_dump: Option<std::path::PathBuf>,
}

/// The view of the synthetic meshes: a unit object at the origin from 3 m.
pub(super) fn bench_view() -> CameraView {
    CameraView::from_project(&lightloom_nodes::project::Camera {
        name: "bench".into(),
        position: [0.0, 0.5, 3.0],
        target: [0.0; 3],
        fov_y_deg: 45.0,
    })
}

pub(super) fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Evaluates what drawing Output `output` on `gpu` needs and gathers the frame: the frame, the
/// CPU milliseconds it took (the wavelet modes' relight among them on a CPU adapter) and how
/// many stages computed.
pub(super) fn evaluate_frame(
    engine: &Arc<Engine>,
    graph: &Graph,
    output: &str,
    gpu: &GpuContext,
) -> Result<(FrameInputs, f64, usize)> {
    let start = Instant::now();
    let relight_on_cpu = lightloom_render::RelightOn::from_env().on_cpu(gpu);
    let evaluation = evaluate(engine.clone(), graph, output_request(graph, output, relight_on_cpu), true);
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
pub(super) fn timed_frame(
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
