//! The frames of a run's motion that its pictures in time share: the browser view
//! ([`crate::view`]) and the MCAP log's 3-D scene ([`crate::mcap_log`]) take the same times
//! ([`frame_times`], [`DEFAULT_FPS`] frames per second of robot time, at most
//! [`MAX_FRAMES`]) and round their points alike ([`coordinate`]), so that neither depends
//! on the other.

/// Frames per second of robot time, by default.
pub const DEFAULT_FPS: f64 = 30.0;
/// The most frames a page holds (about 10 kB each for two runs of the paper's robot); a
/// longer run gets fewer frames per second.
pub const MAX_FRAMES: usize = 1500;
/// Resolution of the embedded coordinates \[m\].
pub const COORDINATE_STEP: f64 = 1e-5;

/// The frame times over `span` \[s\] at `fps` frames per second of robot time: `t0 +
/// k/fps` up to the span's end, and the end itself last; for a span that would take more
/// than [`MAX_FRAMES`], [`MAX_FRAMES`] times evenly from start to end. Returns the times
/// and the rate they have.
pub fn frame_times(span: (f64, f64), fps: f64) -> (Vec<f64>, f64) {
    let (start, end) = span;
    let length = end - start;
    if !(length > 0.0 && length.is_finite() && fps > 0.0) {
        return (vec![start], fps);
    }
    if length * fps >= (MAX_FRAMES - 1) as f64 {
        let step = length / (MAX_FRAMES - 1) as f64;
        let mut times: Vec<f64> = (0..MAX_FRAMES).map(|k| start + k as f64 * step).collect();
        times[MAX_FRAMES - 1] = end;
        return (times, 1.0 / step);
    }
    let steps = (length * fps * (1.0 + 1e-12)).floor() as usize;
    let mut times: Vec<f64> = (0..=steps).map(|k| start + k as f64 / fps).collect();
    let last = times[times.len() - 1];
    if end - last > 1e-9 * end.abs().max(1.0) {
        times.push(end);
    } else {
        times[steps] = end;
    }
    (times, fps)
}

/// `30`, `12.5`, `0.333`: a rate without trailing zeros.
pub fn short(x: f64) -> String {
    let text = format!("{x:.3}");
    text.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// `x` to the nearest multiple of [`COORDINATE_STEP`] (`None` if not finite).
pub fn coordinate(x: f64) -> Option<f64> {
    let rounded = (x / COORDINATE_STEP).round() * COORDINATE_STEP;
    // Written through the decimal of the step, so the JSON holds the short form.
    rounded
        .is_finite()
        .then(|| format!("{rounded:.5}").parse().unwrap_or(rounded))
}
