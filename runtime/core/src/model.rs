//! The runtime model: a validated robot description joined to its generated functions.
//! Immutable after construction; computations write into workspaces built from it.

use softcbf_description::layout::{pack_params, param_layout};
use softcbf_description::robot::{Robot, Routing};
use softcbf_generated::{GeneratedModel, KindGroup};

use nalgebra::{Matrix3, Vector3};

use crate::spatial::Inertia;

/// Why a robot cannot be simulated or controlled with this build.
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    /// No model was generated for this structure.
    #[error(
        "{source}: no generated model for {modules} modules with corners {corners:?} and tendons {tendons:?} \
         ({routing}); register the robot file once, from the checkout:\n  \
         cargo run --release -p softcbf-codegen -- add {register}\n\
         and every later build generates its model (an installed softcbf: then run \
         `cargo install --path runtime` again); this build has: {available}",
        source = source_file,
        register = shell_word(std::path::Path::new(.source_file))
    )]
    NoGeneratedModel {
        source_file: String,
        modules: usize,
        corners: Vec<usize>,
        tendons: Vec<usize>,
        routing: &'static str,
        available: String,
    },
    /// A generated model given for a robot of another structure.
    #[error(
        "{source_file}: the generated model {generated} is for the structure {expected}, \
         not this robot's {found}"
    )]
    StructureMismatch {
        source_file: String,
        generated: &'static str,
        expected: &'static str,
        found: String,
    },
}

/// `path`, absolute, as one shell word of a command printed to be copied.
fn shell_word(path: &std::path::Path) -> String {
    let absolute = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    softcbf_description::toml_file::shell_word(&absolute)
}

/// A robot ready for computation.
pub struct Model {
    /// The description it was built from.
    pub robot: Robot,
    /// Its generated functions.
    pub generated: &'static dyn GeneratedModel,
    /// The parameter vector the generated functions read.
    pub params: Vec<f64>,
    /// Spatial inertia of each module's plate about its tip-frame origin, tip coordinates.
    pub inertias: Vec<Inertia>,
    /// Diagonal of `K` (docs/model.md §4): `κθ/d², κθ/d², κL` per module.
    pub stiffness: Vec<f64>,
    /// Diagonal of `D`: `βθ/d², βθ/d², βL` per module.
    pub damping: Vec<f64>,
    /// The class-K gains `[p1, p2]` \[1/s\] a barrier's own table gives (a module's
    /// `[limits]`, an `[[obstacle]]`), in barrier order; `None` where the run's barrier
    /// gains apply (always for the plate corners).
    pub own_barrier_gains: Vec<[Option<f64>; 2]>,
}

fn routing_name(routing: Routing) -> &'static str {
    match routing {
        Routing::Local => "local",
        Routing::Through => "through",
    }
}

impl Model {
    /// Joins a robot to the generated model of its structure (`softcbf_generated::find`).
    pub fn new(robot: Robot) -> Result<Model, ModelError> {
        let structure = robot.structure();
        let Some(generated) = softcbf_generated::find(&structure) else {
            let available: Vec<String> = softcbf_generated::MODELS
                .iter()
                .map(|m| format!("{} (corners {:?})", m.name(), m.corners()))
                .collect();
            return Err(ModelError::NoGeneratedModel {
                source_file: robot.source.display().to_string(),
                modules: structure.modules(),
                routing: routing_name(structure.routing),
                corners: structure.corners,
                tendons: structure.tendons,
                available: available.join(", "),
            });
        };
        Model::with_generated(robot, generated)
    }

    /// Joins a robot to the given model functions of its structure: a compiled model, one
    /// interpreted at run time (`softcbf_interpreter::interpreted`),
    /// or the model of another robot of the same structure. Refused
    /// ([`ModelError::StructureMismatch`]) if `generated` is for another structure.
    pub fn with_generated(
        robot: Robot,
        generated: &'static dyn GeneratedModel,
    ) -> Result<Model, ModelError> {
        let structure = robot.structure();
        let key = structure.key();
        if generated.structure_key() != key {
            return Err(ModelError::StructureMismatch {
                source_file: robot.source.display().to_string(),
                generated: generated.name(),
                expected: generated.structure_key(),
                found: key,
            });
        }
        let layout = param_layout(&structure);
        assert!(
            layout
                .iter()
                .map(|p| p.name())
                .eq(generated.param_names().iter().map(|s| s.to_string())),
            "parameter layout of {} differs from the codegen library's: rebuild softcbf-generated",
            generated.name()
        );
        let params = pack_params(&robot);
        let mut inertias = Vec::new();
        let mut stiffness = Vec::new();
        let mut damping = Vec::new();
        for m in &robot.modules {
            let [ixx, iyy, izz] = m.inertia;
            inertias.push(Inertia::rigid_body(
                m.mass,
                &Vector3::new(0.0, 0.0, m.com_offset),
                &Matrix3::from_diagonal(&Vector3::new(ixx, iyy, izz)),
            ));
            let d2 = m.tendon_radius * m.tendon_radius;
            stiffness.extend([
                m.bending_stiffness / d2,
                m.bending_stiffness / d2,
                m.axial_stiffness,
            ]);
            damping.extend([
                m.bending_damping / d2,
                m.bending_damping / d2,
                m.axial_damping,
            ]);
        }
        let own_barrier_gains = generated
            .barrier_table()
            .iter()
            .map(|info| match (info.kind.group(), info.obstacle) {
                (KindGroup::Elongation | KindGroup::Bend, _) => robot
                    .limits
                    .get(info.module)
                    .map_or([None, None], |l| l.gains_of(info.kind)),
                (KindGroup::Obstacle, Some(o)) => {
                    robot.obstacles.get(o).map_or([None, None], |ob| ob.gains)
                }
                _ => [None, None],
            })
            .collect();
        Ok(Model {
            robot,
            generated,
            params,
            inertias,
            stiffness,
            damping,
            own_barrier_gains,
        })
    }

    /// Number of modules.
    pub fn n_modules(&self) -> usize {
        self.robot.modules.len()
    }

    /// Number of generalized coordinates.
    pub fn nq(&self) -> usize {
        3 * self.n_modules()
    }

    /// Number of barriers.
    pub fn nb(&self) -> usize {
        self.generated.nb()
    }
}
