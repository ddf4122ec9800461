//! The runtime parameter vector of a generated model: which number sits at which index.
//! Code generation reads symbols from this layout and the runtime packs a robot with it.

use crate::robot::{Robot, Structure};

/// One entry of the parameter vector (module `i`, corner `j`, 0-based).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Param {
    /// `L0` of module `i` \[m\].
    RestLength(usize),
    /// `d` of module `i` \[m\].
    TendonRadius(usize),
    /// `r` of module `i` \[m\].
    CornerRadius(usize),
    /// `cos φ_j` of corner `j` of module `i`.
    CornerCos(usize, usize),
    /// `sin φ_j` of corner `j` of module `i`.
    CornerSin(usize, usize),
    /// `ε_j` of corner `j` of module `i` \[m\].
    Margin(usize, usize),
}

impl Param {
    /// The symbol name used in generated code.
    pub fn name(self) -> String {
        match self {
            Param::RestLength(i) => format!("rest_length_{i}"),
            Param::TendonRadius(i) => format!("tendon_radius_{i}"),
            Param::CornerRadius(i) => format!("corner_radius_{i}"),
            Param::CornerCos(i, j) => format!("corner_cos_{i}_{j}"),
            Param::CornerSin(i, j) => format!("corner_sin_{i}_{j}"),
            Param::Margin(i, j) => format!("margin_{i}_{j}"),
        }
    }

    /// This parameter's value for a robot of the matching structure.
    pub fn value(self, robot: &Robot) -> f64 {
        match self {
            Param::RestLength(i) => robot.modules[i].rest_length,
            Param::TendonRadius(i) => robot.modules[i].tendon_radius,
            Param::CornerRadius(i) => robot.modules[i].corner_radius,
            Param::CornerCos(i, j) => robot.modules[i].corner_angles[j].cos(),
            Param::CornerSin(i, j) => robot.modules[i].corner_angles[j].sin(),
            Param::Margin(i, j) => robot.modules[i].margins[j],
        }
    }
}

/// The parameter layout of a structure: module-major, corner-minor.
pub fn param_layout(structure: &Structure) -> Vec<Param> {
    let mut layout = Vec::new();
    for (i, &corners) in structure.corners.iter().enumerate() {
        layout.extend([
            Param::RestLength(i),
            Param::TendonRadius(i),
            Param::CornerRadius(i),
        ]);
        for j in 0..corners {
            layout.extend([
                Param::CornerCos(i, j),
                Param::CornerSin(i, j),
                Param::Margin(i, j),
            ]);
        }
    }
    layout
}

/// The parameter vector of a robot, in the order of [`param_layout`].
pub fn pack_params(robot: &Robot) -> Vec<f64> {
    param_layout(&robot.structure())
        .into_iter()
        .map(|p| p.value(robot))
        .collect()
}
