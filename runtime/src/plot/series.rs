//! Data preparation for the figures: legend names of the coordinates, the min/max envelope
//! that thins long series, and axis ranges with their tick precision.

/// Legend names of the coordinates: `Δx₁, Δy₁, δL₁, Δx₂, …` when `n` is a multiple of 3
/// (docs/model.md §1), else `q0, q1, …`.
pub fn coordinate_labels(n: usize) -> Vec<String> {
    if n == 0 || !n.is_multiple_of(3) {
        return (0..n).map(|k| format!("q{k}")).collect();
    }
    let subscript = |module: usize| -> String {
        module
            .to_string()
            .chars()
            .map(|c| char::from_u32(0x2080 + c.to_digit(10).unwrap_or(0)).unwrap_or(c))
            .collect()
    };
    (0..n)
        .map(|k| format!("{}{}", ["Δx", "Δy", "δL"][k % 3], subscript(k / 3 + 1)))
        .collect()
}

/// A point of a series with its index: `(k, t_k, y_k)`.
type Indexed = (usize, f64, f64);

/// The lowest and highest point seen so far in one interval of [`envelope`].
struct Extremes {
    bucket: usize,
    low: Indexed,
    high: Indexed,
}

impl Extremes {
    /// Appends the two points (one if they are the same) to `out` in time order.
    fn emit(self, out: &mut Vec<(f64, f64)>) {
        let (first, second) = if self.low.0 <= self.high.0 {
            (self.low, self.high)
        } else {
            (self.high, self.low)
        };
        out.push((first.1, first.2));
        if second.0 != first.0 {
            out.push((second.1, second.2));
        }
    }
}

/// Reduces the series `(t_k, y_k)` (time non-decreasing) for drawing: `[t_start, t_end]`
/// is cut into `buckets` equal intervals and each keeps only its lowest and highest point,
/// in time order. Non-finite points end a segment; each segment is returned separately.
/// Every point that is the lowest or highest of its interval survives, so the series'
/// overall minimum and maximum are always kept; at most `2·buckets` points remain.
pub fn envelope(
    t: &[f64],
    y: &[f64],
    t_start: f64,
    t_end: f64,
    buckets: usize,
) -> Vec<Vec<(f64, f64)>> {
    let buckets = buckets.max(1);
    let span = t_end - t_start;
    let bucket_of = |time: f64| -> usize {
        if span > 0.0 {
            let position = ((time - t_start) / span * buckets as f64).floor().max(0.0);
            (position as usize).min(buckets - 1)
        } else {
            0
        }
    };
    let mut segments = Vec::new();
    let mut current: Vec<(f64, f64)> = Vec::new();
    let mut open: Option<Extremes> = None;
    for (k, (&time, &value)) in t.iter().zip(y).enumerate() {
        if !(time.is_finite() && value.is_finite()) {
            if let Some(extremes) = open.take() {
                extremes.emit(&mut current);
            }
            if !current.is_empty() {
                segments.push(std::mem::take(&mut current));
            }
            continue;
        }
        let bucket = bucket_of(time);
        let point = (k, time, value);
        match &mut open {
            Some(extremes) if extremes.bucket == bucket => {
                if value < extremes.low.2 {
                    extremes.low = point;
                }
                if value > extremes.high.2 {
                    extremes.high = point;
                }
            }
            _ => {
                if let Some(extremes) = open.take() {
                    extremes.emit(&mut current);
                }
                open = Some(Extremes {
                    bucket,
                    low: point,
                    high: point,
                });
            }
        }
    }
    if let Some(extremes) = open {
        extremes.emit(&mut current);
    }
    if !current.is_empty() {
        segments.push(current);
    }
    segments
}

/// A value range `[low, high]` grown to cover `values` (non-finite ones ignored).
#[derive(Clone, Copy, Debug)]
pub(super) struct Range {
    low: f64,
    high: f64,
}

impl Range {
    pub(super) const EMPTY: Range = Range {
        low: f64::INFINITY,
        high: f64::NEG_INFINITY,
    };

    pub(super) fn cover(&mut self, values: impl IntoIterator<Item = f64>) {
        for v in values.into_iter().filter(|v| v.is_finite()) {
            self.low = self.low.min(v);
            self.high = self.high.max(v);
        }
    }

    /// `[low, high]` if it has a positive length, else [`Range::padded`].
    pub(super) fn exact_or_padded(self) -> std::ops::Range<f64> {
        if self.low < self.high {
            self.low..self.high
        } else {
            self.padded()
        }
    }

    /// The range with 5 % padding on each side (±1 around a single value, [0, 1] if empty).
    pub(super) fn padded(self) -> std::ops::Range<f64> {
        if self.low > self.high {
            return 0.0..1.0;
        }
        let span = self.high - self.low;
        let pad = if span > 0.0 {
            0.05 * span
        } else {
            self.high.abs().max(1.0) * 0.05
        };
        self.low - pad..self.high + pad
    }
}

/// Decimals that tell apart ticks about `span / 5` apart.
pub(super) fn tick_decimals(span: f64) -> usize {
    let step = span / 5.0;
    if !(step.is_finite() && step > 0.0) {
        return 2;
    }
    (-step.log10().floor()).clamp(0.0, 9.0) as usize
}
