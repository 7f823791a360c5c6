//! `lightloom`: the node-based lighting design editor and its headless command line.

mod sh_command;

use anyhow::Result;
use clap::{Parser, Subcommand};

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
    /// Print the SH coefficients (RGB) of an environment map and its irradiance along ±X, ±Y, ±Z.
    Sh(sh_command::ShArgs),
}

fn main() {
    let cli = Cli::parse();
    let result: Result<()> = match cli.command {
        Some(Command::Sh(args)) => sh_command::run(&args),
        // Until the editor lands, the main job evaluates the built-in default environment.
        None => sh_command::run(&sh_command::ShArgs::builtin_default()),
    };
    if let Err(error) = result {
        eprintln!("error: {error:#}");
        std::process::exit(2);
    }
}
