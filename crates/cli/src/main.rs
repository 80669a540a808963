//! `pganeus`: one subcommand per pipeline stage. Commands parse, report
//! progress and write files; the work is in the library crates.

mod commands;
mod output;
mod scene_file;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "pganeus",
    version,
    about = "Neural surfaces and rigid-body physics from camera footage (PGA-NeuS)"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a synthetic tabletop dataset with exact ground truth (NeuS layout).
    Synth(commands::synth::SynthArgs),
    /// Simulate the bodies of a scene file and write trajectory.json.
    Simulate(commands::simulate::SimulateArgs),
    /// Find the launch velocity that brings a body to a point at a frame (Sec. 4.1).
    Target(commands::target::TargetArgs),
    /// Recover v0, omega0, k_n and mu of a body from a pose sequence (Eq. 11).
    FitPhysics(commands::fit_physics::FitPhysicsArgs),
    /// Time the simulator (forward and with gradients) and print JSON lines.
    BenchSim(commands::bench_sim::BenchSimArgs),
}

fn main() {
    tracing_subscriber::fmt()
        .with_env_filter(tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "info".into()))
        .with_writer(std::io::stderr)
        .with_target(false)
        .init();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Synth(a) => commands::synth::run(a),
        Command::Simulate(a) => commands::simulate::run(a),
        Command::Target(a) => commands::target::run(a),
        Command::FitPhysics(a) => commands::fit_physics::run(a),
        Command::BenchSim(a) => commands::bench_sim::run(a),
    };
    if let Err(e) = result {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
