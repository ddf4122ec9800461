//! The cross-entropy method (CEM) over the unit box `[0, 1]^d`: a Gaussian with a diagonal
//! covariance, refitted each generation to the best candidates seen so far.
//!
//! A generation is drawn from the current Gaussian (each coordinate clamped into
//! `[0, 1]`, so a worst case on a face or corner of the box is reached, not only
//! approached), except its first, which is uniform in the box (a plain random batch:
//! the search starts where `softcbf verify` would), and a share [`Settings::explore`] of
//! every later one, also uniform (a search settled on one basin still looks elsewhere).
//! After each generation the elite — the [`Settings::elite`] lowest scores among the new
//! candidates and the previous elite — gives the new mean and standard deviation, blended
//! with the old by [`Settings::smoothing`] and [`Settings::sd_smoothing`], the deviation
//! kept above
//! [`Settings::min_sd`] so that the search never freezes. Scores are compared with
//! `total_cmp` after mapping NaN to `-∞`, ties going to the earlier candidate, so the
//! whole search is a function of its generator's seed.

use rand::RngExt;
use rand::rngs::Xoshiro256PlusPlus;

use crate::noise::standard_normal;

/// How the method is tuned.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Settings {
    /// Candidates per generation.
    pub population: usize,
    /// Candidates kept to refit the Gaussian.
    pub elite: usize,
    /// Weight of the new mean against the old one (1: the old one is forgotten).
    pub smoothing: f64,
    /// The same for the standard deviation (slower: a deviation fitted to a few elite
    /// candidates shrinks fast, and a search that shrinks too early stops moving).
    pub sd_smoothing: f64,
    /// Least standard deviation per coordinate (a fraction of the box's width).
    pub min_sd: f64,
    /// Share of each generation after the first drawn uniformly in the box.
    pub explore: f64,
}

impl Settings {
    /// Defaults for a search of `dimension` variables: four more candidates per
    /// generation than variables, at least 12 and at most 20 (small generations move
    /// further on a budget of a few hundred runs), a third of them elite.
    pub fn for_dimension(dimension: usize) -> Settings {
        Settings::with_population((dimension + 4).clamp(12, 20))
    }

    /// Defaults with `population` candidates per generation (at least 2): the mean follows
    /// the elite closely (0.9), the deviation more slowly (0.4), never below 3 % of the
    /// box, one candidate in ten uniform.
    pub fn with_population(population: usize) -> Settings {
        let population = population.max(2);
        Settings {
            population,
            elite: (population / 3).max(2).min(population),
            smoothing: 0.9,
            sd_smoothing: 0.4,
            min_sd: 0.03,
            explore: 0.1,
        }
    }
}

/// A candidate: its point in the unit box and its score (lower is worse for the filter,
/// which the search wants), with its place in the order candidates were drawn.
#[derive(Clone, Debug, PartialEq)]
pub struct Scored {
    /// The point, one coordinate per variable, each in `[0, 1]`.
    pub x: Vec<f64>,
    /// The score (NaN counts as `-∞`).
    pub score: f64,
    /// Its index in the order of drawing (ties go to the lower).
    pub order: usize,
}

/// `score` with NaN as `-∞`, for sorting.
fn key(score: f64) -> f64 {
    if score.is_nan() {
        f64::NEG_INFINITY
    } else {
        score
    }
}

/// The state of one search: the Gaussian and the elite.
#[derive(Clone, Debug)]
pub struct Cem {
    settings: Settings,
    mean: Vec<f64>,
    sd: Vec<f64>,
    elite: Vec<Scored>,
    generation: usize,
}

impl Cem {
    /// A search over `dimension` variables; its first generation is uniform.
    pub fn new(dimension: usize, settings: Settings) -> Cem {
        Cem {
            settings,
            mean: vec![0.5; dimension],
            // A uniform distribution on [0, 1] has this deviation.
            sd: vec![(1.0f64 / 12.0).sqrt(); dimension],
            elite: Vec::new(),
            generation: 0,
        }
    }

    /// The generation the next candidates belong to (0: the uniform one).
    pub fn generation(&self) -> usize {
        self.generation
    }

    /// The method's settings.
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// Candidate `k` of the current generation, drawn from `draws`.
    pub fn sample(&self, draws: &mut Xoshiro256PlusPlus, k: usize) -> Vec<f64> {
        let explorers = (self.settings.explore * self.settings.population as f64).ceil() as usize;
        let uniform = self.generation == 0 || k < explorers;
        self.mean
            .iter()
            .zip(&self.sd)
            .map(|(&m, &s)| {
                if uniform {
                    draws.random::<f64>()
                } else {
                    (m + s * standard_normal(draws)).clamp(0.0, 1.0)
                }
            })
            .collect()
    }

    /// Takes the scores of a generation's candidates and refits the Gaussian.
    pub fn tell(&mut self, scored: Vec<Scored>) {
        let mut pool = std::mem::take(&mut self.elite);
        pool.extend(scored);
        pool.sort_by(|a, b| {
            key(a.score)
                .total_cmp(&key(b.score))
                .then(a.order.cmp(&b.order))
        });
        pool.truncate(self.settings.elite.max(1));
        let n = pool.len() as f64;
        let (alpha, beta) = (self.settings.smoothing, self.settings.sd_smoothing);
        for j in 0..self.mean.len() {
            let mean = pool.iter().map(|c| c.x[j]).sum::<f64>() / n;
            let var = pool.iter().map(|c| (c.x[j] - mean).powi(2)).sum::<f64>() / n;
            self.mean[j] = alpha * mean + (1.0 - alpha) * self.mean[j];
            let sd = beta * var.sqrt() + (1.0 - beta) * self.sd[j];
            self.sd[j] = sd.max(self.settings.min_sd);
        }
        self.elite = pool;
        self.generation += 1;
    }

    /// The mean and standard deviation of the current Gaussian.
    pub fn distribution(&self) -> (&[f64], &[f64]) {
        (&self.mean, &self.sd)
    }
}

#[cfg(test)]
mod tests {
    use rand::SeedableRng;

    use super::*;

    /// The method finds the corner of a box that a uniform sample of the same size misses:
    /// `f(x) = Σ (1 − x_j)` on `[0, 1]^8`, lowest at the corner of ones.
    #[test]
    fn finds_a_corner_uniform_draws_miss() {
        let d = 8;
        let f = |x: &[f64]| x.iter().map(|v| 1.0 - v).sum::<f64>();
        let settings = Settings::for_dimension(d);
        let budget = 200;
        let mut draws = Xoshiro256PlusPlus::seed_from_u64(7);
        let mut cem = Cem::new(d, settings);
        let mut best = f64::INFINITY;
        let mut spent = 0;
        while spent < budget {
            let n = settings.population.min(budget - spent);
            let scored: Vec<Scored> = (0..n)
                .map(|k| {
                    let x = cem.sample(&mut draws, k);
                    let score = f(&x);
                    best = best.min(score);
                    Scored {
                        x,
                        score,
                        order: spent + k,
                    }
                })
                .collect();
            spent += n;
            cem.tell(scored);
        }
        let mut draws = Xoshiro256PlusPlus::seed_from_u64(7);
        let uniform = (0..budget)
            .map(|_| {
                let x: Vec<f64> = (0..d).map(|_| draws.random::<f64>()).collect();
                f(&x)
            })
            .fold(f64::INFINITY, f64::min);
        assert!(best < 0.6, "CEM reached {best}");
        assert!(uniform > 1.0, "uniform reached {uniform}");
    }

    #[test]
    fn nan_scores_count_as_lowest_and_ties_keep_the_first() {
        let mut cem = Cem::new(1, Settings::with_population(6));
        let scored = vec![
            Scored {
                x: vec![0.1],
                score: 1.0,
                order: 0,
            },
            Scored {
                x: vec![0.2],
                score: f64::NAN,
                order: 1,
            },
            Scored {
                x: vec![0.3],
                score: f64::NEG_INFINITY,
                order: 2,
            },
            Scored {
                x: vec![0.4],
                score: 0.5,
                order: 3,
            },
        ];
        cem.tell(scored);
        let kept: Vec<usize> = cem.elite.iter().map(|c| c.order).collect();
        assert_eq!(kept, vec![1, 2]);
        assert_eq!(cem.generation(), 1);
    }
}
