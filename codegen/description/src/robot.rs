//! The robot description: what a robot file (`robots/*.toml`) says, parsed and validated.
//! Structure (module count, corners, tendons) drives code generation; numbers stay runtime.
//!
//! The format is documented in `robots/README.md`. Parsing runs in two steps: serde reads
//! the file into private structs whose values carry their byte span (type errors and
//! unknown fields become [`RobotError::Syntax`] naming the field), then every value is
//! checked and each module resolved ([`crate::module`]) with the span turned into the line
//! of an [`RobotError::Invalid`]. The `[hardware]` table is kept as written
//! ([`HardwareTable`]) for the runtime's hardware path, which checks it.

use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde::Deserialize;
use serde::de::{self, Deserializer, MapAccess, SeqAccess, Visitor};
use toml::Spanned;

use crate::barrier_tables::{LimitsTable, ObstacleTable};
use crate::barriers::{Limits, Obstacle, ObstacleStructure};
use crate::gains::{DEFAULT_BARRIER_GAINS, RawGain};
use crate::limits;
pub use crate::module::{Module, polygon_inertia};
use crate::module::{ModuleTable, Written};
use crate::toml_file::Checker;
pub use crate::toml_file::FileError as RobotError;
use crate::uncertainty_box::{ModuleBox, ModuleUncertainty, Uncertainty, UncertaintyTable};

/// How tendons are routed (§6 of the model notes).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Deserialize)]
#[serde(rename_all = "lowercase")]
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
    /// HOCBF class-K gains `p1`, `p2` [1/s] as the `[barrier]` table gives them (`None`:
    /// not given; [`Robot::barrier_gains`] fills in [`DEFAULT_BARRIER_GAINS`]).
    pub barrier: [Option<f64>; 2],
    /// The nominal controller's gains as the `[gains]` table gives them: `K_P` [N/m] and
    /// `K_D` [N·s/m], `nq × nq` row-major (`None`: not given).
    pub gains: FileGains,
    /// Tendon routing.
    pub routing: Routing,
    /// The modules, base first.
    pub modules: Vec<Module>,
    /// The limits of each module (`[limits]`, `[module.limits]`, else the domain's
    /// defaults: `Limits::domain`), one entry per module. Every module has
    /// its three limit barriers.
    pub limits: Vec<Limits>,
    /// The obstacles (`[[obstacle]]`), in file order.
    pub obstacles: Vec<Obstacle>,
    /// How far the numbers may be off (`[uncertainty]`; none declared by default). Where a
    /// module gives fractions of its own, each fraction here is the widest of any module's
    /// (what a reader of one fraction per kind may take); [`Robot::module_box`] gives each
    /// module's.
    pub uncertainty: Uncertainty,
    /// The robot's own set point `q̄` \[m\] (`set_point`, `3·modules` entries in the state
    /// domain; `None`: not given): what `softcbf simulate` drives it toward when neither
    /// the command line nor the scenario gives a reference.
    pub set_point: Option<Vec<f64>>,
    /// The `[hardware]` table as written, if the file has one; the runtime's hardware path
    /// reads and checks it (`softcbf::hardware_description`).
    pub hardware: Option<HardwareTable>,
}

/// `K_P` and `K_D` of a robot file's `[gains]` table, `nq × nq` row-major (`None`: not
/// given). Whoever runs the robot picks the gains by one precedence (command line, then
/// scenario, then robot file, then the built-in paper gains).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FileGains {
    /// `K_P` [N/m].
    pub kp: Option<Vec<f64>>,
    /// `K_D` [N·s/m].
    pub kd: Option<Vec<f64>>,
}

/// The `[hardware]` table of a robot file, unread: the file's text and where the table
/// is, so that its reader reports errors with the file, line and field like the rest.
#[derive(Clone, Debug, PartialEq)]
pub struct HardwareTable {
    /// The whole robot file (spans are byte offsets into it).
    pub text: Arc<str>,
    /// Where the table is written.
    pub span: Range<usize>,
}

impl HardwareTable {
    /// A checker of the table's values, naming `path` (the robot's [`Robot::source`]).
    pub fn checker<'a>(&'a self, path: &'a Path) -> Checker<'a> {
        Checker {
            text: &self.text,
            path,
        }
    }
}

/// The part of a robot description that decides which code is generated. Every module has
/// its three limit barriers (elongation from below and above, bend), so limits are numbers,
/// not structure.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct Structure {
    /// Corners per plate, one entry per module (base first).
    pub corners: Vec<usize>,
    /// Tendons per module, one entry per module.
    pub tendons: Vec<usize>,
    /// Tendon routing.
    pub routing: Routing,
    /// Each obstacle's kind and watched points.
    pub obstacles: Vec<ObstacleStructure>,
}

/// Default gravity when the file gives none [m/s²].
pub const DEFAULT_GRAVITY: [f64; 3] = [0.0, 0.0, -9.81];
pub use crate::limits::MAX_MODULES;
/// Text of `robots/paper-sim.toml`, compiled in.
pub const PAPER_SIM_TOML: &str = include_str!("../../../robots/paper-sim.toml");

impl Robot {
    /// Module `i`'s box (0-based): its own `uncertainty = { … }` fractions, the robot's
    /// `[uncertainty]` for the numbers it does not give. A module index out of range gets
    /// the robot-wide box.
    pub fn module_box(&self, i: usize) -> ModuleBox {
        match self.modules.get(i) {
            Some(module) => module.uncertainty.over(&self.uncertainty),
            None => ModuleBox::of(&self.uncertainty),
        }
    }

    /// Whether every module's factors (`factors[i]` module `i`'s, one per module) lie in
    /// its box ([`Robot::module_box`]).
    pub fn admits(&self, factors: &[crate::uncertainty_box::ModuleFactors]) -> bool {
        factors.len() == self.modules.len()
            && factors
                .iter()
                .enumerate()
                .all(|(i, f)| self.module_box(i).admits(f))
    }

    /// The structure that code generation depends on.
    pub fn structure(&self) -> Structure {
        Structure {
            corners: self.modules.iter().map(|m| m.corner_angles.len()).collect(),
            tendons: self.modules.iter().map(|m| m.tendon_angles.len()).collect(),
            routing: self.routing,
            obstacles: self.obstacles.iter().map(Obstacle::structure).collect(),
        }
    }

    /// The HOCBF gains `[p1, p2]` [1/s]: the file's, else [`DEFAULT_BARRIER_GAINS`].
    pub fn barrier_gains(&self) -> [f64; 2] {
        let [p1, p2] = self.barrier;
        [
            p1.unwrap_or(DEFAULT_BARRIER_GAINS[0]),
            p2.unwrap_or(DEFAULT_BARRIER_GAINS[1]),
        ]
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
        let file: RobotFile = checker.deserialize()?;
        checker.robot(file)
    }

    /// The paper's simulation robot: `robots/paper-sim.toml` as compiled in, with source
    /// `<embedded>` (a unit test guarantees that it parses).
    pub fn paper_sim() -> Robot {
        Robot::parse(PAPER_SIM_TOML, Path::new("<embedded>"))
            .expect("the embedded robots/paper-sim.toml is valid (tested)")
    }
}

impl Structure {
    /// A structure without obstacles: the plate corners and every module's limits.
    pub fn new(corners: Vec<usize>, tendons: Vec<usize>, routing: Routing) -> Structure {
        Structure {
            corners,
            tendons,
            routing,
            obstacles: Vec::new(),
        }
    }

    /// Number of modules.
    pub fn modules(&self) -> usize {
        self.corners.len()
    }

    /// A canonical text of the whole structure: two structures are equal exactly when their
    /// keys are (a generated model records the key of the structure it was built for).
    pub fn key(&self) -> String {
        format!("{self:?}")
    }
}

// ---------------------------------------------------------------------------------------
// The file as serde reads it: every value keeps its byte span.

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RobotFile {
    name: Option<String>,
    gravity: Option<Spanned<Vec<Spanned<f64>>>>,
    routing: Option<Routing>,
    set_point: Option<Spanned<Vec<Spanned<f64>>>>,
    barrier: Option<BarrierTable>,
    gains: Option<GainsTable>,
    defaults: Option<ModuleTable>,
    module: Option<Spanned<Vec<ModuleTable>>>,
    limits: Option<LimitsTable>,
    obstacle: Option<Vec<ObstacleTable>>,
    uncertainty: Option<UncertaintyTable>,
    modules: Option<Spanned<Count>>,
    /// Any table: its fields are the hardware path's to read.
    hardware: Option<Spanned<toml::Table>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct BarrierTable {
    p1: Option<Spanned<f64>>,
    p2: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct GainsTable {
    kp: Option<Spanned<RawGain>>,
    kd: Option<Spanned<RawGain>>,
}

/// `modules = N`, with a pointed message for the typo `[[modules]]`.
struct Count(i64);

impl<'de> Deserialize<'de> for Count {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct CountVisitor;
        const TABLES: &str = "`modules = N` takes the number of modules (an integer); \
                              module tables are written [[module]], singular";
        impl<'de> Visitor<'de> for CountVisitor {
            type Value = Count;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("the number of modules (an integer)")
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<Count, E> {
                Ok(Count(v))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<Count, E> {
                Ok(Count(i64::try_from(v).unwrap_or(i64::MAX)))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, _: A) -> Result<Count, A::Error> {
                Err(de::Error::custom(TABLES))
            }
            fn visit_map<A: MapAccess<'de>>(self, _: A) -> Result<Count, A::Error> {
                Err(de::Error::custom(TABLES))
            }
        }
        deserializer.deserialize_any(CountVisitor)
    }
}

// ---------------------------------------------------------------------------------------
// Checking and resolving.

impl Checker<'_> {
    fn robot(&self, file: RobotFile) -> Result<Robot, RobotError> {
        let name = file.name.unwrap_or_else(|| {
            self.path
                .file_stem()
                .map_or_else(|| "robot".to_string(), |s| s.to_string_lossy().into_owned())
        });
        let gravity = match &file.gravity {
            Some(g) => {
                let v = self.list_within(g.get_ref(), "gravity", &limits::GRAVITY_M_S2)?;
                self.three(v, g, "gravity", "components [gx, gy, gz]")?
            }
            None => DEFAULT_GRAVITY,
        };
        let mut barrier = [None, None];
        if let Some(table) = &file.barrier {
            let [p1, p2] = &mut barrier;
            for (gain, value, field) in
                [(p1, &table.p1, "barrier.p1"), (p2, &table.p2, "barrier.p2")]
            {
                if let Some(v) = value {
                    *gain = Some(self.within(v, field, &limits::BARRIER_GAIN_PER_S)?);
                }
            }
        }
        let defaults = match &file.defaults {
            Some(d) => self.written(d, "defaults")?,
            None => Written::default(),
        };
        if let Some(limits) = file.defaults.as_ref().and_then(|d| d.limits.as_ref()) {
            return Err(self.invalid(
                &limits.span(),
                "defaults.limits",
                "every module's limits are written [limits], at the top level of the file".into(),
            ));
        }
        let default_tables;
        let tables: &[ModuleTable] = match (&file.module, &file.modules) {
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
                default_tables = (0..count)
                    .map(|_| ModuleTable::default())
                    .collect::<Vec<_>>();
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
            let own = self.written(table, &prefix)?;
            modules.push(self.resolve(&own, &defaults, &prefix)?);
        }
        let module_limits: Vec<_> = tables.iter().map(|t| t.limits.as_ref()).collect();
        let limits = self.limits(file.limits.as_ref(), &module_limits, &modules)?;
        let obstacles = self.obstacles(file.obstacle.as_deref().unwrap_or_default(), &modules)?;
        let mut uncertainty = self.uncertainty(file.uncertainty.as_ref())?;
        resolve_module_boxes(&mut uncertainty, &mut modules);
        let nq = 3 * modules.len();
        let mut gains = FileGains::default();
        if let Some(table) = &file.gains {
            for (slot, raw, field, limit) in [
                (&mut gains.kp, &table.kp, "gains.kp", &limits::KP_N_PER_M),
                (&mut gains.kd, &table.kd, "gains.kd", &limits::KD_N_S_PER_M),
            ] {
                if let Some(raw) = raw {
                    *slot = Some(crate::gains::gain(self, raw, field, nq, limit)?);
                }
            }
        }
        let set_point = match &file.set_point {
            Some(v) => {
                let values = self.finite_list(v.get_ref(), "set_point")?;
                if values.len() != nq {
                    return Err(self.invalid(
                        &v.span(),
                        "set_point",
                        format!(
                            "has {} entries, the robot has {nq} coordinates (3 per module: Δx, \
                             Δy, δL)",
                            values.len()
                        ),
                    ));
                }
                let problem = crate::module_domain::modules_coordinates_problem(&modules, &values);
                self.state(problem, v, "set_point")?;
                Some(values)
            }
            None => None,
        };
        Ok(Robot {
            name,
            source: self.path.to_path_buf(),
            gravity,
            barrier,
            gains,
            set_point,
            routing: file.routing.unwrap_or(Routing::Local),
            limits,
            obstacles,
            uncertainty,
            modules,
            hardware: file.hardware.map(|table| HardwareTable {
                text: Arc::from(self.text),
                span: table.span(),
            }),
        })
    }
}

/// Where a module gives fractions of its own (`uncertainty = { … }`): every module's box
/// written out in full (its own fractions over the table's), and the robot-wide
/// `uncertainty` made the widest of them (the force stays the table's), so that what reads
/// one fraction per kind holds for every module and a fraction no module keeps counts
/// for nothing.
fn resolve_module_boxes(uncertainty: &mut Uncertainty, modules: &mut [Module]) {
    if modules.iter().all(|m| m.uncertainty.is_empty()) {
        return;
    }
    let table = *uncertainty;
    (uncertainty.stiffness, uncertainty.damping, uncertainty.mass) = (0.0, 0.0, 0.0);
    for module in modules.iter_mut() {
        let bx = module.uncertainty.over(&table);
        module.uncertainty = ModuleUncertainty::from_box(&bx);
        uncertainty.stiffness = uncertainty
            .stiffness
            .max(bx.stiffness[0])
            .max(bx.stiffness[1]);
        uncertainty.damping = uncertainty.damping.max(bx.damping[0]).max(bx.damping[1]);
        uncertainty.mass = uncertainty.mass.max(bx.mass);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    const THREE_SQUARE_TOML: &str = include_str!("../../../robots/three-square.toml");

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

    /// The numbers of docs/model.md §1, written here independently of the parser's defaults.
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
        assert_eq!(robot.barrier_gains(), [10.0, 10.0]);
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
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../robots");
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
        assert_eq!(robot.barrier_gains(), [10.0, 10.0]);
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
            (robot.barrier_gains(), robot.modules[0].rest_length),
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
        assert_eq!(robot.barrier_gains(), [1e4, 1e-9]);
        assert_invalid("[barrier]\np2 = nan\n[[module]]", 2, "barrier.p2", "finite");
    }

    #[test]
    fn controller_gains_take_a_number_a_diagonal_or_rows_and_are_checked() {
        let robot = parse("[gains]\nkp = 8\nkd = [1, 2, 3]\n[[module]]").unwrap();
        let kp = robot.gains.kp.as_deref().unwrap();
        assert_eq!((kp[0], kp[1], kp[4], kp[8]), (8.0, 0.0, 8.0, 8.0));
        let kd = robot.gains.kd.as_deref().unwrap();
        assert_eq!((kd[0], kd[4], kd[8], kd[1]), (1.0, 2.0, 3.0, 0.0));
        let none = parse("[[module]]").unwrap();
        assert_eq!((none.gains.kp.as_ref(), none.barrier), (None, [None, None]));
        assert_eq!(none.barrier_gains(), DEFAULT_BARRIER_GAINS);
        assert_invalid(
            "[gains]\nkp = -1\n[[module]]",
            2,
            "gains.kp",
            "must be ≥ 0 and ≤ 1000000 N/m, got -1",
        );
        assert_invalid(
            "[gains]\nkd = [1, 2]\n[[module]]",
            2,
            "gains.kd",
            "has 2 entries, the robot has 3 coordinates",
        );
        assert_invalid(
            "[[module]]\n[gains]\nkp = [[1, 3, 0], [3, 1, 0], [0, 0, 1]]\n",
            3,
            "gains.kp",
            "has the eigenvalue -2",
        );
        let error = parse("[gains]\np1 = 3\n[[module]]")
            .unwrap_err()
            .to_string();
        assert!(
            error.contains("unknown field `p1`, expected `kp` or `kd`"),
            "{error}"
        );
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
            "field `module[2].foo`: unknown field `foo`, expected one of `rest_length`",
        );
        assert_syntax(
            "naem = \"x\"\n[[module]]",
            1,
            1,
            "field `naem`: unknown field `naem`, expected one of `name`",
        );
        assert_syntax(
            "[defaults]\ncorner_raduis = 1\n",
            2,
            1,
            "field `defaults.corner_raduis`: unknown field `corner_raduis`",
        );
        assert_syntax(
            "[barrier]\np = 1\n",
            2,
            1,
            "field `barrier.p`: unknown field `p`, expected `p1` or `p2`",
        );
        assert_syntax(
            "module = [{mass = 1}, {mas = 1}]",
            1,
            24,
            "field `module[2].mas`: unknown field `mas`",
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
        assert_syntax(
            "[[module]\n",
            1,
            10,
            "field `module[1]`: the table header `[[module]` is not closed",
        );
        assert_syntax(
            "é = [",
            1,
            6,
            "field `é`, entry 1: the list opened on line 1 is not closed",
        );
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
