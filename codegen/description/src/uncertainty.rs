//! How far a robot file says its numbers may be off (`[uncertainty]`): the declared bounds
//! the controller's robust margin covers (docs/model.md §5).

/// The declared uncertainty of a robot's numbers: relative bounds on stiffness, damping and
/// mass, and a bound on unmodelled generalized force. All zero (the default): the nominal
/// model is taken as exact.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Uncertainty {
    /// `κθ`, `κL` of every module may be off by this fraction (0.2: ±20 %).
    pub stiffness: f64,
    /// `βθ`, `βL` of every module may be off by this fraction.
    pub damping: f64,
    /// Every plate's mass (and with it its inertia) may be off by this fraction.
    pub mass: f64,
    /// Unmodelled generalized force on each coordinate is at most this \[N\].
    pub force: f64,
}

impl Uncertainty {
    /// Whether anything is declared.
    pub fn is_declared(&self) -> bool {
        *self != Uncertainty::default()
    }
}
