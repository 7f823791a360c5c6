//! `lightloom bake PROJECT --out DIR`: the Output's lighting baked for game engines (see
//! `lightloom_nodes::bake`), with progress bars; Ctrl+C cancels and leaves `DIR` as it was.

use crate::project_commands::{EvalOptions, duration_text, fail_on_errors, follow, load, upstream_of};
use anyhow::{Result, anyhow, bail};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use lightloom_nodes::bake::{self, gltf_export::ExportCamera};
use lightloom_nodes::engine::{CancelToken, Evaluation, Graph, StageStatus};
use lightloom_nodes::frame::FrameInputs;
use lightloom_nodes::kinds::output::find_output;
use lightloom_nodes::project::{Camera, Project};
use std::path::Path;
use std::path::PathBuf;
use std::sync::{Arc, Mutex, OnceLock};
use std::time::Instant;

#[derive(Args, Debug)]
pub struct BakeArgs {
    /// Project file (.ron), or `sample:NAME` for a built-in sample (`lightloom samples` lists them).
    pub project: PathBuf,
    /// Folder the baked files go to (created if missing; files of the same names are replaced).
    #[arg(long)]
    pub out: PathBuf,
    /// Camera written to the glTF [default: the project's render camera].
    #[arg(long)]
    pub camera: Option<String>,
    /// Output node id [default: the only Output node].
    #[arg(long)]
    pub output_node: Option<String>,
    /// Also write Lightloom's own pictures of the baked lighting from the camera, WIDTHxHEIGHT
    /// (preview_vertex.exr, preview_lightmap.exr: albedo × baked light, unlit, linear).
    #[arg(long, value_name = "WIDTHxHEIGHT", value_parser = parse_size)]
    pub preview: Option<(usize, usize)>,
    #[command(flatten)]
    pub eval: EvalOptions,
}

/// What Ctrl+C cancels: the running part of the bake.
fn interrupt() -> &'static Mutex<CancelToken> {
    static CURRENT: OnceLock<Mutex<CancelToken>> = OnceLock::new();
    CURRENT.get_or_init(|| {
        // Without a handler (another one is set), Ctrl+C ends the process: files are still
        // only ever renamed into place whole.
        let _ = ctrlc::set_handler(|| interrupt().lock().unwrap().cancel());
        Mutex::new(CancelToken::default())
    })
}

pub fn run(args: &BakeArgs) -> Result<()> {
    let started = Instant::now();
    let (project, graph) = load(&args.project, &args.eval.overrides)?;
    let output = find_output(&graph, args.output_node.as_deref().or(project.render.output_node()))
        .map_err(|e| anyhow!(e))?
        .id
        .clone();
    let camera = project.camera(args.camera.as_deref()).map_err(|e| anyhow!(e))?;
    let engine = Arc::new(args.eval.engine());
    let job = engine.spawn_request(graph.clone(), bake::bake_request(&graph, &output));
    *interrupt().lock().unwrap() = job.cancel_token();
    let evaluation = follow(job, args.eval.quiet);
    let cancelled = || interrupt().lock().unwrap().is_cancelled();
    let bar = if args.eval.quiet { ProgressBar::hidden() } else { ProgressBar::new(1000) };
    bar.set_style(
        ProgressStyle::with_template("{spinner} baking {msg} [{bar:30}] {percent}%").unwrap().progress_chars("=> "),
    );
    let progress = |what: &str, fraction: f64| {
        bar.set_message(what.to_string());
        bar.set_position((fraction * 1000.0) as u64);
    };
    let baked =
        finish(&evaluation, &graph, &output, &project, &camera, args.preview, &args.out, &progress, &cancelled)?;
    bar.finish_and_clear();

    if !args.eval.quiet {
        let m = &baked.manifest;
        println!(
            "baked output `{output}` (mode {}) into {}: {} vertices, {} triangles, {} point lights",
            m.mode,
            args.out.display(),
            m.vertices,
            m.triangles,
            m.point_lights
        );
        println!("stage times:");
        for s in evaluation.report.stages.iter().filter(|s| s.status == StageStatus::Computed) {
            println!("  {:<34} {}", format!("{}.{}", s.node, s.stage), duration_text(s.ms / 1e3));
        }
        for t in &m.timings {
            println!("  {:<34} {}", format!("bake: {}", t.stage), duration_text(t.ms / 1e3));
        }
        println!("files:");
        for (name, bytes) in &m.files {
            println!("  {name:<20} {:>10} bytes", bytes);
        }
        if let Some(l) = &m.lightmap {
            println!(
                "lightmap {}×{} at {:.1} texels/m, {} surface texels ({:.0}% of the page), RGBM range {}",
                l.width,
                l.height,
                l.texels_per_metre,
                l.surface_texels,
                l.utilization * 100.0,
                l.rgbm_range
            );
        }
        for mat in &m.materials {
            println!(
                "material `{}` ({}): glTF roughness {:.3}, specular {:.3}; fit error {:.1}% (relative L2 of f cos θ)",
                if mat.name.is_empty() { "default" } else { &mat.name },
                mat.model,
                mat.roughness,
                mat.specular_factor,
                mat.fit_error * 100.0
            );
        }
        println!("total {}", duration_text(started.elapsed().as_secs_f64()));
    }
    Ok(())
}

/// `WIDTHxHEIGHT`, each 1..=8192.
fn parse_size(text: &str) -> Result<(usize, usize), String> {
    let (w, h) = text.split_once('x').ok_or("expected WIDTHxHEIGHT, e.g. 640x360")?;
    let parse = |v: &str| match v.trim().parse::<usize>() {
        Ok(n) if (1..=8192).contains(&n) => Ok(n),
        _ => Err(format!("`{v}` is not a size from 1 to 8192")),
    };
    Ok((parse(w)?, parse(h)?))
}

/// After the bake's evaluation: checks it, turns it into files and writes them into `out`
/// whole (the CLI and the editor's File → Bake… share this). A cancel before the files are
/// written leaves `out` as it was.
#[allow(clippy::too_many_arguments)]
pub fn finish(
    evaluation: &Evaluation,
    graph: &Graph,
    output: &str,
    project: &Project,
    camera: &Camera,
    preview: Option<(usize, usize)>,
    out: &Path,
    progress: &dyn Fn(&str, f64),
    cancelled: &dyn Fn() -> bool,
) -> Result<bake::Bake> {
    let unchanged = || anyhow!("bake cancelled; {} is unchanged", out.display());
    if cancelled() {
        return Err(unchanged());
    }
    fail_on_errors(evaluation, &upstream_of(graph, output))?;
    let frame = FrameInputs::gather(evaluation, graph, output).map_err(|e| anyhow!(e))?;
    if let Some(pending) = &frame.pending {
        bail!("the bake needs the mode's transport: {pending}");
    }
    let export_camera = ExportCamera {
        name: camera.name.clone(),
        position: camera.position,
        target: camera.target,
        fov_y_deg: camera.fov_y_deg,
        aspect: f64::from(project.render.width) / f64::from(project.render.height.max(1)),
    };
    let preview = preview.map(|size| bake::PreviewRequest {
        camera: lightloom_nodes::reference::PinholeCamera {
            position: camera.position.into(),
            target: camera.target.into(),
            fov_y_deg: camera.fov_y_deg,
        },
        size,
    });
    let lightmap = bake::BakedStages::gather(evaluation, output).map_err(|e| anyhow!(e))?;
    let baked = bake::bake(&frame, Some(&lightmap), Some(export_camera), preview, progress).map_err(|e| anyhow!(e))?;
    if cancelled() {
        return Err(unchanged());
    }
    bake::write_atomically(&baked, out).map_err(|e| anyhow!("writing into {}: {e}", out.display()))?;
    Ok(baked)
}
