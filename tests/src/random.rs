//! The one seeded random source of the tests, so every random test is reproducible: a
//! named, portable generator of the `rand` crate (its output is fixed for a seed).

/// Xoshiro256++: the same numbers for a seed on every platform and `rand` release, unlike
/// `SmallRng`/`StdRng`, whose algorithms may change.
pub type TestRng = rand::rngs::Xoshiro256PlusPlus;

/// The generator of a test, from its seed. Draw with `rand::RngExt`: `random::<f64>()` in
/// `[0, 1)`, `random_range(lo..hi)`.
pub fn rng(seed: u64) -> TestRng {
    rand::SeedableRng::seed_from_u64(seed)
}
