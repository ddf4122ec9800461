//! Seeded Gaussian draws: the one standard normal sampler that the simulator's sensor
//! noise, the emulator's noisy readings, identification's noise refits and the falsifier's
//! search all draw from; [`SensorNoise`], the one description of noise on readings; and
//! the ranges of a seed and of the sensor noise on the state (scenario files and
//! `softcbf verify` alike). Depends on nothing of the crate.

use rand::RngExt;
use rand::rngs::Xoshiro256PlusPlus;
use softcbf_description::limits::Limit;

/// A seed of draws: any non-negative TOML integer (a `verify` batch's, a sensor noise's).
pub const SEED: Limit = Limit::integer(0, i64::MAX);
/// Standard deviation of the sensor noise on `q` \[m\]: up to a centimetre.
pub const SENSOR_NOISE_M: Limit = Limit::closed(0.0, 0.01, "m");
/// Standard deviation of the sensor noise on `q̇` \[m/s\].
pub const SENSOR_NOISE_M_PER_S: Limit = Limit::closed(0.0, 1.0, "m/s");

/// Gaussian noise added to sampled readings of a position and a velocity: independent per
/// reading, drawn from one seeded stream (the same seed gives the same noise). The one
/// sensor noise of the crate: on the state the simulated controller samples
/// ([`crate::scenario::Scenario::sensor_noise`]: `position` on `q` \[m\], `velocity` on
/// `q̇` \[m/s\]) and on the emulated servos' readings
/// (`softcbf::hardware::emulator::EmulatorSettings`: Present Position and Present Velocity
/// \[register units\], added before they are rounded).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensorNoise {
    /// Standard deviation of a position reading.
    pub position: f64,
    /// Standard deviation of a velocity reading.
    pub velocity: f64,
    /// Seed of the noise draws.
    pub seed: u64,
}

impl SensorNoise {
    /// No noise.
    pub const NONE: SensorNoise = SensorNoise {
        position: 0.0,
        velocity: 0.0,
        seed: 1,
    };

    /// Whether any noise is added.
    pub fn is_on(&self) -> bool {
        self.position > 0.0 || self.velocity > 0.0
    }
}

impl Default for SensorNoise {
    fn default() -> Self {
        SensorNoise::NONE
    }
}

/// A draw of the standard normal distribution (Box–Muller, one of the pair): two uniform
/// draws of `draws` per call.
pub fn standard_normal(draws: &mut Xoshiro256PlusPlus) -> f64 {
    let [u, v]: [f64; 2] = draws.random();
    // 1 − u lies in (0, 1]: its logarithm is finite.
    (-2.0 * (1.0 - u).ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}
