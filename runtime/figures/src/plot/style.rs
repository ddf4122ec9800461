//! Line styles of the figures: a colour and a dash pattern per coordinate, per barrier of a
//! module and for the set points, chosen so that no two lines of a panel look alike.

/// Line colours, colour-blind-friendly (Okabe–Ito and Tol's "muted" scheme), in the order
/// they are handed out.
pub const PALETTE: [(u8, u8, u8); 10] = [
    (0, 114, 178),
    (230, 159, 0),
    (0, 158, 115),
    (204, 51, 17),
    (120, 94, 240),
    (86, 180, 233),
    (136, 34, 85),
    (90, 90, 90),
    (153, 153, 51),
    (51, 34, 136),
];

/// Line colours of the barriers, one per barrier of a module (corner 1, corner 2, …), in
/// the order they are handed out: none repeats a colour of [`PALETTE`] (each lies at least
/// ΔE 25 in CIELAB from every coordinate colour), so that a barrier is never read as the
/// coordinate of its colour.
pub const BARRIER_PALETTE: [(u8, u8, u8); 8] = [
    (238, 51, 119),
    (102, 170, 0),
    (23, 190, 207),
    (140, 86, 75),
    (200, 0, 200),
    (255, 127, 80),
    (128, 0, 0),
    (0, 102, 102),
];

/// Dash patterns `(on, off)` \[px\] that tell apart coordinates sharing a colour: solid,
/// long dashes, short dashes, very long dashes.
const COORDINATE_DASHES: [Option<(u32, u32)>; 4] =
    [None, Some((10, 5)), Some((3, 3)), Some((18, 4))];

/// Dash pattern of the set points: dots, unlike any coordinate's.
pub const SET_POINT_DASH: (u32, u32) = (2, 4);

/// How one line is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct LineStyle {
    /// RGB colour.
    pub colour: (u8, u8, u8),
    /// Dash pattern `(on, off)` in pixels, `None` for a solid line.
    pub dash: Option<(u32, u32)>,
}

/// Number of coordinates that get pairwise distinct styles from [`coordinate_style`].
pub const DISTINCT_COORDINATES: usize = PALETTE.len() * COORDINATE_DASHES.len();

/// Style of coordinate `k` (0-based): the palette's colours in turn, all solid for the
/// first ten, then again dashed, and so on; the first [`DISTINCT_COORDINATES`] (40) are
/// pairwise distinct.
pub fn coordinate_style(k: usize) -> LineStyle {
    LineStyle {
        colour: PALETTE[k % PALETTE.len()],
        dash: COORDINATE_DASHES[(k / PALETTE.len()) % COORDINATE_DASHES.len()],
    }
}

/// Dash pattern of module `module` (0-based) in the barrier panel: module 1 solid
/// (`None`), module 2 dashed 9/6, further modules with shorter dashes.
pub fn module_dash(module: usize) -> Option<(u32, u32)> {
    match module {
        0 => None,
        1 => Some((9, 6)),
        _ => Some(((12 / module as u32).max(1), 4)),
    }
}

/// Style of the barrier that is `index`-th (0-based) in module `module` (0-based): the
/// colour ([`BARRIER_PALETTE`]) says which barrier of the module (corner 1, corner 2, …),
/// the dash which module.
pub fn barrier_style(module: usize, index: usize) -> LineStyle {
    LineStyle {
        colour: BARRIER_PALETTE[index % BARRIER_PALETTE.len()],
        dash: module_dash(module),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// CIELAB `(L*, a*, b*)` of an sRGB colour (D65 white).
    fn lab((r, g, b): (u8, u8, u8)) -> [f64; 3] {
        let linear = |c: u8| {
            let c = f64::from(c) / 255.0;
            if c > 0.04045 {
                ((c + 0.055) / 1.055).powf(2.4)
            } else {
                c / 12.92
            }
        };
        let (r, g, b) = (linear(r), linear(g), linear(b));
        let x = (0.4124 * r + 0.3576 * g + 0.1805 * b) / 0.95047;
        let y = 0.2126 * r + 0.7152 * g + 0.0722 * b;
        let z = (0.0193 * r + 0.1192 * g + 0.9505 * b) / 1.08883;
        let f = |t: f64| {
            if t > 0.008856 {
                t.cbrt()
            } else {
                7.787 * t + 16.0 / 116.0
            }
        };
        let (fx, fy, fz) = (f(x), f(y), f(z));
        [116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)]
    }

    fn delta_e(a: (u8, u8, u8), b: (u8, u8, u8)) -> f64 {
        let (a, b) = (lab(a), lab(b));
        ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
    }

    /// A barrier's colour is never one of the coordinates': every barrier colour lies at
    /// least ΔE 25 from every coordinate colour, and the barrier colours at least ΔE 25 from
    /// each other.
    #[test]
    fn barrier_colours_repeat_no_coordinate_colour() {
        for (k, &barrier) in BARRIER_PALETTE.iter().enumerate() {
            for &coordinate in &PALETTE {
                let distance = delta_e(barrier, coordinate);
                assert!(
                    distance >= 25.0,
                    "{barrier:?} is ΔE {distance:.1} from {coordinate:?}"
                );
            }
            for &other in &BARRIER_PALETTE[k + 1..] {
                let distance = delta_e(barrier, other);
                assert!(
                    distance >= 25.0,
                    "{barrier:?} is ΔE {distance:.1} from {other:?}"
                );
            }
        }
        for module in 0..3 {
            for index in 0..12 {
                let style = barrier_style(module, index);
                assert!(!PALETTE.contains(&style.colour), "{style:?}");
            }
        }
    }
}
