//! Plain f64 evaluators of the code generator's expressions, for the engine's tests:
//! a tree walk without sharing, a step-by-step run of a scheduled program, and a series.

use softcbf_codegen::expr::{Analytic, Arena, Id, Node};
use softcbf_codegen::program::Program;

/// How the evaluators below compute the analytic functions.
pub type AnalyticFn = fn(Analytic, u8, f64) -> f64;

fn apply(node: Node, value: impl Fn(Id) -> f64, symbols: &[f64], analytic: AnalyticFn) -> f64 {
    match node {
        Node::Const(bits) => f64::from_bits(bits),
        Node::Symbol(s) => symbols[s as usize],
        Node::Add(a, b) => value(a) + value(b),
        Node::Mul(a, b) => value(a) * value(b),
        Node::Neg(a) => -value(a),
        Node::Div(a, b) => value(a) / value(b),
        Node::Powi(a, n) => powi_as_emitted(value(a), n),
        Node::Sqrt(a) => value(a).sqrt(),
        Node::Sin(a) => value(a).sin(),
        Node::Cos(a) => value(a).cos(),
        Node::Analytic { func, order, arg } => analytic(func, order, value(arg)),
    }
}

/// `x^n` computed exactly as the emitted code computes it.
pub fn powi_as_emitted(x: f64, n: i32) -> f64 {
    match n {
        2 => x * x,
        3 => x * x * x,
        4 => (x * x) * (x * x),
        -1 => 1.0 / x,
        _ => x.powi(n),
    }
}

/// Evaluates one node by walking its tree without any sharing (a reference for CSE tests;
/// exponential on shared graphs, so only for small expressions).
pub fn eval_tree(arena: &Arena, id: Id, symbols: &[f64], analytic: AnalyticFn) -> f64 {
    apply(
        arena.node(id),
        |child| eval_tree(arena, child, symbols, analytic),
        symbols,
        analytic,
    )
}

/// Evaluates a program step by step, each node once, and returns its outputs.
pub fn eval_program(
    arena: &Arena,
    program: &Program,
    symbols: &[f64],
    analytic: AnalyticFn,
) -> Vec<f64> {
    let mut values = vec![f64::NAN; arena.len()];
    let leaf = |id: Id, values: &[f64]| match arena.node(id) {
        Node::Const(bits) => f64::from_bits(bits),
        Node::Symbol(s) => symbols[s as usize],
        _ => values[id.index()],
    };
    for &id in &program.steps {
        let v = apply(arena.node(id), |c| leaf(c, &values), symbols, analytic);
        values[id.index()] = v;
    }
    program.outputs.iter().map(|&o| leaf(o, &values)).collect()
}

/// The analytic functions by their power series in plain f64 (the emitted code has its
/// own, separately checked evaluation).
pub fn analytic_by_series(func: Analytic, order: u8, u: f64) -> f64 {
    // k-th derivative of Σ_n a_n u^n with a_n = (−1)^n / (2n+1)! (f_s) or (2n+2)! (f_c).
    let shift = match func {
        Analytic::Fs => 1,
        Analytic::Fc => 2,
    };
    let k = u32::from(order);
    let mut total = 0.0;
    let mut power = 1.0;
    for n in 0..80u32 {
        let m = n + k; // index of the coefficient differentiated k times
        let mut coefficient = if m % 2 == 0 { 1.0 } else { -1.0 };
        for i in 1..=(2 * m + shift) {
            coefficient /= f64::from(i);
        }
        for i in (n + 1)..=m {
            coefficient *= f64::from(i);
        }
        total += coefficient * power;
        power *= u;
    }
    total
}
