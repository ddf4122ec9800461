//! Seeded Gaussian draws: the one standard normal sampler that the simulator's sensor
//! noise, the emulator's noisy readings, identification's noise refits and the falsifier's
//! search all draw from, and the ranges of a seed and of the sensor noise on the state
//! (scenario files and `softcbf verify` alike). Depends on nothing of the crate.

use rand::RngExt;
use rand::rngs::Xoshiro256PlusPlus;
use softcbf_description::limits::Limit;

/// A seed of draws: any non-negative TOML integer (a `verify` batch's, a sensor noise's).
pub const SEED: Limit = Limit::integer(0, i64::MAX);
/// Standard deviation of the sensor noise on `q` \[m\]: up to a centimetre.
pub const SENSOR_NOISE_M: Limit = Limit::closed(0.0, 0.01, "m");
/// Standard deviation of the sensor noise on `q̇` \[m/s\].
pub const SENSOR_NOISE_M_PER_S: Limit = Limit::closed(0.0, 1.0, "m/s");

/// A draw of the standard normal distribution (Box–Muller, one of the pair): two uniform
/// draws of `draws` per call.
pub fn standard_normal(draws: &mut Xoshiro256PlusPlus) -> f64 {
    let [u, v]: [f64; 2] = draws.random();
    // 1 − u lies in (0, 1]: its logarithm is finite.
    (-2.0 * (1.0 - u).ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}
