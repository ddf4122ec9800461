//! A robot whose structure no build has: the runtime's error gives the one command that
//! registers its file (`softcbf-codegen add`, with the file's absolute path).

use std::path::Path;

use softcbf::model::Model;
use softcbf_description::robot::Robot;

/// Eleven corners on one plate, three on the next, tendons through: no shipped file, no
/// benchmark and (one hopes) no registered file has this structure.
const ODD: &str = "routing = \"through\"\n\
                   [[module]]\ncorner_angles_deg = [0, 30, 60, 90, 120, 150, 180, 210, 240, 270, 300]\n\
                   [[module]]\ncorner_angles_deg = [0, 120, 240]\n";

fn error_of(path: &Path) -> String {
    let robot = Robot::parse(ODD, path).expect("a valid robot");
    match Model::new(robot) {
        Ok(model) => panic!("{} has a model: {}", path.display(), model.generated.name()),
        Err(error) => error.to_string(),
    }
}

#[test]
fn no_generated_model_gives_the_command_that_registers_the_file() {
    let message = error_of(Path::new("/data/my robots/odd.toml"));
    assert!(
        message.starts_with(
            "/data/my robots/odd.toml: no generated model for 2 modules with corners [11, 3] \
             and tendons [3, 3] (through); register the robot file once, from the checkout:\n  \
             cargo run --release -p softcbf-codegen -- add '/data/my robots/odd.toml'\n"
        ),
        "{message}"
    );
    assert!(
        message.contains("this build has: paper_sim (corners [6, 6])"),
        "{message}"
    );
    // A relative path is given absolute, so the command works from anywhere in the checkout.
    let message = error_of(Path::new("odd.toml"));
    let absolute = std::env::current_dir().unwrap().join("odd.toml");
    assert!(
        message.contains(&format!("-- add {}\n", absolute.display())),
        "{message}"
    );
}
