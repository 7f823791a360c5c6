//! `lightloom`: the node-based lighting design editor and its headless command line.

mod accuracy_command;
mod bake_command;
mod bench;
mod editor;
mod project_commands;
mod samples;
mod sh_command;
mod user_dirs;

use anyhow::Result;
use clap::{Parser, Subcommand};
use lightloom_nodes::engine::Engine;
use std::sync::Arc;

#[derive(Parser)]
#[command(
    name = "lightloom",
    version,
    about = "Node-based lighting design: all-frequency lighting, fog, soft shadows and BRDF edits",
    long_about = "Without a subcommand, opens the editor on PROJECT (or the built-in default project). \
                  Without a display (no DISPLAY or WAYLAND_DISPLAY), or with --headless, renders the \
                  project to a PNG instead.",
    args_conflicts_with_subcommands = true
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    #[command(flatten)]
    editor: EditorArgs,
}

#[derive(clap::Args, Debug, Default)]
struct EditorArgs {
    /// Project to open (.ron), or `sample:NAME` for a copy of a built-in sample (`lightloom
    /// samples` lists them) [default: the built-in default project].
    project: Option<std::path::PathBuf>,
    /// Do not open a window: render the project headlessly to PNG.
    #[arg(long)]
    headless: bool,
    /// Editor: once the first evaluation is on screen, save a screenshot of the window and quit.
    #[arg(long, value_name = "PNG")]
    screenshot: Option<std::path::PathBuf>,
    /// Editor: print UI frame-time statistics (idle and while background work runs) on exit.
    #[arg(long)]
    frame_stats: bool,
    /// Editor: append a line to this file whenever the view settles (evaluated and drawn)
    /// or the project is saved, with the layout in window pixels (for scripted sessions).
    #[arg(long, value_name = "FILE")]
    status_file: Option<std::path::PathBuf>,
    /// Disk cache for expensive stages [default: $XDG_CACHE_HOME/lightloom or ~/.cache/lightloom].
    #[arg(long, value_name = "DIR")]
    cache_dir: Option<std::path::PathBuf>,
    /// Do not read or write the disk cache.
    #[arg(long)]
    no_disk_cache: bool,
}

#[derive(Subcommand)]
enum Command {
    /// Render a project headlessly to PNG (tone-mapped) or EXR (linear radiance).
    Render(project_commands::RenderArgs),
    /// Evaluate a project, apply --set overrides, re-evaluate and report what was recomputed and why.
    Eval(project_commands::EvalArgs),
    /// Render projects and compare them with their golden images.
    Replay(project_commands::ReplayArgs),
    /// Validate a project and summarise it.
    Info(project_commands::InfoArgs),
    /// Render the Monte Carlo reference once and report each relighting mode's error against it.
    Accuracy(accuracy_command::AccuracyArgs),
    /// Print relighting figures: edit-to-frame latency, frame times, 100k-vertex relight cost.
    Bench(bench::BenchArgs),
    /// Print the SH coefficients (RGB) of an environment map and its irradiance along ±X, ±Y, ±Z.
    Sh(sh_command::ShArgs),
    /// List the built-in sample projects (`sample:NAME` opens or renders one from any folder).
    Samples,
    /// Bake the Output's lighting for game engines: scene.glb (meshes, materials, light per vertex,
    /// point lights, camera) and bake.json into --out DIR.
    Bake(bake_command::BakeArgs),
}

impl Command {
    /// The project file the command reads, where it reads one.
    fn project_mut(&mut self) -> Option<&mut std::path::PathBuf> {
        match self {
            Command::Render(a) => Some(&mut a.project),
            Command::Eval(a) => Some(&mut a.project),
            Command::Info(a) => Some(&mut a.project),
            Command::Accuracy(a) => Some(&mut a.project),
            Command::Bake(a) => Some(&mut a.project),
            _ => None,
        }
    }
}

/// Exit codes: 0 success, 1 replay regression, 2 bad input or failure.
fn main() {
    let mut cli = Cli::parse();
    // `sample:NAME` names a built-in sample in every command that reads one project; the
    // editor opens a copy of it, as File → Open sample does.
    if let Some(arg) = cli.command.as_mut().and_then(Command::project_mut) {
        match samples::resolve(arg) {
            Ok(path) => *arg = path,
            Err(error) => {
                eprintln!("error: {error:#}");
                std::process::exit(2);
            }
        }
    }
    // Errors name the project they concern, even those raised far from where it was read.
    let project = match cli.command.as_mut() {
        Some(command) => command.project_mut().cloned(),
        None => cli.editor.project.clone(),
    };
    let result: Result<bool> = match cli.command {
        Some(Command::Render(args)) => project_commands::render(&args).map(|_| true),
        Some(Command::Eval(args)) => project_commands::eval(&args).map(|_| true),
        Some(Command::Replay(args)) => project_commands::replay(&args),
        Some(Command::Info(args)) => project_commands::info(&args).map(|_| true),
        Some(Command::Accuracy(args)) => accuracy_command::run(&args).map(|_| true),
        Some(Command::Bench(args)) => bench::run(&args).map(|_| true),
        Some(Command::Sh(args)) => sh_command::run(&args).map(|_| true),
        Some(Command::Bake(args)) => bake_command::run(&args).map(|_| true),
        Some(Command::Samples) => list_samples().map(|_| true),
        None => main_job(cli.editor).map(|_| true),
    };
    match result {
        Ok(true) => {}
        Ok(false) => std::process::exit(1),
        Err(error) => {
            let message = format!("{error:#}");
            match project.map(|p| p.display().to_string()) {
                Some(path) if !message.contains(&path) => eprintln!("error: {path}: {message}"),
                _ => eprintln!("error: {message}"),
            }
            std::process::exit(2);
        }
    }
}

fn has_display() -> bool {
    ["DISPLAY", "WAYLAND_DISPLAY"].iter().any(|v| std::env::var_os(v).is_some_and(|d| !d.is_empty()))
}

/// The editor where there is a display; otherwise a headless render of the same project.
fn main_job(args: EditorArgs) -> Result<()> {
    if !args.headless && has_display() {
        let options = editor::EditorOptions {
            project: args.project.clone(),
            screenshot: args.screenshot.clone(),
            cache_dir: args.cache_dir.clone(),
            no_disk_cache: args.no_disk_cache,
            frame_stats: args.frame_stats,
            status_file: args.status_file.clone(),
            viewport_slow_down: std::time::Duration::ZERO,
        };
        match editor::run(options) {
            Ok(()) => return Ok(()),
            Err(e) if args.screenshot.is_some() => return Err(e),
            Err(e) => eprintln!("{e:#}; rendering headlessly instead"),
        }
    } else if !args.headless {
        eprintln!(
            "no display (DISPLAY and WAYLAND_DISPLAY are unset): rendering headlessly instead of opening the editor"
        );
    }
    headless_render(&args)
}

/// Renders the project (or the built-in default) to `<name>.png` in the current folder.
fn headless_render(args: &EditorArgs) -> Result<()> {
    let (project, graph, out) = match &args.project {
        Some(arg) => {
            let path = &samples::resolve(arg)?;
            let (project, graph) = project_commands::load(path, &[])?;
            let stem = path.file_stem().map_or("project".into(), |s| s.to_string_lossy().into_owned());
            (project, graph, std::path::PathBuf::from(format!("{stem}.png")))
        }
        None => {
            let project = lightloom_nodes::project::default_project();
            let graph = project.graph(std::path::Path::new("default.ron")).map_err(|e| anyhow::anyhow!("{e:?}"))?;
            (project, graph, std::path::PathBuf::from("lightloom-default.png"))
        }
    };
    let options = project_commands::EvalOptions {
        cache_dir: args.cache_dir.clone(),
        no_disk_cache: args.no_disk_cache,
        ..Default::default()
    };
    let project_commands::Rendered { frame, eval_ms, render_ms, .. } = project_commands::render_project(
        &project,
        &graph,
        Arc::new(if args.project.is_some() { options.engine() } else { Engine::in_memory() }),
        None,
        None,
        (None, None),
        false,
    )?;
    project_commands::write_image(&frame, &out)?;
    println!(
        "{}: rendered {}x{} to {} (evaluation {eval_ms:.0} ms, render {render_ms:.0} ms)",
        project.name,
        frame.width,
        frame.height,
        out.display()
    );
    Ok(())
}

/// `lightloom samples`: each built-in sample's name and title, and where its files are.
fn list_samples() -> Result<()> {
    for sample in samples::list() {
        println!("{}{:<18} {}", samples::PREFIX, sample.stem, sample.title);
    }
    println!("(written out to {})", samples::folder()?.display());
    Ok(())
}
