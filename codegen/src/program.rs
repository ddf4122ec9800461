//! Common-subexpression elimination: turns output nodes into a straight-line program.
//! Hash-consing already shares equal subtrees; this orders every needed node once.

use std::collections::{BTreeMap, BTreeSet};

use crate::expr::{Arena, Id, Node};

/// A straight-line program computing some outputs: each step is evaluated once.
#[derive(Clone, Debug)]
pub struct Program {
    /// Nodes to evaluate, children before parents (constants and symbols excluded).
    pub steps: Vec<Id>,
    /// The outputs, in the caller's order.
    pub outputs: Vec<Id>,
    /// For each argument of an analytic node, the highest derivative order used.
    pub analytic_orders: BTreeMap<Id, u8>,
    /// How often each step is read: as an operand of another step or as an output.
    pub uses: BTreeMap<Id, usize>,
    /// Negations read only as operands of sums: they are emitted as subtractions inside
    /// those sums, never computed on their own.
    pub absorbed: BTreeSet<Id>,
}

/// Operation counts of a program, printed in generated file headers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct OpCount {
    /// Additions, subtractions and the negations computed on their own.
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

    let is_step = |id: Id| !matches!(arena.node(id), Node::Const(_) | Node::Symbol(_));
    let mut uses = BTreeMap::new();
    let mut outside_sums = BTreeSet::new();
    for &id in &steps {
        let in_sum = matches!(arena.node(id), Node::Add(..));
        for child in arena.node(id).children().filter(|&c| is_step(c)) {
            *uses.entry(child).or_insert(0) += 1;
            if !in_sum {
                outside_sums.insert(child);
            }
        }
    }
    for &id in outputs.iter().filter(|&&id| is_step(id)) {
        *uses.entry(id).or_insert(0) += 1;
        outside_sums.insert(id);
    }
    let absorbed = steps
        .iter()
        .copied()
        .filter(|&id| matches!(arena.node(id), Node::Neg(_)) && !outside_sums.contains(&id))
        .collect();
    Program {
        steps,
        outputs: outputs.to_vec(),
        analytic_orders,
        uses,
        absorbed,
    }
}

/// Counts the arithmetic a program performs as emitted: a subtraction is one addition,
/// a negation absorbed into a sum costs nothing.
pub fn op_count(arena: &Arena, program: &Program) -> OpCount {
    let mut count = OpCount {
        analytic: program.analytic_orders.len(),
        ..OpCount::default()
    };
    for &id in &program.steps {
        if program.absorbed.contains(&id) {
            continue;
        }
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
