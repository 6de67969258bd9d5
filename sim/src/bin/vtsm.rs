//! The `vtsm` command line: see `vtsm --help`.

use clap::{Parser, Subcommand};
use std::process::ExitCode;
use vtsm_sim::cli;

/// VTSM rover relocalization: Virtual Template Synthesis and Matching.
#[derive(Debug, Parser)]
#[command(name = "vtsm", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Build a simulated depot, relocalize one stereo pair from a perturbed prior, report.
    Demo(cli::demo::Args),
    /// Relocalize a stereo pair (or, with --pairs, a batch of pairs) against a mesh or map product.
    Relocalize(cli::relocalize::Args),
    /// Match one template in one image by integer zero-mean NCC; prints one JSON line.
    Ncc(cli::ncc::Args),
    /// Run an evaluation suite reproducing the paper's tables.
    Eval(cli::eval::Args),
    /// Map product tools.
    #[command(subcommand)]
    Map(MapCommand),
    /// Simulated scene tools.
    #[command(subcommand)]
    Scene(SceneCommand),
    /// Print memory and work budgets, measured.
    Budget(cli::budget::Args),
    /// Measure where relocalization time goes (per stage) and NCC speed against OpenCV; prints Markdown.
    Bench(cli::bench::Args),
}

#[derive(Debug, Subcommand)]
enum MapCommand {
    /// Build a map product from a textured mesh (OBJ + MTL texture) and optional mask sub-mesh.
    Build(cli::map_build::Args),
}

#[derive(Debug, Subcommand)]
enum SceneCommand {
    /// Export a simulated scene as the files `vtsm relocalize` reads.
    Export(cli::scene_export::Args),
    /// Contact sheet PNG of the three terrains at am, noon and pm.
    Sheet(cli::scene_sheet::Args),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match &cli.command {
        Command::Demo(a) => cli::demo::run(a),
        Command::Relocalize(a) => cli::relocalize::run(a),
        Command::Ncc(a) => cli::ncc::run(a),
        Command::Eval(a) => cli::eval::run(a),
        Command::Map(MapCommand::Build(a)) => cli::map_build::run(a),
        Command::Scene(SceneCommand::Export(a)) => cli::scene_export::run(a),
        Command::Scene(SceneCommand::Sheet(a)) => cli::scene_sheet::run(a),
        Command::Budget(a) => cli::budget::run(a),
        Command::Bench(a) => cli::bench::run(a),
    };
    match result {
        Ok(code) => ExitCode::from(code),
        Err(e) => ExitCode::from(cli::report(&e)),
    }
}
