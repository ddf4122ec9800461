//! `softcbf-codegen --robot FILE --out FILE.rs`: writes the generated model of a robot file.
//! The output is what the `softcbf-generated` crate's build script produces for that robot.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use softcbf_codegen::generate;
use softcbf_description::Robot;

const USAGE: &str = "usage: softcbf-codegen --robot FILE.toml --out FILE.rs";

fn parse_args() -> Result<(PathBuf, PathBuf), String> {
    let mut robot = None;
    let mut out = None;
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        let slot = match arg.as_str() {
            "--robot" => &mut robot,
            "--out" => &mut out,
            "-h" | "--help" => return Err(USAGE.to_string()),
            other => return Err(format!("unknown argument `{other}`\n{USAGE}")),
        };
        match args.next() {
            Some(value) => *slot = Some(PathBuf::from(value)),
            None => return Err(format!("`{arg}` needs a value\n{USAGE}")),
        }
    }
    match (robot, out) {
        (Some(robot), Some(out)) => Ok((robot, out)),
        _ => Err(format!("both --robot and --out are required\n{USAGE}")),
    }
}

fn main() -> ExitCode {
    let (robot_path, out_path) = match parse_args() {
        Ok(paths) => paths,
        Err(message) => {
            eprintln!("{message}");
            return ExitCode::from(2);
        }
    };
    let robot = match Robot::load(&robot_path) {
        Ok(robot) => robot,
        Err(error) => {
            eprintln!("error: {error}");
            return ExitCode::FAILURE;
        }
    };
    let start = Instant::now();
    let source = generate(&robot.structure(), &robot_path.display().to_string());
    if let Err(error) = std::fs::write(&out_path, &source.text) {
        eprintln!("error: cannot write {}: {error}", out_path.display());
        return ExitCode::FAILURE;
    }
    let total: usize = source.ops.iter().map(|(_, c)| c.total()).sum();
    eprintln!(
        "wrote {} ({} modules, {} lines, {} operations) in {:.2} s",
        out_path.display(),
        robot.modules.len(),
        source.text.lines().count(),
        total,
        start.elapsed().as_secs_f64()
    );
    ExitCode::SUCCESS
}
