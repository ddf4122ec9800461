//! Servo readings ↔ generalized coordinates, and generalized forces ↔ tendon tensions ↔
//! motor currents (MODEL.md §6), for robots with three local tendons per module.
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

use softcbf_description::robot::Robot;
use softcbf_description::toml_file::FileError;

use crate::hardware::description::{self, Hardware, ModuleHardware};

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
    /// `A_i`, row-major: `a[r][k]` is row `r` of tendon column `k`.
    a: [[f64; 3]; 3],
    /// `A_i⁻¹`, row-major.
    a_inv: [[f64; 3]; 3],
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

fn invert3(m: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    let mut inv = [[0.0; 3]; 3];
    for (r, row) in inv.iter_mut().enumerate() {
        for (c, entry) in row.iter_mut().enumerate() {
            // Cofactor of m[c][r] (transpose), by cyclic indices.
            let (r1, r2) = ((c + 1) % 3, (c + 2) % 3);
            let (c1, c2) = ((r + 1) % 3, (r + 2) % 3);
            *entry = (m[r1][c1] * m[r2][c2] - m[r1][c2] * m[r2][c1]) / det;
        }
    }
    inv
}

impl TendonMap {
    /// The mapping of `robot` through the hardware of its `[hardware]` table
    /// ([`description::load`]).
    pub fn new(robot: &Robot) -> Result<TendonMap, MappingError> {
        match description::load(robot)? {
            Some(hardware) => Ok(TendonMap::with_hardware(robot, hardware)),
            None => Err(MappingError::NoHardware {
                file: robot.source.display().to_string(),
            }),
        }
    }

    /// The mapping of `robot` through `hardware`, checked against it by
    /// [`description::load`] (three tendons per module with a full-rank `A_i`, local
    /// routing), perhaps with settings changed since (`softcbf run`'s options).
    pub fn with_hardware(robot: &Robot, hardware: Hardware) -> TendonMap {
        let modules = robot
            .modules
            .iter()
            .zip(&hardware.modules)
            .map(|(module, hw)| {
                let mut a = [[0.0; 3]; 3];
                for (k, psi) in module.tendon_angles.iter().enumerate() {
                    a[0][k] = psi.cos();
                    a[1][k] = psi.sin();
                    a[2][k] = -1.0;
                }
                ModuleMap {
                    a,
                    a_inv: invert3(&a),
                    rest_length: module.rest_length,
                    hardware: hw.clone(),
                }
            })
            .collect();
        TendonMap { modules, hardware }
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
            let y: [f64; 3] = std::array::from_fn(|k| {
                let length = hw.zero_lengths[k]
                    - hw.pulley_radius * hw.directions[k] * (angles[3 * i + k] - hw.zero_angles[k]);
                m.rest_length - length
            });
            for r in 0..3 {
                q[3 * i + r] = (0..3).map(|k| m.a_inv[k][r] * y[k]).sum();
            }
        }
    }

    /// Generalized velocities from servo angular velocities \[rad/s\].
    pub fn qd_from_rates(&self, rates: &[f64], qd: &mut [f64]) {
        for (i, m) in self.modules.iter().enumerate() {
            let hw = &m.hardware;
            // ℓ̇_k = −ρ s_k θ̇_k and q̇_i = −A⁻ᵀ ℓ̇ = A⁻ᵀ (ρ s θ̇).
            let y: [f64; 3] =
                std::array::from_fn(|k| hw.pulley_radius * hw.directions[k] * rates[3 * i + k]);
            for r in 0..3 {
                qd[3 * i + r] = (0..3).map(|k| m.a_inv[k][r] * y[k]).sum();
            }
        }
    }

    /// Servo angles \[rad\] of the configuration `q` (the emulator's direction).
    pub fn angles_from_q(&self, q: &[f64], angles: &mut [f64]) {
        for (i, m) in self.modules.iter().enumerate() {
            let hw = &m.hardware;
            for k in 0..3 {
                let aq: f64 = (0..3).map(|r| m.a[r][k] * q[3 * i + r]).sum();
                let length = m.rest_length - aq;
                angles[3 * i + k] = hw.zero_angles[k]
                    + (hw.zero_lengths[k] - length) / (hw.pulley_radius * hw.directions[k]);
            }
        }
    }

    /// Servo angular velocities \[rad/s\] of the velocity `q̇`.
    pub fn rates_from_qd(&self, qd: &[f64], rates: &mut [f64]) {
        for (i, m) in self.modules.iter().enumerate() {
            let hw = &m.hardware;
            for k in 0..3 {
                let aqd: f64 = (0..3).map(|r| m.a[r][k] * qd[3 * i + r]).sum();
                rates[3 * i + k] = aqd / (hw.pulley_radius * hw.directions[k]);
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
            for k in 0..3 {
                let f: f64 = (0..3).map(|r| m.a_inv[k][r] * tau[3 * i + r]).sum();
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
                        row[3 * i + r] = sign * m.a_inv[k][r];
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
            for r in 0..3 {
                tau[3 * i + r] = (0..3).map(|k| m.a[r][k] * tensions[3 * i + k]).sum();
            }
        }
    }

    /// The Goal Current register value commanding tension `f` \[N\] on servo `s`:
    /// `round(s_k f / (gain · unit))`, saturated to the register's range.
    pub fn current_from_tension(&self, servo: usize, f: f64) -> i16 {
        let hw = &self.modules[servo / 3].hardware;
        let units = hw.directions[servo % 3] * f / (hw.actuator_gain * self.hardware.current_unit);
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
            * hw.actuator_gain
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
