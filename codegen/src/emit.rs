//! Emission of straight-line programs as Rust functions through syn/quote/prettyplease.
//! Temporaries are numbered in program order; small single-use terms are written inline.
//!
//! Every rewrite here leaves the computed numbers bit for bit as the program says:
//! `a + (−b)` is written `a − b`, `−(a·b)` as `−a * b`, and the operands of one sum or
//! product may swap (both exact in IEEE arithmetic); inlining never reorders roundings.

use std::collections::{BTreeMap, BTreeSet};

use proc_macro2::{Ident, Literal, Span, TokenStream};
use quote::{format_ident, quote};

use crate::analytic;
use crate::expr::{Analytic, Arena, Id, Node};
use crate::program::{OpCount, Program, op_count, schedule};

/// Most operations one emitted statement may hold once single-use terms are inlined.
const STATEMENT_OPS: usize = 4;

/// A function to emit: inputs bound to symbols, outputs written to places.
pub struct FunctionSpec {
    /// Function name.
    pub name: Ident,
    /// Doc comment (one paragraph per line).
    pub doc: Vec<String>,
    /// The argument list, e.g. `p: &[f64; 21], q: &[f64; 6], out: &mut [f64; 12]`.
    pub args: TokenStream,
    /// Where each symbol's value comes from, e.g. `(dx_0, quote!(q[0]))`.
    pub inputs: Vec<(Id, TokenStream)>,
    /// Each output: the place written (e.g. `out[3]`) and the node whose value goes there.
    pub outputs: Vec<(TokenStream, Id)>,
    /// Statements run after the outputs are written.
    pub epilogue: TokenStream,
    /// The number type the function computes in.
    pub scalar: Scalar,
}

/// The number type of an emitted function.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scalar {
    /// `f64` throughout (every temporary typed `f64`).
    F64,
    /// Enclosures: inputs bound from interval arrays (`softcbf_interval::Interval`) stay
    /// intervals, parameters stay `f64`, temporaries take the type their operands give
    /// (the interval operators accept `f64` on either side), `f_s`, `f_c` come from the
    /// `pcc_fs_fc_<k>_interval` enclosures and every output is written as an interval.
    /// Encloses the `f64` function's exact value over any point of the input boxes.
    Interval,
    /// Jets of intervals (`softcbf_interval::Dual`): as [`Scalar::Interval`], and each value
    /// carries an enclosure of its derivative along the direction the inputs' slopes give
    /// (`pcc_fs_fc_<k>_dual`, outputs written as jets).
    Dual,
}

/// An emitted function with its operation count and the analytic orders it calls.
pub struct Emitted {
    /// The function item.
    pub tokens: TokenStream,
    /// Arithmetic performed by one call.
    pub ops: OpCount,
    /// Orders `K` of the `pcc_fs_fc_K` functions it calls.
    pub analytic_orders: BTreeSet<usize>,
}

/// A floating-point literal written so that it parses back to exactly `value`.
pub fn literal(value: f64) -> TokenStream {
    let magnitude = Literal::f64_unsuffixed(value.abs());
    if value.is_sign_negative() && value != 0.0 {
        quote!((-#magnitude))
    } else {
        quote!(#magnitude)
    }
}

/// How tightly a written expression binds, loosest first.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Precedence {
    Sum,
    Product,
    Unary,
    Atom,
}

/// An expression as written, with how tightly it binds.
#[derive(Clone)]
struct Written {
    tokens: TokenStream,
    precedence: Precedence,
}

impl Written {
    fn atom(tokens: TokenStream) -> Written {
        Written {
            tokens,
            precedence: Precedence::Atom,
        }
    }

    /// As an operand that needs at least `precedence` (parenthesized otherwise).
    fn at_least(&self, precedence: Precedence) -> TokenStream {
        let tokens = &self.tokens;
        if self.precedence >= precedence {
            quote!(#tokens)
        } else {
            quote!((#tokens))
        }
    }

    /// As the right operand of a left-associative operator of `precedence`.
    fn right_of(&self, precedence: Precedence) -> TokenStream {
        let tokens = &self.tokens;
        if self.precedence > precedence && self.precedence != Precedence::Unary {
            quote!(#tokens)
        } else {
            quote!((#tokens))
        }
    }
}

/// `left op right` for `op` one of `*`, `/`, negated as `-left op right` when `left` is an
/// atom (exact: negation commutes with both) and as `-(left op right)` otherwise.
fn times_or_over(mut left: Written, right: Written, op: TokenStream, negated: bool) -> Written {
    if negated {
        if left.precedence == Precedence::Atom {
            let tokens = &left.tokens;
            left = Written {
                tokens: quote!(-#tokens),
                precedence: Precedence::Unary,
            };
        } else {
            let (l, r) = (
                left.at_least(Precedence::Product),
                right.right_of(Precedence::Product),
            );
            return Written {
                tokens: quote!(-(#l #op #r)),
                precedence: Precedence::Unary,
            };
        }
    }
    let (l, r) = (
        left.at_least(Precedence::Product),
        right.right_of(Precedence::Product),
    );
    Written {
        tokens: quote!(#l #op #r),
        precedence: Precedence::Product,
    }
}

/// Which nodes get a statement of their own and which are written inside their one user.
struct Plan<'a> {
    arena: &'a Arena,
    program: &'a Program,
    inlined: BTreeSet<Id>,
    temps: BTreeMap<Id, Ident>,
    analytic_names: BTreeMap<Id, (Ident, Ident)>,
    bound: BTreeSet<Id>,
}

impl Plan<'_> {
    fn uses(&self, id: Id) -> usize {
        self.program.uses.get(&id).copied().unwrap_or(0)
    }

    /// Whether `id` is a kind of node that reads well inside another expression.
    fn inlinable(&self, id: Id) -> bool {
        matches!(
            self.arena.node(id),
            Node::Add(..) | Node::Mul(..) | Node::Div(..) | Node::Neg(_) | Node::Powi(..)
        ) && !self.program.absorbed.contains(&id)
    }

    /// Operations written in the expression of `id` once its inlined terms are counted.
    fn written_ops(&self, id: Id, ops: &BTreeMap<Id, usize>) -> usize {
        ops.get(&id).copied().unwrap_or(0)
    }

    /// Decides, children first, which single-use terms are written inside their user.
    fn decide(&mut self, outputs: &[Id]) {
        let mut ops: BTreeMap<Id, usize> = BTreeMap::new();
        for &id in &self.program.steps {
            let node = self.arena.node(id);
            let own = match node {
                Node::Analytic { .. } => continue,
                _ if self.program.absorbed.contains(&id) => 0,
                Node::Powi(_, n) if (2..=4).contains(&n) => (n - 1) as usize,
                _ => 1,
            };
            let mut total = own;
            // The terms a parent could take in: its operands, and the operand of an
            // absorbed negation it subtracts.
            let takes_in = matches!(
                node,
                Node::Add(..) | Node::Mul(..) | Node::Div(..) | Node::Neg(_)
            ) && !self.program.absorbed.contains(&id);
            for child in node.children() {
                let (candidate, single) = match self.arena.node(child) {
                    Node::Neg(x) if self.program.absorbed.contains(&child) => {
                        (x, self.uses(child) == 1)
                    }
                    _ => (child, true),
                };
                if self.program.absorbed.contains(&child) && !single {
                    continue;
                }
                let candidate_ops = self.written_ops(candidate, &ops);
                if takes_in
                    && single
                    && self.uses(candidate) == 1
                    && self.inlinable(candidate)
                    && total + candidate_ops <= STATEMENT_OPS
                {
                    self.inlined.insert(candidate);
                    total += candidate_ops;
                }
            }
            ops.insert(id, total);
        }
        for &id in outputs {
            if self.uses(id) == 1
                && self.inlinable(id)
                && self.written_ops(id, &ops) <= STATEMENT_OPS
            {
                self.inlined.insert(id);
            }
        }
    }

    /// The expression that gives the value of `id` where it is read.
    fn read(&self, id: Id) -> Written {
        match self.arena.node(id) {
            Node::Const(bits) => {
                let value = f64::from_bits(bits);
                let magnitude = Literal::f64_unsuffixed(value.abs());
                if value.is_sign_negative() && value != 0.0 {
                    Written {
                        tokens: quote!(-#magnitude),
                        precedence: Precedence::Unary,
                    }
                } else {
                    Written::atom(quote!(#magnitude))
                }
            }
            Node::Symbol(s) => {
                let name = Ident::new(self.arena.symbol_name(s), Span::call_site());
                Written::atom(quote!(#name))
            }
            Node::Analytic { func, order, arg } => {
                let (fs, fc) = &self.analytic_names[&arg];
                let index = Literal::usize_unsuffixed(usize::from(order));
                match func {
                    Analytic::Fs => Written::atom(quote!(#fs[#index])),
                    Analytic::Fc => Written::atom(quote!(#fc[#index])),
                }
            }
            _ if self.inlined.contains(&id) => self.expression(id),
            _ => {
                let t = &self.temps[&id];
                Written::atom(quote!(#t))
            }
        }
    }

    /// One operand of a sum: whether it is subtracted, and what.
    fn term(&self, id: Id) -> (bool, Written) {
        match self.arena.node(id) {
            Node::Neg(x)
                if self.program.absorbed.contains(&id)
                    || !(self.inlined.contains(&x) || self.inlined.contains(&id)) =>
            {
                (true, self.read(x))
            }
            Node::Const(bits) if f64::from_bits(bits) < 0.0 => {
                let magnitude = Literal::f64_unsuffixed(-f64::from_bits(bits));
                (true, Written::atom(quote!(#magnitude)))
            }
            _ => (false, self.read(id)),
        }
    }

    fn product(&self, a: Id, b: Id, negated: bool) -> Written {
        let (mut left, mut right) = (self.read(a), self.read(b));
        let left_is_constant = matches!(self.arena.node(a), Node::Const(_));
        // A product inside a product reads without parentheses on the left.
        if !left_is_constant
            && right.precedence == Precedence::Product
            && left.precedence == Precedence::Atom
        {
            std::mem::swap(&mut left, &mut right);
        }
        times_or_over(left, right, quote!(*), negated)
    }

    fn quotient(&self, a: Id, b: Id, negated: bool) -> Written {
        times_or_over(self.read(a), self.read(b), quote!(/), negated)
    }

    /// The expression computing `id` from its operands.
    fn expression(&self, id: Id) -> Written {
        match self.arena.node(id) {
            Node::Add(a, b) => {
                let (mut first, mut second) = (self.term(a), self.term(b));
                // Added terms first; a sum on the left needs no parentheses.
                if (first.0 && !second.0)
                    || (first.0 == second.0
                        && second.1.precedence == Precedence::Sum
                        && first.1.precedence != Precedence::Sum)
                {
                    std::mem::swap(&mut first, &mut second);
                }
                let left = if first.0 {
                    let tokens = first.1.at_least(Precedence::Unary);
                    quote!(-#tokens)
                } else {
                    first.1.at_least(Precedence::Sum)
                };
                let right = second.1.right_of(Precedence::Sum);
                let tokens = if second.0 {
                    quote!(#left - #right)
                } else {
                    quote!(#left + #right)
                };
                Written {
                    tokens,
                    precedence: Precedence::Sum,
                }
            }
            Node::Mul(a, b) => self.product(a, b, false),
            Node::Div(a, b) => self.quotient(a, b, false),
            Node::Neg(x) => match self.arena.node(x) {
                Node::Mul(a, b) if self.inlined.contains(&x) => self.product(a, b, true),
                Node::Div(a, b) if self.inlined.contains(&x) => self.quotient(a, b, true),
                _ => {
                    let operand = self.read(x).right_of(Precedence::Unary);
                    Written {
                        tokens: quote!(-#operand),
                        precedence: Precedence::Unary,
                    }
                }
            },
            Node::Powi(a, n) => {
                let a = self.read(a).at_least(Precedence::Atom);
                match n {
                    2 => Written {
                        tokens: quote!(#a * #a),
                        precedence: Precedence::Product,
                    },
                    3 => Written {
                        tokens: quote!(#a * #a * #a),
                        precedence: Precedence::Product,
                    },
                    4 => Written {
                        tokens: quote!((#a * #a) * (#a * #a)),
                        precedence: Precedence::Product,
                    },
                    -1 => Written {
                        tokens: quote!(1.0 / #a),
                        precedence: Precedence::Product,
                    },
                    _ => Written::atom(quote!(#a.powi(#n))),
                }
            }
            Node::Sqrt(a) => {
                let a = self.read(a).at_least(Precedence::Atom);
                Written::atom(quote!(#a.sqrt()))
            }
            Node::Sin(a) => {
                let a = self.read(a).at_least(Precedence::Atom);
                Written::atom(quote!(#a.sin()))
            }
            Node::Cos(a) => {
                let a = self.read(a).at_least(Precedence::Atom);
                Written::atom(quote!(#a.cos()))
            }
            Node::Const(_) | Node::Symbol(_) | Node::Analytic { .. } => self.read(id),
        }
    }
}

/// Emits one function.
pub fn emit_function(arena: &Arena, spec: &FunctionSpec) -> Emitted {
    let outputs: Vec<Id> = spec.outputs.iter().map(|&(_, id)| id).collect();
    let program = schedule(arena, &outputs);
    let ops = op_count(arena, &program);
    let mut plan = Plan {
        arena,
        program: &program,
        inlined: BTreeSet::new(),
        temps: BTreeMap::new(),
        analytic_names: BTreeMap::new(),
        bound: BTreeSet::new(),
    };
    plan.decide(&outputs);

    // Bind the inputs this program reads, in symbol order.
    let bound: BTreeMap<Id, &TokenStream> = spec
        .inputs
        .iter()
        .map(|(id, source)| (*id, source))
        .collect();
    for &id in program.steps.iter().chain(&program.outputs) {
        let node = arena.node(id);
        for c in std::iter::once(id).chain(node.children()) {
            if let Node::Symbol(_) = arena.node(c) {
                plan.bound.insert(c);
            }
        }
    }
    let mut body = TokenStream::new();
    for symbol in &plan.bound {
        let Node::Symbol(s) = arena.node(*symbol) else {
            unreachable!("only symbols are bound")
        };
        let name = Ident::new(arena.symbol_name(s), Span::call_site());
        let source = bound
            .get(symbol)
            .unwrap_or_else(|| panic!("symbol `{name}` has no input binding"));
        body.extend(match spec.scalar {
            Scalar::F64 => quote!(let #name: f64 = #source;),
            Scalar::Interval | Scalar::Dual => quote!(let #name = #source;),
        });
    }

    let mut analytic_orders = BTreeSet::new();
    for &id in &program.steps {
        if let Node::Analytic { arg, .. } = arena.node(id) {
            if plan.analytic_names.contains_key(&arg) {
                continue;
            }
            let k = plan.analytic_names.len();
            let names = (format_ident!("fs_{}", k), format_ident!("fc_{}", k));
            let max_order = usize::from(program.analytic_orders[&arg]);
            analytic_orders.insert(max_order);
            let function = match spec.scalar {
                Scalar::F64 => analytic::function_ident(max_order),
                Scalar::Interval => analytic::interval_function_ident(max_order),
                Scalar::Dual => analytic::dual_function_ident(max_order),
            };
            let argument = plan.read(arg).tokens;
            let (fs, fc) = &names;
            body.extend(quote!(let (#fs, #fc) = #function(#argument);));
            plan.analytic_names.insert(arg, names);
            continue;
        }
        if plan.inlined.contains(&id) || program.absorbed.contains(&id) {
            continue;
        }
        let value = plan.expression(id).tokens;
        let t = format_ident!("t{}", plan.temps.len());
        body.extend(match spec.scalar {
            Scalar::F64 => quote!(let #t: f64 = #value;),
            Scalar::Interval | Scalar::Dual => quote!(let #t = #value;),
        });
        plan.temps.insert(id, t);
    }
    for (place, id) in &spec.outputs {
        let value = plan.read(*id).tokens;
        body.extend(match spec.scalar {
            Scalar::F64 => quote!(#place = #value;),
            Scalar::Interval => quote!(#place = Interval::from(#value);),
            Scalar::Dual => quote!(#place = Dual::from(#value);),
        });
    }
    let epilogue = &spec.epilogue;
    let name = &spec.name;
    let args = &spec.args;
    let docs = spec.doc.iter().map(|line| quote!(#[doc = #line]));
    let tokens = quote! {
        #(#docs)*
        pub fn #name(#args) {
            #body
            #epilogue
        }
    };
    Emitted {
        tokens,
        ops,
        analytic_orders,
    }
}

/// Formats a token stream holding items as a Rust source file.
pub fn format_file(tokens: TokenStream) -> String {
    let file: syn::File = syn::parse2(tokens).expect("emitted code is valid Rust");
    prettyplease::unparse(&file)
}
