//! Symbolic differentiation: partial derivatives with respect to a symbol, and forward-mode
//! time derivatives (tangents). Both memoize per node, so derivatives of shared
//! subexpressions stay shared and derivatives of derivatives are cheap.

use std::collections::HashMap;

use crate::expr::{Arena, Id, Node};

/// Applies the chain rule to every node below `expr` (iteratively, children first) and
/// returns the derivative of `expr`. `memo` holds derivatives already known; `leaf` gives
/// the derivative of a symbol.
fn propagate(
    arena: &mut Arena,
    expr: Id,
    memo: &mut HashMap<Id, Id>,
    leaf: &dyn Fn(&mut Arena, Id) -> Id,
) -> Id {
    let mut stack = vec![(expr, false)];
    while let Some((id, children_done)) = stack.pop() {
        if memo.contains_key(&id) {
            continue;
        }
        let node = arena.node(id);
        if !children_done {
            stack.push((id, true));
            stack.extend(
                node.children()
                    .filter(|c| !memo.contains_key(c))
                    .map(|c| (c, false)),
            );
            continue;
        }
        let d = |child: Id| memo[&child];
        let result = match node {
            Node::Const(_) => arena.constant(0.0),
            Node::Symbol(_) => leaf(arena, id),
            Node::Add(a, b) => arena.add(d(a), d(b)),
            Node::Mul(a, b) => {
                let left = arena.mul(d(a), b);
                let right = arena.mul(a, d(b));
                arena.add(left, right)
            }
            Node::Neg(a) => arena.neg(d(a)),
            Node::Div(a, b) => {
                // (a/b)' = (a' − (a/b)·b') / b, reusing the quotient node.
                let scaled = arena.mul(id, d(b));
                let numerator = arena.sub(d(a), scaled);
                arena.div(numerator, b)
            }
            Node::Powi(a, n) => {
                let coefficient = arena.constant(f64::from(n));
                let power = arena.powi(a, n - 1);
                let outer = arena.mul(coefficient, power);
                arena.mul(outer, d(a))
            }
            Node::Sqrt(a) => {
                // (√a)' = a' / (2√a)
                let two = arena.constant(2.0);
                let denominator = arena.mul(two, id);
                arena.div(d(a), denominator)
            }
            Node::Sin(a) => {
                let cos = arena.cos(a);
                arena.mul(cos, d(a))
            }
            Node::Cos(a) => {
                let sin = arena.sin(a);
                let product = arena.mul(sin, d(a));
                arena.neg(product)
            }
            Node::Analytic { func, order, arg } => {
                let next = arena.analytic(func, order + 1, arg);
                arena.mul(next, d(arg))
            }
        };
        memo.insert(id, result);
    }
    memo[&expr]
}

/// Partial derivatives; keeps one memo per symbol, so reuse one across calls on an arena.
#[derive(Clone, Debug, Default)]
pub struct Differentiator {
    memo: HashMap<Id, HashMap<Id, Id>>,
}

impl Differentiator {
    /// An empty memo.
    pub fn new() -> Differentiator {
        Differentiator::default()
    }

    /// `∂expr/∂symbol`, where `symbol` is a node made by [`Arena::symbol`].
    pub fn derivative(&mut self, arena: &mut Arena, expr: Id, symbol: Id) -> Id {
        assert!(
            matches!(arena.node(symbol), Node::Symbol(_)),
            "derivative with respect to a non-symbol"
        );
        let memo = self.memo.entry(symbol).or_default();
        let leaf =
            move |arena: &mut Arena, s: Id| arena.constant(if s == symbol { 1.0 } else { 0.0 });
        propagate(arena, expr, memo, &leaf)
    }

    /// The gradient of `expr` with respect to each symbol in `symbols`.
    pub fn gradient(&mut self, arena: &mut Arena, expr: Id, symbols: &[Id]) -> Vec<Id> {
        symbols
            .iter()
            .map(|&s| self.derivative(arena, expr, s))
            .collect()
    }
}

/// Forward-mode time derivative: every symbol has a rate (another node, often a velocity
/// symbol; symbols without one are constant in time).
#[derive(Clone, Debug, Default)]
pub struct Tangent {
    rates: HashMap<Id, Id>,
    memo: HashMap<Id, Id>,
}

impl Tangent {
    /// No rates yet: every symbol is constant.
    pub fn new() -> Tangent {
        Tangent::default()
    }

    /// Declares `d(symbol)/dt = rate`. Must be called before any [`Tangent::tangent`].
    pub fn set_rate(&mut self, symbol: Id, rate: Id) {
        assert!(
            self.memo.is_empty(),
            "rates changed after derivatives were taken"
        );
        self.rates.insert(symbol, rate);
    }

    /// `d(expr)/dt`.
    pub fn tangent(&mut self, arena: &mut Arena, expr: Id) -> Id {
        let rates = &self.rates;
        let leaf = |arena: &mut Arena, s: Id| match rates.get(&s) {
            Some(&rate) => rate,
            None => arena.constant(0.0),
        };
        propagate(arena, expr, &mut self.memo, &leaf)
    }
}
