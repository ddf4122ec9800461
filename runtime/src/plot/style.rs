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
/// colour says which barrier of the module (corner 1, corner 2, …), the dash which module.
pub fn barrier_style(module: usize, index: usize) -> LineStyle {
    LineStyle {
        colour: PALETTE[index % PALETTE.len()],
        dash: module_dash(module),
    }
}
