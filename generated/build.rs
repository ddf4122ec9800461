//! Generates one model per robot structure found in the workspace's `robots/` directory
//! (plus `SOFTCBF_ROBOTS`, a `:`-separated list of extra robot files, and the benchmark
//! structures `hex_1`, `hex_4`, `hex_8`), and a registry that finds them by structure.
//!
//! The benchmark structures are always built, not put behind a feature: generating all of
//! them takes < 0.5 s and compiling hex_4 and hex_8 adds ≈ 0.5–1 s and ≈ 1.5–2.5 s to a
//! release build of this crate (measured with `scripts/measure-scaling`, out of a 4-minute
//! workspace build), and tests use hex_1 and hex_4.

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use softcbf_description::robot::{Robot, Routing, Structure};

fn module_name(path: &Path) -> String {
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
    if name.starts_with(|c: char| c.is_ascii_digit()) {
        name.insert(0, 'm');
    }
    name
}

fn main() {
    let manifest =
        PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"));
    let root = manifest
        .parent()
        .expect("generated/ sits in the workspace")
        .to_path_buf();
    let out_dir = PathBuf::from(std::env::var("OUT_DIR").expect("cargo sets OUT_DIR"));
    let robots_dir = root.join("robots");
    println!("cargo:rerun-if-changed={}", robots_dir.display());
    println!(
        "cargo:rerun-if-changed={}",
        root.join("codegen/src").display()
    );
    println!("cargo:rerun-if-env-changed=SOFTCBF_ROBOTS");

    let mut files: Vec<PathBuf> = std::fs::read_dir(&robots_dir)
        .map(|entries| {
            entries
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|e| e == "toml"))
                .collect()
        })
        .unwrap_or_default();
    // Sorted, with the paper's robot first: a structure's model is named after the first
    // file that has it, and the paper's structure must stay `paper_sim` whatever other
    // files share it (e.g. hardware-example.toml).
    files.sort_by_key(|p| {
        (
            p.file_name().is_none_or(|n| n != "paper-sim.toml"),
            p.clone(),
        )
    });
    if let Ok(extra) = std::env::var("SOFTCBF_ROBOTS") {
        files.extend(
            extra
                .split(':')
                .filter(|s| !s.is_empty())
                .map(PathBuf::from),
        );
    }

    let mut models: Vec<(String, String, Structure)> = Vec::new();
    let mut seen = HashSet::new();
    for path in &files {
        println!("cargo:rerun-if-changed={}", path.display());
        let robot = match Robot::load(path) {
            Ok(robot) => robot,
            Err(error) => panic!(
                "\n\nerror: {error}\n(robot files in {} are compiled into the model)\n",
                robots_dir.display()
            ),
        };
        let structure = robot.structure();
        if seen.insert(structure.clone()) {
            let label = path
                .strip_prefix(&root)
                .unwrap_or(path)
                .display()
                .to_string();
            models.push((module_name(path), label, structure));
        }
    }
    for n in [1usize, 4, 8] {
        let structure = Structure {
            corners: vec![6; n],
            tendons: vec![3; n],
            routing: Routing::Local,
        };
        if seen.insert(structure.clone()) {
            models.push((
                format!("hex_{n}"),
                format!("the benchmark structure hex_{n}"),
                structure,
            ));
        }
    }

    let mut registry = String::new();
    let mut entries = Vec::new();
    for (name, label, structure) in &models {
        let source = softcbf_codegen::generate(structure, label);
        let file = out_dir.join(format!("{name}.rs"));
        std::fs::write(&file, source.text).expect("OUT_DIR is writable");
        let routing = match structure.routing {
            Routing::Local => "local",
            Routing::Through => "through",
        };
        registry.push_str(&format!(
            "/// Model generated from {label}.\n#[allow(clippy::all, clippy::pedantic, unused)]\npub mod {name} {{\n    include!(concat!(env!(\"OUT_DIR\"), \"/{name}.rs\"));\n    /// The generated source compiled above (unused constants cost nothing in a binary).\n    pub const SOURCE: &str = include_str!(concat!(env!(\"OUT_DIR\"), \"/{name}.rs\"));\n    /// This model behind the [`crate::GeneratedModel`] interface.\n    pub struct Model;\n    crate::impl_generated_model!(Model, \"{name}\", \"{label}\", \"{routing}\");\n}}\n"
        ));
        entries.push(format!("&{name}::Model"));
    }
    registry.push_str(&format!(
        "/// Every model this crate was built with.\npub static MODELS: &[&dyn GeneratedModel] = &[{}];\n",
        entries.join(", ")
    ));
    std::fs::write(out_dir.join("models.rs"), registry).expect("OUT_DIR is writable");
}
