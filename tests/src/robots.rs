//! The shipped robot files the integration tests load, found from the tests crate's folder.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use softcbf::model::Model;
use softcbf_description::robot::Robot;

/// Path of `robots/<name>` in the checkout.
pub fn path(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../robots")
        .join(name)
}

/// `robots/hardware-example.toml`: the paper's hardware layout, six servos with IDs 1–6.
pub fn hardware_example() -> Robot {
    Robot::load(&path("hardware-example.toml")).expect("the shipped example robot is valid")
}

/// The model of [`hardware_example`], built once per test binary.
pub fn hardware_example_model() -> &'static Model {
    static MODEL: OnceLock<Model> = OnceLock::new();
    MODEL.get_or_init(|| Model::new(hardware_example()).expect("the example robot has a model"))
}
