//! A scheduled program evaluated on f64 (or on intervals) at run time: what the interpreter
//! of the generated model runs when a structure was not compiled in, step for step as the
//! emitted code.
//!
//! [`Compiled`] flattens a [`crate::program::schedule`] into numbered value slots once; each
//! evaluation then copies the constants and inputs into a caller's buffer and runs the
//! steps in order. Every step is the operation the emitted code performs (`x²` as `x * x`,
//! `x⁻¹` as `1.0 / x`, `f_s`, `f_c` by [`crate::analytic::evaluate`]), and the emitter's
//! rewrites are exact (`a + (−b)` is `a − b`), so the results are the emitted code's bits.

use std::collections::HashMap;
use std::ops::{Add, Div, Mul, Neg};

use softcbf_interval::{Dual, Interval};

use crate::analytic;
use crate::expr::{Analytic, Arena, Id, Node};
use crate::program::schedule;

/// A number type a program runs on: `f64` (the emitted code's bits) or [`Interval`]
/// (enclosures, as the emitted `*_interval` functions compute them).
pub trait Value:
    Copy + From<f64> + Add<Output = Self> + Mul<Output = Self> + Div<Output = Self> + Neg<Output = Self>
{
    /// `√x`.
    fn sqrt(self) -> Self;
    /// `sin x`.
    fn sin(self) -> Self;
    /// `cos x`.
    fn cos(self) -> Self;
    /// `x^n` for the exponents the emitter writes as a call.
    fn powi(self, n: i32) -> Self;
    /// `f_s`, `f_c` and their derivatives up to `order` at `u` (entries past `order` unused).
    fn analytic(
        order: usize,
        u: Self,
    ) -> (
        [Self; analytic::MAX_ORDER + 1],
        [Self; analytic::MAX_ORDER + 1],
    );
}

impl Value for f64 {
    fn sqrt(self) -> f64 {
        f64::sqrt(self)
    }
    fn sin(self) -> f64 {
        f64::sin(self)
    }
    fn cos(self) -> f64 {
        f64::cos(self)
    }
    fn powi(self, n: i32) -> f64 {
        f64::powi(self, n)
    }
    fn analytic(
        order: usize,
        u: f64,
    ) -> (
        [f64; analytic::MAX_ORDER + 1],
        [f64; analytic::MAX_ORDER + 1],
    ) {
        analytic::evaluate(order, u)
    }
}

impl Value for Interval {
    fn sqrt(self) -> Interval {
        Interval::sqrt(self)
    }
    fn sin(self) -> Interval {
        Interval::sin(self)
    }
    fn cos(self) -> Interval {
        Interval::cos(self)
    }
    fn powi(self, n: i32) -> Interval {
        Interval::powi(self, n)
    }
    fn analytic(
        order: usize,
        u: Interval,
    ) -> (
        [Interval; analytic::MAX_ORDER + 1],
        [Interval; analytic::MAX_ORDER + 1],
    ) {
        analytic::evaluate_interval(order, u)
    }
}

impl Value for Dual {
    fn sqrt(self) -> Dual {
        Dual::sqrt(self)
    }
    fn sin(self) -> Dual {
        Dual::sin(self)
    }
    fn cos(self) -> Dual {
        Dual::cos(self)
    }
    fn powi(self, n: i32) -> Dual {
        Dual::powi(self, n)
    }
    fn analytic(
        order: usize,
        u: Dual,
    ) -> (
        [Dual; analytic::MAX_ORDER + 1],
        [Dual; analytic::MAX_ORDER + 1],
    ) {
        analytic::evaluate_dual(order, u)
    }
}

/// One step: an operation on value slots, its result written at `dst`.
#[derive(Clone, Copy, Debug)]
enum Op {
    Add(u32, u32),
    Mul(u32, u32),
    Neg(u32),
    Div(u32, u32),
    Powi(u32, i32),
    Sqrt(u32),
    Sin(u32),
    Cos(u32),
    /// `f_s^(0..=order)` at `dst..`, then `f_c^(0..=order)`.
    Analytic(u32, u8),
}

/// A straight-line program ready to run on f64: constants, inputs and steps in slots.
#[derive(Clone, Debug)]
pub struct Compiled {
    /// The constants' values: slots `0..constants.len()`.
    constants: Vec<f64>,
    /// Number of input slots, after the constants.
    inputs: usize,
    /// The steps, each with its destination slot.
    steps: Vec<(Op, u32)>,
    /// The slot of each output.
    outputs: Vec<u32>,
    /// Slots in all.
    slots: usize,
}

impl Compiled {
    /// Schedules `outputs` of `arena` with `inputs` the symbols bound, in order, to the
    /// values [`Compiled::run`] is given.
    ///
    /// # Panics
    ///
    /// If an output reads a symbol that is not among `inputs` (a programming error, as in
    /// the emitter), or an analytic function above [`analytic::MAX_ORDER`].
    pub fn new(arena: &Arena, inputs: &[Id], outputs: &[Id]) -> Compiled {
        let program = schedule(arena, outputs);
        let mut slot: HashMap<Id, u32> = HashMap::new();
        let mut constants = Vec::new();
        let needed = |id: Id, slot: &mut HashMap<Id, u32>, constants: &mut Vec<f64>| {
            if let Node::Const(bits) = arena.node(id)
                && !slot.contains_key(&id)
            {
                slot.insert(id, constants.len() as u32);
                constants.push(f64::from_bits(bits));
            }
        };
        for &id in program.steps.iter().chain(outputs) {
            needed(id, &mut slot, &mut constants);
            for child in arena.node(id).children() {
                needed(child, &mut slot, &mut constants);
            }
        }
        let mut next = constants.len() as u32;
        for &input in inputs {
            assert!(
                matches!(arena.node(input), Node::Symbol(_)),
                "inputs are symbols"
            );
            slot.insert(input, next);
            next += 1;
        }
        let mut steps = Vec::with_capacity(program.steps.len());
        let mut analytic_base: HashMap<Id, u32> = HashMap::new();
        for &id in &program.steps {
            let node = arena.node(id);
            let read = |child: Id| -> u32 {
                *slot.get(&child).unwrap_or_else(|| match arena.node(child) {
                    Node::Symbol(s) => {
                        panic!("symbol `{}` has no input binding", arena.symbol_name(s))
                    }
                    other => panic!("{other:?} read before it is computed"),
                })
            };
            let op = match node {
                Node::Add(a, b) => Op::Add(read(a), read(b)),
                Node::Mul(a, b) => Op::Mul(read(a), read(b)),
                Node::Neg(a) => Op::Neg(read(a)),
                Node::Div(a, b) => Op::Div(read(a), read(b)),
                Node::Powi(a, n) => Op::Powi(read(a), n),
                Node::Sqrt(a) => Op::Sqrt(read(a)),
                Node::Sin(a) => Op::Sin(read(a)),
                Node::Cos(a) => Op::Cos(read(a)),
                Node::Analytic { func, order, arg } => {
                    let max = program.analytic_orders[&arg];
                    let base = match analytic_base.get(&arg) {
                        Some(&base) => base,
                        None => {
                            assert!(
                                usize::from(max) <= analytic::MAX_ORDER,
                                "analytic order {max} above {}",
                                analytic::MAX_ORDER
                            );
                            let base = next;
                            steps.push((Op::Analytic(read(arg), max), base));
                            next += 2 * (u32::from(max) + 1);
                            analytic_base.insert(arg, base);
                            base
                        }
                    };
                    let offset = match func {
                        Analytic::Fs => 0,
                        Analytic::Fc => u32::from(max) + 1,
                    };
                    slot.insert(id, base + offset + u32::from(order));
                    continue;
                }
                Node::Const(_) | Node::Symbol(_) => unreachable!("not scheduled as steps"),
            };
            steps.push((op, next));
            slot.insert(id, next);
            next += 1;
        }
        let outputs = outputs
            .iter()
            .map(|id| match slot.get(id) {
                Some(&s) => s,
                None => panic!("output {id:?} reads a symbol without an input binding"),
            })
            .collect();
        Compiled {
            inputs: inputs.len(),
            constants,
            steps,
            outputs,
            slots: next as usize,
        }
    }

    /// The length of the value buffer [`Compiled::run`] needs.
    pub fn slots(&self) -> usize {
        self.slots
    }

    /// Number of outputs.
    pub fn outputs(&self) -> usize {
        self.outputs.len()
    }

    /// Number of steps (an analytic evaluation counts once).
    pub fn steps(&self) -> usize {
        self.steps.len()
    }

    /// Runs the program: `inputs`, concatenated, are the values of the input symbols in
    /// the order given to [`Compiled::new`]; `values` (at least [`Compiled::slots`] long)
    /// receives every slot. Read the outputs with [`Compiled::output`]. Allocates nothing.
    ///
    /// # Panics
    ///
    /// If the inputs do not add up to the number of input symbols or `values` is short.
    pub fn run<T: Value>(&self, inputs: &[&[T]], values: &mut [T]) {
        let values = &mut values[..self.slots];
        let (constants, rest) = values.split_at_mut(self.constants.len());
        for (slot, &c) in constants.iter_mut().zip(&self.constants) {
            *slot = T::from(c);
        }
        let mut at = 0;
        for group in inputs {
            rest[at..at + group.len()].copy_from_slice(group);
            at += group.len();
        }
        assert_eq!(at, self.inputs, "input values");
        for &(op, dst) in &self.steps {
            let v = |s: u32| values[s as usize];
            let result = match op {
                Op::Add(a, b) => v(a) + v(b),
                Op::Mul(a, b) => v(a) * v(b),
                Op::Neg(a) => -v(a),
                Op::Div(a, b) => v(a) / v(b),
                Op::Powi(a, n) => {
                    let x = v(a);
                    match n {
                        2 => x * x,
                        3 => x * x * x,
                        4 => (x * x) * (x * x),
                        -1 => T::from(1.0) / x,
                        _ => x.powi(n),
                    }
                }
                Op::Sqrt(a) => v(a).sqrt(),
                Op::Sin(a) => v(a).sin(),
                Op::Cos(a) => v(a).cos(),
                Op::Analytic(arg, order) => {
                    let order = usize::from(order);
                    let (fs, fc) = T::analytic(order, v(arg));
                    let dst = dst as usize;
                    values[dst..=dst + order].copy_from_slice(&fs[..=order]);
                    values[dst + order + 1..=dst + 2 * order + 1].copy_from_slice(&fc[..=order]);
                    continue;
                }
            };
            values[dst as usize] = result;
        }
    }

    /// Output `k` after [`Compiled::run`] filled `values`.
    pub fn output<T: Copy>(&self, values: &[T], k: usize) -> T {
        values[self.outputs[k] as usize]
    }

    /// Every output in order after [`Compiled::run`] filled `values`.
    pub fn output_values<'a, T: Copy>(&'a self, values: &'a [T]) -> impl Iterator<Item = T> + 'a {
        self.outputs.iter().map(|&s| values[s as usize])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn evaluates_a_small_program() {
        let mut arena = Arena::new();
        let x = arena.symbol("x");
        let y = arena.symbol("y");
        let x2 = arena.powi(x, 2);
        let s = arena.sin(y);
        let sum = arena.add(x2, s);
        let half = arena.constant(0.5);
        let scaled = arena.mul(half, sum);
        let fs = arena.fs(x);
        let fc1 = arena.analytic(Analytic::Fc, 1, x);
        let compiled = Compiled::new(&arena, &[x, y], &[scaled, fs, fc1, half]);
        let mut values = vec![0.0; compiled.slots()];
        compiled.run(&[&[2.0], &[0.25]], &mut values);
        let out: Vec<f64> = compiled.output_values(&values).collect();
        assert_eq!(out[0], 0.5 * (2.0 * 2.0 + 0.25f64.sin()));
        let (fs_ref, fc_ref) = analytic::evaluate(1, 2.0);
        assert_eq!(out[1], fs_ref[0]);
        assert_eq!(out[2], fc_ref[1]);
        assert_eq!(out[3], 0.5);
        assert_eq!(compiled.outputs(), 4);
    }

    #[test]
    #[should_panic(expected = "no input binding")]
    fn an_unbound_symbol_is_refused() {
        let mut arena = Arena::new();
        let x = arena.symbol("x");
        let y = arena.symbol("y");
        let sum = arena.add(x, y);
        Compiled::new(&arena, &[x], &[sum]);
    }
}
