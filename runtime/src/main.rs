//! The `softcbf` command: inspect a robot's model, simulate the safe controller, and run
//! it on hardware or against the servo emulator.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

use softcbf::cli::{load_robot, parse_vector};
use softcbf::inspect::model_report;
use softcbf::model::Model;

#[derive(Parser)]
#[command(
    name = "softcbf",
    version,
    about = "Safe control of soft-rigid robots with self-contact"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Print the model (poses, barriers, Jacobians, dynamics) at one state as JSON.
    Model {
        /// Robot file (default: the embedded paper simulation robot).
        #[arg(long)]
        robot: Option<PathBuf>,
        /// Generalized coordinates `Δx,Δy,δL,…` [m] (default: all zero).
        #[arg(long, allow_hyphen_values = true)]
        q: Option<String>,
        /// Generalized velocities [m/s] (default: all zero).
        #[arg(long, allow_hyphen_values = true)]
        qd: Option<String>,
    },
    /// Emulate the robot's servos on a pseudo-terminal (prints the port to connect to).
    Emulate(softcbf::hardware::cli::EmulateArgs),
    /// Run the safe controller on the robot's servos (or on `softcbf emulate`).
    Run(softcbf::hardware::cli::RunArgs),
}

fn run(cli: Cli) -> Result<(), String> {
    match cli.command {
        Command::Model { robot, q, qd } => {
            let robot = load_robot(robot.as_deref()).map_err(|e| e.to_string())?;
            let model = Model::new(robot).map_err(|e| e.to_string())?;
            let nq = model.nq();
            let q = match q {
                Some(text) => parse_vector("--q", &text, nq)?,
                None => vec![0.0; nq],
            };
            let qd = match qd {
                Some(text) => parse_vector("--qd", &text, nq)?,
                None => vec![0.0; nq],
            };
            let report = model_report(&model, &q, &qd);
            println!(
                "{}",
                serde_json::to_string_pretty(&report).map_err(|e| e.to_string())?
            );
            Ok(())
        }
        Command::Emulate(args) => softcbf::hardware::cli::emulate(args),
        Command::Run(args) => softcbf::hardware::cli::run(args),
    }
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("error: {message}");
            ExitCode::FAILURE
        }
    }
}
