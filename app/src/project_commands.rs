//! `lightloom render | eval | replay | info`: the headless side of the editor.

use anyhow::{Context, Result, anyhow, bail};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use lightloom_nodes::engine::CancelToken;
use lightloom_nodes::engine::spec::Availability;
use lightloom_nodes::engine::{Engine, EngineConfig, EvalEvent, Evaluation, Graph, Request, StageStatus};
use lightloom_nodes::frame::FrameInputs;
use lightloom_nodes::kinds::output::{Tonemap, View, find_output};
use lightloom_nodes::project::Project;
use lightloom_nodes::reference::{self, ImageError, PinholeCamera};
use lightloom_render::{CameraView, CapturedFrame, GpuContext, ViewportRenderer};
use std::collections::HashMap;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

/// Options shared by the commands that evaluate a project.
#[derive(Args, Clone, Debug, Default)]
pub struct EvalOptions {
    /// Override a parameter: NODE.PARAM=VALUE (repeatable).
    #[arg(long = "set", value_name = "NODE.PARAM=VALUE")]
    pub overrides: Vec<String>,
    /// Disk cache for expensive stages [default: $XDG_CACHE_HOME/lightloom or ~/.cache/lightloom].
    #[arg(long, value_name = "DIR")]
    pub cache_dir: Option<PathBuf>,
    /// Do not read or write the disk cache.
    #[arg(long)]
    pub no_disk_cache: bool,
    /// Print only errors.
    #[arg(short, long)]
    pub quiet: bool,
}

impl EvalOptions {
    pub(crate) fn engine(&self) -> Engine {
        let disk_cache = if self.no_disk_cache {
            None
        } else {
            Some(self.cache_dir.clone().unwrap_or_else(lightloom_nodes::engine::cache::DiskCache::default_dir))
        };
        Engine::new(EngineConfig { disk_cache, ..Default::default() })
    }
}

#[derive(Args, Debug)]
pub struct RenderArgs {
    /// Project file (.ron), or `sample:NAME` for a built-in sample (`lightloom samples` lists them).
    pub project: PathBuf,
    /// Output image: .png (tone-mapped) or .exr (linear radiance).
    #[arg(short, long)]
    pub output: PathBuf,
    #[arg(long)]
    pub width: Option<u32>,
    #[arg(long)]
    pub height: Option<u32>,
    /// Camera name [default: the project's render camera].
    #[arg(long)]
    pub camera: Option<String>,
    /// Output node id [default: the only Output node].
    #[arg(long)]
    pub output_node: Option<String>,
    #[command(flatten)]
    pub eval: EvalOptions,
}

#[derive(Args, Debug)]
pub struct EvalArgs {
    /// Project file (.ron), or `sample:NAME` for a built-in sample (`lightloom samples` lists them).
    pub project: PathBuf,
    /// Report format.
    #[arg(long, default_value = "text", value_parser = ["text", "json"])]
    pub report: String,
    /// Evaluate every stage of every node, not only what the Output's mode and view need.
    #[arg(long)]
    pub all: bool,
    #[command(flatten)]
    pub eval: EvalOptions,
}

#[derive(Args, Debug)]
pub struct ReplayArgs {
    /// Projects to replay [default: every projects/*.ron].
    pub projects: Vec<PathBuf>,
    /// Rewrite the golden images instead of comparing.
    #[arg(long)]
    pub update: bool,
    /// Largest RMSE (sRGB, 0..1) accepted.
    #[arg(long, default_value_t = 0.02)]
    pub tolerance: f64,
    #[command(flatten)]
    pub eval: EvalOptions,
}

#[derive(Args, Debug)]
pub struct InfoArgs {
    /// Project file (.ron), or `sample:NAME` for a built-in sample (`lightloom samples` lists them).
    pub project: PathBuf,
}

pub fn load(path: &Path, overrides: &[String]) -> Result<(Project, Graph)> {
    let (project, graph) = Project::load_with_overrides(path, overrides)?;
    for warning in &graph.warnings {
        eprintln!("warning: {}: {warning}", path.display());
    }
    // A missing file blocks only what needs it.
    for (node, param, file) in project.missing_assets(&graph) {
        let message =
            format!("{}: node `{node}` parameter `{param}`: asset {} does not exist", path.display(), file.display());
        if graph.feeds_sink(&node) {
            bail!(message);
        }
        eprintln!("warning: {message} (the node feeds no output)");
    }
    Ok((project, graph))
}

/// What rendering the Output node `output` needs (its mode and view), for the CLI, with the
/// wavelet modes relit by the engine when the renderer relights on the CPU.
pub(crate) fn output_request(graph: &Graph, output: &str, relight_on_cpu: bool) -> Request {
    let needs = lightloom_nodes::frame::FrameNeeds { picking: false, relight_on_cpu };
    lightloom_nodes::frame::frame_request_for(graph, output, needs)
}

/// Evaluates what `request` needs on a background thread, driving a progress bar from its
/// events.
pub(crate) fn evaluate(engine: Arc<Engine>, graph: &Graph, request: Request, quiet: bool) -> Evaluation {
    follow(engine.spawn_request(graph.clone(), request), quiet)
}

/// Waits for `job`, driving a progress bar from its events.
pub(crate) fn follow(job: lightloom_nodes::engine::EvalJob, quiet: bool) -> Evaluation {
    let bar = if quiet { ProgressBar::hidden() } else { ProgressBar::new(0) };
    bar.set_style(
        ProgressStyle::with_template("{spinner} evaluating [{bar:30}] {pos}/{len} {msg}")
            .unwrap()
            .progress_chars("=> "),
    );
    // Long stages report their progress and an estimate of the time left: on the bar in a
    // terminal, as a line every tenth of the way otherwise (logs, CI).
    let lines = !quiet && !std::io::stderr().is_terminal();
    let mut started: HashMap<(String, String), (std::time::Instant, u32)> = HashMap::new();
    for event in job.events.iter() {
        match event {
            EvalEvent::Started { stages } => bar.set_length(stages as u64),
            EvalEvent::StageStarted { node, stage } => {
                bar.set_message(format!("{node}.{stage}"));
                started.insert((node, stage), (std::time::Instant::now(), 0));
            }
            EvalEvent::StageFinished { .. } => bar.inc(1),
            EvalEvent::Finished => break,
            EvalEvent::StageProgress { node, stage, fraction } => {
                let Some((start, tenths)) = started.get_mut(&(node.clone(), stage.clone())) else { continue };
                let elapsed = start.elapsed().as_secs_f64();
                if fraction <= 0.01 || fraction >= 1.0 || elapsed < 2.0 {
                    bar.tick();
                    continue;
                }
                let left = elapsed * (1.0 - fraction) / fraction;
                let message = format!("{node}.{stage} {:.0}% (about {} left)", fraction * 100.0, duration_text(left));
                bar.set_message(message.clone());
                let tenth = (fraction * 10.0) as u32;
                if lines && tenth > *tenths && (*tenths > 0 || tenth == 1 || elapsed > 5.0) {
                    *tenths = tenth;
                    eprintln!("evaluating {message}");
                }
            }
            EvalEvent::TierReady { .. } => bar.tick(),
        }
    }
    bar.finish_and_clear();
    job.wait()
}

/// "180 ms", "4.2 s", "40 s", "3 min", "2.0 h".
pub(crate) fn duration_text(seconds: f64) -> String {
    match seconds {
        s if s < 1.0 => format!("{:.0} ms", s * 1e3),
        s if s < 10.0 => format!("{s:.1} s"),
        s if s < 90.0 => format!("{s:.0} s"),
        s if s < 5400.0 => format!("{:.0} min", s / 60.0),
        s => format!("{:.1} h", s / 3600.0),
    }
}

pub(crate) fn fail_on_errors(evaluation: &Evaluation, needed: &[String]) -> Result<()> {
    for s in evaluation.report.failed() {
        if needed.contains(&s.node) {
            bail!("{}.{}: {}", s.node, s.stage, s.error.as_deref().unwrap_or("failed"));
        }
    }
    Ok(())
}

/// Nodes the output depends on (transitively).
pub(crate) fn upstream_of(graph: &Graph, node: &str) -> Vec<String> {
    let mut out = vec![node.to_string()];
    let mut i = 0;
    while i < out.len() {
        let current = out[i].clone();
        for l in graph.links.iter().filter(|l| l.to_node == current) {
            if !out.contains(&l.from_node) {
                out.push(l.from_node.clone());
            }
        }
        i += 1;
    }
    out
}

/// A rendered view and what it cost.
pub struct Rendered {
    pub frame: CapturedFrame,
    pub eval_ms: f64,
    pub render_ms: f64,
    /// For the `reference` and `error` views: the approximation's error and the reference time.
    pub error: Option<(ImageError, f64)>,
}

/// Evaluates and renders a loaded project (the Output node's `view`: the approximation, the
/// Monte Carlo reference, or the error heat map).
pub fn render_project(
    project: &Project,
    graph: &Graph,
    engine: Arc<Engine>,
    camera: Option<&str>,
    output_node: Option<&str>,
    size: (Option<u32>, Option<u32>),
    quiet: bool,
) -> Result<Rendered> {
    let output_name = output_node.or(project.render.output_node());
    let output = find_output(graph, output_name).map_err(|e| anyhow!(e))?;
    let camera = project.camera(camera).map_err(|e| anyhow!(e))?;
    // View-dependent results (area-light highlights) for the camera rendered.
    let mut seen = graph.clone();
    lightloom_nodes::kinds::output::see_from(&mut seen, camera.position);
    let graph = &seen;
    let gpu = GpuContext::headless()?;
    let relight_on_cpu = lightloom_render::RelightOn::from_env().on_cpu(&gpu);
    let start = Instant::now();
    let evaluation = evaluate(engine, graph, output_request(graph, &output.id, relight_on_cpu), quiet);
    let eval_ms = start.elapsed().as_secs_f64() * 1e3;
    fail_on_errors(&evaluation, &upstream_of(graph, &output.id))?;
    let frame = FrameInputs::gather(&evaluation, graph, &output.id).map_err(|e| anyhow!(e))?;
    if !quiet {
        for note in &evaluation.report.notes {
            eprintln!("warning: {note}");
        }
        for note in &frame.ignored_inputs {
            eprintln!("note: output `{}`: {note}", output.id);
        }
        for (node, note) in &frame.lobe_limits {
            eprintln!("note: material `{node}`: {note}");
        }
    }
    let (width, height) = (size.0.unwrap_or(project.render.width), size.1.unwrap_or(project.render.height));
    let start = Instant::now();
    let mut renderer = ViewportRenderer::new(&gpu);
    let captured = renderer.render_offscreen(&gpu, &frame, &CameraView::from_project(&camera), width, height)?;
    let render_ms = start.elapsed().as_secs_f64() * 1e3;
    if frame.settings.view == View::Approximation {
        return Ok(Rendered { frame: captured, eval_ms, render_ms, error: None });
    }
    let start = Instant::now();
    let pinhole =
        PinholeCamera { position: camera.position.into(), target: camera.target.into(), fov_y_deg: camera.fov_y_deg };
    let bar = if quiet { ProgressBar::hidden() } else { ProgressBar::new(1000) };
    bar.set_style(
        ProgressStyle::with_template("{spinner} reference ({msg}) [{bar:30}] {percent}%")
            .unwrap()
            .progress_chars("=> "),
    );
    bar.set_message(format!("{} spp", frame.settings.reference_samples));
    let reference = frame
        .render_reference(&pinhole, (width as usize, height as usize), 1, &CancelToken::default(), &|f| {
            bar.set_position((f * 1000.0) as u64)
        })
        .map_err(|e| anyhow!(e))?;
    bar.finish_and_clear();
    let reference_ms = start.elapsed().as_secs_f64() * 1e3;
    let approximation: Vec<[f32; 3]> = captured.hdr.iter().map(|p| [p[0], p[1], p[2]]).collect();
    let mask = reference.surface_mask();
    let error = reference::compare(&approximation, &reference.pixels, Some(&mask)).map_err(|e| anyhow!(e))?;
    let settings = &frame.settings;
    if settings.view == View::Reference {
        renderer.present(&gpu, &reference.pixels, (width, height), settings.exposure, settings.tonemap)?;
    } else {
        let scale = reference::error_map_scale(&reference.pixels);
        let map = reference::error_heat_map(&approximation, &reference.pixels, Some(&mask), scale);
        renderer.present(&gpu, &map, (width, height), 0.0, Tonemap::Linear)?;
        if !quiet {
            eprintln!(
                "error map: black = 0, white = |error| >= {scale:.4} (half the reference's mean radiance); \
                 grey = not compared (background, silhouettes)"
            );
        }
    }
    Ok(Rendered { frame: renderer.capture(&gpu)?, eval_ms, render_ms, error: Some((error, reference_ms)) })
}

pub fn write_image(frame: &CapturedFrame, path: &Path) -> Result<()> {
    match path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase()).as_deref() {
        Some("png") => lightloom_render::write_png(frame, path).map_err(|e| anyhow!(e)),
        Some("exr") => lightloom_render::write_exr(frame, path).map_err(|e| anyhow!(e)),
        _ => bail!("{}: the output must end in .png (tone-mapped) or .exr (linear radiance)", path.display()),
    }
}

pub fn render(args: &RenderArgs) -> Result<()> {
    if !matches!(args.output.extension().and_then(|e| e.to_str()), Some("png" | "exr" | "PNG" | "EXR")) {
        bail!("{}: the output must end in .png (tone-mapped) or .exr (linear radiance)", args.output.display());
    }
    let (project, graph) = load(&args.project, &args.eval.overrides)?;
    let engine = Arc::new(args.eval.engine());
    let Rendered { frame, eval_ms, render_ms, error } = render_project(
        &project,
        &graph,
        engine,
        args.camera.as_deref(),
        args.output_node.as_deref(),
        (args.width, args.height),
        args.eval.quiet,
    )?;
    write_image(&frame, &args.output)?;
    if !args.eval.quiet {
        println!(
            "{} -> {} ({}x{}; evaluation {eval_ms:.0} ms, render {render_ms:.0} ms)",
            args.project.display(),
            args.output.display(),
            frame.width,
            frame.height
        );
    }
    if let Some((e, ms)) = error {
        println!(
            "approximation vs reference over surface pixels: RMSE {:.5} (relative {:.2}%), PSNR {:.1} dB; reference {ms:.0} ms",
            e.rmse,
            e.relative_rmse * 100.0,
            e.psnr_db
        );
    }
    Ok(())
}

pub fn eval(args: &EvalArgs) -> Result<()> {
    let (_, base) = load(&args.project, &[])?;
    let (_, changed) = load(&args.project, &args.eval.overrides)?;
    let engine = Arc::new(args.eval.engine());
    let request = |graph: &Graph| -> Result<Request> {
        if args.all {
            return Ok(Request::everything(graph));
        }
        let output = find_output(graph, None).map_err(|e| anyhow!("{e} (or pass --all)"))?;
        Ok(output_request(graph, &output.id, false))
    };
    let quiet = args.eval.quiet || args.report == "json";
    let initial = evaluate(engine.clone(), &base, request(&base)?, quiet);
    let after = evaluate(engine, &changed, request(&changed)?, quiet);
    if args.report == "json" {
        let json = serde_json::json!({
            "project": args.project.display().to_string(),
            "overrides": args.eval.overrides,
            "initial": initial.report,
            "after_overrides": after.report,
            "recomputed": after.report.computed().iter().map(|(n, s)| format!("{n}.{s}")).collect::<Vec<_>>(),
        });
        println!("{}", serde_json::to_string_pretty(&json)?);
    } else {
        println!("initial evaluation: {} stages, {:.1} ms", initial.report.stages.len(), initial.report.total_ms);
        println!("after {:?}: {:.1} ms", args.eval.overrides, after.report.total_ms);
        for s in &after.report.stages {
            let status = match s.status {
                StageStatus::Computed => "computed",
                StageStatus::MemoryHit => "cached",
                StageStatus::DiskHit => "disk cache",
                StageStatus::Failed => "FAILED",
                StageStatus::KnownFailure => "FAILED (known)",
                StageStatus::Blocked => "blocked",
                StageStatus::Cancelled => "cancelled",
                StageStatus::NotNeeded => "not needed",
            };
            let why = if s.reasons.is_empty() { String::new() } else { format!(" — {}", s.reasons.join("; ")) };
            let err = s.error.as_deref().map(|e| format!(" [{e}]")).unwrap_or_default();
            println!("  {:<24} {:<14} {:>8.2} ms{why}{err}", format!("{}.{}", s.node, s.stage), status, s.ms);
        }
    }
    Ok(())
}

/// Golden image of a project: `goldens/<stem>.png` beside it.
pub fn golden_path(project: &Path) -> PathBuf {
    let stem = project.file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_default();
    project.parent().unwrap_or(Path::new(".")).join("goldens").join(format!("{stem}.png"))
}

/// RMSE and PSNR between two RGB8 images (values scaled to 0..1).
pub fn compare(a: &image::RgbImage, b: &image::RgbImage) -> Result<(f64, f64)> {
    if a.dimensions() != b.dimensions() {
        bail!("size {:?} differs from the golden's {:?}", a.dimensions(), b.dimensions());
    }
    let n = (a.width() * a.height() * 3) as f64;
    let sse: f64 = a.as_raw().iter().zip(b.as_raw()).map(|(x, y)| ((*x as f64 - *y as f64) / 255.0).powi(2)).sum();
    let rmse = (sse / n).sqrt();
    let psnr = if rmse == 0.0 { f64::INFINITY } else { 20.0 * (1.0 / rmse).log10() };
    Ok((rmse, psnr))
}

pub fn replay(args: &ReplayArgs) -> Result<bool> {
    let projects = if args.projects.is_empty() {
        let mut found: Vec<PathBuf> = std::fs::read_dir("projects")
            .context("no projects given and no projects/ folder here")?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|e| e == "ron"))
            .collect();
        found.sort();
        found
    } else {
        args.projects.clone()
    };
    let mut ok = true;
    for path in &projects {
        let (project, graph) = load(path, &args.eval.overrides)?;
        let Rendered { frame, .. } =
            render_project(&project, &graph, Arc::new(args.eval.engine()), None, None, (None, None), true)?;
        let golden = golden_path(path);
        let rendered = image::RgbImage::from_raw(
            frame.width,
            frame.height,
            frame.ldr.iter().flat_map(|p| [p[0], p[1], p[2]]).collect(),
        )
        .ok_or_else(|| anyhow!("frame size mismatch"))?;
        if args.update {
            std::fs::create_dir_all(golden.parent().unwrap())?;
            write_image(&frame, &golden)?;
            println!("{}: golden written to {}", path.display(), golden.display());
            continue;
        }
        let expected = image::open(&golden)
            .with_context(|| {
                format!("{}: no golden image at {} (run with --update to create it)", path.display(), golden.display())
            })?
            .into_rgb8();
        let (rmse, psnr) = compare(&rendered, &expected).with_context(|| path.display().to_string())?;
        let pass = rmse <= args.tolerance;
        ok &= pass;
        println!(
            "{}: RMSE {rmse:.5}, PSNR {psnr:.1} dB (tolerance RMSE {}) {}",
            path.display(),
            args.tolerance,
            if pass { "ok" } else { "REGRESSION" }
        );
        if !pass {
            let failed = path.with_extension("replay-failed.png");
            let _ = write_image(&frame, &failed);
            println!("  rendered image kept at {}", failed.display());
        }
    }
    Ok(ok)
}

pub fn info(args: &InfoArgs) -> Result<()> {
    let (project, graph) = load(&args.project, &[])?;
    println!("{}: `{}`, version {}", args.project.display(), project.name, project.version);
    println!(
        "render {}x{}, cameras: {}",
        project.render.width,
        project.render.height,
        project.cameras.iter().map(|c| c.name.as_str()).collect::<Vec<_>>().join(", ")
    );
    println!("nodes:");
    for node in &project.nodes {
        let kind = lightloom_nodes::kinds::kind(&node.kind).expect("validated");
        let status = match kind.availability {
            Availability::Ready => String::new(),
            Availability::Planned(missing) => format!("  ({missing})"),
        };
        println!("  {:<12} {:<18} {} parameter(s) set{status}", node.id, node.kind, node.params.len());
    }
    println!("links:");
    for link in &graph.links {
        println!("  {}.{} -> {}.{}", link.from_node, link.from_port, link.to_node, link.to_port);
    }
    let linked: Vec<&str> = graph.links.iter().flat_map(|l| [l.from_node.as_str(), l.to_node.as_str()]).collect();
    for node in &graph.nodes {
        if !linked.contains(&node.id.as_str()) && graph.nodes.len() > 1 {
            println!("warning: node `{}` is not connected to anything", node.id);
        }
    }
    find_output(&graph, None).map_err(|e| anyhow!(e))?;
    // Valid means renderable: every file a parameter names is loaded.
    let request = Request::assets(&graph);
    let loads: Vec<String> =
        request.tiers.iter().flat_map(|t| &t.stages).map(|s| format!("{}.{}", s.node, s.stage)).collect();
    let evaluation = evaluate(Arc::new(EvalOptions::default().engine()), &graph, request, true);
    let failed = evaluation.report.failed();
    if let Some(s) = failed.first() {
        bail!("{}.{}: {}", s.node, s.stage, s.error.as_deref().unwrap_or("failed"));
    }
    for s in evaluation.report.stages.iter().filter(|s| !s.warnings.is_empty()) {
        for w in &s.warnings {
            println!("warning: {}.{}: {w}", s.node, s.stage);
        }
    }
    println!("assets: {} loaded ({})", loads.len(), if loads.is_empty() { "none".into() } else { loads.join(", ") });
    println!("valid: every asset loads");
    Ok(())
}
