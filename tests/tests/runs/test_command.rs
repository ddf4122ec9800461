//! The README's test command is the one CI runs (`.ci/run`'s `TEST_COMMAND`), and it gives
//! the whole picture: every test binary runs even after one fails, so the end of its output
//! counts every failure.

use std::path::Path;

fn text(path: &str) -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(path);
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn the_readme_shows_the_test_command_ci_runs_and_it_runs_every_binary() {
    let ci = text(".ci/run");
    let command = ci
        .lines()
        .find_map(|l| l.strip_prefix("TEST_COMMAND=\""))
        .and_then(|rest| rest.strip_suffix('"'))
        .expect(".ci/run sets TEST_COMMAND=\"…\"");
    let readme = text("README.md");
    let shown: Vec<&str> = readme
        .lines()
        .filter(|l| l.trim_start().starts_with("cargo test"))
        .collect();
    assert_eq!(
        shown,
        [command],
        "the README's test commands are not exactly .ci/run's"
    );
    assert!(
        command.split_whitespace().any(|w| w == "--no-fail-fast"),
        "`{command}` stops at the first failing test binary"
    );
}
