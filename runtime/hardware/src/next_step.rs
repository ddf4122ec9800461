//! The `next:` line `softcbf run --experiment` prints when its experiment is over: what
//! to run next. `softcbf identify` fits a static and a dynamic log of one robot together
//! (stiffness and actuator gains from the rest states, damping from the motion), so the
//! line after either experiment names both logs.

use std::path::{Path, PathBuf};

use super::experiment::ExperimentKind;
use super::summary_file::{FILE_NAME, HardwareSummary};

/// The `next:` line after an experiment of kind `kind` logged into `out`, of the robot
/// `robot_name` read from `robot_file`, on the bus `port`.
///
/// After the static experiment: the dynamic one (into a sibling `dynamic` directory, or
/// the dynamic log already beside it), then `identify` with both logs. After the dynamic
/// one: `identify` with the static log beside it (the newest sibling directory whose
/// `summary.json` records a static experiment of the same robot) and this one; `STATIC_LOG`
/// when there is none, with what to put there.
pub fn after_experiment(
    kind: ExperimentKind,
    robot_file: &Path,
    robot_name: &str,
    out: &Path,
    port: &str,
) -> String {
    let robot = robot_file.display();
    let identify =
        |logs: &str| format!("softcbf identify --robot {robot} {logs} --out identified.toml");
    match kind {
        ExperimentKind::Static => match sibling_log(out, robot_name, "dynamic") {
            Some(dynamic) => format!(
                "next: {} (this static log with the dynamic one beside it)",
                identify(&format!("{} {}", out.display(), dynamic.display()))
            ),
            None => {
                let dynamic = sibling(out, "dynamic");
                format!(
                    "next: the dynamic experiment, softcbf run --robot {robot} --port {port} \
                     --experiment dynamic --out {dynamic}, then {} (identify fits both logs \
                     together)",
                    identify(&format!("{} {}", out.display(), dynamic.display())),
                    dynamic = dynamic.display()
                )
            }
        },
        ExperimentKind::Dynamic => match sibling_log(out, robot_name, "static") {
            Some(static_log) => format!(
                "next: {} (the static log beside this one, and this dynamic log)",
                identify(&format!("{} {}", static_log.display(), out.display()))
            ),
            None => format!(
                "next: {}, STATIC_LOG being the directory of a `softcbf run --robot {robot} \
                 --experiment static` of this robot (identify fits both logs together)",
                identify(&format!("STATIC_LOG {}", out.display()))
            ),
        },
    }
}

/// `name` beside `out` (in its parent directory).
fn sibling(out: &Path, name: &str) -> PathBuf {
    match out.parent() {
        Some(parent) if !parent.as_os_str().is_empty() => parent.join(name),
        _ => PathBuf::from(name),
    }
}

/// The newest directory beside `out` (not `out` itself) whose `summary.json` records an
/// experiment of kind `kind` (`"static"`, `"dynamic"`) of the robot `robot_name`.
fn sibling_log(out: &Path, robot_name: &str, kind: &str) -> Option<PathBuf> {
    let parent = match out.parent() {
        Some(parent) if !parent.as_os_str().is_empty() => parent.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let same = |a: &Path, b: &Path| match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    };
    let mut found: Option<(std::time::SystemTime, PathBuf)> = None;
    for entry in std::fs::read_dir(&parent).ok()?.flatten() {
        let dir = entry.path();
        if !dir.is_dir() || same(&dir, out) {
            continue;
        }
        let summary = dir.join(FILE_NAME);
        // A directory of something else (a simulation's, an unreadable file) is skipped.
        let Ok(Some(read)) = HardwareSummary::read(&dir) else {
            continue;
        };
        let matches = read.robot == robot_name && read.experiment_kind() == Some(kind);
        if !matches {
            continue;
        }
        let modified = std::fs::metadata(&summary)
            .and_then(|m| m.modified())
            .unwrap_or(std::time::UNIX_EPOCH);
        if found.as_ref().is_none_or(|(newest, _)| modified > *newest) {
            // As the user wrote `out`: beside it, by its own name.
            let shown = match out.parent() {
                Some(p) if !p.as_os_str().is_empty() => p.join(entry.file_name()),
                _ => PathBuf::from(entry.file_name()),
            };
            found = Some((modified, shown));
        }
    }
    found.map(|(_, dir)| dir)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write_summary(dir: &Path, robot: &str, kind: &str) {
        use crate::experiment::ExperimentKind;
        use crate::summary_file::{ExperimentDesign, ExperimentSummary};
        std::fs::create_dir_all(dir).unwrap();
        let design = ExperimentDesign::unknown(match kind {
            "static" => ExperimentKind::Static,
            _ => ExperimentKind::Dynamic,
        });
        let summary = HardwareSummary {
            robot: robot.to_string(),
            hardware: true,
            experiment: Some(ExperimentSummary {
                design,
                ..ExperimentSummary::default()
            }),
            ..HardwareSummary::default()
        };
        summary.write(dir).unwrap();
    }

    /// The line after the dynamic experiment names both logs: the static one beside it
    /// when there is one, else a placeholder saying what it stands for.
    #[test]
    fn the_line_after_an_experiment_names_both_logs() {
        let root = std::env::temp_dir().join(format!("softcbf-next-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        let (static_dir, dynamic_dir) = (root.join("static"), root.join("dynamic"));
        let robot = Path::new("robots/hardware-example.toml");
        let port = "/dev/ttyUSB0";

        // The static experiment first: the dynamic one to run next, then identify on both.
        write_summary(&static_dir, "hardware-example", "static");
        let line = after_experiment(
            ExperimentKind::Static,
            robot,
            "hardware-example",
            &static_dir,
            port,
        );
        let identify = format!(
            "softcbf identify --robot robots/hardware-example.toml {} {} --out identified.toml",
            static_dir.display(),
            dynamic_dir.display()
        );
        assert!(line.contains(&identify), "{line}");
        assert!(
            line.contains(&format!(
                "--experiment dynamic --out {}",
                dynamic_dir.display()
            )),
            "{line}"
        );

        // Then the dynamic one: identify on the static log beside it and this one.
        write_summary(&dynamic_dir, "hardware-example", "dynamic");
        let line = after_experiment(
            ExperimentKind::Dynamic,
            robot,
            "hardware-example",
            &dynamic_dir,
            port,
        );
        assert!(line.starts_with(&format!("next: {identify}")), "{line}");

        // A static log of another robot is not it: the placeholder, explained.
        let line = after_experiment(ExperimentKind::Dynamic, robot, "other", &dynamic_dir, port);
        assert!(
            line.contains(&format!(
                "softcbf identify --robot robots/hardware-example.toml STATIC_LOG {} --out",
                dynamic_dir.display()
            )),
            "{line}"
        );
        assert!(line.contains("--experiment static"), "{line}");
        let _ = std::fs::remove_dir_all(&root);
    }
}
