//! `softcbf-codegen`: registers robot files kept outside `robots/` so that every build of
//! the checkout compiles their models (`add`, `remove`, `list`), and writes a model's source.
//!
//! Exit status: 0 done, 1 a bad robot file, registry or output, 2 the command line could
//! not be read (clap: usage on standard error; `--help` prints it on standard output).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use clap::{CommandFactory, Parser, Subcommand};

use softcbf_codegen::generate;
use softcbf_codegen::registry::{self, ADD_COMMAND, Added, REMOVE_COMMAND};
use softcbf_description::Robot;

#[derive(Parser)]
#[command(
    name = "softcbf-codegen",
    version,
    about = "Generate robot models, and register robot files kept outside robots/",
    long_about = "Generate robot models, and register robot files kept outside robots/.\n\n\
        Every robots/*.toml of the checkout is compiled into its builds. A robot file kept \
        elsewhere is registered once with `add FILE`: the registry (robots/local.list, ignored \
        by git) is read by every later build, which generates a model for each new structure \
        (module count, corners, tendons, routing). Run from the checkout as \
        `cargo run --release -p softcbf-codegen -- COMMAND`.",
    args_conflicts_with_subcommands = true,
    override_usage = "softcbf-codegen add|remove|list …\n       \
        softcbf-codegen [generate] --robot FILE.toml --out FILE.rs"
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    #[command(flatten)]
    generate: GenerateArgs,
}

#[derive(clap::Args)]
struct GenerateArgs {
    /// Robot file whose model source is written.
    #[arg(long, value_name = "FILE.toml")]
    robot: Option<PathBuf>,
    /// Where to write the generated Rust source.
    #[arg(long, value_name = "FILE.rs")]
    out: Option<PathBuf>,
}

#[derive(clap::Args)]
struct RegistryArg {
    /// The registry file [default: robots/local.list of the checkout this program was
    /// built from].
    #[arg(long, value_name = "FILE")]
    registry: Option<PathBuf>,
}

impl RegistryArg {
    fn path(&self) -> PathBuf {
        self.registry
            .clone()
            .unwrap_or_else(registry::default_registry)
    }
}

#[derive(Subcommand)]
enum Command {
    /// Check a robot file and register it: every later build of this checkout compiles its
    /// model (its absolute path is recorded in robots/local.list).
    Add {
        /// The robot file (anywhere; relative to the current directory).
        file: PathBuf,
        #[command(flatten)]
        registry: RegistryArg,
    },
    /// Unregister a robot file (it need not exist any more).
    Remove {
        /// The robot file, as registered (relative to the current directory).
        file: PathBuf,
        #[command(flatten)]
        registry: RegistryArg,
    },
    /// Show the registered robot files: whether each still reads, and its structure
    /// (exit status 1 if one does not, since builds fail until it is fixed or removed).
    List {
        #[command(flatten)]
        registry: RegistryArg,
    },
    /// Write the generated model source of a robot file (the same as the flags without a
    /// command).
    Generate(GenerateArgs),
}

/// Prints to standard output; a closed output is not worth a panic.
macro_rules! say {
    ($($arg:tt)*) => {{
        let _ = writeln!(std::io::stdout().lock(), $($arg)*);
    }};
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Some(Command::Add { file, registry }) => add(&file, &registry.path()),
        Some(Command::Remove { file, registry }) => remove(&file, &registry.path()),
        Some(Command::List { registry }) => list(&registry.path()),
        Some(Command::Generate(args)) => generate_file(args),
        None => generate_file(cli.generate),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("error: {message}");
            ExitCode::FAILURE
        }
    }
}

fn generate_file(args: GenerateArgs) -> Result<(), String> {
    let (Some(robot_path), Some(out_path)) = (args.robot, args.out) else {
        Cli::command()
            .error(
                clap::error::ErrorKind::MissingRequiredArgument,
                "give a command (add, remove, list), or both --robot FILE.toml and --out FILE.rs",
            )
            .exit();
    };
    let robot = Robot::load(&robot_path).map_err(|e| e.to_string())?;
    let start = Instant::now();
    let source = generate(&robot.structure(), &robot_path.display().to_string());
    let write = |path: &Path| -> std::io::Result<()> {
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir)?;
        }
        std::fs::write(path, &source.text)
    };
    write(&out_path).map_err(|error| format!("cannot write {}: {error}", out_path.display()))?;
    let total: usize = source.ops.iter().map(|(_, c)| c.total()).sum();
    eprintln!(
        "wrote {} ({} modules, {} lines, {} operations) in {:.2} s",
        out_path.display(),
        robot.modules.len(),
        source.text.lines().count(),
        total,
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

fn add(file: &Path, registry_file: &Path) -> Result<(), String> {
    let robot = Robot::load(file).map_err(|e| e.to_string())?;
    let structure = robot.structure();
    let added = registry::add(registry_file, file).map_err(|e| e.to_string())?;
    let path = match &added {
        Added::New { line, path } => {
            say!(
                "registered {}\n  in {}, line {line}",
                path.display(),
                registry_file.display()
            );
            path
        }
        Added::Already { line, path } => {
            say!(
                "{} is already registered\n  in {}, line {line}",
                path.display(),
                registry_file.display()
            );
            path
        }
        Added::Shipped { path } => {
            say!(
                "{} is in {}, whose robot files every build compiles in: nothing to register",
                path.display(),
                registry::registry_dir(registry_file).display()
            );
            path
        }
    };
    say!("structure: {}", registry::describe(&structure));
    let sources = registry::sources(registry_file).map_err(|e| e.to_string())?;
    match registry::model_owner(&sources, &structure, path) {
        _ if matches!(added, Added::Shipped { .. }) => {}
        Some(owner) => say!(
            "model: every build already has one for this structure (from {owner});\n  \
             registered, the file stays compiled in if its structure changes later"
        ),
        None => say!(
            "model: a new structure; the next build of this checkout generates its model\n  \
             (any `cargo build --release` or `cargo run --release -p softcbf -- …`; an \
             installed softcbf\n  has the models it was installed with: run \
             `cargo install --path runtime` again)"
        ),
    }
    say!(
        "next: cargo run --release -p softcbf -- model --robot {}",
        registry::shell_word(path)
    );
    Ok(())
}

fn remove(file: &Path, registry_file: &Path) -> Result<(), String> {
    let removed = registry::remove(registry_file, file).map_err(|e| e.to_string())?;
    if removed.is_empty() {
        let entries = registry::read(registry_file).map_err(|e| e.to_string())?;
        let registered: Vec<String> = entries
            .iter()
            .map(|e| format!("\n  line {}: {}", e.line, e.path.display()))
            .collect();
        return Err(format!(
            "{} is not registered in {}{}",
            file.display(),
            registry_file.display(),
            if registered.is_empty() {
                "; it registers no files".to_string()
            } else {
                format!(", which registers:{}", registered.concat())
            }
        ));
    }
    for entry in &removed {
        say!(
            "unregistered {} (line {} of {}); later builds no longer compile it in",
            entry.path.display(),
            entry.line,
            registry_file.display()
        );
    }
    Ok(())
}

fn list(registry_file: &Path) -> Result<(), String> {
    let sources = registry::sources(registry_file).map_err(|e| e.to_string())?;
    let shipped = sources.iter().filter(|s| s.line.is_none()).count();
    say!(
        "{}: every build compiles in the {shipped} robot files of {} and these:",
        registry_file.display(),
        registry::registry_dir(registry_file).display()
    );
    let mut broken = 0;
    for source in sources.iter().filter(|s| s.line.is_some()) {
        let line = source.line.unwrap_or_default();
        match &source.structure {
            Ok(structure) => {
                let model = match registry::model_owner(&sources, structure, &source.path) {
                    Some(owner) => format!("model shared with {owner}"),
                    None => "a model of its own".to_string(),
                };
                say!(
                    "  line {line}: {}\n    {}; {model}",
                    source.path.display(),
                    registry::describe(structure)
                );
            }
            Err(error) => {
                broken += 1;
                say!(
                    "  line {line}: {}\n    does not read: {error}\n    builds fail until it is \
                     fixed or removed: {REMOVE_COMMAND} {}",
                    source.path.display(),
                    registry::shell_word(&source.path)
                );
            }
        }
    }
    if sources.len() == shipped {
        say!("  (none; register a robot file with `{ADD_COMMAND} FILE`)");
    }
    if broken > 0 {
        return Err(format!(
            "{broken} registered robot file{} cannot be read",
            if broken == 1 { "" } else { "s" }
        ));
    }
    Ok(())
}
