//! Generates one model per robot structure the checkout names: every `robots/*.toml`, the
//! files registered in `robots/local.list` (`softcbf-codegen add FILE`), `SOFTCBF_ROBOTS` (a
//! `:`-separated list of extra files, for one build), and the benchmark structures `hex_1`,
//! `hex_4`, `hex_8`; and a registry that finds them by structure.
//!
//! A registered file that is gone or does not read fails the build, naming the registry line
//! and the command that unregisters it: building on without it would only move the error to
//! `softcbf`'s "no generated model", far from its cause.
//!
//! The benchmark structures are always built, not put behind a feature: generating all of
//! them takes < 0.5 s and compiling hex_4 and hex_8 adds ≈ 0.5–1 s and ≈ 1.5–2.5 s to a
//! release build of this crate (measured with `scripts/measure-scaling`, out of a 4-minute
//! workspace build), and tests use hex_1 and hex_4.

use std::collections::HashSet;
use std::path::PathBuf;

use softcbf_codegen::registry::{self, REGISTRY_FILE, REMOVE_COMMAND};
use softcbf_description::robot::{Robot, Routing, Structure};

/// Ends the build script with `message` on standard error (cargo shows it under
/// `--- stderr`), without a panic's backtrace noise.
fn fail(message: &str) -> ! {
    eprintln!("\nerror: {message}\n");
    std::process::exit(1)
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
    let registry_file = robots_dir.join(REGISTRY_FILE);
    // The directory catches a new robot file and the registry's creation; a path that does
    // not exist must not be named (cargo would rerun this script on every build).
    println!("cargo:rerun-if-changed={}", robots_dir.display());
    if registry_file.exists() {
        println!("cargo:rerun-if-changed={}", registry_file.display());
    }
    println!(
        "cargo:rerun-if-changed={}",
        root.join("codegen/src").display()
    );
    println!("cargo:rerun-if-env-changed=SOFTCBF_ROBOTS");

    // (file, where it was named, for errors)
    let mut files: Vec<(PathBuf, String)> = registry::shipped(&robots_dir)
        .into_iter()
        .map(|p| {
            (
                p,
                format!(
                    "robot files in {} are compiled into every build",
                    robots_dir.display()
                ),
            )
        })
        .collect();
    let registered = registry::read(&registry_file).unwrap_or_else(|e| fail(&e.to_string()));
    for entry in registered {
        let context = format!(
            "{}:{}: this robot file is registered for every build of this checkout; fix it, or \
             unregister it with\n  {REMOVE_COMMAND} {}",
            registry_file.display(),
            entry.line,
            registry::shell_word(&entry.path)
        );
        files.push((entry.path, context));
    }
    if let Ok(extra) = std::env::var("SOFTCBF_ROBOTS") {
        for path in extra.split(':').filter(|s| !s.is_empty()) {
            files.push((
                PathBuf::from(path),
                "this robot file is listed in SOFTCBF_ROBOTS".to_string(),
            ));
        }
    }

    let mut models: Vec<(String, String, Structure)> = Vec::new();
    let mut seen = HashSet::new();
    let mut taken: HashSet<String> = registry::benchmarks().into_iter().map(|(n, _)| n).collect();
    for (path, context) in &files {
        let robot = match Robot::load(path) {
            Ok(robot) => robot,
            Err(error) => fail(&format!("{error}\n({context})")),
        };
        println!("cargo:rerun-if-changed={}", path.display());
        let structure = robot.structure();
        if seen.insert(structure.clone()) {
            let label = path
                .strip_prefix(&root)
                .unwrap_or(path)
                .display()
                .to_string();
            if label.contains(['\n', '\r']) {
                fail(&format!(
                    "{label:?}: a robot file's path cannot hold a line break ({context})"
                ));
            }
            models.push((registry::model_name(path, &mut taken), label, structure));
        }
    }
    for (name, structure) in registry::benchmarks() {
        if seen.insert(structure.clone()) {
            models.push((
                name.clone(),
                format!("the benchmark structure {name}"),
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
        // The label is any path: written as string literals, and as code in the docs.
        let doc = if label.starts_with("the benchmark") {
            format!("Model of {label}.")
        } else {
            format!("Model generated from `{}`.", label.replace('`', "'"))
        };
        registry.push_str(&format!(
            "#[doc = {doc:?}]\n#[allow(clippy::all, clippy::pedantic, unused)]\npub mod {name} {{\n    include!(concat!(env!(\"OUT_DIR\"), \"/{name}.rs\"));\n    /// The generated source compiled above (unused constants cost nothing in a binary).\n    pub const SOURCE: &str = include_str!(concat!(env!(\"OUT_DIR\"), \"/{name}.rs\"));\n    /// This model behind the [`crate::GeneratedModel`] interface.\n    pub struct Model;\n    /// The key of the structure this model was generated for.\n    pub const STRUCTURE_KEY: &str = {key:?};\n    crate::impl_generated_model!(Model, \"{name}\", {label:?}, \"{routing}\");\n}}\n",
            key = structure.key()
        ));
        entries.push(format!("&{name}::Model"));
    }
    registry.push_str(&format!(
        "/// Every model this crate was built with.\npub static MODELS: &[&dyn GeneratedModel] = &[{}];\n",
        entries.join(", ")
    ));
    std::fs::write(out_dir.join("models.rs"), registry).expect("OUT_DIR is writable");
}
