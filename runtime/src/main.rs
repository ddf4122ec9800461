//! The `softcbf` command: inspect a robot's model, simulate the safe controller, and run
//! it on hardware or against the servo emulator.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

use softcbf::cli::{load_robot, parse_vector};
use softcbf::inspect::model_report;
use softcbf::model::Model;
use softcbf::output::{Progress, one_line, write_outputs};
use softcbf::scenario::ScenarioFile;
use softcbf::sim::simulate;

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
    /// Simulate the safe controller (default: the paper's scenario, with the plain PD+
    /// comparison) and write trajectories, summary.json and figures.
    Simulate {
        /// Scenario file (default: the embedded scenarios/paper-sim.toml).
        #[arg(long)]
        scenario: Option<PathBuf>,
        /// Robot file (default: the scenario's robot, else the embedded paper robot).
        #[arg(long)]
        robot: Option<PathBuf>,
        /// Run plain PD+ without the safety filter.
        #[arg(long)]
        no_filter: bool,
        /// Also run plain PD+ and draw it beside the filtered run.
        #[arg(long)]
        compare: bool,
        /// Output directory.
        #[arg(long, default_value = "out")]
        out: PathBuf,
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
            say(&serde_json::to_string_pretty(&report).map_err(|e| e.to_string())?);
            Ok(())
        }
        Command::Emulate(args) => softcbf::hardware::cli::emulate(args),
        Command::Run(args) => softcbf::hardware::cli::run(args),
        Command::Simulate {
            scenario,
            robot,
            no_filter,
            compare,
            out,
        } => run_simulation(scenario, robot, no_filter, compare, &out),
    }
}

fn run_simulation(
    scenario: Option<PathBuf>,
    robot: Option<PathBuf>,
    no_filter: bool,
    compare: bool,
    out: &std::path::Path,
) -> Result<(), String> {
    let file = match &scenario {
        Some(path) => ScenarioFile::load(path).map_err(|e| e.to_string())?,
        None => ScenarioFile::paper_sim(),
    };
    let robot_path = robot.or_else(|| file.robot_path());
    let robot = load_robot(robot_path.as_deref()).map_err(|e| e.to_string())?;
    let model = Model::new(robot).map_err(|e| e.to_string())?;
    let scenario = file.resolve(&model).map_err(|e| e.to_string())?;
    let filter = scenario.controller.filter && !no_filter;
    let compare = filter && (scenario.compare || compare);

    let mut progress = Progress::new(if filter { "filter" } else { "PD+" });
    let main = simulate(&model, &scenario, filter, &mut |f| progress.update(f))
        .map_err(|e| e.to_string())?;
    let comparison = if compare {
        let mut progress = Progress::new("PD+");
        Some(
            simulate(&model, &scenario, false, &mut |f| progress.update(f))
                .map_err(|e| e.to_string())?,
        )
    } else {
        None
    };
    let written = write_outputs(out, &main, comparison.as_ref(), model.generated.corners())
        .map_err(|e| e.to_string())?;
    say(&one_line(&main.summary));
    if let Some(pd) = &comparison {
        say(&one_line(&pd.summary));
    }
    let names: Vec<String> = written.iter().map(|p| p.display().to_string()).collect();
    say(&format!("wrote {}", names.join(", ")));
    match (
        &main.summary.stopped,
        comparison.as_ref().and_then(|r| r.summary.stopped.as_ref()),
    ) {
        (None, None) => Ok(()),
        _ => Err("the simulation stopped early (see the summary above)".to_string()),
    }
}

/// Prints a line on standard output; a closed pipe (`softcbf … | head`) is not an error.
fn say(text: &str) {
    use std::io::Write;
    let _ = writeln!(std::io::stdout().lock(), "{text}");
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
