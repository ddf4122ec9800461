//! The `softcbf` command: inspect a robot's model, simulate the safe controller, and run
//! it on hardware or against the servo emulator.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand};

use softcbf::cli::{
    SimulateOptions, check_simulate_options, parse_coordinates, parse_vector, parse_velocities,
};
use softcbf::control::SafetyMode;
use softcbf::exit;
use softcbf::inspect::model_report;
use softcbf::model::Model;
use softcbf::output::output_directory;
use softcbf::output::{Console, Progress, one_line, write_outputs};
use softcbf::robot_file::load_robot;
use softcbf::scenario::ScenarioFile;
use softcbf::settings::check_number;
use softcbf::sim::{settings_report, simulate};
use softcbf::verdict::{Limits, Verdict, judge};
use softcbf::verify::start::StartSet;
use softcbf_description::domain;
use softcbf_description::limits;

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

/// Options of `softcbf simulate`. A setting given here wins over the scenario file, which
/// wins over the robot file, which wins over the built-in default (`softcbf::settings`).
#[derive(Args)]
struct SimulateArgs {
    /// Scenario file (default: the embedded scenarios/default.toml, which fits a robot of
    /// any structure: it starts at rest and drives toward the robot file's `set_point`).
    #[arg(long)]
    scenario: Option<PathBuf>,
    /// Robot file (default: the scenario's robot, else the embedded paper robot).
    #[arg(long)]
    robot: Option<PathBuf>,
    /// Robot file whose physics the plant integrates, while the controller uses the robot
    /// above (same structure, other numbers; default: the scenario's `plant`, else the
    /// controller's robot).
    #[arg(long, value_name = "FILE")]
    plant: Option<PathBuf>,
    /// Set point `Δx,Δy,δL,…` (m), replacing the scenario's reference and the robot
    /// file's `set_point`.
    #[arg(long, allow_hyphen_values = true)]
    set_point: Option<String>,
    /// Simulated time (s).
    #[arg(long, allow_negative_numbers = true)]
    duration: Option<f64>,
    /// Control period (s): the state is sampled and τ held for this long.
    #[arg(long, allow_negative_numbers = true)]
    control_period: Option<f64>,
    /// Also record the plant's state between ticks, every S seconds after each tick (at
    /// most the control period; default: one row per tick).
    #[arg(long, value_name = "S", allow_negative_numbers = true)]
    record_period: Option<f64>,
    /// Both HOCBF class-K gains p1 = p2 (1/s).
    #[arg(long, allow_negative_numbers = true)]
    p: Option<f64>,
    /// HOCBF class-K gain p1 (1/s).
    #[arg(long, allow_negative_numbers = true)]
    p1: Option<f64>,
    /// HOCBF class-K gain p2 (1/s).
    #[arg(long, allow_negative_numbers = true)]
    p2: Option<f64>,
    /// Proportional gain K_P = kp·I (N/m).
    #[arg(long, allow_negative_numbers = true)]
    kp: Option<f64>,
    /// Derivative gain K_D = kd·I (N·s/m).
    #[arg(long, allow_negative_numbers = true)]
    kd: Option<f64>,
    /// How the filter keeps the barriers between samples: `certified` (every barrier proven
    /// over the whole hold), `predicted` (kept at samples of the hold), `paper` (the paper's
    /// rows) or `hold-correction` (docs/model.md §5).
    #[arg(long, value_name = "MODE", value_parser = SafetyMode::parse)]
    safety: Option<SafetyMode>,
    /// Run plain PD+ without the safety filter.
    #[arg(long, conflicts_with = "compare")]
    no_filter: bool,
    /// Also run plain PD+ and draw it beside the filtered run.
    #[arg(long)]
    compare: bool,
    /// Output directory.
    #[arg(long, default_value = "out")]
    out: PathBuf,
    /// Also write an animation of the run, `robot.gif` (about a second more).
    #[arg(long)]
    animate: bool,
    /// Also write the run as an MCAP log, `run.mcap` (JSON channels for Foxglove,
    /// PlotJuggler, Rerun; README.md, "MCAP logs").
    #[arg(long)]
    mcap: bool,
    /// Also write `view.html`, the run in 3-D in the browser, as `softcbf view` does.
    #[arg(long)]
    view: bool,
    /// A filtered run whose lowest barrier falls below this (m) is unsafe (exit status 3).
    #[arg(long, default_value_t = limits::DEFAULT_SIMULATION_THRESHOLD, allow_negative_numbers = true)]
    barrier_threshold: f64,
}

#[derive(Subcommand)]
enum Command {
    /// Print the model (poses, barriers, Jacobians, dynamics) at one state as JSON.
    Model {
        /// Robot file (default: the embedded paper simulation robot).
        #[arg(long)]
        robot: Option<PathBuf>,
        /// Generalized coordinates `Δx,Δy,δL,…` (m) (default: all zero).
        #[arg(long, allow_hyphen_values = true)]
        q: Option<String>,
        /// Generalized velocities [m/s] (default: all zero).
        #[arg(long, allow_hyphen_values = true)]
        qd: Option<String>,
    },
    /// Simulate the safe controller (default: the paper's scenario, with the plain PD+
    /// comparison) and write trajectories, summary.json and figures.
    Simulate(SimulateArgs),
    /// Emulate the robot's servos on a pseudo-terminal (prints the port to connect to).
    Emulate(softcbf::hardware::cli::EmulateArgs),
    /// Run the safe controller on the robot's servos (or on `softcbf emulate`).
    Run(softcbf::hardware::cli::RunArgs),
    /// Redraw the figures from trajectory CSVs or hardware logs (several: side by side).
    Plot(softcbf::replot::PlotArgs),
    /// Write an interactive 3-D view of a `simulate` run in the browser: one HTML file that
    /// works offline (default DIR/view.html).
    View(softcbf::view::ViewArgs),
    /// Identify stiffness, damping and actuator gains from run logs, and write the robot
    /// file with those numbers (and a figure of a held-out part predicted).
    Identify(softcbf::identify::IdentifyArgs),
    /// Run a batch of closed-loop simulations drawn from a scenario's `[verify]` ranges
    /// (or one shard of it), merge shards, or replay one run.
    Verify(softcbf::verify::cli::VerifyArgs),
}

fn run(cli: Cli, console: &mut Console) -> Result<u8, String> {
    match cli.command {
        Command::Model { robot, q, qd } => {
            let robot = load_robot(robot.as_deref()).map_err(|e| e.to_string())?;
            let model = Model::new(robot).map_err(|e| e.to_string())?;
            let nq = model.nq();
            let q = match q {
                Some(text) => parse_coordinates("--q", &text, &model.robot)?,
                None => vec![0.0; nq],
            };
            let qd = match qd {
                Some(text) => parse_velocities("--qd", &text, &model.robot)?,
                None => vec![0.0; nq],
            };
            let report = model_report(&model, &q, &qd).map_err(|e| e.to_string())?;
            console.say(&serde_json::to_string_pretty(&report).map_err(|e| e.to_string())?);
            let mut code = exit::OK;
            let bad = non_finite(&report);
            if bad > 0 {
                eprintln!(
                    "error: {bad} values of the model are not finite at this state (null in \
                     the JSON)"
                );
                code = exit::UNSAFE;
            }
            if let Some(error) = console.error() {
                return Err(error.to_string());
            }
            Ok(code)
        }
        Command::Emulate(args) => softcbf::hardware::cli::emulate(args, console),
        Command::Run(args) => softcbf::hardware::cli::run(args, console),
        Command::Plot(args) => softcbf::replot::plot(args, console),
        Command::View(args) => softcbf::view::view(args, console),
        Command::Identify(args) => softcbf::identify::run(args, console),
        Command::Verify(args) => softcbf::verify::cli::verify_interruptible(args, console),
        Command::Simulate(args) => run_simulation(args, console),
    }
}

/// Numbers in `value` that JSON could not hold (NaN and infinities become `null`).
fn non_finite(value: &serde_json::Value) -> usize {
    match value {
        serde_json::Value::Null => 1,
        serde_json::Value::Array(items) => items.iter().map(non_finite).sum(),
        serde_json::Value::Object(map) => map.values().map(non_finite).sum(),
        _ => 0,
    }
}

fn run_simulation(args: SimulateArgs, console: &mut Console) -> Result<u8, String> {
    let threshold = check_number(
        "--barrier-threshold",
        args.barrier_threshold,
        &limits::BARRIER_THRESHOLD_M,
    )?;
    let file = match &args.scenario {
        Some(path) => ScenarioFile::load(path).map_err(|e| e.to_string())?,
        None => ScenarioFile::default_scenario(),
    };
    // The scenario's own robot is read and checked also when --robot replaces it.
    if args.robot.is_some() {
        file.load_robot().map_err(|e| e.to_string())?;
    }
    let robot = match &args.robot {
        Some(path) => load_robot(Some(path)),
        None => file
            .load_robot()
            .and_then(|robot| robot.map_or_else(|| load_robot(None), Ok)),
    }
    .map_err(|e| e.to_string())?;
    let model = Model::new(robot).map_err(|e| e.to_string())?;
    let set_point = args
        .set_point
        .as_deref()
        .map(|text| parse_vector("--set-point", text, model.nq()))
        .transpose()?;
    let options = SimulateOptions {
        kp: args.kp,
        kd: args.kd,
        p: args.p,
        p1: args.p1,
        p2: args.p2,
        set_point,
        duration: args.duration,
        control_period: args.control_period,
        record_period: args.record_period,
        filter: args.no_filter.then_some(false),
        safety: args.safety,
        compare: args.compare.then_some(true),
        plant: args.plant,
    };
    let spell = |name: &str| format!("--{}", name.replace('_', "-"));
    let overrides = check_simulate_options(options, &model.robot, &spell)?;
    let scenario = file
        .resolve_with(&model, &overrides)
        .map_err(|e| e.to_string())?;
    let filter = scenario.controller.filter;
    // The guarantee is about starts inside the model's domain with every barrier and its
    // first HOCBF level non-negative (docs/model.md §5): a start outside it is refused (no
    // domain) or said (no guarantee).
    if let Some(problem) =
        domain::state_problem(&model.robot, &scenario.initial_q, &scenario.initial_qd)
    {
        return Err(format!(
            "{}: the initial state is outside the model's domain: {problem}",
            scenario.file
        ));
    }
    if filter {
        let starts = StartSet::new(&model, &scenario.controller)?;
        if let Some(problem) = starts.problem(&model, &scenario.initial_q, &scenario.initial_qd) {
            eprintln!(
                "note: the initial state is outside the set the safety guarantee covers \
                 ({problem}); the filter brings it back at the rate p1, and nothing is \
                 guaranteed until it has"
            );
        }
    }
    if !filter && args.compare {
        return Err(format!(
            "--compare: the scenario runs without the safety filter (`filter = false` in {}), \
             so it is itself the plain PD+ run; drop --compare, or turn the filter on",
            scenario.file
        ));
    }
    if !filter && scenario.compare {
        eprintln!(
            "note: no PD+ comparison: the run is itself plain PD+ (the scenario's `compare = \
             true` applies to filtered runs)"
        );
    }
    let compare = filter && scenario.compare;
    let out = args.out.as_path();
    output_directory(out, "--out")?;
    let settings = settings_report(&model, &scenario, filter);
    console.say(&settings.line());

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
    let mut written = write_outputs(out, &main, comparison.as_ref(), &model, args.animate)
        .map_err(|e| e.to_string())?;
    if args.mcap {
        let path = out.join(softcbf::mcap_log::FILE_NAME);
        let log = softcbf::mcap_log::write_simulation(&path, &main, comparison.as_ref(), &model)
            .map_err(|e| e.to_string())?;
        console.say(&log.line());
        written.push(log.path);
    }
    if args.view {
        let path = out.join(softcbf::view::FILE_NAME);
        let view = softcbf::view::write_view(out, &path, Some(&model), softcbf::view::DEFAULT_FPS)
            .map_err(|e| e.to_string())?;
        written.push(view.path);
    }
    console.say(&one_line(&main.summary));
    if let Some(pd) = &comparison {
        console.say(&one_line(&pd.summary));
    }
    let names: Vec<String> = written.iter().map(|p| p.display().to_string()).collect();
    console.say(&format!("wrote {}", names.join(", ")));

    // The exit status is the verdict on the run asked for (filtered, or with --no-filter
    // plain PD+); a comparison beside it is reported, not judged: it is there to fail.
    let verdict = judge(&main.summary.outcome(), &Limits::new(threshold));
    let counts = &main.summary.counts;
    console.say(&format!(
        "verdict: {}",
        verdict.line_with_unproven(counts.uncertified, counts.ticks)
    ));
    match &verdict {
        Verdict::Safe => {}
        Verdict::Unsafe(why) => eprintln!("error: unsafe run: {why}"),
        Verdict::NotRun(why) | Verdict::Fault(why) => eprintln!("error: {why}"),
    }
    if filter && !verdict.is_safe() && scenario.controller.safety != SafetyMode::Certified {
        // Which mode would have held: the same run with the certified rows.
        let mut certified = scenario.clone();
        certified.controller.safety = SafetyMode::Certified;
        let other = simulate(&model, &certified, true, &mut |_| {}).map_err(|e| e.to_string())?;
        let held = judge(&other.summary.outcome(), &Limits::new(threshold));
        eprintln!(
            "note: the same run with the certified rows (--safety certified, docs/model.md §5) \
             ends {}: lowest barrier {:.3e}",
            if held.is_safe() { "safe" } else { "unsafe too" },
            other.summary.min_barrier.value
        );
    }
    let mut code = verdict.status();
    if let Some(error) = console.error() {
        eprintln!("error: {error}");
        code = exit::worst(code, exit::ERROR);
    }
    Ok(code)
}

fn main() -> ExitCode {
    let mut console = Console::new();
    match run(Cli::parse(), &mut console) {
        Ok(code) => ExitCode::from(code),
        Err(message) => {
            eprintln!("error: {message}");
            ExitCode::from(exit::ERROR)
        }
    }
}
