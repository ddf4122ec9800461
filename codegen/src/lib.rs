//! softcbf-codegen: turns a robot's structure into the Rust source of its model.
//!
//! A small symbolic engine: a flat hash-consed [`expr::Arena`] whose constructors simplify,
//! [`diff::Differentiator`] for derivatives of any order, [`program::schedule`] for common
//! subexpressions, and [`emit`] writing Rust through syn/quote/prettyplease. The analytic
//! functions `f_s`, `f_c` of docs/model.md §2 and their derivatives are nodes of their own,
//! evaluated by [`analytic`]'s series-or-closed-form code. [`model`] builds the PCC
//! kinematics, barriers and joint terms of a robot's `Structure` and [`source`] emits them; [`eval`] runs the same
//! programs on f64 at run time (the interpreter of a structure that was not compiled in). Robot files and the
//! parameter layout are `softcbf-description`'s: the generator reads structures only.
//!
//! ```
//! use softcbf_codegen::{expr::Arena, diff::Differentiator};
//! let mut arena = Arena::new();
//! let x = arena.symbol("x");
//! let sin_x = arena.sin(x);
//! let mut diff = Differentiator::new();
//! let derivative = diff.derivative(&mut arena, sin_x, x);
//! assert_eq!(derivative, arena.cos(x));
//! ```

pub mod analytic;
pub mod diff;
pub mod emit;
pub mod eval;
pub mod expr;
pub mod model;
pub mod program;
pub mod registry;
pub mod sexpr;
pub mod source;

pub use source::{GeneratedSource, generate};
// The modules of the description that generation reads, under their old paths inside this
// crate (`crate::robot::Structure`, `crate::layout::param_layout`, `crate::barriers`).
use softcbf_description::{barriers, layout, robot};
