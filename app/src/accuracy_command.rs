//! `lightloom accuracy`: renders the Monte Carlo reference of a project once, then the
//! approximation at several coefficient counts, and prints each one's error against it — the
//! numbers behind "honest about its error". Errors are over pixels wholly covered by geometry.

use crate::project_commands::{evaluate, fail_on_errors, load, upstream_of};
use anyhow::{Result, anyhow, bail};
use clap::Args;
use lightloom_nodes::engine::spec::ParamValue;
use lightloom_nodes::engine::{CancelToken, Graph};
use lightloom_nodes::frame::{FrameInputs, FrameNeeds, frame_request_for, mode_stages};
use lightloom_nodes::kinds::output::{SUN, find_output};
use lightloom_nodes::reference::{self, ImageError, PinholeCamera};
use lightloom_render::{CameraView, GpuContext, ViewportRenderer};
use serde::Serialize;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

#[derive(Args, Debug)]
pub struct AccuracyArgs {
    /// Project file (.ron), or `sample:NAME` for a built-in sample (`lightloom samples` lists them).
    pub project: PathBuf,
    /// SH band counts for the `sh_prt` rows (lighting and transport use the same count).
    #[arg(long, value_delimiter = ',', default_value = "2,3,4,6,8")]
    pub bands: Vec<usize>,
    /// SH levels for the `sh_adaptive` rows, each with the Output's adaptive threshold (lighting
    /// and transport take one band more; none: `--adaptive` alone).
    #[arg(long, value_delimiter = ',', num_args = 0.., default_value = "5,10")]
    pub adaptive: Vec<usize>,
    /// Top-only coefficient counts for the `wavelet_vertex` rows (none: `--wavelets` alone).
    #[arg(long, value_delimiter = ',', num_args = 0.., default_value = "80,320")]
    pub wavelets: Vec<usize>,
    /// Detail terms per receiver for the wavelet rows (the Output's `wavelet_details`), a row
    /// for each (default: the project's own setting).
    #[arg(long, value_delimiter = ',')]
    pub details: Vec<usize>,
    /// Square-light counts for the `rsl` rows (when an RSL decomposer feeds the Output; none:
    /// `--square-lights` alone).
    #[arg(long, value_delimiter = ',', num_args = 0.., default_value = "10,30,60,100")]
    pub square_lights: Vec<usize>,
    /// Reference samples per pixel.
    #[arg(long, default_value_t = 256)]
    pub samples: usize,
    #[arg(long, default_value_t = 320)]
    pub width: u32,
    #[arg(long, default_value_t = 180)]
    pub height: u32,
    #[arg(long)]
    pub camera: Option<String>,
    /// Rows for each way of lighting the environment's sun (`separate`, `in_environment`;
    /// default: the project's own setting).
    #[arg(long, value_delimiter = ',')]
    pub sun: Vec<String>,
    /// Time an edit (repeatable, applied together): each row draws the project, then sets these
    /// parameters and reports the edit→frame time (the changed stages, relight, draw). Errors
    /// are then the edited image's against the edited project's reference.
    #[arg(long = "edit", value_name = "NODE.PARAM=VALUE")]
    pub edits: Vec<String>,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub eval: crate::project_commands::EvalOptions,
}

/// One approximation's error against the reference.
#[derive(Debug, Serialize)]
pub struct Row {
    pub mode: String,
    pub coefficients: usize,
    /// The wavelet rows' detail terms per receiver.
    pub details: Option<usize>,
    /// How the environment's sun was lit (the Output's `sun`).
    pub sun: String,
    #[serde(flatten)]
    pub error: ImageError,
    /// The relative RMSE with the reference's own noise taken out: √(rel² − noise²), the
    /// approximation's error against the converged image.
    pub relative_rmse_less_noise: f64,
    /// The first frame: uploads, relighting and drawing (with `--edit`, the first offscreen
    /// frame after the edit's own).
    pub render_ms: f64,
    /// A steady frame (nothing changed): what orbiting the camera costs.
    pub frame_ms: f64,
    /// With `--edit`: from the edit to its frame drawn (the changed stages, relight, draw).
    pub edit_ms: Option<f64>,
    /// With `--edit`: of `edit_ms`, evaluating the stages the edit changed.
    pub edit_stages_ms: Option<f64>,
    /// What the mode's stages hold (transport, visibility, lighting), bytes.
    pub memory_bytes: usize,
    /// No other row has lower-or-equal error, frame time and memory (one strictly lower).
    pub pareto: bool,
}

#[derive(Debug, Serialize)]
pub struct Report {
    pub project: String,
    pub width: u32,
    pub height: u32,
    pub reference_samples: usize,
    pub reference_ms: f64,
    /// The reference's own noise: RMSE between two independent references, divided by √2.
    pub reference_noise: ImageError,
    /// The `--edit` assignments the rows were timed and measured after.
    pub edits: Vec<String>,
    pub rows: Vec<Row>,
}

pub fn run(args: &AccuracyArgs) -> Result<()> {
    let (project, graph) = load(&args.project, &args.eval.overrides)?;
    let output = find_output(&graph, project.render.output_node()).map_err(|e| anyhow!(e))?.id.clone();
    let edits = args
        .edits
        .iter()
        .map(|e| project.parse_override(e).map_err(|e| anyhow!(e.replacen("--set", "--edit", 1))))
        .collect::<Result<Vec<_>>>()?;
    refuse_edits_the_rows_make(args, &graph, &output, &edits)?;
    let upstream_id = |input: &str| graph.upstream(&output, input).map(|n| n.id.clone());
    let (scene_id, environment_id, decomposer_id) =
        (upstream_id("scene"), upstream_id("environment"), upstream_id("square_lights"));
    let camera = project.camera(args.camera.as_deref()).map_err(|e| anyhow!(e))?;
    let engine = Arc::new(args.eval.engine());
    let size = (args.width, args.height);
    let gpu = GpuContext::headless()?;
    let mut renderer = ViewportRenderer::new(&gpu);
    let relight_on_cpu = lightloom_render::RelightOn::from_env().on_cpu(&gpu);
    let view = CameraView::from_project(&camera);
    let pinhole =
        PinholeCamera { position: camera.position.into(), target: camera.target.into(), fov_y_deg: camera.fov_y_deg };

    let evaluated_in = |engine: &Arc<lightloom_nodes::engine::Engine>, graph: &Graph| -> Result<(FrameInputs, usize)> {
        let needs = FrameNeeds { picking: true, relight_on_cpu };
        let evaluation = evaluate(engine.clone(), graph, frame_request_for(graph, &output, needs), true);
        fail_on_errors(&evaluation, &upstream_of(graph, &output))?;
        let frame = FrameInputs::gather(&evaluation, graph, &output).map_err(|e| anyhow!(e))?;
        let memory = frame_memory(&evaluation, graph, &output, &frame);
        Ok((frame, memory))
    };
    let evaluated = |graph: &Graph| evaluated_in(&engine, graph);
    let frame_of = |graph: &Graph| evaluated(graph).map(|(frame, _)| frame);
    let edited = |graph: &Graph| -> Result<Graph> {
        let mut graph = graph.clone();
        for (node, param, value) in &edits {
            graph.set_param(node, param, value.clone())?;
        }
        Ok(graph)
    };
    let mut base = graph.clone();
    base.set_param(&output, "reference_samples", ParamValue::Int(args.samples as i64))?;
    let base_frame = frame_of(&edited(&base)?)?;
    let start = Instant::now();
    let reference_with = |seed| {
        base_frame
            .render_reference(&pinhole, (size.0 as usize, size.1 as usize), seed, &CancelToken::default(), &|_| {})
            .map_err(|e| anyhow!(e))
    };
    let reference = reference_with(1)?;
    let reference_ms = start.elapsed().as_secs_f64() * 1e3;
    let second = reference_with(2)?;
    let mask = reference.surface_mask();
    let mut noise = reference::compare(&second.pixels, &reference.pixels, Some(&mask)).map_err(|e| anyhow!(e))?;
    noise.rmse /= 2f64.sqrt();
    noise.relative_rmse /= 2f64.sqrt();
    noise.psnr_db += 20.0 * 2f64.sqrt().log10();

    let suns: Vec<Option<&str>> =
        if args.sun.is_empty() { vec![None] } else { args.sun.iter().map(|s| Some(s.as_str())).collect() };
    let mut measure_one = |graph: &Graph, mode: &str, coefficients: usize, sun: Option<&str>| -> Result<Row> {
        let mut graph = graph.clone();
        if let Some(sun) = sun {
            graph.set_param(&output, SUN, ParamValue::Choice(sun.into()))?;
        }
        let (mut edit_ms, mut edit_stages_ms) = (None, None);
        if !edits.is_empty() {
            // The project drawn as it was, then the edit to its frame on screen, in an engine of
            // its own: the shared one already holds the edited project's stages (the reference
            // and earlier rows computed them). Transports still come from the disk cache.
            let own = Arc::new(args.eval.engine());
            let (before, _) = evaluated_in(&own, &graph)?;
            for _ in 0..2 {
                renderer.render(&gpu, &before, &view, size.0, size.1)?;
                gpu.wait()?;
            }
            graph = edited(&graph)?;
            let start = Instant::now();
            let (after, _) = evaluated_in(&own, &graph)?;
            edit_stages_ms = Some(start.elapsed().as_secs_f64() * 1e3);
            renderer.render(&gpu, &after, &view, size.0, size.1)?;
            gpu.wait()?;
            edit_ms = Some(start.elapsed().as_secs_f64() * 1e3);
        }
        let (frame, memory_bytes) = evaluated(&graph)?;
        // What the frame does: a mode that cannot light the sun apart (rsl), or an environment
        // without a sun, leaves it in the environment whatever was asked.
        let sun = if frame.sun.is_some() { "separate" } else { "in_environment" }.to_string();
        let start = Instant::now();
        let captured = renderer.render_offscreen(&gpu, &frame, &view, size.0, size.1)?;
        let render_ms = start.elapsed().as_secs_f64() * 1e3;
        let start = Instant::now();
        renderer.render_offscreen(&gpu, &frame, &view, size.0, size.1)?;
        let frame_ms = start.elapsed().as_secs_f64() * 1e3;
        let pixels: Vec<[f32; 3]> = captured.hdr.iter().map(|p| [p[0], p[1], p[2]]).collect();
        let error = reference::compare(&pixels, &reference.pixels, Some(&mask)).map_err(|e| anyhow!(e))?;
        let relative_rmse_less_noise = (error.relative_rmse.powi(2) - noise.relative_rmse.powi(2)).max(0.0).sqrt();
        let details = match &frame.surfaces {
            lightloom_nodes::frame::Surfaces::Wavelet(w) => Some(w.details.kept),
            _ => None,
        };
        Ok(Row {
            mode: mode.into(),
            coefficients,
            details,
            sun,
            error,
            relative_rmse_less_noise,
            render_ms,
            frame_ms,
            edit_ms,
            edit_stages_ms,
            memory_bytes,
            pareto: false,
        })
    };
    // A row per way of lighting the sun that the mode takes (one where asking changes nothing).
    let mut measure = |graph: &Graph, mode: &str, coefficients: usize| -> Result<Vec<Row>> {
        let mut rows: Vec<Row> = Vec::new();
        for &sun in &suns {
            let row = measure_one(graph, mode, coefficients, sun)?;
            if rows.iter().all(|r| r.sun != row.sun) {
                rows.push(row);
            }
        }
        Ok(rows)
    };
    let scene = scene_id.as_deref().ok_or_else(|| anyhow!("no scene"))?;
    let linked =
        Linked { output: &output, scene, environment: environment_id.as_deref(), decomposer: decomposer_id.as_deref() };
    let mut rows = every_row(args, &base, &linked, &mut measure)?;
    mark_pareto_front(&mut rows);
    let report = Report {
        project: args.project.display().to_string(),
        width: size.0,
        height: size.1,
        reference_samples: args.samples,
        reference_ms,
        reference_noise: noise,
        edits: args.edits.clone(),
        rows,
    };
    print_report(args, &report, !edits.is_empty())
}

/// Marks the rows no other row dominates in (error less noise, steady frame time, memory).
fn mark_pareto_front(rows: &mut [Row]) {
    let key = |r: &Row| [r.relative_rmse_less_noise, r.frame_ms, r.memory_bytes as f64];
    let keys: Vec<[f64; 3]> = rows.iter().map(key).collect();
    for (i, row) in rows.iter_mut().enumerate() {
        row.pareto = !keys.iter().enumerate().any(|(j, other)| {
            j != i && other.iter().zip(&keys[i]).all(|(o, m)| o <= m) && other.iter().zip(&keys[i]).any(|(o, m)| o < m)
        });
    }
}

/// Refuses an `--edit` of what the rows set themselves (each would silently replace it),
/// naming the flag that sets it.
fn refuse_edits_the_rows_make(
    args: &AccuracyArgs,
    graph: &Graph,
    output: &str,
    edits: &[(String, String, ParamValue)],
) -> Result<()> {
    // What the rows set themselves, and the flag that sets it: an edit of it would silently
    // replace each row's value.
    let upstream_id = |input: &str| graph.upstream(output, input).map(|n| n.id.clone());
    let (scene_id, environment_id, decomposer_id) =
        (upstream_id("scene"), upstream_id("environment"), upstream_id("square_lights"));
    let set_by_rows = |node: &str, param: &str| -> Option<&'static str> {
        let is = |id: &Option<String>| id.as_deref() == Some(node);
        match param {
            "mode" if node == output => Some("the rows themselves (one per mode)"),
            "wavelet_terms" if node == output => Some("--wavelets"),
            "adaptive_level" if node == output => Some("--adaptive"),
            "wavelet_details" if node == output && !args.details.is_empty() => Some("--details"),
            "reference_samples" if node == output => Some("--samples"),
            SUN if node == output && !args.sun.is_empty() => Some("--sun"),
            "transport_bands" if is(&scene_id) => Some("--bands and --adaptive"),
            "sh_bands" if is(&environment_id) => Some("--bands and --adaptive"),
            "light_count" if is(&decomposer_id) => Some("--square-lights"),
            _ => None,
        }
    };
    for (node, param, _) in edits {
        if let Some(flag) = set_by_rows(node, param) {
            bail!(
                "--edit {node}.{param}: each row sets {node}.{param} itself (from {flag}); edit a light, material, \
                 camera or scene parameter instead"
            );
        }
    }
    Ok(())
}

/// The bytes a frame keeps for its mode: the stages it reads (but the scene's geometry and
/// the materials, which every mode keeps), a separately lit sun's shadow maps, and the kept
/// detail terms and fine lobe tables of the wavelet modes.
fn frame_memory(
    evaluation: &lightloom_nodes::engine::Evaluation,
    graph: &Graph,
    output: &str,
    frame: &FrameInputs,
) -> usize {
    let memory = mode_stages(graph, output, frame.mode)
        .iter()
        .filter(|r| !matches!(r.stage.as_str(), "settings" | "geometry" | "material"))
        .filter_map(|r| evaluation.get(&r.node, &r.stage)?.value.as_ref().ok().map(|v| v.approx_bytes()))
        .sum::<usize>();
    // The viewport's shadow maps of a separately lit sun.
    let memory = memory + if frame.sun.is_some() { lightloom_render::SUN_SHADOW_MAP_BYTES } else { 0 };
    // The kept detail terms (five words per receiver and term) and the fine lobe tables.
    memory
        + match &frame.surfaces {
            lightloom_nodes::frame::Surfaces::Wavelet(w) => {
                let receivers = (w.vertices.frames.len() + w.texels.as_ref().map_or(0, |t| t.frames.len())) / 2;
                receivers * w.details.kept * 20 + w.fine_specular_tables.iter().map(|t| t.len() * 2).sum::<usize>()
            }
            _ => 0,
        }
}

/// The report as JSON, or as a table with what it measured.
fn print_report(args: &AccuracyArgs, report: &Report, edited: bool) -> Result<()> {
    let (size, noise, reference_ms) = ((report.width, report.height), &report.reference_noise, report.reference_ms);
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        println!(
            "{}: {}x{}, reference {} spp in {:.0} ms (its own noise: RMSE {:.5}, relative {:.2}%)",
            report.project,
            size.0,
            size.1,
            args.samples,
            reference_ms,
            noise.rmse,
            noise.relative_rmse * 100.0
        );
        if edited {
            println!("after the edit {}; edit ms: from the edit to its frame drawn", args.edits.join(" "));
        }
        println!(
            "{:<28} {:>6} {:>7} {:<15} {:>10} {:>7} {:>9} {:>8} {:>9} {:>9} {:>9} {:>7}",
            "mode",
            "coeffs",
            "details",
            "sun",
            "RMSE",
            "rel. %",
            "- noise %",
            "PSNR dB",
            "frame ms",
            "edit ms",
            "memory",
            "Pareto"
        );
        for r in &report.rows {
            println!(
                "{:<28} {:>6} {:>7} {:<15} {:>10.5} {:>7.2} {:>9.2} {:>8.1} {:>9.1} {:>9} {:>8.1}M {:>7}",
                r.mode,
                r.coefficients,
                r.details.map_or("-".to_string(), |d| d.to_string()),
                r.sun,
                r.error.rmse,
                r.error.relative_rmse * 100.0,
                r.relative_rmse_less_noise * 100.0,
                r.error.psnr_db,
                r.frame_ms,
                r.edit_ms.map_or("-".to_string(), |ms| format!("{ms:.1}")),
                r.memory_bytes as f64 / (1 << 20) as f64,
                if r.pareto { "*" } else { "" }
            );
        }
        println!(
            "(- noise: the error with the reference's own noise taken out; Pareto: no other row has lower-or-equal \
             error, frame time and memory)"
        );
    }
    Ok(())
}

/// Measures a graph as one mode's rows: `(graph, mode label, coefficients)`.
type Measure<'a> = dyn FnMut(&Graph, &str, usize) -> Result<Vec<Row>> + 'a;

/// The nodes linked to the Output that the rows set.
struct Linked<'a> {
    output: &'a str,
    scene: &'a str,
    environment: Option<&'a str>,
    decomposer: Option<&'a str>,
}

/// Every row the flags ask for: the unshadowed sky, then `sh_prt` per band count,
/// `sh_adaptive` per level, the wavelet modes per term count and detail count, and `rsl` per
/// square-light count, each `measure`d on `base` with the row's settings.
fn every_row(args: &AccuracyArgs, base: &Graph, linked: &Linked, measure: &mut Measure) -> Result<Vec<Row>> {
    let mut rows = Vec::new();
    let mut irradiance = base.clone();
    irradiance.set_param(linked.output, "mode", ParamValue::Choice("sh_irradiance".into()))?;
    rows.extend(measure(&irradiance, "sh_irradiance (unshadowed sky)", 25)?);
    // An SH mode with its lighting and transport at `bands`.
    let sh_mode = |mode: &str, bands: usize| -> Result<Graph> {
        let mut g = base.clone();
        g.set_param(linked.output, "mode", ParamValue::Choice(mode.into()))?;
        g.set_param(linked.scene, "transport_bands", ParamValue::Int(bands as i64))?;
        if let Some(env) = linked.environment {
            g.set_param(env, "sh_bands", ParamValue::Int(bands as i64))?;
        }
        Ok(g)
    };
    for &bands in &args.bands {
        rows.extend(measure(&sh_mode("sh_prt", bands)?, "sh_prt", bands * bands)?);
    }
    for &level in &args.adaptive {
        let bands = level + 1;
        let mut g = sh_mode("sh_adaptive", bands)?;
        g.set_param(linked.output, "adaptive_level", ParamValue::Int(level as i64))?;
        rows.extend(measure(&g, "sh_adaptive", bands * bands)?);
    }
    let details: Vec<Option<usize>> =
        if args.details.is_empty() { vec![None] } else { args.details.iter().map(|d| Some(*d)).collect() };
    for mode in ["wavelet_vertex", "wavelet_pixel"] {
        for &terms in &args.wavelets {
            for &details in &details {
                let mut g = base.clone();
                g.set_param(linked.output, "mode", ParamValue::Choice(mode.into()))?;
                g.set_param(linked.output, "wavelet_terms", ParamValue::Choice(terms.to_string()))?;
                if let Some(details) = details {
                    g.set_param(linked.output, "wavelet_details", ParamValue::Int(details as i64))?;
                }
                rows.extend(measure(&g, mode, terms)?);
            }
        }
    }
    if let Some(decomposer) = linked.decomposer {
        for &k in &args.square_lights {
            let mut g = base.clone();
            g.set_param(linked.output, "mode", ParamValue::Choice("rsl".into()))?;
            g.set_param(decomposer, "light_count", ParamValue::Int(k as i64))?;
            rows.extend(measure(&g, "rsl", k)?);
        }
    }
    Ok(rows)
}
