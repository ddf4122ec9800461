//! The `[limits]`, `[module.limits]` and `[[obstacle]]` tables of a robot file, read and
//! checked into [`Limits`] per module and [`Obstacle`]s (format: `robots/README.md`).
//! Every module gets its limits: a value no table writes is the domain's default
//! ([`Limits::domain`]).
//!
//! Every value is checked against its range in `crate::limits` where it is written; what
//! depends on a module (an elongation limit must lie within the domain's defaults for its
//! rest length, a watched corner must exist) is checked for each module the value applies
//! to, with the error on the line that wrote it.

use std::ops::Range;

use serde::Deserialize;
use toml::Spanned;

use crate::barriers::{LimitFlags, Limits, Obstacle, Shape, Watched, WatchedPoint};
use crate::limits;
use crate::module::Module;
use crate::toml_file::{Checker, FileError};

/// `[limits]` or `[module.limits]` as serde reads it.
#[derive(Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct LimitsTable {
    elongation: Option<Spanned<Vec<Spanned<f64>>>>,
    elongation_margin: Option<Spanned<f64>>,
    max_bend_deg: Option<Spanned<f64>>,
    bend_margin_deg: Option<Spanned<f64>>,
    p1: Option<Spanned<f64>>,
    p2: Option<Spanned<f64>>,
    elongation_rate: Option<Spanned<f64>>,
}

/// One `[[obstacle]]` table as serde reads it.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct ObstacleTable {
    kind: Spanned<String>,
    center: Option<Spanned<Vec<Spanned<f64>>>>,
    radius: Option<Spanned<f64>>,
    normal: Option<Spanned<Vec<Spanned<f64>>>>,
    offset: Option<Spanned<f64>>,
    margin: Option<Spanned<f64>>,
    p1: Option<Spanned<f64>>,
    p2: Option<Spanned<f64>>,
    watch: Option<Spanned<Vec<Spanned<WatchTable>>>>,
}

/// One entry of an obstacle's `watch` list.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct WatchTable {
    module: Spanned<i64>,
    points: Option<Vec<Spanned<String>>>,
    plate_points: Option<Vec<Spanned<Vec<Spanned<f64>>>>>,
    arc: Option<Vec<Spanned<f64>>>,
}

/// A value checked where it was written: the value, its span and its field path.
struct At<T> {
    value: T,
    span: Range<usize>,
    field: String,
}

/// The fields of one limits table, each checked on its own.
#[derive(Default)]
struct WrittenLimits {
    elongation: Option<At<[f64; 2]>>,
    elongation_margin: Option<At<f64>>,
    max_bend: Option<At<f64>>,
    bend_margin: Option<At<f64>>,
    gains: [Option<f64>; 2],
    elongation_rate: Option<At<f64>>,
}

impl Checker<'_> {
    /// Checks the values of one limits table; `prefix` is its field path (`limits`,
    /// `module[2].limits`).
    fn written_limits(
        &self,
        table: &LimitsTable,
        prefix: &str,
    ) -> Result<WrittenLimits, FileError> {
        let mut written = WrittenLimits::default();
        if let Some(e) = &table.elongation {
            let field = format!("{prefix}.elongation");
            let values = self.list_within(e.get_ref(), &field, &limits::ELONGATION_LIMIT_M)?;
            let [min, max] = <[f64; 2]>::try_from(values).map_err(|v| {
                self.invalid(
                    &e.span(),
                    &field,
                    format!("needs 2 entries [δL_min, δL_max] in m, got {}", v.len()),
                )
            })?;
            if min >= max {
                return Err(self.invalid(
                    &e.span(),
                    &field,
                    format!("δL_min = {min} m must be below δL_max = {max} m"),
                ));
            }
            written.elongation = Some(At {
                value: [min, max],
                span: e.span(),
                field,
            });
        }
        let number = |v: &Option<Spanned<f64>>, name: &str, limit: &limits::Limit, scale: f64| {
            v.as_ref()
                .map(|v| {
                    let field = format!("{prefix}.{name}");
                    Ok(At {
                        value: self.within(v, &field, limit)? * scale,
                        span: v.span(),
                        field,
                    })
                })
                .transpose()
        };
        let radians = std::f64::consts::PI / 180.0;
        written.elongation_margin = number(
            &table.elongation_margin,
            "elongation_margin",
            &limits::MARGIN_M,
            1.0,
        )?;
        written.max_bend = number(
            &table.max_bend_deg,
            "max_bend_deg",
            &limits::MAX_BEND_DEG,
            radians,
        )?;
        written.bend_margin = number(
            &table.bend_margin_deg,
            "bend_margin_deg",
            &limits::BEND_MARGIN_DEG,
            radians,
        )?;
        written.elongation_rate = number(
            &table.elongation_rate,
            "elongation_rate",
            &limits::ELONGATION_RATE_M_S,
            1.0,
        )?;
        for (slot, value, name) in [(0, &table.p1, "p1"), (1, &table.p2, "p2")] {
            if let Some(v) = value {
                let field = format!("{prefix}.{name}");
                written.gains[slot] = Some(self.within(v, &field, &limits::BARRIER_GAIN_PER_S)?);
            }
        }
        Ok(written)
    }

    /// The limits of every module: each module's `[module.limits]` field over the file's
    /// `[limits]` field, checked against the module (`tables[i]` is module `i`'s table).
    pub(crate) fn limits(
        &self,
        top: Option<&LimitsTable>,
        tables: &[Option<&Spanned<LimitsTable>>],
        modules: &[Module],
    ) -> Result<Vec<Limits>, FileError> {
        let top = match top {
            Some(table) => self.written_limits(table, "limits")?,
            None => WrittenLimits::default(),
        };
        let mut out = Vec::with_capacity(modules.len());
        for (i, (module, table)) in modules.iter().zip(tables).enumerate() {
            let own = match table {
                Some(table) => {
                    self.written_limits(table.get_ref(), &format!("module[{}].limits", i + 1))?
                }
                None => WrittenLimits::default(),
            };
            let elongation = own.elongation.as_ref().or(top.elongation.as_ref());
            let elongation_margin = own
                .elongation_margin
                .as_ref()
                .or(top.elongation_margin.as_ref());
            let max_bend = own.max_bend.as_ref().or(top.max_bend.as_ref());
            let bend_margin = own.bend_margin.as_ref().or(top.bend_margin.as_ref());
            let margin = elongation_margin.map_or(0.0, |m| m.value);
            let l0 = module.rest_length;
            let domain = Limits::domain(l0);
            let [lowest, highest] = domain.elongation;
            let allowed = || {
                format!(
                    "the model's domain allows {} ≤ δL_min < δL_max ≤ {} m for L0 = {l0} m \
                     (docs/model.md §3)",
                    crate::limits::rounded(lowest),
                    crate::limits::rounded(highest)
                )
            };
            if let Some(e) = elongation {
                let [min, max] = e.value;
                if min < lowest {
                    return Err(self.invalid(
                        &e.span,
                        &e.field,
                        format!(
                            "module {}: δL_min = {min} m leaves a backbone length L0 + δL_min = \
                             {} m, shorter than {} L0 = {} m; {}",
                            i + 1,
                            crate::limits::rounded(l0 + min),
                            limits::DEFAULT_MIN_LENGTH_FRACTION,
                            crate::limits::rounded(limits::DEFAULT_MIN_LENGTH_FRACTION * l0),
                            allowed()
                        ),
                    ));
                }
                if max > highest {
                    return Err(self.invalid(
                        &e.span,
                        &e.field,
                        format!(
                            "module {}: δL_max = {max} m stretches the backbone beyond {} rest \
                             lengths; {}",
                            i + 1,
                            limits::DEFAULT_MAX_ELONGATION_RATIO,
                            allowed()
                        ),
                    ));
                }
            }
            let [min, max] = elongation.map_or(domain.elongation, |e| e.value);
            // Only a written margin or written limits can leave no room (the defaults
            // without a margin always do).
            let written_at = elongation_margin
                .map(|m| (&m.span, &m.field))
                .or(elongation.map(|e| (&e.span, &e.field)));
            if min + margin >= max - margin
                && let Some((span, field)) = written_at
            {
                return Err(self.invalid(
                    span,
                    field,
                    format!(
                        "module {}: the margin {margin} m leaves no allowed elongation inside \
                         [{}, {}] m (it needs δL_min + ε < δL_max − ε)",
                        i + 1,
                        crate::limits::rounded(min),
                        crate::limits::rounded(max)
                    ),
                ));
            }
            let bend_margin_value = bend_margin.map_or(0.0, |m| m.value);
            let max_bend_value = max_bend.map_or(domain.max_bend, |b| b.value);
            // A margin of zero (none written) is always below the limit.
            if bend_margin_value >= max_bend_value
                && let Some(at) = bend_margin.or(max_bend)
            {
                return Err(self.invalid(
                    &at.span,
                    &at.field,
                    format!(
                        "module {}: the bend margin ({:.6}°) must be below the bend limit \
                         ({:.6}°{})",
                        i + 1,
                        bend_margin_value.to_degrees(),
                        max_bend_value.to_degrees(),
                        if max_bend.is_some() {
                            ", max_bend_deg"
                        } else {
                            ", the domain's default"
                        }
                    ),
                ));
            }
            out.push(Limits {
                elongation: [min, max],
                elongation_margin: margin,
                max_bend: max_bend_value,
                bend_margin: bend_margin_value,
                gains: [own.gains[0].or(top.gains[0]), own.gains[1].or(top.gains[1])],
                written: LimitFlags {
                    elongation: elongation.is_some(),
                    bend: max_bend.is_some(),
                },
                elongation_rate: own
                    .elongation_rate
                    .as_ref()
                    .or(top.elongation_rate.as_ref())
                    .map_or(domain.elongation_rate, |r| r.value),
            });
        }
        Ok(out)
    }

    /// Checks every `[[obstacle]]` table against the modules.
    pub(crate) fn obstacles(
        &self,
        tables: &[ObstacleTable],
        modules: &[Module],
    ) -> Result<Vec<Obstacle>, FileError> {
        tables
            .iter()
            .enumerate()
            .map(|(o, table)| self.obstacle(table, &format!("obstacle[{}]", o + 1), modules))
            .collect()
    }

    fn obstacle(
        &self,
        table: &ObstacleTable,
        prefix: &str,
        modules: &[Module],
    ) -> Result<Obstacle, FileError> {
        let field = |name: &str| format!("{prefix}.{name}");
        let vector = |v: &Spanned<Vec<Spanned<f64>>>, name: &str, limit, what| {
            let values = self.list_within(v.get_ref(), &field(name), limit)?;
            self.three(values, v, &field(name), what)
        };
        // A field the other kind of obstacle takes, written here by mistake.
        let foreign = |present: Option<Range<usize>>, name: &str, kind: &str| match present {
            Some(span) => Err(self.invalid(
                &span,
                &field(name),
                format!("a {kind} obstacle has no `{name}`"),
            )),
            None => Ok(()),
        };
        let required = |name: &str, kind: &str, needs: &str| {
            self.invalid(
                &table.kind.span(),
                &field(name),
                format!("missing; a {kind} obstacle needs `{name}` ({needs})"),
            )
        };
        let shape = match table.kind.get_ref().as_str() {
            "sphere" => {
                foreign(table.normal.as_ref().map(Spanned::span), "normal", "sphere")?;
                foreign(table.offset.as_ref().map(Spanned::span), "offset", "sphere")?;
                let center = table
                    .center
                    .as_ref()
                    .ok_or_else(|| required("center", "sphere", "[x, y, z] in m, world frame"))?;
                let radius = table
                    .radius
                    .as_ref()
                    .ok_or_else(|| required("radius", "sphere", "in m"))?;
                Shape::Sphere {
                    center: vector(
                        center,
                        "center",
                        &limits::POSITION_M,
                        "coordinates [x, y, z]",
                    )?,
                    radius: self.within(radius, &field("radius"), &limits::OBSTACLE_RADIUS_M)?,
                }
            }
            "half-space" => {
                foreign(
                    table.center.as_ref().map(Spanned::span),
                    "center",
                    "half-space",
                )?;
                foreign(
                    table.radius.as_ref().map(Spanned::span),
                    "radius",
                    "half-space",
                )?;
                let normal = table.normal.as_ref().ok_or_else(|| {
                    required(
                        "normal",
                        "half-space",
                        "[nx, ny, nz], toward the allowed side",
                    )
                })?;
                let n = vector(
                    normal,
                    "normal",
                    &limits::NORMAL_COMPONENT,
                    "components [nx, ny, nz]",
                )?;
                let norm = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                if norm <= 1e-9 {
                    return Err(self.invalid(
                        &normal.span(),
                        &field("normal"),
                        "is zero; it gives the plane's direction (toward the allowed side) and \
                         needs a length > 1e-9"
                            .into(),
                    ));
                }
                let offset = match &table.offset {
                    Some(v) => self.within(v, &field("offset"), &limits::POSITION_M)?,
                    None => 0.0,
                };
                Shape::HalfSpace {
                    normal: n.map(|c| c / norm),
                    offset,
                }
            }
            other => {
                return Err(self.invalid(
                    &table.kind.span(),
                    &field("kind"),
                    format!(
                        "{other:?} is not an obstacle kind; write \"sphere\" or \"half-space\""
                    ),
                ));
            }
        };
        let margin = match &table.margin {
            Some(v) => self.within(v, &field("margin"), &limits::MARGIN_M)?,
            None => 0.0,
        };
        let mut gains = [None, None];
        for (slot, value, name) in [(0, &table.p1, "p1"), (1, &table.p2, "p2")] {
            if let Some(v) = value {
                gains[slot] = Some(self.within(v, &field(name), &limits::BARRIER_GAIN_PER_S)?);
            }
        }
        let Some(watch_tables) = &table.watch else {
            return Err(required(
                "watch",
                table.kind.get_ref(),
                "the points that stay out, e.g. watch = [{ module = 2, points = [\"corners\"] }]",
            ));
        };
        let mut watch = Vec::new();
        for (w, entry) in watch_tables.get_ref().iter().enumerate() {
            let prefix = field(&format!("watch[{}]", w + 1));
            let before = watch.len();
            self.watched(entry, &prefix, modules, &mut watch)?;
            if watch.len() == before {
                return Err(self.invalid(
                    &entry.span(),
                    &prefix,
                    "watches no point; give `points` (\"corners\", \"corner N\", \"centre\"), \
                     `plate_points` or `arc`"
                        .into(),
                ));
            }
        }
        if watch.is_empty() {
            return Err(self.invalid(
                &watch_tables.span(),
                &field("watch"),
                "is empty; an obstacle needs at least one watched point".into(),
            ));
        }
        Ok(Obstacle {
            shape,
            margin,
            gains,
            watch,
        })
    }

    /// The points one `watch` entry names, appended to `watch` in the order: named points,
    /// plate points, arc points.
    fn watched(
        &self,
        entry: &Spanned<WatchTable>,
        prefix: &str,
        modules: &[Module],
        watch: &mut Vec<Watched>,
    ) -> Result<(), FileError> {
        let table = entry.get_ref();
        let n = modules.len() as i64;
        let number = *table.module.get_ref();
        if !(1..=n).contains(&number) {
            return Err(self.invalid(
                &table.module.span(),
                &format!("{prefix}.module"),
                format!("must be a module of this robot, 1..={n}, got {number}"),
            ));
        }
        let module = (number - 1) as usize;
        let corners = modules[module].corner_angles.len();
        for (k, name) in table.points.iter().flatten().enumerate() {
            let field = format!("{prefix}.points[{}]", k + 1);
            let words: Vec<&str> = name.get_ref().split_whitespace().collect();
            match words.as_slice() {
                ["corners"] => watch.extend((0..corners).map(|j| Watched {
                    module,
                    point: WatchedPoint::Corner(j),
                })),
                ["centre" | "center"] => watch.push(Watched {
                    module,
                    point: WatchedPoint::Centre,
                }),
                ["corner", j] => {
                    let j = j
                        .parse::<usize>()
                        .ok()
                        .filter(|j| (1..=corners).contains(j));
                    let Some(j) = j else {
                        return Err(self.invalid(
                            &name.span(),
                            &field,
                            format!(
                                "{:?}: module {number} has corners 1..={corners}",
                                name.get_ref()
                            ),
                        ));
                    };
                    watch.push(Watched {
                        module,
                        point: WatchedPoint::Corner(j - 1),
                    });
                }
                _ => {
                    return Err(self.invalid(
                        &name.span(),
                        &field,
                        format!(
                            "{:?} is not a point name; write \"corners\" (all of them), \
                             \"corner N\" (1..={corners}) or \"centre\"; other points of the \
                             plate go in `plate_points`, points of the backbone in `arc`",
                            name.get_ref()
                        ),
                    ));
                }
            }
        }
        for (k, point) in table.plate_points.iter().flatten().enumerate() {
            let field = format!("{prefix}.plate_points[{}]", k + 1);
            let values = self.list_within(point.get_ref(), &field, &limits::PLATE_POINT_M)?;
            let xyz = self.three(
                values,
                point,
                &field,
                "coordinates [x, y, z] in the plate frame",
            )?;
            watch.push(Watched {
                module,
                point: WatchedPoint::Listed(xyz),
            });
        }
        for (k, s) in table.arc.iter().flatten().enumerate() {
            let field = format!("{prefix}.arc[{}]", k + 1);
            let s = self.limited(
                *s.get_ref(),
                &s.span(),
                &field,
                "arc fraction ",
                &limits::ARC_FRACTION,
            )?;
            watch.push(Watched {
                module,
                point: WatchedPoint::Arc(s),
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use crate::Robot;
    use crate::barriers::{LimitFlags, Limits, Shape, Watched, WatchedPoint};
    use crate::toml_file::FileError;
    use crate::toml_file::testing::assert_invalid;

    fn parse(text: &str) -> Result<Robot, FileError> {
        Robot::parse(text, Path::new("robots/x.toml"))
    }

    #[test]
    fn limits_resolve_per_module_over_the_top_table() {
        let robot = parse(
            "[limits]\nelongation = [-0.05, 0.03]\nmax_bend_deg = 90\np1 = 4\n\
             [[module]]\n\
             [[module]]\n[module.limits]\nelongation = [-0.02, 0.02]\nelongation_margin = 0.001\n\
             bend_margin_deg = 10\n",
        )
        .unwrap();
        let right = std::f64::consts::FRAC_PI_2;
        assert_eq!(
            robot.limits[0],
            Limits {
                elongation: [-0.05, 0.03],
                elongation_margin: 0.0,
                max_bend: right,
                bend_margin: 0.0,
                gains: [Some(4.0), None],
                written: LimitFlags {
                    elongation: true,
                    bend: true
                },
                elongation_rate: 1.0,
            }
        );
        assert_eq!(robot.limits[1].elongation, [-0.02, 0.02]);
        assert_eq!(robot.limits[1].elongation_margin, 0.001);
        assert!((robot.limits[1].bend_margin - right / 9.0).abs() < 1e-15);
        assert_eq!(robot.limits[1].max_bend, right);
        // The rate: the default ten rest lengths per second, a table's own over the top's.
        let rates = parse(
            "[limits]\nelongation_rate = 0.5\n[[module]]\nrest_length = 0.2\n\
             [[module]]\n[module.limits]\nelongation_rate = 0.25\n",
        )
        .unwrap();
        assert_eq!(rates.limits[0].elongation_rate, 0.5);
        assert_eq!(rates.limits[1].elongation_rate, 0.25);
        let plain = parse("[[module]]\nrest_length = 0.2\n").unwrap();
        assert_eq!(plain.limits[0].elongation_rate, 2.0);
        // No tables: every module keeps the domain's limits, and the same structure (limits
        // are numbers).
        let plain = parse("modules = 2").unwrap();
        let l0 = plain.modules[0].rest_length;
        assert_eq!(plain.limits, vec![Limits::domain(l0); 2]);
        assert_eq!(plain.limits[0].written, LimitFlags::default());
        assert_eq!(plain.structure(), robot.structure());
    }

    #[test]
    fn unwritten_limits_are_the_domains_defaults_with_their_own_gains() {
        use crate::barriers::BarrierKind;
        use crate::limits::{DEFAULT_MAX_BEND_RAD, DOMAIN_BARRIER_GAINS};
        // Module 1 writes a bend limit only, module 2 nothing; L0 = 0.1 m and 0.2 m.
        let robot = parse(
            "[[module]]\nrest_length = 0.1\n[module.limits]\nmax_bend_deg = 90\np1 = 4\n\
             elongation_margin = 0.01\n[[module]]\nrest_length = 0.2\n",
        )
        .unwrap();
        let [one, two] = &robot.limits[..] else {
            panic!("two modules")
        };
        // −(1 − 0.05)·L0 and 4·L0, written out by hand.
        assert!((one.elongation[0] + 0.095).abs() < 1e-15);
        assert!((one.elongation[1] - 0.4).abs() < 1e-15);
        assert!((two.elongation[0] + 0.19).abs() < 1e-15);
        assert!((two.elongation[1] - 0.8).abs() < 1e-15);
        assert_eq!(one.elongation_margin, 0.01);
        assert_eq!(two.max_bend, DEFAULT_MAX_BEND_RAD);
        assert!((DEFAULT_MAX_BEND_RAD - 225f64.to_radians()).abs() < 1e-15);
        // The written bend limit keeps the table's gains (p2: the run's); the defaults
        // take the domain's.
        assert!(!one.is_domain_default(BarrierKind::Bend));
        assert_eq!(one.gains_of(BarrierKind::Bend), [Some(4.0), None]);
        let domain = DOMAIN_BARRIER_GAINS.map(Some);
        assert!(one.is_domain_default(BarrierKind::ElongationMin));
        assert_eq!(one.gains_of(BarrierKind::ElongationMax), domain);
        assert_eq!(two.gains_of(BarrierKind::Bend), domain);
        assert!(!two.is_domain_default(BarrierKind::PlateCorner));
    }

    #[test]
    fn obstacles_read_their_geometry_and_points() {
        let robot = parse(
            "modules = 2\n\
             [[obstacle]]\nkind = \"sphere\"\ncenter = [0.1, 0, 0.2]\nradius = 0.03\nmargin = 0.002\n\
             watch = [{ module = 2, points = [\"corners\", \"centre\"] },\n\
                      { module = 1, plate_points = [[0.0, 0.01, 0.02]], arc = [0.5, 1] }]\n\
             [[obstacle]]\nkind = \"half-space\"\nnormal = [0, 3, 4]\noffset = -0.1\np2 = 7\n\
             watch = [{ module = 1, points = [\"corner 4\"] }]\n",
        )
        .unwrap();
        let [sphere, plane] = &robot.obstacles[..] else {
            panic!("two obstacles")
        };
        assert_eq!(
            sphere.shape,
            Shape::Sphere {
                center: [0.1, 0.0, 0.2],
                radius: 0.03
            }
        );
        assert_eq!((sphere.margin, sphere.gains), (0.002, [None, None]));
        assert_eq!(sphere.watch.len(), 6 + 1 + 1 + 2);
        assert_eq!(
            sphere.watch[6],
            Watched {
                module: 1,
                point: WatchedPoint::Centre
            }
        );
        assert_eq!(
            sphere.watch[7..],
            [
                Watched {
                    module: 0,
                    point: WatchedPoint::Listed([0.0, 0.01, 0.02])
                },
                Watched {
                    module: 0,
                    point: WatchedPoint::Arc(0.5)
                },
                Watched {
                    module: 0,
                    point: WatchedPoint::Arc(1.0)
                },
            ]
        );
        // The normal is normalized; the offset is kept.
        assert_eq!(
            plane.shape,
            Shape::HalfSpace {
                normal: [0.0, 0.6, 0.8],
                offset: -0.1
            }
        );
        assert_eq!(plane.gains, [None, Some(7.0)]);
        assert_eq!(plane.watch[0].point, WatchedPoint::Corner(3));
        // Moving an obstacle is a number; watching another kind of point is structure.
        let moved = parse(
            "modules = 2\n[[obstacle]]\nkind = \"half-space\"\nnormal = [1, 0, 0]\n\
             watch = [{ module = 1, points = [\"corner 4\"] }]\n",
        )
        .unwrap();
        let one_plane = |robot: &Robot| robot.structure().obstacles[..].to_vec();
        assert_eq!(one_plane(&moved)[0], robot.structure().obstacles[1]);
    }

    #[test]
    fn bad_limits_name_file_line_and_field() {
        assert_invalid(
            parse("modules = 1\n[limits]\nelongation = [0.03, -0.05]\n"),
            3,
            "limits.elongation",
            "must be below δL_max",
        );
        assert_invalid(
            parse("modules = 1\n[limits]\nelongation = [0.03]\n"),
            3,
            "limits.elongation",
            "needs 2 entries",
        );
        // L0 = 0.1 m: δL_min = −0.1 m would leave no backbone, −0.096 m less than 5 %.
        assert_invalid(
            parse("modules = 1\n[limits]\nelongation = [-0.1, 0.03]\n"),
            3,
            "limits.elongation",
            "L0 + δL_min = 0 m, shorter than 0.05 L0 = 0.005 m",
        );
        assert_invalid(
            parse("modules = 1\n[limits]\nelongation = [-0.096, 0.03]\n"),
            3,
            "limits.elongation",
            "allows -0.095 ≤ δL_min < δL_max ≤ 0.4 m for L0 = 0.1 m",
        );
        // The domain's defaults are the widest limits a file may write.
        assert!(parse("modules = 1\n[limits]\nelongation = [-0.095, 0.4]\n").is_ok());
        assert_invalid(
            parse("modules = 1\n[limits]\nelongation = [-0.05, 0.41]\n"),
            3,
            "limits.elongation",
            "δL_max = 0.41 m stretches the backbone beyond 4 rest lengths",
        );
        assert_invalid(
            parse("modules = 1\n[limits]\nmax_bend_deg = 226\n"),
            3,
            "limits.max_bend_deg",
            "must be > 0 and ≤ 225°, got 226",
        );
        assert!(parse("modules = 1\n[limits]\nmax_bend_deg = 225\n").is_ok());
        // The elongation rate: above zero, at most the domain's speed.
        assert_invalid(
            parse("modules = 1\n[limits]\nelongation_rate = 0\n"),
            3,
            "limits.elongation_rate",
            "must be > 0 and ≤ 100 m/s, got 0",
        );
        assert_invalid(
            parse("modules = 1\n[limits]\nelongation_rate = 101\n"),
            3,
            "limits.elongation_rate",
            "must be > 0 and ≤ 100 m/s, got 101",
        );
        // A margin tightens the defaults too, and must leave them room.
        assert_invalid(
            parse("modules = 1\n[limits]\nelongation_margin = 0.25\n"),
            3,
            "limits.elongation_margin",
            "leaves no allowed elongation inside [-0.095, 0.4] m",
        );
        assert_invalid(
            parse("modules = 1\n[limits]\nbend_margin_deg = 225\n"),
            3,
            "limits.bend_margin_deg",
            "below the bend limit (225.000000°, the domain's default)",
        );
        assert_invalid(
            parse(
                "[[module]]\n[[module]]\nrest_length = 0.02\n[module.limits]\nelongation = [-0.03, 0]\n",
            ),
            5,
            "module[2].limits.elongation",
            "module 2: δL_min = -0.03 m",
        );
        // The file-wide limit is checked against every module it applies to.
        assert_invalid(
            parse(
                "[limits]\nelongation = [-0.05, 0.03]\n[[module]]\n[[module]]\nrest_length = 0.04\n",
            ),
            2,
            "limits.elongation",
            "module 2",
        );
        assert_invalid(
            parse("modules = 1\n[limits]\nelongation = [-0.01, 0.01]\nelongation_margin = 0.01\n"),
            4,
            "limits.elongation_margin",
            "leaves no allowed elongation",
        );
        assert_invalid(
            parse("modules = 1\n[limits]\nmax_bend_deg = 300\n"),
            3,
            "limits.max_bend_deg",
            "must be > 0 and ≤ 225°",
        );
        assert_invalid(
            parse("modules = 1\n[limits]\nmax_bend_deg = 30\nbend_margin_deg = 30\n"),
            4,
            "limits.bend_margin_deg",
            "must be below the bend limit (30.000000°, max_bend_deg)",
        );
        assert_invalid(
            parse("modules = 1\n[limits]\np1 = 0\n"),
            3,
            "limits.p1",
            "must be > 0",
        );
        assert_invalid(
            parse("[defaults.limits]\nmax_bend_deg = 30\n[[module]]\n"),
            1,
            "defaults.limits",
            "written [limits]",
        );
    }

    #[test]
    fn bad_obstacles_name_file_line_and_field() {
        let sphere = |rest: &str| {
            parse(&format!(
                "modules = 2\n[[obstacle]]\nkind = \"sphere\"\ncenter = [0, 0, 0.3]\n{rest}"
            ))
        };
        let watch = "watch = [{ module = 2, points = [\"centre\"] }]\n";
        assert_invalid(
            sphere(&format!("radius = -0.01\n{watch}")),
            5,
            "obstacle[1].radius",
            "must be > 0",
        );
        assert_invalid(sphere(watch), 3, "obstacle[1].radius", "missing");
        assert_invalid(
            sphere(&format!("radius = 0.01\nnormal = [0, 0, 1]\n{watch}")),
            6,
            "obstacle[1].normal",
            "a sphere obstacle has no `normal`",
        );
        assert_invalid(
            parse(&format!(
                "modules = 2\n[[obstacle]]\nkind = \"half-space\"\nnormal = [0, 0, 0]\n{watch}"
            )),
            4,
            "obstacle[1].normal",
            "is zero",
        );
        assert_invalid(
            parse(&format!(
                "modules = 2\n[[obstacle]]\nkind = \"cube\"\n{watch}"
            )),
            3,
            "obstacle[1].kind",
            "not an obstacle kind",
        );
        assert_invalid(
            sphere("radius = 0.01\nwatch = [{ module = 1,\n arc = [0.5, 1.5] }]\n"),
            7,
            "obstacle[1].watch[1].arc[2]",
            "arc fraction must be > 0 and ≤ 1",
        );
        assert_invalid(
            sphere("radius = 0.01\nwatch = [{ module = 1, arc = [0] }]\n"),
            6,
            "obstacle[1].watch[1].arc[1]",
            "arc fraction must be > 0",
        );
        assert_invalid(
            sphere("radius = 0.01\nwatch = [{ module = 1,\n points = [\"centre\", \"tip\"] }]\n"),
            7,
            "obstacle[1].watch[1].points[2]",
            "\"tip\" is not a point name",
        );
        assert_invalid(
            sphere("radius = 0.01\nwatch = [{ module = 1, points = [\"corner 7\"] }]\n"),
            6,
            "obstacle[1].watch[1].points[1]",
            "module 1 has corners 1..=6",
        );
        assert_invalid(
            sphere("radius = 0.01\nwatch = [{ module = 3, points = [\"centre\"] }]\n"),
            6,
            "obstacle[1].watch[1].module",
            "1..=2, got 3",
        );
        assert_invalid(
            sphere("radius = 0.01\nwatch = [{ module = 1 }]\n"),
            6,
            "obstacle[1].watch[1]",
            "watches no point",
        );
        assert_invalid(sphere("radius = 0.01\n"), 3, "obstacle[1].watch", "missing");
        assert_invalid(
            sphere("radius = 0.01\nwatch = [{ module = 1, plate_points = [[0, 0]] }]\n"),
            6,
            "obstacle[1].watch[1].plate_points[1]",
            "needs 3 coordinates",
        );
    }
}
