//! `lightloom bench --only normal_maps`: what a normal map costs a frame. The hammered-metal
//! sample (`projects/samples/hammered_metal.ron`: a 256² map on a floor and a sphere, a low sun
//! glinting on them) drawn without its map and with each filter, and the stages that build
//! its pyramids; then in `sh_prt`, whose per-vertex highlight each pixel corrects for its NDF.

use super::common::{BenchArgs, evaluate_frame, median, timed_frame};
use anyhow::{Result, anyhow};
use lightloom_nodes::engine::Engine;
use lightloom_nodes::engine::spec::ParamValue;
use lightloom_render::{CameraView, GpuContext, ViewportRenderer};
use std::sync::Arc;

pub fn normal_map_figures(args: &BenchArgs, gpu: &GpuContext) -> Result<()> {
    let path = crate::samples::project("hammered_metal")?;
    let (project, graph) = lightloom_nodes::project::Project::load(&path).map_err(|e| anyhow!("{e}"))?;
    let view = CameraView::from_project(&project.camera(Some("main")).map_err(|e| anyhow!(e))?);
    let size = (1280, 720);
    let engine = Arc::new(Engine::in_memory());
    let mut renderer = ViewportRenderer::new(gpu);
    const FILTERS: [(&str, bool, &str); 5] = [
        ("no normal map", false, "sh"),
        ("averaged normals", true, "none"),
        ("Toksvig", true, "toksvig"),
        ("SH NDF", true, "sh"),
        ("vMF mixture", true, "vmf"),
    ];
    // sh_prt shades the environment per vertex and corrects each pixel's highlight for its NDF
    // through the prefiltered light.
    for (mode, filters) in [("sh_irradiance", &FILTERS[..]), ("sh_prt", &[FILTERS[0], FILTERS[3], FILTERS[4]][..])] {
        println!(
            "\nnormal maps, the hammered-metal sample ({mode}, a 256² map tiled 8 times), {}x{}: frame time without \
             the map and with each filter, and the stages the map's first evaluation computed",
            size.0, size.1
        );
        let mut baseline = None;
        for &(label, map, filter) in filters {
            let mut graph = graph.clone();
            graph.set_param("output", "mode", ParamValue::Choice(mode.into()))?;
            if !map {
                graph.set_param("hammered", "normal_map", ParamValue::Path(String::new()))?;
            }
            graph.set_param("hammered", "normal_filter", ParamValue::Choice(filter.into()))?;
            let (frame, stages_ms, computed) = evaluate_frame(&engine, &graph, "output", gpu)?;
            timed_frame(gpu, &mut renderer, &frame, &view, size)?;
            let times: Vec<f64> = (0..args.frames)
                .map(|_| timed_frame(gpu, &mut renderer, &frame, &view, size))
                .collect::<Result<_>>()?;
            let ms = median(times);
            let overhead = match baseline {
                None => {
                    baseline = Some(ms);
                    String::new()
                }
                Some(base) => format!(" ({:+.1} ms, {:+.0}% over no map)", ms - base, 100.0 * (ms / base - 1.0)),
            };
            println!("  {label:<17} frame {ms:>8.1} ms{overhead}; stages {stages_ms:.0} ms ({computed} computed)");
        }
    }
    Ok(())
}
