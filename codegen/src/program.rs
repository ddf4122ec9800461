//! Common-subexpression elimination: turns output nodes into a straight-line program.
//! Hash-consing already shares equal subtrees; this orders every needed node once.

use std::collections::BTreeMap;

use crate::expr::{Analytic, Arena, Id, Node};

/// A straight-line program computing some outputs: each step is evaluated once.
#[derive(Clone, Debug)]
pub struct Program {
    /// Nodes to evaluate, children before parents (constants and symbols excluded).
    pub steps: Vec<Id>,
    /// The outputs, in the caller's order.
    pub outputs: Vec<Id>,
    /// For each argument of an analytic node, the highest derivative order used.
    pub analytic_orders: BTreeMap<Id, u8>,
}

/// Operation counts of a program, printed in generated file headers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct OpCount {
    /// Additions, subtractions and negations.
    pub add: usize,
    /// Multiplications (including those of small integer powers).
    pub mul: usize,
    /// Divisions.
    pub div: usize,
    /// Square roots, sines, cosines and general powers.
    pub special: usize,
    /// Evaluations of the analytic functions (one per distinct argument).
    pub analytic: usize,
}

impl OpCount {
    /// Sum of two counts.
    pub fn plus(self, other: OpCount) -> OpCount {
        OpCount {
            add: self.add + other.add,
            mul: self.mul + other.mul,
            div: self.div + other.div,
            special: self.special + other.special,
            analytic: self.analytic + other.analytic,
        }
    }

    /// Total number of operations.
    pub fn total(self) -> usize {
        self.add + self.mul + self.div + self.special + self.analytic
    }
}

/// Collects every node the outputs need, in an order where children come first.
pub fn schedule(arena: &Arena, outputs: &[Id]) -> Program {
    let mut needed = vec![false; arena.len()];
    let mut stack: Vec<Id> = outputs.to_vec();
    while let Some(id) = stack.pop() {
        if needed[id.index()] {
            continue;
        }
        needed[id.index()] = true;
        stack.extend(arena.node(id).children());
    }
    // Children have smaller ids than parents, so increasing id order is topological.
    let mut steps = Vec::new();
    let mut analytic_orders = BTreeMap::new();
    for (index, &is_needed) in needed.iter().enumerate() {
        if !is_needed {
            continue;
        }
        let id = Id(index as u32);
        match arena.node(id) {
            Node::Const(_) | Node::Symbol(_) => {}
            Node::Analytic { order, arg, .. } => {
                let entry = analytic_orders.entry(arg).or_insert(order);
                *entry = (*entry).max(order);
                steps.push(id);
            }
            _ => steps.push(id),
        }
    }
    Program {
        steps,
        outputs: outputs.to_vec(),
        analytic_orders,
    }
}

/// Counts the arithmetic a program performs.
pub fn op_count(arena: &Arena, program: &Program) -> OpCount {
    let mut count = OpCount {
        analytic: program.analytic_orders.len(),
        ..OpCount::default()
    };
    for &id in &program.steps {
        match arena.node(id) {
            Node::Add(..) | Node::Neg(_) => count.add += 1,
            Node::Mul(..) => count.mul += 1,
            Node::Div(..) => count.div += 1,
            Node::Powi(_, n) if (2..=4).contains(&n) => count.mul += (n - 1) as usize,
            Node::Powi(..) | Node::Sqrt(_) | Node::Sin(_) | Node::Cos(_) => count.special += 1,
            Node::Analytic { .. } | Node::Const(_) | Node::Symbol(_) => {}
        }
    }
    count
}

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
        4 => {
            let x2 = x * x;
            x2 * x2
        }
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

/// A plain f64 evaluation of the analytic functions by their power series, for tests of
/// the engine (the emitted code has its own, checked evaluation).
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
