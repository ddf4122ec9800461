//! The robot description: what a robot file (`robots/*.toml`) says, parsed and validated.
//! Structure (module count, corners, tendons) drives code generation; numbers stay runtime.
//!
//! The format is documented in `robots/README.md`. Parsing runs in two steps: serde reads
//! the file into private `Raw*` structs whose values carry their byte span (type errors
//! and unknown fields become [`RobotError::Syntax`]), then every value is checked and
//! resolved (module field > `[defaults]` > built-in default) with the span turned into
//! the line of an [`RobotError::Invalid`].

use std::f64::consts::PI;
use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};

use serde::Deserialize;
use serde::de::{self, Deserializer, MapAccess, SeqAccess, Visitor};
use toml::Spanned;

use crate::hardware::{Hardware, RawHardware};
use crate::limits::{self, Limit};
use crate::toml_file::Checker;
pub use crate::toml_file::FileError as RobotError;

/// One module: a PCC foam segment and the rigid plate on top of it. SI units.
#[derive(Clone, Debug, PartialEq)]
pub struct Module {
    /// `L0`: rest length of the backbone \[m\].
    pub rest_length: f64,
    /// `d`: radius from the backbone to the tendons, which defines θ \[m\].
    pub tendon_radius: f64,
    /// `r`: radius from the backbone to a plate corner \[m\].
    pub corner_radius: f64,
    /// `φ_j`: angle of each plate corner from the module's x axis \[rad\].
    pub corner_angles: Vec<f64>,
    /// `ψ_k`: angle of each tendon from the module's x axis \[rad\].
    pub tendon_angles: Vec<f64>,
    /// `m`: mass lumped in the top plate \[kg\].
    pub mass: f64,
    /// Principal inertia of the plate about its centre of mass, plate axes [kg·m²].
    pub inertia: [f64; 3],
    /// Offset of the centre of mass along the plate normal (tip-frame z) \[m\].
    pub com_offset: f64,
    /// `κθ`: bending stiffness [N·m/rad].
    pub bending_stiffness: f64,
    /// `κL`: axial stiffness [N/m].
    pub axial_stiffness: f64,
    /// `βθ`: bending damping [N·m·s/rad].
    pub bending_damping: f64,
    /// `βL`: axial damping [N·s/m].
    pub axial_damping: f64,
    /// `ε_j`: barrier margin of each corner \[m\] (same length as `corner_angles`).
    pub margins: Vec<f64>,
}

/// How tendons are routed (MODEL.md §6).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Routing {
    /// Each tendon is anchored at its own module's two plates.
    Local,
    /// A tendon of module `i` also crosses modules `1..i-1`.
    Through,
}

/// A parsed, validated robot description.
#[derive(Clone, Debug, PartialEq)]
pub struct Robot {
    /// Name given in the file (defaults to the file stem).
    pub name: String,
    /// Where it was read from (`<embedded>` for the built-in default).
    pub source: PathBuf,
    /// Gravity vector in the world (= base) frame [m/s²].
    pub gravity: [f64; 3],
    /// HOCBF class-K gains `p1`, `p2` [1/s].
    pub barrier_gains: [f64; 2],
    /// Tendon routing.
    pub routing: Routing,
    /// The modules, base first.
    pub modules: Vec<Module>,
    /// The `[hardware]` table: servos and calibration, if the file has one.
    pub hardware: Option<Hardware>,
}

/// The part of a robot description that decides which code is generated.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct Structure {
    /// Corners per plate, one entry per module (base first).
    pub corners: Vec<usize>,
    /// Tendons per module, one entry per module.
    pub tendons: Vec<usize>,
    /// Tendon routing.
    pub routing: Routing,
}

/// Default gravity when the file gives none [m/s²].
pub const DEFAULT_GRAVITY: [f64; 3] = [0.0, 0.0, -9.81];
/// Default HOCBF gains `p1`, `p2` when the file gives none [1/s] (MODEL.md §5).
pub const DEFAULT_BARRIER_GAINS: [f64; 2] = [10.0, 10.0];
/// Largest `modules = N` accepted: a guard against typos, not a limit of the model.
pub const MAX_MODULES: usize = 1000;
/// Text of `robots/paper-sim.toml`, compiled in.
pub const PAPER_SIM_TOML: &str = include_str!("../../robots/paper-sim.toml");

/// Corner angles of the paper's hexagonal plate [deg].
const PAPER_CORNERS_DEG: [f64; 6] = [0.0, 60.0, 120.0, 180.0, 240.0, 300.0];
/// Tendon angles of the paper's module [deg].
const PAPER_TENDONS_DEG: [f64; 3] = [90.0, 210.0, 330.0];
/// Barrier margin of the paper's corners \[m\].
const PAPER_MARGIN: f64 = 0.005;
/// Two angles closer than this modulo 2π are the same direction \[rad\].
const ANGLE_TOLERANCE: f64 = 1e-9;
/// `det(A Aᵀ)` of the tendon matrix must exceed this times `(tr(A Aᵀ)/3)³`.
const RANK_TOLERANCE: f64 = 1e-12;

impl Module {
    /// The paper's simulation module (MODEL.md §1): the built-in default of every field.
    pub fn paper() -> Module {
        let (mass, corner_radius) = (0.15, 0.05);
        Module {
            rest_length: 0.1,
            tendon_radius: 0.04,
            corner_radius,
            corner_angles: PAPER_CORNERS_DEG.iter().map(|a| a.to_radians()).collect(),
            tendon_angles: PAPER_TENDONS_DEG.iter().map(|a| a.to_radians()).collect(),
            mass,
            inertia: polygon_inertia(mass, corner_radius, PAPER_CORNERS_DEG.len()),
            com_offset: 0.0,
            bending_stiffness: 10.0,
            axial_stiffness: 10.0,
            bending_damping: 5.0,
            axial_damping: 5.0,
            margins: vec![PAPER_MARGIN; PAPER_CORNERS_DEG.len()],
        }
    }
}

/// Principal inertia `[Ixx, Iyy, Izz]` [kg·m²] of a uniform thin regular polygon plate of
/// mass `mass` \[kg\] with `corners` corners at radius `corner_radius` \[m\], about its centre:
/// `Izz = m r²/6 · (1 + 2 cos²(π/n))`, `Ixx = Iyy = Izz/2` (hexagon: `diag(5/24, 5/24, 5/12)·m r²`).
pub fn polygon_inertia(mass: f64, corner_radius: f64, corners: usize) -> [f64; 3] {
    let cos = (PI / corners as f64).cos();
    let izz = mass * corner_radius * corner_radius / 6.0 * (1.0 + 2.0 * cos * cos);
    [izz / 2.0, izz / 2.0, izz]
}

impl Robot {
    /// The structure that code generation depends on.
    pub fn structure(&self) -> Structure {
        Structure {
            corners: self.modules.iter().map(|m| m.corner_angles.len()).collect(),
            tendons: self.modules.iter().map(|m| m.tendon_angles.len()).collect(),
            routing: self.routing,
        }
    }

    /// Reads and validates a robot file.
    pub fn load(path: &Path) -> Result<Robot, RobotError> {
        let text = crate::toml_file::read(path, "robot file")?;
        Robot::parse(&text, path)
    }

    /// Parses and validates robot-file text; `path` is used in error messages only (and
    /// its file stem is the name when the file gives none). Never panics.
    pub fn parse(text: &str, path: &Path) -> Result<Robot, RobotError> {
        let checker = Checker { text, path };
        let raw: RawRobot = toml::from_str(text).map_err(|error| checker.syntax(&error))?;
        checker.robot(raw)
    }

    /// The paper's simulation robot: `robots/paper-sim.toml` as compiled in, with source
    /// `<embedded>` (a unit test guarantees that it parses).
    pub fn paper_sim() -> Robot {
        Robot::parse(PAPER_SIM_TOML, Path::new("<embedded>"))
            .expect("the embedded robots/paper-sim.toml is valid (tested)")
    }
}

impl Structure {
    /// Number of modules.
    pub fn modules(&self) -> usize {
        self.corners.len()
    }
}

/// Why a robot file could not be used. Every variant names the file.

// ---------------------------------------------------------------------------------------
// The file as serde reads it: every value keeps its byte span.

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawRobot {
    name: Option<String>,
    gravity: Option<Spanned<Vec<Spanned<f64>>>>,
    routing: Option<RawRouting>,
    barrier: Option<RawBarrier>,
    defaults: Option<RawModule>,
    module: Option<Spanned<Vec<RawModule>>>,
    modules: Option<Spanned<RawCount>>,
    hardware: Option<Spanned<RawHardware>>,
}

#[derive(Deserialize)]
#[serde(rename_all = "lowercase")]
enum RawRouting {
    Local,
    Through,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawBarrier {
    p1: Option<Spanned<f64>>,
    p2: Option<Spanned<f64>>,
}

type RawNumber = Option<Spanned<f64>>;
type RawList = Option<Spanned<Vec<Spanned<f64>>>>;

#[derive(Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawModule {
    rest_length: RawNumber,
    tendon_radius: RawNumber,
    corner_radius: RawNumber,
    corner_angles_deg: RawList,
    tendon_angles_deg: RawList,
    mass: RawNumber,
    inertia: RawList,
    com_offset: RawNumber,
    bending_stiffness: RawNumber,
    axial_stiffness: RawNumber,
    bending_damping: RawNumber,
    axial_damping: RawNumber,
    margin: Option<Spanned<RawMargin>>,
}

/// `margin`: one number for all corners, or one per corner.
enum RawMargin {
    All(f64),
    Each(Vec<Spanned<f64>>),
}

impl<'de> Deserialize<'de> for RawMargin {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct MarginVisitor;
        impl<'de> Visitor<'de> for MarginVisitor {
            type Value = RawMargin;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a number [m] or an array of numbers, one per corner")
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<RawMargin, E> {
                Ok(RawMargin::All(v))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<RawMargin, E> {
                Ok(RawMargin::All(v as f64))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<RawMargin, E> {
                Ok(RawMargin::All(v as f64))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<RawMargin, A::Error> {
                let mut each = Vec::new();
                while let Some(value) = seq.next_element::<Spanned<f64>>()? {
                    each.push(value);
                }
                Ok(RawMargin::Each(each))
            }
        }
        deserializer.deserialize_any(MarginVisitor)
    }
}

/// `modules = N`, with a pointed message for the typo `[[modules]]`.
struct RawCount(i64);

impl<'de> Deserialize<'de> for RawCount {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct CountVisitor;
        const TABLES: &str = "`modules = N` takes the number of modules (an integer); \
                              module tables are written [[module]], singular";
        impl<'de> Visitor<'de> for CountVisitor {
            type Value = RawCount;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("the number of modules (an integer)")
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<RawCount, E> {
                Ok(RawCount(v))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<RawCount, E> {
                Ok(RawCount(i64::try_from(v).unwrap_or(i64::MAX)))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, _: A) -> Result<RawCount, A::Error> {
                Err(de::Error::custom(TABLES))
            }
            fn visit_map<A: MapAccess<'de>>(self, _: A) -> Result<RawCount, A::Error> {
                Err(de::Error::custom(TABLES))
            }
        }
        deserializer.deserialize_any(CountVisitor)
    }
}

// ---------------------------------------------------------------------------------------
// Checking and resolving.

/// A checked value, where it was written and under which field path.
struct Val<T> {
    value: T,
    span: Range<usize>,
    field: String,
}

/// A checked margin: one for every corner, or one per corner.
#[derive(Clone)]
enum Margin {
    All(f64),
    Each(Vec<f64>),
}

/// The checked fields of one `[[module]]` or of `[defaults]`; `None` where not written.
#[derive(Default)]
struct Fields {
    rest_length: Option<Val<f64>>,
    tendon_radius: Option<Val<f64>>,
    corner_radius: Option<Val<f64>>,
    corner_angles: Option<Val<Vec<f64>>>,
    tendon_angles: Option<Val<Vec<f64>>>,
    mass: Option<Val<f64>>,
    inertia: Option<Val<[f64; 3]>>,
    com_offset: Option<Val<f64>>,
    bending_stiffness: Option<Val<f64>>,
    axial_stiffness: Option<Val<f64>>,
    bending_damping: Option<Val<f64>>,
    axial_damping: Option<Val<f64>>,
    margin: Option<Val<Margin>>,
}

/// The value of `own` if written, else of `defaults`, else `builtin`.
fn resolve<T: Clone>(own: &Option<Val<T>>, defaults: &Option<Val<T>>, builtin: T) -> T {
    own.as_ref()
        .or(defaults.as_ref())
        .map_or(builtin, |v| v.value.clone())
}

impl Checker<'_> {
    fn robot(&self, raw: RawRobot) -> Result<Robot, RobotError> {
        let name = raw.name.unwrap_or_else(|| {
            self.path
                .file_stem()
                .map_or_else(|| "robot".to_string(), |s| s.to_string_lossy().into_owned())
        });
        let gravity = match &raw.gravity {
            Some(g) => {
                let v = self.list_within(g.get_ref(), "gravity", &limits::GRAVITY_M_S2)?;
                self.three(v, g, "gravity", "components [gx, gy, gz]")?
            }
            None => DEFAULT_GRAVITY,
        };
        let routing = match raw.routing {
            None | Some(RawRouting::Local) => Routing::Local,
            Some(RawRouting::Through) => Routing::Through,
        };
        let mut barrier_gains = DEFAULT_BARRIER_GAINS;
        if let Some(barrier) = &raw.barrier {
            let [p1, p2] = &mut barrier_gains;
            for (gain, raw, field) in [
                (p1, &barrier.p1, "barrier.p1"),
                (p2, &barrier.p2, "barrier.p2"),
            ] {
                if let Some(v) = raw {
                    *gain = self.within(v, field, &limits::BARRIER_GAIN_PER_S)?;
                }
            }
        }
        let defaults = match &raw.defaults {
            Some(d) => self.fields(d, "defaults")?,
            None => Fields::default(),
        };
        let default_tables;
        let tables: &[RawModule] = match (&raw.module, &raw.modules) {
            (Some(_), Some(n)) => {
                return Err(self.invalid(
                    &n.span(),
                    "modules",
                    "give either `modules = N` or [[module]] tables, not both".into(),
                ));
            }
            (Some(tables), None) if tables.get_ref().is_empty() => {
                return Err(self.invalid(
                    &tables.span(),
                    "module",
                    "the robot needs at least one module, got an empty list".into(),
                ));
            }
            (Some(tables), None) => tables.get_ref(),
            (None, Some(n)) => {
                let count = limits::MODULES
                    .check_integer(n.get_ref().0)
                    .map_err(|message| self.invalid(&n.span(), "modules", message))?;
                default_tables = (0..count).map(|_| RawModule::default()).collect::<Vec<_>>();
                &default_tables
            }
            (None, None) => {
                return Err(self.invalid(
                    &(0..0),
                    "module",
                    "the robot has no modules: add one [[module]] table per module (base \
                     first), or `modules = N` for N modules of defaults"
                        .into(),
                ));
            }
        };
        let mut modules = Vec::with_capacity(tables.len());
        for (i, table) in tables.iter().enumerate() {
            let prefix = format!("module[{}]", i + 1);
            let own = self.fields(table, &prefix)?;
            modules.push(self.module(&own, &defaults, &prefix)?);
        }
        let hardware = match &raw.hardware {
            Some(table) => {
                Some(self.hardware(table.get_ref(), &table.span(), &modules, routing)?)
            }
            None => None,
        };
        Ok(Robot {
            name,
            source: self.path.to_path_buf(),
            gravity,
            barrier_gains,
            routing,
            modules,
            hardware,
        })
    }

    /// Resolves one module from its own fields, `[defaults]` and the built-in values.
    fn module(&self, own: &Fields, defaults: &Fields, prefix: &str) -> Result<Module, RobotError> {
        let paper = Module::paper();
        let corner_angles = resolve(
            &own.corner_angles,
            &defaults.corner_angles,
            paper.corner_angles,
        );
        let corners = corner_angles.len();
        let mass = resolve(&own.mass, &defaults.mass, paper.mass);
        let corner_radius = resolve(
            &own.corner_radius,
            &defaults.corner_radius,
            paper.corner_radius,
        );
        let inertia = resolve(
            &own.inertia,
            &defaults.inertia,
            polygon_inertia(mass, corner_radius, corners),
        );
        let margins = match own.margin.as_ref().or(defaults.margin.as_ref()) {
            None => vec![PAPER_MARGIN; corners],
            Some(Val {
                value: Margin::All(e),
                ..
            }) => vec![*e; corners],
            Some(Val {
                value: Margin::Each(each),
                span,
                field,
            }) => {
                if each.len() != corners {
                    return Err(self.invalid(
                        span,
                        field,
                        format!(
                            "has {} entries but {prefix} has {corners} corners; give one \
                             margin per corner, or a single number for all",
                            each.len()
                        ),
                    ));
                }
                each.clone()
            }
        };
        Ok(Module {
            rest_length: resolve(&own.rest_length, &defaults.rest_length, paper.rest_length),
            tendon_radius: resolve(
                &own.tendon_radius,
                &defaults.tendon_radius,
                paper.tendon_radius,
            ),
            corner_radius,
            corner_angles,
            tendon_angles: resolve(
                &own.tendon_angles,
                &defaults.tendon_angles,
                paper.tendon_angles,
            ),
            mass,
            inertia,
            com_offset: resolve(&own.com_offset, &defaults.com_offset, paper.com_offset),
            bending_stiffness: resolve(
                &own.bending_stiffness,
                &defaults.bending_stiffness,
                paper.bending_stiffness,
            ),
            axial_stiffness: resolve(
                &own.axial_stiffness,
                &defaults.axial_stiffness,
                paper.axial_stiffness,
            ),
            bending_damping: resolve(
                &own.bending_damping,
                &defaults.bending_damping,
                paper.bending_damping,
            ),
            axial_damping: resolve(
                &own.axial_damping,
                &defaults.axial_damping,
                paper.axial_damping,
            ),
            margins,
        })
    }

    /// Checks every field written in one module table (or `[defaults]`) on its own.
    fn fields(&self, raw: &RawModule, prefix: &str) -> Result<Fields, RobotError> {
        let field = |name: &str| format!("{prefix}.{name}");
        let number = |v: &RawNumber, name: &str, limit: &Limit| {
            v.as_ref()
                .map(|v| {
                    let field = field(name);
                    let value = self.within(v, &field, limit)?;
                    Ok(Val {
                        value,
                        span: v.span(),
                        field,
                    })
                })
                .transpose()
        };
        let angles = |v: &RawList, name: &str, what: &str| {
            v.as_ref()
                .map(|v| {
                    let field = field(name);
                    let value = self.angles(v, &field, what)?;
                    Ok(Val {
                        value,
                        span: v.span(),
                        field,
                    })
                })
                .transpose()
        };
        let fields = Fields {
            rest_length: number(&raw.rest_length, "rest_length", &limits::LENGTH_M)?,
            tendon_radius: number(&raw.tendon_radius, "tendon_radius", &limits::LENGTH_M)?,
            corner_radius: number(&raw.corner_radius, "corner_radius", &limits::LENGTH_M)?,
            corner_angles: angles(&raw.corner_angles_deg, "corner_angles_deg", "corner")?,
            tendon_angles: angles(&raw.tendon_angles_deg, "tendon_angles_deg", "tendon")?,
            mass: number(&raw.mass, "mass", &limits::MASS_KG)?,
            inertia: raw
                .inertia
                .as_ref()
                .map(|v| {
                    let field = field("inertia");
                    let value = self.inertia(v, &field)?;
                    Ok(Val {
                        value,
                        span: v.span(),
                        field,
                    })
                })
                .transpose()?,
            com_offset: number(&raw.com_offset, "com_offset", &limits::COM_OFFSET_M)?,
            bending_stiffness: number(
                &raw.bending_stiffness,
                "bending_stiffness",
                &limits::BENDING_STIFFNESS,
            )?,
            axial_stiffness: number(
                &raw.axial_stiffness,
                "axial_stiffness",
                &limits::AXIAL_STIFFNESS,
            )?,
            bending_damping: number(
                &raw.bending_damping,
                "bending_damping",
                &limits::BENDING_DAMPING,
            )?,
            axial_damping: number(&raw.axial_damping, "axial_damping", &limits::AXIAL_DAMPING)?,
            margin: raw
                .margin
                .as_ref()
                .map(|v| {
                    let field = field("margin");
                    let value = match v.get_ref() {
                        RawMargin::All(e) => Margin::All(self.limited(
                            *e,
                            &v.span(),
                            &field,
                            "",
                            &limits::MARGIN_M,
                        )?),
                        RawMargin::Each(each) => {
                            Margin::Each(self.list_within(each, &field, &limits::MARGIN_M)?)
                        }
                    };
                    Ok(Val {
                        value,
                        span: v.span(),
                        field,
                    })
                })
                .transpose()?,
        };
        Ok(fields)
    }

    /// Corner or tendon angles: finite degrees, at least 3, distinct modulo 360°; for
    /// tendons also a full-rank tendon matrix. Returns radians.
    fn angles(
        &self,
        v: &Spanned<Vec<Spanned<f64>>>,
        field: &str,
        what: &str,
    ) -> Result<Vec<f64>, RobotError> {
        let degrees = self.list_within(v.get_ref(), field, &limits::ANGLE_DEG)?;
        if degrees.len() < 3 {
            return Err(self.invalid(
                &v.span(),
                field,
                format!("needs at least 3 {what}s, got {}", degrees.len()),
            ));
        }
        let radians: Vec<f64> = degrees.iter().map(|d| d.to_radians()).collect();
        // Sort the directions on the circle; neighbours (and last/first) must differ.
        let mut order: Vec<(f64, usize)> = radians
            .iter()
            .enumerate()
            .map(|(k, a)| (a.rem_euclid(2.0 * PI), k))
            .collect();
        order.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let n = order.len();
        for i in 0..n {
            let (a, ka) = order[i];
            let (b, kb) = order[(i + 1) % n];
            let gap = if i + 1 == n { b + 2.0 * PI - a } else { b - a };
            if gap < ANGLE_TOLERANCE {
                let (first, second) = (ka.min(kb), ka.max(kb));
                return Err(self.invalid(
                    &v.get_ref()[second].span(),
                    field,
                    format!(
                        "entry {} ({}°) is the same direction as entry {} ({}°); {what} angles \
                         must be distinct modulo 360°",
                        second + 1,
                        degrees[second],
                        first + 1,
                        degrees[first]
                    ),
                ));
            }
        }
        if what == "tendon" {
            // Gram matrix G = A Aᵀ of the 3×N tendon matrix with columns (cos ψ, sin ψ, −1).
            let mut g = [[0.0; 3]; 3];
            for psi in &radians {
                let column = [psi.cos(), psi.sin(), -1.0];
                for (r, row) in g.iter_mut().enumerate() {
                    for (c, entry) in row.iter_mut().enumerate() {
                        *entry += column[r] * column[c];
                    }
                }
            }
            let det = g[0][0] * (g[1][1] * g[2][2] - g[1][2] * g[2][1])
                - g[0][1] * (g[1][0] * g[2][2] - g[1][2] * g[2][0])
                + g[0][2] * (g[1][0] * g[2][1] - g[1][1] * g[2][0]);
            let scale = ((g[0][0] + g[1][1] + g[2][2]) / 3.0).powi(3);
            if det <= RANK_TOLERANCE * scale {
                return Err(self.invalid(
                    &v.span(),
                    field,
                    format!(
                        "the tendon directions (cos ψ, sin ψ, −1) do not span R³ \
                         (det(A Aᵀ)/(tr/3)³ = {:.1e} ≤ {RANK_TOLERANCE:.0e}), so τ = A f has no \
                         unique tensions; spread the tendons around the backbone",
                        det / scale
                    ),
                ));
            }
        }
        Ok(radians)
    }

    /// Principal moments: three, each > 0, and the triangle inequalities of a rigid body.
    fn inertia(&self, v: &Spanned<Vec<Spanned<f64>>>, field: &str) -> Result<[f64; 3], RobotError> {
        let values = self.list_within(v.get_ref(), field, &limits::INERTIA_KG_M2)?;
        let moments = self.three(
            values,
            v,
            field,
            "principal moments [Ixx, Iyy, Izz] in kg·m²",
        )?;
        let names = ["Ixx", "Iyy", "Izz"];
        for c in 0..3 {
            let (a, b) = ((c + 1) % 3, (c + 2) % 3);
            let (a, b) = (a.min(b), a.max(b));
            if moments[a] + moments[b] < moments[c] * (1.0 - 1e-12) {
                return Err(self.invalid(
                    &v.span(),
                    field,
                    format!(
                        "principal moments violate the triangle inequality of a rigid body: \
                         {} + {} = {} < {} = {}",
                        names[a],
                        names[b],
                        moments[a] + moments[b],
                        names[c],
                        moments[c]
                    ),
                ));
            }
        }
        Ok(moments)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const THREE_SQUARE_TOML: &str = include_str!("../../robots/three-square.toml");

    fn parse(text: &str) -> Result<Robot, RobotError> {
        Robot::parse(text, Path::new("robots/x.toml"))
    }

    /// Asserts that `text` fails validation at `line` on `field`, with `fragment` in the
    /// message.
    #[track_caller]
    fn assert_invalid(text: &str, line: usize, field: &str, fragment: &str) {
        crate::toml_file::testing::assert_invalid(parse(text), line, field, fragment);
    }

    /// Asserts a syntax error at `line:column` whose message contains `fragment`.
    #[track_caller]
    fn assert_syntax(text: &str, line: usize, column: usize, fragment: &str) {
        match parse(text) {
            Err(RobotError::Syntax {
                line: l,
                column: c,
                message,
                ..
            }) => {
                assert_eq!((l, c), (line, column), "message: {message}");
                assert!(message.contains(fragment), "`{message}` lacks `{fragment}`");
            }
            other => panic!("expected a Syntax error, got {other:?}"),
        }
    }

    #[track_caller]
    fn close(a: f64, b: f64) {
        assert!((a - b).abs() <= 1e-14 * b.abs().max(1e-300), "{a} != {b}");
    }

    /// The numbers of MODEL.md §1, written here independently of the parser's defaults.
    #[track_caller]
    fn assert_paper_module(m: &Module) {
        assert_eq!(m.rest_length, 0.1);
        assert_eq!(m.tendon_radius, 0.04);
        assert_eq!(m.corner_radius, 0.05);
        assert_eq!(m.corner_angles.len(), 6);
        for (j, &phi) in m.corner_angles.iter().enumerate() {
            close(phi, j as f64 * PI / 3.0);
        }
        assert_eq!(m.tendon_angles.len(), 3);
        for (k, &psi) in m.tendon_angles.iter().enumerate() {
            close(psi, PI / 2.0 + k as f64 * 2.0 * PI / 3.0);
        }
        assert_eq!(m.mass, 0.15);
        let mr2 = 0.15 * 0.05 * 0.05;
        close(m.inertia[0], 5.0 / 24.0 * mr2);
        close(m.inertia[1], 5.0 / 24.0 * mr2);
        close(m.inertia[2], 5.0 / 12.0 * mr2);
        assert_eq!(m.com_offset, 0.0);
        assert_eq!(
            [
                m.bending_stiffness,
                m.axial_stiffness,
                m.bending_damping,
                m.axial_damping
            ],
            [10.0, 10.0, 5.0, 5.0]
        );
        assert_eq!(m.margins, vec![0.005; 6]);
    }

    #[test]
    fn paper_sim_file_has_the_papers_numbers() {
        let robot = Robot::paper_sim();
        assert_eq!(robot.name, "paper-sim");
        assert_eq!(robot.source, PathBuf::from("<embedded>"));
        assert_eq!(robot.gravity, [0.0, 0.0, -9.81]);
        assert_eq!(robot.barrier_gains, [10.0, 10.0]);
        assert_eq!(robot.routing, Routing::Local);
        assert_eq!(robot.modules.len(), 2);
        robot.modules.iter().for_each(assert_paper_module);
        let structure = robot.structure();
        assert_eq!(
            (structure.corners, structure.tendons),
            (vec![6, 6], vec![3, 3])
        );
        assert_eq!(robot.structure().modules(), 2);
    }

    #[test]
    fn load_reads_the_shipped_files() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../robots");
        let robot = Robot::load(&dir.join("paper-sim.toml")).unwrap();
        assert_eq!(robot.modules, Robot::paper_sim().modules);
        assert!(Robot::load(&dir.join("three-square.toml")).is_ok());
        let missing = Robot::load(&dir.join("no-such-robot.toml")).unwrap_err();
        assert!(matches!(missing, RobotError::Io { .. }));
        assert!(
            missing
                .to_string()
                .contains("no-such-robot.toml: cannot read robot file")
        );
    }

    #[test]
    fn three_square_has_square_plates_and_paper_values() {
        let robot = Robot::parse(THREE_SQUARE_TOML, Path::new("robots/three-square.toml")).unwrap();
        assert_eq!(robot.name, "three-square");
        assert_eq!(robot.modules.len(), 3);
        let (m, r) = (0.15, 0.045);
        // A square of circumradius r has side s = r√2: Izz = m s²/6, Ixx = Iyy = m s²/12.
        let side2 = 2.0 * r * r;
        for module in &robot.modules {
            assert_eq!(module.corner_radius, r);
            let expected = [PI / 4.0, 3.0 * PI / 4.0, 5.0 * PI / 4.0, 7.0 * PI / 4.0];
            assert_eq!(module.corner_angles.len(), 4);
            for (&got, want) in module.corner_angles.iter().zip(expected) {
                close(got, want);
            }
            close(module.inertia[0], m * side2 / 12.0);
            close(module.inertia[1], m * side2 / 12.0);
            close(module.inertia[2], m * side2 / 6.0);
            assert_eq!(module.margins, vec![0.005; 4]);
            let paper = Module {
                corner_radius: r,
                corner_angles: module.corner_angles.clone(),
                inertia: module.inertia,
                margins: vec![0.005; 4],
                ..Module::paper()
            };
            assert_eq!(module, &paper);
        }
        let structure = robot.structure();
        assert_eq!(structure.corners, vec![4, 4, 4]);
        assert_eq!(structure.tendons, vec![3, 3, 3]);
    }

    #[test]
    fn built_in_defaults_are_the_papers_numbers() {
        let robot = parse("modules = 2").unwrap();
        assert_eq!(robot.name, "x");
        assert_eq!(robot.gravity, [0.0, 0.0, -9.81]);
        assert_eq!(robot.barrier_gains, [10.0, 10.0]);
        assert_eq!(robot.routing, Routing::Local);
        assert_eq!(robot.modules.len(), 2);
        robot.modules.iter().for_each(assert_paper_module);
        let one = parse("[[module]]").unwrap();
        assert_eq!(one.modules.len(), 1);
        assert_paper_module(&one.modules[0]);
    }

    #[test]
    fn regular_polygon_inertia_matches_closed_forms() {
        // Triangle with circumradius r: side a = r√3, polar moment m a²/12 = m r²/4.
        let [ixx, iyy, izz] = polygon_inertia(2.0, 0.5, 3);
        close(izz, 2.0 * 0.25 / 4.0);
        close(ixx, izz / 2.0);
        close(iyy, izz / 2.0);
        // Many corners tend to the disc, Izz = m r²/2.
        assert!((polygon_inertia(1.0, 1.0, 100_000)[2] - 0.5).abs() < 1e-9);
    }

    #[test]
    fn module_fields_override_defaults_which_override_built_ins() {
        let robot = parse(
            "routing = \"through\"\n\
             [defaults]\nmass = 0.2\ncorner_radius = 0.06\nmargin = [0.001, 0.002, 0.003]\n\
             corner_angles_deg = [0, 120, 240]\n\
             [[module]]\nmass = 0.3\nmargin = 0.004\n\
             [[module]]\n\
             [[module]]\ncorner_angles_deg = [10, 100, 190, 280]\nmargin = 0.0\ninertia = [1, 2, 3]\n",
        )
        .unwrap();
        assert_eq!(robot.routing, Routing::Through);
        let [a, b, c] = &robot.modules[..] else {
            panic!("three modules")
        };
        assert_eq!((a.mass, b.mass, c.mass), (0.3, 0.2, 0.2));
        assert_eq!(a.margins, vec![0.004; 3]);
        assert_eq!(b.margins, vec![0.001, 0.002, 0.003]);
        assert_eq!(c.margins, vec![0.0; 4]);
        assert_eq!(c.corner_angles.len(), 4);
        assert_eq!(c.inertia, [1.0, 2.0, 3.0]);
        // Default inertia follows the resolved mass, radius and corner count:
        // triangle Izz = m r²/4.
        close(a.inertia[2], 0.3 * 0.06 * 0.06 / 4.0);
        close(b.inertia[2], 0.2 * 0.06 * 0.06 / 4.0);
        // Untouched fields keep the built-in values.
        for m in [a, b, c] {
            assert_eq!(
                (m.rest_length, m.tendon_radius, m.bending_damping),
                (0.1, 0.04, 5.0)
            );
            assert_eq!(m.corner_radius, 0.06);
        }
        // Integers are accepted where numbers are expected.
        let robot = parse("[barrier]\np1 = 3\n[[module]]\nrest_length = 1").unwrap();
        assert_eq!(
            (robot.barrier_gains, robot.modules[0].rest_length),
            ([3.0, 10.0], 1.0)
        );
    }

    #[test]
    fn invalid_display_names_file_line_field_value_and_expectation() {
        let text = "[[module]]\n\n[[module]]\nmass = 0.1\ncorner_radius = -0.05\n";
        let error = parse(text).unwrap_err();
        assert_eq!(
            error.to_string(),
            "robots/x.toml:5: field `module[2].corner_radius`: must be ≥ 0.0001 and ≤ 10 m, got -0.05"
        );
    }

    #[test]
    fn numbers_must_be_finite() {
        assert_invalid(
            "[[module]]\nmass = nan\n",
            2,
            "module[1].mass",
            "must be a finite number ≥ 1e-6 and ≤ 10000 kg, got NaN",
        );
        assert_invalid(
            "[[module]]\ncom_offset = inf\n",
            2,
            "module[1].com_offset",
            "finite",
        );
        assert_invalid(
            "gravity = [0.0,\n  -inf,\n 0.0]\n[[module]]",
            2,
            "gravity",
            "entry 2 must be a finite number ≥ -100 and ≤ 100 m/s², got -inf",
        );
        assert_invalid(
            "[[module]]\ncorner_angles_deg = [0, nan, 90]",
            2,
            "module[1].corner_angles_deg",
            "entry 2",
        );
        assert_invalid(
            "[[module]]\nbending_damping = -nan\n",
            2,
            "module[1].bending_damping",
            "finite",
        );
        assert_invalid(
            "[[module]]\nmargin = [0.1, 0.1, inf, 0, 0, 0]",
            2,
            "module[1].margin",
            "entry 3",
        );
    }

    #[test]
    fn lengths_and_mass_lie_in_their_physical_ranges() {
        assert_invalid(
            "[[module]]\nrest_length = 0.0",
            2,
            "module[1].rest_length",
            "must be ≥ 0.0001 and ≤ 10 m, got 0",
        );
        assert_invalid(
            "[[module]]\nrest_length = 1e300",
            2,
            "module[1].rest_length",
            "must be ≥ 0.0001 and ≤ 10 m, got 1e300",
        );
        assert_invalid(
            "[[module]]\n\ntendon_radius = -0.04",
            3,
            "module[1].tendon_radius",
            "≥ 0.0001 and ≤ 10 m",
        );
        assert_invalid(
            "[[module]]\ntendon_radius = 1e-300",
            2,
            "module[1].tendon_radius",
            "got 1e-300",
        );
        assert_invalid(
            "[[module]]\ncorner_radius = 10.5",
            2,
            "module[1].corner_radius",
            "≤ 10 m, got 10.5",
        );
        assert_invalid(
            "[[module]]\nmass = -1",
            2,
            "module[1].mass",
            "must be ≥ 1e-6 and ≤ 10000 kg, got -1",
        );
        assert_invalid("[[module]]\nmass = 2e4", 2, "module[1].mass", "got 20000");
        assert_invalid(
            "[[module]]\ncom_offset = -11",
            2,
            "module[1].com_offset",
            "must be ≥ -10 and ≤ 10 m, got -11",
        );
        // The bounds themselves are accepted.
        let robot = parse(
            "[[module]]\nrest_length = 10\ntendon_radius = 0.0001\ncorner_radius = 10\n\
             mass = 0.000001\ncom_offset = -10",
        )
        .unwrap();
        let m = &robot.modules[0];
        assert_eq!(
            (
                m.rest_length,
                m.tendon_radius,
                m.corner_radius,
                m.mass,
                m.com_offset
            ),
            (10.0, 1e-4, 10.0, 1e-6, -10.0)
        );
    }

    #[test]
    fn stiffness_and_damping_are_non_negative_and_bounded() {
        let ok = parse(
            "[[module]]\nbending_stiffness = 0\naxial_stiffness = 0\nbending_damping = 0\naxial_damping = 0",
        );
        assert!(ok.is_ok());
        let ok = parse(
            "[[module]]\nbending_stiffness = 1e4\naxial_stiffness = 1e7\nbending_damping = 1e4\naxial_damping = 1e6",
        );
        assert!(ok.is_ok());
        assert_invalid(
            "[[module]]\nbending_stiffness = -1",
            2,
            "module[1].bending_stiffness",
            "≥ 0 and ≤ 10000 N·m/rad, got -1",
        );
        assert_invalid(
            "[[module]]\naxial_stiffness = 1.5e7",
            2,
            "module[1].axial_stiffness",
            "≥ 0 and ≤ 1e7 N/m, got 1.5e7",
        );
        assert_invalid(
            "[[module]]\nbending_damping = 1e300",
            2,
            "module[1].bending_damping",
            "≥ 0 and ≤ 10000 N·m·s/rad, got 1e300",
        );
        assert_invalid(
            "[[module]]\naxial_damping = -0.5",
            2,
            "module[1].axial_damping",
            "≥ 0 and ≤ 1000000 N·s/m, got -0.5",
        );
    }

    #[test]
    fn inertia_must_be_three_positive_moments_of_a_rigid_body() {
        assert_invalid(
            "[[module]]\ninertia = [1, 1]",
            2,
            "module[1].inertia",
            "needs 3 principal moments",
        );
        assert_invalid(
            "[[module]]\ninertia = [1,\n 0,\n 1]",
            3,
            "module[1].inertia",
            "entry 2 must be ≥ 1e-16 and ≤ 1000000 kg·m², got 0",
        );
        assert_invalid(
            "[[module]]\ninertia = [1, 1, 2.5]",
            2,
            "module[1].inertia",
            "Ixx + Iyy = 2 < Izz = 2.5",
        );
        assert_invalid(
            "[[module]]\ninertia = [3, 1, 1]",
            2,
            "module[1].inertia",
            "Iyy + Izz = 2 < Ixx = 3",
        );
        // A thin plate sits exactly on the boundary and is accepted.
        assert!(parse("[[module]]\ninertia = [0.1, 0.2, 0.30000000000000004]").is_ok());
        assert!(parse("[[module]]\ninertia = [1, 1, 2]").is_ok());
        assert_invalid(
            "[[module]]\ninertia = [1e300, 1e300, 1e300]",
            2,
            "module[1].inertia",
            "entry 1 must be ≥ 1e-16 and ≤ 1000000 kg·m², got 1e300",
        );
    }

    #[test]
    fn corners_need_three_distinct_directions() {
        assert_invalid(
            "[[module]]\ncorner_angles_deg = [0, 180]",
            2,
            "module[1].corner_angles_deg",
            "at least 3 corners, got 2",
        );
        assert_invalid(
            "[[module]]\ncorner_angles_deg = [\n  0,\n  120,\n  360,\n]",
            5,
            "module[1].corner_angles_deg",
            "entry 3 (360°) is the same direction as entry 1 (0°)",
        );
        assert_invalid(
            "[[module]]\ncorner_angles_deg = [-90, 90, 270]",
            2,
            "module[1].corner_angles_deg",
            "entry 3 (270°)",
        );
        // 1e-9 rad is about 5.7e-8°: closer is the same direction, farther is distinct.
        assert_invalid(
            "[[module]]\ncorner_angles_deg = [0, 120, 120.00000001]",
            2,
            "module[1].corner_angles_deg",
            "entry 3",
        );
        assert!(parse("[[module]]\ncorner_angles_deg = [0, 120, 120.000001]\nmargin = 0").is_ok());
        assert_invalid(
            "[[module]]\ncorner_angles_deg = [0.000000001, 120, 359.99999999999]",
            2,
            "module[1].corner_angles_deg",
            "entry 3",
        );
    }

    #[test]
    fn tendons_need_three_distinct_directions_spanning_r3() {
        assert_invalid(
            "[[module]]\ntendon_angles_deg = [90, 270]",
            2,
            "module[1].tendon_angles_deg",
            "at least 3 tendons",
        );
        assert_invalid(
            "[[module]]\ntendon_angles_deg = [90, 210, -270]",
            2,
            "module[1].tendon_angles_deg",
            "entry 3 (-270°) is the same direction as entry 1 (90°)",
        );
        assert_invalid(
            "[[module]]\ntendon_angles_deg = [90, 210, 450]",
            2,
            "module[1].tendon_angles_deg",
            "entry 3 must be ≥ -360 and ≤ 360°, got 450",
        );
        // Distinct, but three nearly coincident directions leave A nearly singular.
        assert_invalid(
            "[[module]]\ntendon_angles_deg = [0, 0.01, 0.02]",
            2,
            "module[1].tendon_angles_deg",
            "do not span R³",
        );
        let robot = parse("[[module]]\ntendon_angles_deg = [0, 90, 180, 270]").unwrap();
        assert_eq!(robot.structure().tendons, vec![4]);
        // Independent check of the rank rule on the paper's layout: det A ≠ 0.
        let a: Vec<[f64; 3]> = Robot::paper_sim().modules[0]
            .tendon_angles
            .iter()
            .map(|p| [p.cos(), p.sin(), -1.0])
            .collect();
        let det = a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
            - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
            + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
        assert!((det.abs() - 3.0 * 3f64.sqrt() / 2.0).abs() < 1e-12, "{det}");
    }

    #[test]
    fn margins_must_be_non_negative_and_one_per_corner() {
        assert_invalid(
            "[[module]]\nmargin = -0.001",
            2,
            "module[1].margin",
            "must be ≥ 0 and ≤ 1 m, got -0.001",
        );
        assert_invalid(
            "[[module]]\nmargin = [0, 0,\n 0, -1, 0, 0]",
            3,
            "module[1].margin",
            "entry 4 must be ≥ 0 and ≤ 1 m, got -1",
        );
        assert_invalid(
            "[[module]]\nmargin = [0.1, 0.1, 0.1]",
            2,
            "module[1].margin",
            "has 3 entries but module[1] has 6 corners",
        );
        assert_invalid(
            "[defaults]\nmargin = [0, 0, 0, 0]\ncorner_angles_deg = [0, 90, 180, 270]\n[[module]]\n[[module]]\ncorner_angles_deg = [0, 120, 240]",
            2,
            "defaults.margin",
            "has 4 entries but module[2] has 3 corners",
        );
        assert_invalid(
            "[[module]]\nmargin = []",
            2,
            "module[1].margin",
            "has 0 entries",
        );
    }

    #[test]
    fn barrier_gains_must_be_positive_and_bounded() {
        assert_invalid(
            "[barrier]\np1 = 0\n[[module]]",
            2,
            "barrier.p1",
            "must be > 0 and ≤ 10000 1/s, got 0",
        );
        assert_invalid(
            "[barrier]\np1 = 1\np2 = -2\n[[module]]",
            3,
            "barrier.p2",
            "> 0 and ≤ 10000 1/s",
        );
        assert_invalid(
            "[barrier]\np1 = 1e308\n[[module]]",
            2,
            "barrier.p1",
            "got 1e308",
        );
        let robot = parse("[barrier]\np1 = 1e4\np2 = 1e-9\n[[module]]").unwrap();
        assert_eq!(robot.barrier_gains, [1e4, 1e-9]);
        assert_invalid("[barrier]\np2 = nan\n[[module]]", 2, "barrier.p2", "finite");
    }

    #[test]
    fn gravity_must_have_three_finite_components() {
        assert_invalid(
            "gravity = [0, -9.81]\n[[module]]",
            1,
            "gravity",
            "needs 3 components [gx, gy, gz], got 2",
        );
        let robot = parse("gravity = [0, 0, 0]\n[[module]]").unwrap();
        assert_eq!(robot.gravity, [0.0; 3]);
        let robot = parse("gravity = [100, -100, 0]\n[[module]]").unwrap();
        assert_eq!(robot.gravity, [100.0, -100.0, 0.0]);
        assert_invalid(
            "gravity = [0, 0, -1e300]\n[[module]]",
            1,
            "gravity",
            "entry 3 must be ≥ -100 and ≤ 100 m/s², got -1e300",
        );
    }

    #[test]
    fn defaults_are_checked_under_their_own_name() {
        assert_invalid(
            "[defaults]\n\ncorner_radius = -0.05\n[[module]]\ncorner_radius = 0.05",
            3,
            "defaults.corner_radius",
            "≥ 0.0001 and ≤ 10 m, got -0.05",
        );
        assert_invalid(
            "[defaults]\ntendon_angles_deg = [0, 0, 90]\n[[module]]",
            2,
            "defaults.tendon_angles_deg",
            "entry 2",
        );
    }

    #[test]
    fn module_count_is_given_exactly_once() {
        assert_invalid("name = \"a\"\n", 1, "module", "has no modules");
        assert_invalid(
            "\n\nmodules = 0",
            3,
            "modules",
            "an integer in 1..=1000, got 0",
        );
        assert_invalid("modules = -3", 1, "modules", "got -3");
        assert_invalid(
            "modules = 1000000000000",
            1,
            "modules",
            "an integer in 1..=1000",
        );
        assert_invalid("modules = 2\n[[module]]", 1, "modules", "not both");
        assert_invalid("module = []", 1, "module", "at least one module");
        assert_eq!(parse("modules = 3").unwrap().modules.len(), 3);
    }

    #[test]
    fn unknown_fields_are_errors_naming_their_table() {
        assert_syntax(
            "[[module]]\nmass = 0.1\n[[module]]\n  foo = 3\n",
            4,
            3,
            "unknown field `foo` in [[module]] 2; expected one of `rest_length`",
        );
        assert_syntax(
            "naem = \"x\"\n[[module]]",
            1,
            1,
            "unknown field `naem` at top level; expected one of `name`",
        );
        assert_syntax(
            "[defaults]\ncorner_raduis = 1\n",
            2,
            1,
            "unknown field `corner_raduis` in [defaults]",
        );
        assert_syntax(
            "[barrier]\np = 1\n",
            2,
            1,
            "unknown field `p` in [barrier]; expected `p1` or `p2`",
        );
        assert_syntax(
            "module = [{mass = 1}, {mas = 1}]",
            1,
            24,
            "unknown field `mas` in [[module]] 2",
        );
        assert_syntax(
            "[[modules]]\nmass = 1",
            1,
            1,
            "module tables are written [[module]]",
        );
    }

    #[test]
    fn type_errors_are_syntax_errors_naming_the_field() {
        assert_syntax(
            "[[module]]\nmass = \"heavy\"\n",
            2,
            8,
            "field `module[1].mass`: invalid type: string \"heavy\", expected a number",
        );
        assert_syntax(
            "[[module]]\ncorner_angles_deg = [0, \"a\", 3]",
            2,
            25,
            "field `module[1].corner_angles_deg`, entry 2",
        );
        assert_syntax(
            "routing = \"sideways\"\n[[module]]",
            1,
            11,
            "field `routing`: unknown variant `sideways`, expected `local` or `through`",
        );
        assert_syntax("modules = 2.5", 1, 11, "the number of modules (an integer)");
        assert_syntax(
            "[[module]]\nmargin = \"small\"",
            2,
            10,
            "a number [m] or an array of numbers, one per corner",
        );
        assert_syntax("[[module]]\nmass = 0.1\nmass = 0.2", 3, 1, "duplicate key");
        assert_syntax("[[module]\n", 1, 10, "unclosed array table");
        assert_syntax("é = [", 1, 6, "unclosed array");
    }

    /// Mutations of the shipped files: every prefix, every line removed or doubled, and
    /// every value replaced by hostile text. None may panic; all must return.
    #[test]
    fn never_panics_on_mutated_files() {
        let replacements = [
            "",
            "-1",
            "0",
            "nan",
            "-inf",
            "1e400",
            "\"x\"",
            "[]",
            "[1,",
            "{}",
            "9999999999999999999",
            "[0, 0, 0]",
            "[[1]]",
            "true",
            "1979-05-27",
        ];
        let mut count = 0;
        for text in [PAPER_SIM_TOML, THREE_SQUARE_TOML] {
            for (end, _) in text.char_indices() {
                let _ = parse(&text[..end]);
                count += 1;
            }
            let lines: Vec<&str> = text.lines().collect();
            for i in 0..lines.len() {
                let mut removed = lines.clone();
                removed.remove(i);
                let _ = parse(&removed.join("\n"));
                let mut doubled = lines.clone();
                doubled.insert(i, lines[i]);
                let _ = parse(&doubled.join("\n"));
                if let Some((key, _)) = lines[i].split_once('=') {
                    for value in replacements {
                        let mut changed = lines.clone();
                        let line = format!("{key}= {value}");
                        changed[i] = &line;
                        let _ = parse(&changed.join("\n"));
                        count += 1;
                    }
                }
                count += 2;
            }
        }
        assert!(count > 2000, "{count}");
    }
}
