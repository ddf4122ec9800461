//! Data preparation for the figures: names of the coordinates, the part of a series in a
//! time window, when a run settles, the min/max envelope that thins long series, and axis
//! ranges with their tick precision.

/// How a coordinate named in a CSV column (see [`crate::record::coordinate_names`]) is
/// shown in a figure: `dx1 → Δx₁`, `dy2 → Δy₂`, `dL12 → δL₁₂`; any other name as it is.
pub fn display_name(name: &str) -> String {
    let symbols = [("dx", "Δx"), ("dy", "Δy"), ("dL", "δL")];
    for (ascii, symbol) in symbols {
        if let Some(digits) = name.strip_prefix(ascii)
            && !digits.is_empty()
            && digits.bytes().all(|c| c.is_ascii_digit())
        {
            let subscript: String = digits
                .chars()
                .map(|c| char::from_u32(0x2080 + c.to_digit(10).unwrap_or(0)).unwrap_or(c))
                .collect();
            return format!("{symbol}{subscript}");
        }
    }
    name.to_string()
}

/// The part of the series `(t_k, y_k)` inside `[start, end]`: the points within, and where
/// the series enters or leaves the window between two finite points, the point on the
/// straight line between them at the window's edge (so that lines run to the edge).
pub fn window(t: &[f64], y: &[f64], start: f64, end: f64) -> (Vec<f64>, Vec<f64>) {
    let (mut times, mut values) = (Vec::new(), Vec::new());
    let inside = |time: f64| (start..=end).contains(&time);
    let mut previous: Option<(f64, f64)> = None;
    for (&time, &value) in t.iter().zip(y) {
        if let Some((t0, y0)) = previous
            && time.is_finite()
            && t0.is_finite()
            && time > t0
        {
            for edge in [start, end] {
                // The segment crosses the edge with one end strictly outside.
                let crosses = (t0 < edge && edge < time) && (!inside(t0) || !inside(time));
                if crosses {
                    let s = (edge - t0) / (time - t0);
                    times.push(edge);
                    values.push(y0 + s * (value - y0));
                }
            }
        }
        if inside(time) {
            times.push(time);
            values.push(value);
        }
        previous = Some((time, value));
    }
    (times, values)
}

/// When a run's coordinates settle: the last time at which some coordinate is further
/// than `tolerance` from its last value (only finite values count); the first time if none
/// ever is. `series` holds each coordinate's values at the times `t`. `None` when there is
/// no finite value.
pub fn settle_time(t: &[f64], series: &[Vec<f64>], tolerance: f64) -> Option<f64> {
    let finite = |k: usize, y: &[f64]| {
        t.get(k).is_some_and(|x| x.is_finite()) && y.get(k).is_some_and(|v| v.is_finite())
    };
    let mut settled: Option<f64> = None;
    for y in series {
        let Some(end) = (0..y.len()).rev().find(|&k| finite(k, y)) else {
            continue;
        };
        let first = (0..y.len()).find(|&k| finite(k, y)).unwrap_or(end);
        let out = (0..y.len())
            .rev()
            .find(|&k| finite(k, y) && (y[k] - y[end]).abs() > tolerance);
        let time = t[out.unwrap_or(first)];
        settled = Some(settled.map_or(time, |s| s.max(time)));
    }
    settled
}

/// The largest excursion `max − min` of the finite values of any of `series` (0 if none).
pub fn excursion(series: &[Vec<f64>]) -> f64 {
    series
        .iter()
        .map(|y| {
            let mut range = Range::EMPTY;
            range.cover(y.iter().copied());
            if range.low <= range.high {
                range.high - range.low
            } else {
                0.0
            }
        })
        .fold(0.0, f64::max)
}

/// The smallest of `1, 1.5, 2, 2.5, 3, 4, 5, 6, 8` times a power of ten that is at least
/// `x` (`x` positive and finite; anything else is returned as it is).
pub fn nice_ceil(x: f64) -> f64 {
    if !(x.is_finite() && x > 0.0) {
        return x;
    }
    let power = 10f64.powf(x.log10().floor());
    let steps = [1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0];
    steps
        .iter()
        .map(|s| s * power)
        .find(|v| *v >= x * (1.0 - 1e-12))
        .unwrap_or(10.0 * power)
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

/// The parts of the line through `points` that lie within `low ≤ y ≤ high`: where it
/// leaves or enters the band between two points, the point on the straight line between
/// them at the band's edge ends or starts a part; a point that is not finite ends a part.
/// Nothing is drawn outside a panel this way, whatever the values (a run whose state left
/// the model's domain, or a zoomed panel).
pub fn clip(points: &[(f64, f64)], low: f64, high: f64) -> Vec<Vec<(f64, f64)>> {
    let inside = |y: f64| (low..=high).contains(&y);
    let mut parts = Vec::new();
    let mut current: Vec<(f64, f64)> = Vec::new();
    let mut previous: Option<(f64, f64)> = None;
    for &(t, y) in points {
        if !(t.is_finite() && y.is_finite()) {
            parts.push(std::mem::take(&mut current));
            previous = None;
            continue;
        }
        let Some((t0, y0)) = previous else {
            if inside(y) {
                current.push((t, y));
            }
            previous = Some((t, y));
            continue;
        };
        previous = Some((t, y));
        // The part of the segment inside the band, as fractions of its length.
        let (mut enter, mut leave) = (0.0, 1.0);
        if y != y0 {
            let at = |edge: f64| (edge - y0) / (y - y0);
            let (a, b) = (at(low), at(high));
            enter = f64::max(enter, a.min(b));
            leave = f64::min(leave, a.max(b));
        } else if !inside(y) {
            continue;
        }
        if enter > leave {
            parts.push(std::mem::take(&mut current));
            continue;
        }
        let point = |s: f64| {
            let y = y0 + s * (y - y0);
            (t0 + s * (t - t0), y.clamp(low, high))
        };
        if enter > 0.0 {
            parts.push(std::mem::take(&mut current));
            current.push(point(enter));
        }
        if leave < 1.0 {
            current.push(point(leave));
            parts.push(std::mem::take(&mut current));
        } else {
            current.push((t, y));
        }
    }
    parts.push(current);
    parts.retain(|part| !part.is_empty());
    parts
}

/// A value range `[low, high]` grown to cover `values` (non-finite ones ignored).
#[derive(Clone, Copy, Debug)]
pub(super) struct Range {
    pub(super) low: f64,
    pub(super) high: f64,
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

/// `x` with at most six significant digits and no trailing zeros: `1`, `0.5`, `2.25`.
pub(super) fn short_number(x: f64) -> String {
    let text = format!("{x:.6}");
    let text = text.trim_end_matches('0').trim_end_matches('.');
    if text == "-0" {
        "0".into()
    } else {
        text.into()
    }
}

/// Decimals that tell apart ticks about `span / labels` apart.
pub(super) fn tick_decimals(span: f64, labels: usize) -> usize {
    let step = span / labels.max(1) as f64;
    if !(step.is_finite() && step > 0.0) {
        return 2;
    }
    (-step.log10().floor()).clamp(0.0, 9.0) as usize
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clip_keeps_the_band_and_cuts_at_its_edges() {
        // Up through the band and out of it, back in, a NaN, then inside.
        let points = [
            (0.0, -2.0),
            (1.0, 0.0),
            (2.0, 2.0),
            (3.0, 3.0),
            (4.0, 0.5),
            (5.0, f64::NAN),
            (6.0, 0.25),
            (7.0, 0.75),
        ];
        let parts = clip(&points, -1.0, 1.0);
        assert_eq!(
            parts,
            vec![
                vec![(0.5, -1.0), (1.0, 0.0), (1.5, 1.0)],
                vec![(3.8, 1.0), (4.0, 0.5)],
                vec![(6.0, 0.25), (7.0, 0.75)],
            ]
        );
        // A segment that jumps across the whole band keeps its part inside it.
        assert_eq!(
            clip(&[(0.0, -3.0), (4.0, 5.0)], -1.0, 1.0),
            vec![vec![(1.0, -1.0), (2.0, 1.0)]]
        );
        // Nothing inside: nothing drawn; huge values are cut, not drawn off the panel.
        assert!(clip(&[(0.0, 2.0), (1.0, 3.0)], -1.0, 1.0).is_empty());
        let far = clip(&[(0.0, 0.0), (1.0, 1e300)], -1.0, 1.0);
        assert_eq!(far.len(), 1);
        assert!(far[0].iter().all(|&(_, y)| (-1.0..=1.0).contains(&y)));
    }
}
