//! `lightloom`: the node-based lighting design editor and its headless command line.

mod accuracy_command;
mod bench_command;
mod project_commands;
mod sh_command;

use anyhow::Result;
use clap::{Parser, Subcommand};
use lightloom_nodes::engine::Engine;
use std::sync::Arc;

#[derive(Parser)]
#[command(
    name = "lightloom",
    version,
    about = "Node-based lighting design: all-frequency lighting, fog, soft shadows and BRDF edits"
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
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
    Bench(bench_command::BenchArgs),
    /// Print the SH coefficients (RGB) of an environment map and its irradiance along ±X, ±Y, ±Z.
    Sh(sh_command::ShArgs),
}

/// Exit codes: 0 success, 1 replay regression, 2 bad input or failure.
fn main() {
    let cli = Cli::parse();
    let result: Result<bool> = match cli.command {
        Some(Command::Render(args)) => project_commands::render(&args).map(|_| true),
        Some(Command::Eval(args)) => project_commands::eval(&args).map(|_| true),
        Some(Command::Replay(args)) => project_commands::replay(&args),
        Some(Command::Info(args)) => project_commands::info(&args).map(|_| true),
        Some(Command::Accuracy(args)) => accuracy_command::run(&args).map(|_| true),
        Some(Command::Bench(args)) => bench_command::run(&args).map(|_| true),
        Some(Command::Sh(args)) => sh_command::run(&args).map(|_| true),
        None => default_job().map(|_| true),
    };
    match result {
        Ok(true) => {}
        Ok(false) => std::process::exit(1),
        Err(error) => {
            eprintln!("error: {error:#}");
            std::process::exit(2);
        }
    }
}

/// Until the editor lands: render the built-in default project headlessly.
fn default_job() -> Result<()> {
    let project = lightloom_nodes::project::default_project();
    let graph = project.graph(std::path::Path::new("default.ron")).map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let project_commands::Rendered { frame, eval_ms, render_ms, .. } = project_commands::render_project(
        &project,
        &graph,
        Arc::new(Engine::in_memory()),
        None,
        None,
        (None, None),
        false,
    )?;
    let path = std::path::Path::new("lightloom-default.png");
    project_commands::write_image(&frame, path)?;
    println!(
        "{}: rendered {}x{} to {} (evaluation {eval_ms:.0} ms, render {render_ms:.0} ms)",
        project.name,
        frame.width,
        frame.height,
        path.display()
    );
    Ok(())
}
