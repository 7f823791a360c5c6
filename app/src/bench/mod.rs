//! `lightloom bench`: prints the relighting figures (the numbers behind the speed claims).
//! Benchmarks print; tests never time anything.
//!
//! * Visibility rays (`rays.rs`): one at a time and in bundles, beside Embree's rate.
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
//! * Blocker spheres (`blockers.rs`): the thesis's Fig. 5.5 speed-up table and its scenes'
//!   update rates, on the CPU.

mod adaptive;
mod anchors;
mod area;
mod blockers;
mod common;
mod normal_maps;
mod rays;
mod rsl;
mod synthetic;

use anyhow::{Result, anyhow};
pub use common::BenchArgs;
use common::*;
use lightloom_nodes::engine::spec::ParamValue;
use lightloom_nodes::engine::{Engine, Graph};
use lightloom_render::{CameraView, GpuContext, ViewportRenderer};
use std::sync::Arc;
use std::time::Instant;

pub fn run(args: &BenchArgs) -> Result<()> {
    let wanted = |section: &str| args.only.is_empty() || args.only.iter().any(|s| s == section);
    if wanted("rays") {
        rays::ray_figures(args.rays_dump.as_deref())?;
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
        rsl::rsl_figures();
        rsl::rsl_mode_figures(args, &gpu)?;
    }
    if wanted("blockers") {
        blockers::blocker_figures(&gpu);
    }
    if wanted("adaptive") {
        adaptive::adaptive_figures();
    }
    if wanted("area") {
        area::area_light_figures();
        area::area_sample_figures(args, &gpu)?;
    }
    if wanted("area_engine") {
        area::area_engine_figures(args)?;
    }
    if wanted("rsl_engine") {
        rsl::rsl_engine_figures()?;
    }
    if wanted("normal_maps") {
        normal_maps::normal_map_figures(args, &gpu)?;
    }
    if wanted("synthetic") {
        synthetic::synthetic_figures(args, &gpu)?;
    }
    Ok(())
}

fn fog_figures(args: &BenchArgs, gpu: &GpuContext) -> Result<()> {
    let path = std::path::Path::new("fog_lamps.ron");
    let project =
        lightloom_nodes::project::Project::from_ron(include_str!("../../../tests/projects/fog_lamps.ron"), path)?;
    let view = CameraView::from_project(&project.camera(None).map_err(|e| anyhow!(e))?);
    let mut graph = project.graph(path).map_err(|e| anyhow!("{e:?}"))?;
    // The default table resolution (the project uses a smaller one to keep tests quick).
    graph.set_param("fog", "table_resolution", ParamValue::Choice("512".into()))?;
    let engine = Arc::new(Engine::in_memory());
    let mut renderer = ViewportRenderer::new(gpu);
    let frame_of = |graph: &Graph| evaluate_frame(&engine, graph, "output", gpu);
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
        let frame_of = |graph: &Graph| evaluate_frame(&engine, graph, "output", gpu).map(|(frame, _, _)| frame);
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
