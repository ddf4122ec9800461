//! Seeded Gaussian draws: the one standard normal sampler that the simulator's sensor
//! noise, the emulator's noisy readings, identification's noise refits and the falsifier's
//! search all draw from. Depends on nothing of the crate.

use rand::RngExt;
use rand::rngs::Xoshiro256PlusPlus;

/// A draw of the standard normal distribution (Box–Muller, one of the pair): two uniform
/// draws of `draws` per call.
pub fn standard_normal(draws: &mut Xoshiro256PlusPlus) -> f64 {
    let [u, v]: [f64; 2] = draws.random();
    // 1 − u lies in (0, 1]: its logarithm is finite.
    (-2.0 * (1.0 - u).ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}
