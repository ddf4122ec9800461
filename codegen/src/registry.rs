//! Which robot files a build of this checkout compiles in: every `robots/*.toml`, the files
//! registered in `robots/local.list` (`softcbf-codegen add`), and the benchmark structures.
//!
//! `generated/build.rs` and the `softcbf-codegen` binary both read them through this module,
//! so that `add` can say whether the next build generates a new model. The registry is a
//! text file ignored by git: one robot file a line (absolute paths when written by `add`;
//! relative ones are relative to the registry's directory), blank lines and lines starting
//! with `#` ignored.

use std::path::{Component, Path, PathBuf};

use softcbf_description::robot::{Robot, RobotError, Routing, Structure};

/// File name of the registry inside the robots directory (`robots/local.list`).
pub const REGISTRY_FILE: &str = "local.list";

/// The command that unregisters a file, run from the checkout (for messages).
pub const REMOVE_COMMAND: &str = "cargo run --release -p softcbf-codegen -- remove";

/// The command that registers a file, run from the checkout (for messages).
pub const ADD_COMMAND: &str = "cargo run --release -p softcbf-codegen -- add";

const HEADER: &str = "\
# Robot files compiled into every build of this checkout besides robots/*.toml: one path a
# line, `#` starts a comment line. Written by `softcbf-codegen add FILE` (and `remove FILE`,
# `list`); read by generated/build.rs. Ignored by git: it names files on this machine.
";

/// The checkout this crate was built from (its workspace root).
pub fn checkout() -> PathBuf {
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR"));
    manifest.parent().unwrap_or(manifest).to_path_buf()
}

/// The registry of the checkout this crate was built from: `<checkout>/robots/local.list`.
pub fn default_registry() -> PathBuf {
    checkout().join("robots").join(REGISTRY_FILE)
}

/// One registered robot file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Entry {
    /// 1-based line of the registry that names it.
    pub line: usize,
    /// The file, as written (relative paths joined to the registry's directory).
    pub path: PathBuf,
}

/// Why the registry could not be read or written. Every variant names the registry.
#[derive(Debug, thiserror::Error)]
pub enum RegistryError {
    /// It exists but could not be read (or is not UTF-8 text).
    #[error("{path}: cannot read the robot registry: {source}", path = path.display())]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    /// It could not be written.
    #[error("{path}: cannot write the robot registry: {source}", path = path.display())]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
    /// The file to register could not be located (no such file, or no current directory).
    #[error("{path}: cannot register: {source}", path = path.display())]
    Locate {
        path: PathBuf,
        source: std::io::Error,
    },
}

/// The text of `registry`; `None` when it does not exist.
fn read_text(registry: &Path) -> Result<Option<String>, RegistryError> {
    match std::fs::read_to_string(registry) {
        Ok(text) => Ok(Some(text)),
        Err(error) if error.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(source) => Err(RegistryError::Read {
            path: registry.to_path_buf(),
            source,
        }),
    }
}

/// The registered files of `registry`, in file order; a registry that does not exist
/// registers nothing.
pub fn read(registry: &Path) -> Result<Vec<Entry>, RegistryError> {
    let Some(text) = read_text(registry)? else {
        return Ok(Vec::new());
    };
    Ok(parse(&text, registry_dir(registry)))
}

/// The entries of a registry's text; relative paths are joined to `dir`.
pub fn parse(text: &str, dir: &Path) -> Vec<Entry> {
    text.lines()
        .enumerate()
        .filter_map(|(k, line)| {
            let line = line.trim();
            (!line.is_empty() && !line.starts_with('#')).then(|| Entry {
                line: k + 1,
                path: dir.join(line),
            })
        })
        .collect()
}

/// The directory of `registry`, which is also the robots directory whose `*.toml` every
/// build compiles in.
pub fn registry_dir(registry: &Path) -> &Path {
    match registry.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => dir,
        _ => Path::new("."),
    }
}

/// Every `*.toml` of `robots_dir`, sorted, with `paper-sim.toml` first: a structure's model
/// is named after the first file that has it, and the paper's must stay `paper_sim`.
/// An unreadable directory gives none.
pub fn shipped(robots_dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(robots_dir)
        .map(|entries| {
            entries
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|e| e == "toml"))
                .collect()
        })
        .unwrap_or_default();
    files.sort_by_key(|p| {
        (
            p.file_name().is_none_or(|n| n != "paper-sim.toml"),
            p.clone(),
        )
    });
    files
}

/// The benchmark and test structures every build has: `hex_1`, `hex_4`, `hex_8` (n
/// hexagonal modules, three local tendons each) and `every_barrier` ([`every_barrier`]).
pub fn benchmarks() -> Vec<(String, Structure)> {
    let mut list: Vec<(String, Structure)> = [1usize, 4, 8]
        .into_iter()
        .map(|n| {
            (
                format!("hex_{n}"),
                Structure::new(vec![6; n], vec![3; n], Routing::Local),
            )
        })
        .collect();
    list.push(("every_barrier".to_string(), every_barrier()));
    list
}

/// Two hexagonal modules with every kind of barrier, for the tests: the elongation and bend
/// limits every module has, a half-space and a sphere, each watching a corner, the centre,
/// a listed point and two backbone points of each module.
pub fn every_barrier() -> Structure {
    use softcbf_description::barriers::{ObstacleKind, ObstacleStructure, PointShape};
    let mut structure = Structure::new(vec![6, 6], vec![3, 3], Routing::Local);
    let watch: Vec<(usize, PointShape)> = (0..2)
        .flat_map(|i| {
            [
                (i, PointShape::Corner(2)),
                (i, PointShape::Centre),
                (i, PointShape::Listed),
                (i, PointShape::Arc),
                (i, PointShape::Arc),
            ]
        })
        .collect();
    structure.obstacles = [ObstacleKind::HalfSpace, ObstacleKind::Sphere]
        .into_iter()
        .map(|kind| ObstacleStructure {
            kind,
            watch: watch.clone(),
        })
        .collect();
    structure
}

/// Rust's keywords (strict, reserved and weak ones that cannot name a module).
const KEYWORDS: &[&str] = &[
    "as", "async", "await", "break", "const", "continue", "crate", "dyn", "else", "enum", "extern",
    "false", "fn", "for", "if", "impl", "in", "let", "loop", "match", "mod", "move", "mut", "pub",
    "ref", "return", "self", "static", "struct", "super", "trait", "true", "type", "unsafe", "use",
    "where", "while", "abstract", "become", "box", "do", "final", "gen", "macro", "override",
    "priv", "try", "typeof", "unsized", "virtual", "yield",
];

/// The name of the generated module for the model of robot file `path`, unique among
/// `taken` (and added to it): the file stem in lower case with `_` for any other
/// character, `m` before a leading digit or `_`, `_robot` after a Rust keyword, `_2`,
/// `_3`, … when taken (`paper-sim.toml` is `paper_sim`).
pub fn model_name(path: &Path, taken: &mut std::collections::HashSet<String>) -> String {
    let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("robot");
    let mut name: String = stem
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() {
                c.to_ascii_lowercase()
            } else {
                '_'
            }
        })
        .collect();
    if name.is_empty() || name.starts_with(|c: char| c.is_ascii_digit() || c == '_') {
        name.insert(0, 'm');
    }
    if KEYWORDS.contains(&name.as_str()) {
        name.push_str("_robot");
    }
    let mut unique = name.clone();
    let mut k = 2;
    while taken.contains(&unique) {
        unique = format!("{name}_{k}");
        k += 1;
    }
    taken.insert(unique.clone());
    unique
}

/// A structure in words: `2 modules, corners [5, 5], tendons [3, 3], local routing`.
pub fn describe(structure: &Structure) -> String {
    let routing = match structure.routing {
        Routing::Local => "local",
        Routing::Through => "through",
    };
    let n = structure.modules();
    let mut text = format!(
        "{n} module{}, corners {:?}, tendons {:?}, {routing} routing",
        if n == 1 { "" } else { "s" },
        structure.corners,
        structure.tendons
    );
    if !structure.obstacles.is_empty() {
        let watched: usize = structure.obstacles.iter().map(|o| o.watch.len()).sum();
        text.push_str(&format!(
            ", {} obstacle{} watching {watched} point{}",
            structure.obstacles.len(),
            if structure.obstacles.len() == 1 {
                ""
            } else {
                "s"
            },
            if watched == 1 { "" } else { "s" },
        ));
    }
    text
}

/// What [`add`] did.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Added {
    /// Recorded at this line.
    New { line: usize, path: PathBuf },
    /// Already registered, at this line.
    Already { line: usize, path: PathBuf },
    /// The file lies in the robots directory, which every build compiles in.
    Shipped { path: PathBuf },
}

/// Registers `file` (which must exist) in `registry`: records its canonical absolute path
/// as a new line, creating the registry with a header comment if needed. The file is not
/// read here; check it with [`Robot::load`] first.
pub fn add(registry: &Path, file: &Path) -> Result<Added, RegistryError> {
    let path = std::fs::canonicalize(file).map_err(|source| RegistryError::Locate {
        path: file.to_path_buf(),
        source,
    })?;
    if let Ok(dir) = std::fs::canonicalize(registry_dir(registry))
        && path.parent() == Some(dir.as_path())
        && path.extension().is_some_and(|e| e == "toml")
    {
        return Ok(Added::Shipped { path });
    }
    if let Some(entry) = read(registry)?
        .into_iter()
        .find(|e| same_file(&e.path, &path))
    {
        return Ok(Added::Already {
            line: entry.line,
            path: entry.path,
        });
    }
    let mut text = match std::fs::read_to_string(registry) {
        Ok(text) => text,
        Err(error) if error.kind() == std::io::ErrorKind::NotFound => HEADER.to_string(),
        Err(source) => {
            return Err(RegistryError::Read {
                path: registry.to_path_buf(),
                source,
            });
        }
    };
    if !text.is_empty() && !text.ends_with('\n') {
        text.push('\n');
    }
    let written = path.to_str().unwrap_or("\n");
    if written.contains(['\n', '\r']) || written.trim() != written {
        return Err(RegistryError::Locate {
            path: path.clone(),
            source: std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                "its path has a line break, surrounding spaces or bytes that are not UTF-8, \
                 which a registry line cannot hold; move or rename it",
            ),
        });
    }
    text.push_str(written);
    text.push('\n');
    let line = text.lines().count();
    write(registry, &text)?;
    Ok(Added::New { line, path })
}

/// Unregisters every line of `registry` that names `file` (relative to the current
/// directory; the file need not exist any more) and returns the lines removed. A registry
/// left with nothing but its header comment is deleted.
pub fn remove(registry: &Path, file: &Path) -> Result<Vec<Entry>, RegistryError> {
    let wanted = std::path::absolute(file).map_err(|source| RegistryError::Locate {
        path: file.to_path_buf(),
        source,
    })?;
    let Some(text) = read_text(registry)? else {
        return Ok(Vec::new());
    };
    let removed: Vec<Entry> = parse(&text, registry_dir(registry))
        .into_iter()
        .filter(|e| same_file(&e.path, &wanted))
        .collect();
    if removed.is_empty() {
        return Ok(removed);
    }
    let kept: String = text
        .lines()
        .enumerate()
        .filter(|(k, _)| !removed.iter().any(|e| e.line == k + 1))
        .map(|(_, line)| format!("{line}\n"))
        .collect();
    if kept == HEADER || kept.trim().is_empty() {
        std::fs::remove_file(registry).map_err(|source| RegistryError::Write {
            path: registry.to_path_buf(),
            source,
        })?;
    } else {
        write(registry, &kept)?;
    }
    Ok(removed)
}

/// Writes the registry through a temporary file renamed over it, so that a build never
/// reads half of it.
fn write(registry: &Path, text: &str) -> Result<(), RegistryError> {
    let error = |source| RegistryError::Write {
        path: registry.to_path_buf(),
        source,
    };
    let mut temporary = registry.as_os_str().to_owned();
    temporary.push(".tmp");
    let temporary = PathBuf::from(temporary);
    std::fs::write(&temporary, text).map_err(error)?;
    std::fs::rename(&temporary, registry).map_err(error)
}

/// Whether `a` and `b` name the same file: the same canonical path when both exist, else
/// the same absolute path once `.` and `..` are resolved in the text.
pub fn same_file(a: &Path, b: &Path) -> bool {
    match (std::fs::canonicalize(a), std::fs::canonicalize(b)) {
        (Ok(a), Ok(b)) => a == b,
        _ => lexical(a) == lexical(b),
    }
}

/// `path` made absolute with `.` and `..` resolved in the text (no file system access
/// beyond the current directory).
fn lexical(path: &Path) -> PathBuf {
    let absolute = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    let mut out = PathBuf::new();
    for component in absolute.components() {
        match component {
            Component::CurDir => {}
            Component::ParentDir => {
                out.pop();
            }
            other => out.push(other),
        }
    }
    out
}

pub use softcbf_description::toml_file::shell_word;

/// A robot file a build compiles in, and how it reads now.
pub struct Source {
    /// The file.
    pub path: PathBuf,
    /// Its registry line, for registered files (`None`: a `robots/*.toml`).
    pub line: Option<usize>,
    /// Its structure, or why it cannot be read.
    pub structure: Result<Structure, RobotError>,
}

/// Every robot file a build with `registry` compiles in, shipped files first, each loaded.
pub fn sources(registry: &Path) -> Result<Vec<Source>, RegistryError> {
    let load = |path: &Path| Robot::load(path).map(|robot| robot.structure());
    let mut all: Vec<Source> = shipped(registry_dir(registry))
        .into_iter()
        .map(|path| Source {
            structure: load(&path),
            path,
            line: None,
        })
        .collect();
    for entry in read(registry)? {
        all.push(Source {
            structure: load(&entry.path),
            path: entry.path,
            line: Some(entry.line),
        });
    }
    Ok(all)
}

/// Which other robot file (or benchmark) of `sources` already has `structure`, so that
/// the build has its model whatever `file` says: its path or benchmark name.
pub fn model_owner(sources: &[Source], structure: &Structure, file: &Path) -> Option<String> {
    sources
        .iter()
        .filter(|s| !same_file(&s.path, file))
        .find(|s| s.structure.as_ref().is_ok_and(|s| s == structure))
        .map(|s| s.path.display().to_string())
        .or_else(|| {
            benchmarks()
                .into_iter()
                .find(|(_, b)| b == structure)
                .map(|(name, _)| format!("the benchmark structure {name}"))
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("softcbf-registry-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn comments_blank_lines_and_relative_paths() {
        let entries = parse(
            "# header\n\n  /abs/a.toml  \n#/not/this.toml\nrel/b.toml\n",
            Path::new("/r"),
        );
        assert_eq!(
            entries,
            vec![
                Entry {
                    line: 3,
                    path: PathBuf::from("/abs/a.toml")
                },
                Entry {
                    line: 5,
                    path: PathBuf::from("/r/rel/b.toml")
                },
            ]
        );
    }

    #[test]
    fn add_records_once_and_remove_deletes_an_empty_registry() {
        let dir = scratch("add");
        let robots = dir.join("robots");
        std::fs::create_dir_all(&robots).unwrap();
        let registry = robots.join(REGISTRY_FILE);
        let file = dir.join("mine.toml");
        std::fs::write(&file, "modules = 1\n").unwrap();
        assert!(read(&registry).unwrap().is_empty());
        let canonical = std::fs::canonicalize(&file).unwrap();
        let added = add(&registry, &file).unwrap();
        assert_eq!(
            added,
            Added::New {
                line: HEADER.lines().count() + 1,
                path: canonical.clone()
            }
        );
        // The same file under another spelling is the same entry.
        let other = dir.join("robots/../mine.toml");
        assert!(matches!(
            add(&registry, &other).unwrap(),
            Added::Already { .. }
        ));
        assert_eq!(read(&registry).unwrap().len(), 1);
        // A file of the robots directory is compiled in anyway.
        let shipped_file = robots.join("x.toml");
        std::fs::write(&shipped_file, "modules = 1\n").unwrap();
        assert!(matches!(
            add(&registry, &shipped_file).unwrap(),
            Added::Shipped { .. }
        ));
        // Remove works once the file is gone, and drops the header-only registry.
        std::fs::remove_file(&file).unwrap();
        let removed = remove(&registry, &file).unwrap();
        assert_eq!(removed.len(), 1);
        assert!(!registry.exists());
        assert!(remove(&registry, &file).unwrap().is_empty());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn remove_keeps_other_lines_and_comments() {
        let dir = scratch("remove");
        let registry = dir.join(REGISTRY_FILE);
        std::fs::write(&registry, "# mine\n/a/x.toml\n/b/y.toml\n/a/./x.toml\n").unwrap();
        let removed = remove(&registry, Path::new("/a/x.toml")).unwrap();
        assert_eq!(
            removed.iter().map(|e| e.line).collect::<Vec<_>>(),
            vec![2, 4]
        );
        assert_eq!(
            std::fs::read_to_string(&registry).unwrap(),
            "# mine\n/b/y.toml\n"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn model_names_are_unique_rust_identifiers() {
        let mut taken: std::collections::HashSet<String> =
            benchmarks().into_iter().map(|(name, _)| name).collect();
        let names: Vec<String> = [
            "robots/paper-sim.toml",
            "/a/Paper Sim.toml",
            "/b/2-modules.toml",
            "/c/type.toml",
            "/d/_x.toml",
            "/e/hex-4.toml",
            "/f/ünïcode.toml",
        ]
        .iter()
        .map(|p| model_name(Path::new(p), &mut taken))
        .collect();
        assert_eq!(
            names,
            [
                "paper_sim",
                "paper_sim_2",
                "m2_modules",
                "type_robot",
                "m_x",
                "hex_4_2",
                "m_n_code"
            ]
        );
    }

    #[test]
    fn structures_in_words() {
        let structure = Structure::new(vec![5, 5], vec![3, 3], Routing::Local);
        assert_eq!(
            describe(&structure),
            "2 modules, corners [5, 5], tendons [3, 3], local routing"
        );
        assert_eq!(
            model_owner(&[], &benchmarks()[1].1, Path::new("x")).as_deref(),
            Some("the benchmark structure hex_4")
        );
        assert_eq!(model_owner(&[], &structure, Path::new("x")), None);
        assert_eq!(shell_word(Path::new("/a/b-1.toml")), "/a/b-1.toml");
        assert_eq!(
            shell_word(Path::new("/my robots/it's.toml")),
            "'/my robots/it'\\''s.toml'"
        );
    }
}
