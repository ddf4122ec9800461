//! One module of a robot file: every field declared once, in `module_fields!`'s table,
//! with its Rust type, built-in default, file key, written form and check.
//!
//! From that table come the [`Module`] struct, the serde form of a `[[module]]` table (and
//! of `[defaults]`), the checks of every written value, and the resolution module field >
//! `[defaults]` > built-in default. A value is checked where it is written, so a bad
//! `[defaults]` value is an error even where every module overrides it.

use std::f64::consts::PI;
use std::fmt;
use std::ops::Range;

use nalgebra::{Matrix3, Vector3};
use serde::Deserialize;
use serde::de::{self, Deserializer, SeqAccess, Visitor};
use toml::Spanned;

use crate::limits::{self, Limit};
use crate::toml_file::{Checker, FileError};

/// Corner angles of the paper's hexagonal plate \[deg\].
const PAPER_CORNERS_DEG: [f64; 6] = [0.0, 60.0, 120.0, 180.0, 240.0, 300.0];
/// Tendon angles of the paper's module \[deg\].
const PAPER_TENDONS_DEG: [f64; 3] = [90.0, 210.0, 330.0];
/// Barrier margin of the paper's corners \[m\].
const PAPER_MARGIN: f64 = 0.005;
/// Two angles closer than this modulo 2π are the same direction \[rad\].
const ANGLE_TOLERANCE: f64 = 1e-9;
/// `det(A Aᵀ)` of the tendon matrix must exceed this times `(tr(A Aᵀ)/3)³`.
const RANK_TOLERANCE: f64 = 1e-12;

/// A checked value, where it was written and under which field path.
pub(crate) struct Val<T> {
    value: T,
    span: Range<usize>,
    field: String,
}

/// The checked type of a field: its Rust type, unless the table names another.
macro_rules! checked_type {
    ($ty:ty) => {
        $ty
    };
    ($ty:ty, $checked:ty) => {
        $checked
    };
}

/// The value of a field from its checked form: itself, or the table's resolution (which
/// may use the fields resolved before it).
macro_rules! resolved {
    ($checker:expr, $v:expr, $prefix:expr) => {
        $v.value.clone()
    };
    ($checker:expr, $v:expr, $prefix:expr, $resolve:expr) => {
        ($resolve)($checker, $v, $prefix)?
    };
}

/// Declares the fields of a module. One line per field:
///
/// `name: Type = built-in default, "file key": written form => check [, as Checked => resolution];`
///
/// A default may use the fields above it (the inertia follows the mass); the check turns
/// the written value into the checked one, with errors on its line; the resolution, when
/// given, turns a checked value into the field's value once the fields above are known.
macro_rules! module_fields {
    ($(
        $(#[doc = $doc:literal])*
        $name:ident: $ty:ty = $default:expr,
            $key:literal: $raw:ty => $check:expr $(, as $checked:ty => $resolve:expr)?;
    )*) => {
        /// One module: a PCC foam segment and the rigid plate on top of it. SI units.
        #[derive(Clone, Debug, PartialEq)]
        pub struct Module {
            $( $(#[doc = $doc])* pub $name: $ty, )*
        }

        /// One `[[module]]` table or `[defaults]` as serde reads it: each value with its
        /// byte span.
        #[derive(Default, Deserialize)]
        #[serde(deny_unknown_fields)]
        pub(crate) struct ModuleTable {
            $( #[serde(rename = $key)] $name: Option<Spanned<$raw>>, )*
            /// `[module.limits]`: this module's limits over the file's `[limits]`.
            pub(crate) limits: Option<Spanned<crate::barrier_tables::LimitsTable>>,
        }

        /// The fields written in one table, each checked on its own; `None` where not
        /// written.
        #[derive(Default)]
        pub(crate) struct Written {
            $( $name: Option<Val<checked_type!($ty $(, $checked)?)>>, )*
        }

        impl Checker<'_> {
            /// Checks every field written in one module table (or `[defaults]`, `prefix`).
            pub(crate) fn written(
                &self,
                table: &ModuleTable,
                prefix: &str,
            ) -> Result<Written, FileError> {
                Ok(Written {
                    $( $name: match &table.$name {
                        Some(v) => {
                            let field = format!("{prefix}.{}", $key);
                            let value = ($check)(self, v, &field)?;
                            Some(Val { value, span: v.span(), field })
                        }
                        None => None,
                    }, )*
                })
            }

            /// Resolves one module (`prefix`, for messages): its own field, else the one of
            /// `[defaults]`, else the built-in default.
            pub(crate) fn resolve(
                &self,
                own: &Written,
                defaults: &Written,
                prefix: &str,
            ) -> Result<Module, FileError> {
                $(
                    let $name: $ty = match own.$name.as_ref().or(defaults.$name.as_ref()) {
                        Some(v) => resolved!(self, v, prefix $(, $resolve)?),
                        None => $default,
                    };
                )*
                Ok(Module { $( $name ),* })
            }
        }

        impl Module {
            /// The paper's simulation module (§1 of the model notes): the built-in default
            /// of every field.
            pub fn paper() -> Module {
                $( let $name: $ty = $default; )*
                Module { $( $name ),* }
            }
        }
    };
}

module_fields! {
    /// `L0`: rest length of the backbone \[m\].
    rest_length: f64 = 0.1,
        "rest_length": f64 => number(&limits::LENGTH_M);
    /// `d`: radius from the backbone to the tendons, which defines θ \[m\].
    tendon_radius: f64 = 0.04,
        "tendon_radius": f64 => number(&limits::LENGTH_M);
    /// `r`: radius from the backbone to a plate corner \[m\].
    corner_radius: f64 = 0.05,
        "corner_radius": f64 => number(&limits::LENGTH_M);
    /// `φ_j`: angle of each plate corner from the module's x axis \[rad\] (file: degrees).
    corner_angles: Vec<f64> = radians(&PAPER_CORNERS_DEG),
        "corner_angles_deg": Vec<Spanned<f64>> => Checker::corner_angles;
    /// `ψ_k`: angle of each tendon from the module's x axis \[rad\] (file: degrees).
    tendon_angles: Vec<f64> = radians(&PAPER_TENDONS_DEG),
        "tendon_angles_deg": Vec<Spanned<f64>> => Checker::tendon_angles;
    /// `m`: mass lumped in the top plate \[kg\].
    mass: f64 = 0.15,
        "mass": f64 => number(&limits::MASS_KG);
    /// Principal inertia of the plate about its centre of mass, plate axes \[kg·m²\]
    /// (default: a uniform thin plate of the module's polygon, [`polygon_inertia`]).
    inertia: [f64; 3] = polygon_inertia(mass, corner_radius, corner_angles.len()),
        "inertia": Vec<Spanned<f64>> => Checker::inertia;
    /// Offset of the centre of mass along the plate normal (tip-frame z) \[m\].
    com_offset: f64 = 0.0,
        "com_offset": f64 => number(&limits::COM_OFFSET_M);
    /// `κθ`: bending stiffness \[N·m/rad\].
    bending_stiffness: f64 = 10.0,
        "bending_stiffness": f64 => number(&limits::BENDING_STIFFNESS);
    /// `κL`: axial stiffness \[N/m\].
    axial_stiffness: f64 = 10.0,
        "axial_stiffness": f64 => number(&limits::AXIAL_STIFFNESS);
    /// `βθ`: bending damping \[N·m·s/rad\].
    bending_damping: f64 = 5.0,
        "bending_damping": f64 => number(&limits::BENDING_DAMPING);
    /// `βL`: axial damping \[N·s/m\].
    axial_damping: f64 = 5.0,
        "axial_damping": f64 => number(&limits::AXIAL_DAMPING);
    /// This module's own fractions of uncertainty (`uncertainty = { bending_stiffness = 0.02,
    /// … }`), over the robot's `[uncertainty]`; see [`crate::robot::Robot::module_box`].
    uncertainty: crate::uncertainty_box::ModuleUncertainty = Default::default(),
        "uncertainty": crate::uncertainty_box::ModuleUncertaintyTable =>
            Checker::module_uncertainty;
    /// `ε_j`: barrier margin of each corner \[m\] (same length as `corner_angles`; the
    /// file gives one number for all corners or one per corner).
    margins: Vec<f64> = vec![PAPER_MARGIN; corner_angles.len()],
        "margin": RawMargin => Checker::margin,
        as Margin => |c: &Checker, v: &Val<Margin>, prefix: &str| {
            c.margins(v, corner_angles.len(), prefix)
        };
}

/// Principal inertia `[Ixx, Iyy, Izz]` \[kg·m²\] of a uniform thin regular polygon plate of
/// mass `mass` \[kg\] with `corners` corners at radius `corner_radius` \[m\], about its centre:
/// `Izz = m r²/6 · (1 + 2 cos²(π/n))`, `Ixx = Iyy = Izz/2` (hexagon: `diag(5/24, 5/24, 5/12)·m r²`).
pub fn polygon_inertia(mass: f64, corner_radius: f64, corners: usize) -> [f64; 3] {
    let cos = (PI / corners as f64).cos();
    let izz = mass * corner_radius * corner_radius / 6.0 * (1.0 + 2.0 * cos * cos);
    [izz / 2.0, izz / 2.0, izz]
}

fn radians(degrees: &[f64]) -> Vec<f64> {
    degrees.iter().map(|a| a.to_radians()).collect()
}

/// The check of one number against `limit`.
fn number(
    limit: &'static Limit,
) -> impl Fn(&Checker<'_>, &Spanned<f64>, &str) -> Result<f64, FileError> {
    move |checker, v, field| checker.within(v, field, limit)
}

/// What a list of angles gives the directions of.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Directions {
    Corner,
    Tendon,
}

/// `margin` as written: one number for all corners, or one per corner.
pub(crate) enum RawMargin {
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

/// A checked margin: one for every corner, or one per corner.
#[derive(Clone)]
pub(crate) enum Margin {
    All(f64),
    Each(Vec<f64>),
}

/// A list of directions as written in a file: its entries with their spans.
type Angles = Spanned<Vec<Spanned<f64>>>;

impl Checker<'_> {
    fn corner_angles(&self, v: &Angles, field: &str) -> Result<Vec<f64>, FileError> {
        self.angles(v, field, Directions::Corner)
    }

    fn tendon_angles(&self, v: &Angles, field: &str) -> Result<Vec<f64>, FileError> {
        self.angles(v, field, Directions::Tendon)
    }

    /// Corner or tendon angles: finite degrees, at least 3, distinct modulo 360°; for
    /// tendons also a full-rank tendon matrix. Returns radians.
    fn angles(
        &self,
        v: &Spanned<Vec<Spanned<f64>>>,
        field: &str,
        what: Directions,
    ) -> Result<Vec<f64>, FileError> {
        let name = match what {
            Directions::Corner => "corner",
            Directions::Tendon => "tendon",
        };
        let degrees = self.list_within(v.get_ref(), field, &limits::ANGLE_DEG)?;
        if degrees.len() < 3 {
            return Err(self.invalid(
                &v.span(),
                field,
                format!("needs at least 3 {name}s, got {}", degrees.len()),
            ));
        }
        let radians = radians(&degrees);
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
                        "entry {} ({}°) is the same direction as entry {} ({}°); {name} angles \
                         must be distinct modulo 360°",
                        second + 1,
                        degrees[second],
                        first + 1,
                        degrees[first]
                    ),
                ));
            }
        }
        if what == Directions::Tendon {
            // Gram matrix G = A Aᵀ of the 3×N tendon matrix with columns (cos ψ, sin ψ, −1).
            let gram: Matrix3<f64> = radians
                .iter()
                .map(|psi| {
                    let column = Vector3::new(psi.cos(), psi.sin(), -1.0);
                    column * column.transpose()
                })
                .sum();
            let det = gram.determinant();
            let scale = (gram.trace() / 3.0).powi(3);
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
    fn inertia(&self, v: &Spanned<Vec<Spanned<f64>>>, field: &str) -> Result<[f64; 3], FileError> {
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

    /// A margin as written: each value within [`limits::MARGIN_M`].
    fn margin(&self, v: &Spanned<RawMargin>, field: &str) -> Result<Margin, FileError> {
        Ok(match v.get_ref() {
            RawMargin::All(e) => {
                Margin::All(self.limited(*e, &v.span(), field, "", &limits::MARGIN_M)?)
            }
            RawMargin::Each(each) => {
                Margin::Each(self.list_within(each, field, &limits::MARGIN_M)?)
            }
        })
    }

    /// The margins of a module (`prefix`) with `corners` corners: one number for all, or
    /// exactly one per corner.
    fn margins(
        &self,
        v: &Val<Margin>,
        corners: usize,
        prefix: &str,
    ) -> Result<Vec<f64>, FileError> {
        match &v.value {
            Margin::All(e) => Ok(vec![*e; corners]),
            Margin::Each(each) if each.len() == corners => Ok(each.clone()),
            Margin::Each(each) => Err(self.invalid(
                &v.span,
                &v.field,
                format!(
                    "has {} entries but {prefix} has {corners} corners; give one margin per \
                     corner, or a single number for all",
                    each.len()
                ),
            )),
        }
    }
}
