//! Servo readings ↔ generalized coordinates, and generalized forces ↔ tendon tensions ↔
//! motor currents (docs/model.md §6), for robots with three local tendons per module.
//!
//! Per module `i` with tendon matrix `A_i` (columns `(cos ψ_k, sin ψ_k, −1)`):
//!
//! ```text
//! tendon length   ℓ_k = L0 + δL − (Δx cos ψ_k + Δy sin ψ_k) = L0 − (A_iᵀ q_i)_k
//! servo angle     ℓ_k = ℓ_k0 − ρ s_k (θ_k − θ_k0)
//! so              q_i = A_i⁻ᵀ (L0 − ℓ),   q̇_i = −A_i⁻ᵀ ℓ̇,   ℓ̇_k = −ρ s_k θ̇_k
//! forces          τ_i = A_i f_i,   f_i = A_i⁻¹ τ_i, each f_k held in [f_min, f_max]
//! current         I_k = s_k f_k / gain  [mA],  register = round(I_k / unit)
//! ```
//!
//! Every function writes into caller-provided slices and allocates nothing.

use nalgebra::{Matrix3, Vector3};
use softcbf_description::robot::Robot;
use softcbf_description::toml_file::FileError;

use crate::hardware_description::{self as description, Hardware, ModuleHardware};

/// Why a robot cannot be driven through servos.
#[derive(Debug, thiserror::Error)]
pub enum MappingError {
    /// The robot file has no `[hardware]` table.
    #[error(
        "{file}: no [hardware] table; the hardware path needs servo IDs and calibration (see robots/README.md)"
    )]
    NoHardware {
        /// The robot file.
        file: String,
    },
    /// A module's tendon matrix `A_i` has no inverse (tendon angles that coincide).
    #[error("{file}: the tendons of module {module} do not span its coordinates")]
    SingularTendons {
        /// The robot file.
        file: String,
        /// The module (from 0).
        module: usize,
    },
    /// The `[hardware]` table is not valid.
    #[error(transparent)]
    Invalid(#[from] FileError),
}

/// How many tensions were held at each limit (one tick, or summed).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Clamps {
    /// Tensions raised to `f_min` (the command needed less, possibly a push).
    pub low: u32,
    /// Tensions lowered to `f_max`.
    pub high: u32,
}

impl Clamps {
    /// Adds another count.
    pub fn add(&mut self, other: Clamps) {
        self.low += other.low;
        self.high += other.high;
    }
}

/// One module's constant matrices and calibration.
#[derive(Clone, Debug)]
struct ModuleMap {
    /// `A_i`: column `k` is tendon `k`'s `(cos ψ_k, sin ψ_k, −1)`.
    a: Matrix3<f64>,
    /// `A_i⁻¹`.
    a_inv: Matrix3<f64>,
    rest_length: f64,
    hardware: ModuleHardware,
}

/// How far \[N\] a tension may lie outside its limits and still count as on them (a
/// thousandth of a millinewton: far below a servo's current resolution, far above the
/// safety QP's rounding).
pub const CLAMP_TOLERANCE: f64 = 1e-6;

/// The mapping of a whole robot; servo `3i + k` is tendon `k` of module `i`.
#[derive(Clone, Debug)]
pub struct TendonMap {
    modules: Vec<ModuleMap>,
    hardware: Hardware,
}

/// The three entries of module `i` in a vector over all coordinates or servos.
fn part(v: &[f64], i: usize) -> Vector3<f64> {
    Vector3::from_column_slice(&v[3 * i..3 * i + 3])
}

impl TendonMap {
    /// The mapping of `robot` through the hardware of its `[hardware]` table
    /// ([`description::load`]).
    pub fn new(robot: &Robot) -> Result<TendonMap, MappingError> {
        match description::load(robot)? {
            Some(hardware) => TendonMap::with_hardware(robot, hardware),
            None => Err(MappingError::NoHardware {
                file: robot.source.display().to_string(),
            }),
        }
    }

    /// The mapping of `robot` through `hardware`, checked against it by
    /// [`description::load`] (three tendons per module with a full-rank `A_i`, local
    /// routing), perhaps with settings changed since (`softcbf run`'s options).
    pub fn with_hardware(robot: &Robot, hardware: Hardware) -> Result<TendonMap, MappingError> {
        let modules = robot
            .modules
            .iter()
            .zip(&hardware.modules)
            .enumerate()
            .map(|(i, (module, hw))| {
                let psi = &module.tendon_angles;
                let a = Matrix3::from_fn(|r, k| match r {
                    0 => psi[k].cos(),
                    1 => psi[k].sin(),
                    _ => -1.0,
                });
                let a_inv = a
                    .try_inverse()
                    .ok_or_else(|| MappingError::SingularTendons {
                        file: robot.source.display().to_string(),
                        module: i,
                    })?;
                Ok(ModuleMap {
                    a,
                    a_inv,
                    rest_length: module.rest_length,
                    hardware: hw.clone(),
                })
            })
            .collect::<Result<_, MappingError>>()?;
        Ok(TendonMap { modules, hardware })
    }

    /// The hardware description.
    pub fn hardware(&self) -> &Hardware {
        &self.hardware
    }

    /// Number of servos (three per module).
    pub fn n_servos(&self) -> usize {
        3 * self.modules.len()
    }

    /// Generalized coordinates from servo angles \[rad\] (both length `3·modules`).
    pub fn q_from_angles(&self, angles: &[f64], q: &mut [f64]) {
        for (i, m) in self.modules.iter().enumerate() {
            let hw = &m.hardware;
            // y_k = L0 − ℓ_k, then q_i = A⁻ᵀ y.
            let y = Vector3::from_fn(|k, _| {
                let length = hw.zero_lengths[k]
                    - hw.pulley_radius * hw.directions[k] * (angles[3 * i + k] - hw.zero_angles[k]);
                m.rest_length - length
            });
            q[3 * i..3 * i + 3].copy_from_slice(m.a_inv.tr_mul(&y).as_slice());
        }
    }

    /// Generalized velocities from servo angular velocities \[rad/s\].
    pub fn qd_from_rates(&self, rates: &[f64], qd: &mut [f64]) {
        for (i, m) in self.modules.iter().enumerate() {
            let hw = &m.hardware;
            // ℓ̇_k = −ρ s_k θ̇_k and q̇_i = −A⁻ᵀ ℓ̇ = A⁻ᵀ (ρ s θ̇).
            let y = Vector3::from_fn(|k, _| hw.pulley_radius * hw.directions[k] * rates[3 * i + k]);
            qd[3 * i..3 * i + 3].copy_from_slice(m.a_inv.tr_mul(&y).as_slice());
        }
    }

    /// Servo angles \[rad\] of the configuration `q` (the emulator's direction).
    pub fn angles_from_q(&self, q: &[f64], angles: &mut [f64]) {
        for (i, m) in self.modules.iter().enumerate() {
            let hw = &m.hardware;
            let aq = m.a.tr_mul(&part(q, i));
            for k in 0..3 {
                let length = m.rest_length - aq[k];
                angles[3 * i + k] = hw.zero_angles[k]
                    + (hw.zero_lengths[k] - length) / (hw.pulley_radius * hw.directions[k]);
            }
        }
    }

    /// Servo angular velocities \[rad/s\] of the velocity `q̇`.
    pub fn rates_from_qd(&self, qd: &[f64], rates: &mut [f64]) {
        for (i, m) in self.modules.iter().enumerate() {
            let hw = &m.hardware;
            let aqd = m.a.tr_mul(&part(qd, i));
            for k in 0..3 {
                rates[3 * i + k] = aqd[k] / (hw.pulley_radius * hw.directions[k]);
            }
        }
    }

    /// Tensions \[N\] realizing `τ` (`f_i = A_i⁻¹ τ_i`), each held in `[f_min, f_max]`;
    /// returns how many were held. A tension outside by less than [`CLAMP_TOLERANCE`] is
    /// rounding of a command the safety filter put on the limit: it is held without being
    /// counted. A non-finite entry of `τ` gives `f_min` throughout that module (counted as
    /// low clamps).
    pub fn tensions_from_tau(&self, tau: &[f64], tensions: &mut [f64]) -> Clamps {
        let mut clamps = Clamps::default();
        for (i, m) in self.modules.iter().enumerate() {
            let [f_min, f_max] = m.hardware.tension_limits;
            let f_free = m.a_inv * part(tau, i);
            for (k, &f) in f_free.iter().enumerate() {
                tensions[3 * i + k] = if f.is_nan() || f < f_min {
                    if f.is_nan() || f < f_min - CLAMP_TOLERANCE {
                        clamps.low += 1;
                    }
                    f_min
                } else if f > f_max {
                    if f > f_max + CLAMP_TOLERANCE {
                        clamps.high += 1;
                    }
                    f_max
                } else {
                    f
                };
            }
        }
        clamps
    }

    /// The tension limits as rows on `τ` for the safety filter: `(A_i⁻¹)_k τ_i ≥ f_min` and
    /// `−(A_i⁻¹)_k τ_i ≥ −f_max` for every tendon (row-major, `3 n_modules` columns), with
    /// their right-hand sides; see [`crate::control::ControllerSettings::input_limits`].
    pub fn tension_limit_rows(&self) -> (Vec<f64>, Vec<f64>) {
        let nq = 3 * self.modules.len();
        let (mut rows, mut rhs) = (Vec::new(), Vec::new());
        for (i, m) in self.modules.iter().enumerate() {
            let [f_min, f_max] = m.hardware.tension_limits;
            for k in 0..3 {
                for (sign, bound) in [(1.0, f_min), (-1.0, -f_max)] {
                    let mut row = vec![0.0; nq];
                    for r in 0..3 {
                        row[3 * i + r] = sign * m.a_inv[(k, r)];
                    }
                    rows.extend(row);
                    rhs.push(bound);
                }
            }
        }
        (rows, rhs)
    }

    /// Generalized forces `τ_i = A_i f_i` of tensions \[N\].
    pub fn tau_from_tensions(&self, tensions: &[f64], tau: &mut [f64]) {
        for (i, m) in self.modules.iter().enumerate() {
            tau[3 * i..3 * i + 3].copy_from_slice((m.a * part(tensions, i)).as_slice());
        }
    }

    /// The Goal Current register value commanding tension `f` \[N\] on servo `s`:
    /// `round(s_k f / (gain · unit))`, saturated to the register's range.
    pub fn current_from_tension(&self, servo: usize, f: f64) -> i16 {
        let hw = &self.modules[servo / 3].hardware;
        let units = hw.directions[servo % 3] * f
            / (hw.actuator_gain[servo % 3] * self.hardware.current_unit);
        units
            .round()
            .clamp(f64::from(i16::MIN), f64::from(i16::MAX)) as i16
    }

    /// The tension \[N\] a Goal Current register value pulls with on servo `s`
    /// (negative: the motor unwinds, a cable then goes slack).
    pub fn tension_from_current(&self, servo: usize, current: i16) -> f64 {
        let hw = &self.modules[servo / 3].hardware;
        hw.directions[servo % 3]
            * f64::from(current)
            * hw.actuator_gain[servo % 3]
            * self.hardware.current_unit
    }

    /// Servo angle \[rad\] of a Present Position register value.
    pub fn angle_from_position(&self, position: i32) -> f64 {
        (f64::from(position) * self.hardware.position_unit).to_radians()
    }

    /// Present Position register value of a servo angle \[rad\] (rounded).
    pub fn position_from_angle(&self, angle: f64) -> i32 {
        (angle.to_degrees() / self.hardware.position_unit)
            .round()
            .clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32
    }

    /// Angular velocity \[rad/s\] of a Present Velocity register value.
    pub fn rate_from_velocity(&self, velocity: i32) -> f64 {
        f64::from(velocity) * self.hardware.velocity_unit * std::f64::consts::TAU / 60.0
    }

    /// Present Velocity register value of an angular velocity \[rad/s\] (rounded).
    pub fn velocity_from_rate(&self, rate: f64) -> i32 {
        (rate * 60.0 / (std::f64::consts::TAU * self.hardware.velocity_unit))
            .round()
            .clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32
    }
}
