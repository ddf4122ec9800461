//! Emission of straight-line programs as Rust functions through syn/quote/prettyplease.
//! One `let` per scheduled node; analytic nodes share one call per distinct argument.

use std::collections::{BTreeMap, BTreeSet};

use proc_macro2::{Ident, Literal, Span, TokenStream};
use quote::{format_ident, quote};

use crate::analytic;
use crate::expr::{Analytic, Arena, Id, Node};
use crate::program::{OpCount, op_count, schedule};

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

fn temp(id: Id) -> Ident {
    format_ident!("t{}", id.0)
}

fn analytic_arrays(arg: Id) -> (Ident, Ident) {
    (format_ident!("fs_{}", arg.0), format_ident!("fc_{}", arg.0))
}

/// Emits one function.
pub fn emit_function(arena: &Arena, spec: &FunctionSpec) -> Emitted {
    let outputs: Vec<Id> = spec.outputs.iter().map(|&(_, id)| id).collect();
    let program = schedule(arena, &outputs);
    let ops = op_count(arena, &program);

    let bound: BTreeMap<Id, &TokenStream> = spec
        .inputs
        .iter()
        .map(|(id, source)| (*id, source))
        .collect();
    let operand = |id: Id| -> TokenStream {
        match arena.node(id) {
            Node::Const(bits) => literal(f64::from_bits(bits)),
            Node::Symbol(s) => {
                let name = Ident::new(arena.symbol_name(s), Span::call_site());
                quote!(#name)
            }
            _ => {
                let t = temp(id);
                quote!(#t)
            }
        }
    };

    // Bind the inputs this program reads.
    let mut used_symbols = BTreeSet::new();
    for &id in program.steps.iter().chain(&program.outputs) {
        let mut note = |c: Id| {
            if let Node::Symbol(_) = arena.node(c) {
                used_symbols.insert(c);
            }
        };
        note(id);
        arena.node(id).children().for_each(note);
    }
    let mut body = TokenStream::new();
    for symbol in &used_symbols {
        let Node::Symbol(s) = arena.node(*symbol) else {
            unreachable!()
        };
        let name = Ident::new(arena.symbol_name(s), Span::call_site());
        let source = bound
            .get(symbol)
            .unwrap_or_else(|| panic!("symbol `{name}` has no input binding"));
        body.extend(quote!(let #name: f64 = #source;));
    }

    let mut called = BTreeSet::new();
    let mut analytic_orders = BTreeSet::new();
    for &id in &program.steps {
        let node = arena.node(id);
        let t = temp(id);
        let value = match node {
            Node::Add(a, b) => {
                let (a, b) = (operand(a), operand(b));
                quote!(#a + #b)
            }
            Node::Mul(a, b) => {
                let (a, b) = (operand(a), operand(b));
                quote!(#a * #b)
            }
            Node::Neg(a) => {
                let a = operand(a);
                quote!(-#a)
            }
            Node::Div(a, b) => {
                let (a, b) = (operand(a), operand(b));
                quote!(#a / #b)
            }
            Node::Powi(a, n) => {
                let a = operand(a);
                match n {
                    2 => quote!(#a * #a),
                    3 => quote!(#a * #a * #a),
                    4 => quote!((#a * #a) * (#a * #a)),
                    -1 => quote!(1.0 / #a),
                    _ => quote!(#a.powi(#n)),
                }
            }
            Node::Sqrt(a) => {
                let a = operand(a);
                quote!(#a.sqrt())
            }
            Node::Sin(a) => {
                let a = operand(a);
                quote!(#a.sin())
            }
            Node::Cos(a) => {
                let a = operand(a);
                quote!(#a.cos())
            }
            Node::Analytic { func, order, arg } => {
                let (fs, fc) = analytic_arrays(arg);
                if called.insert(arg) {
                    let max_order = usize::from(program.analytic_orders[&arg]);
                    analytic_orders.insert(max_order);
                    let function = analytic::function_ident(max_order);
                    let argument = operand(arg);
                    body.extend(quote!(let (#fs, #fc) = #function(#argument);));
                }
                let index = Literal::usize_unsuffixed(usize::from(order));
                match func {
                    Analytic::Fs => quote!(#fs[#index]),
                    Analytic::Fc => quote!(#fc[#index]),
                }
            }
            Node::Const(_) | Node::Symbol(_) => unreachable!("leaves are not scheduled"),
        };
        body.extend(quote!(let #t: f64 = #value;));
    }
    for (place, id) in &spec.outputs {
        let value = operand(*id);
        body.extend(quote!(#place = #value;));
    }
    let epilogue = &spec.epilogue;
    let name = &spec.name;
    let args = &spec.args;
    let docs = spec.doc.iter().map(|line| quote!(#[doc = #line]));
    let tokens = quote! {
        #(#docs)*
        #[allow(clippy::too_many_arguments, clippy::needless_range_loop)]
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
