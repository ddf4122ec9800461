//! A small S-expression syntax for arena expressions, for table tests and debugging:
//! `(+ a b)`, `(- a)`, `(- a b)`, `(* a b)`, `(/ a b)`, `(^ a 3)`, `(sqrt a)`, `(sin a)`,
//! `(cos a)`, `(fs a)`, `(fc a)`, `(fs^2 a)` (second derivative), numbers and symbols.

use crate::expr::{Analytic, Arena, Id, Node};

/// Renders an expression.
pub fn display(arena: &Arena, id: Id) -> String {
    match arena.node(id) {
        Node::Const(bits) => format!("{}", f64::from_bits(bits)),
        Node::Symbol(s) => arena.symbol_name(s).to_string(),
        Node::Add(a, b) => format!("(+ {} {})", display(arena, a), display(arena, b)),
        Node::Mul(a, b) => format!("(* {} {})", display(arena, a), display(arena, b)),
        Node::Neg(a) => format!("(- {})", display(arena, a)),
        Node::Div(a, b) => format!("(/ {} {})", display(arena, a), display(arena, b)),
        Node::Powi(a, n) => format!("(^ {} {n})", display(arena, a)),
        Node::Sqrt(a) => format!("(sqrt {})", display(arena, a)),
        Node::Sin(a) => format!("(sin {})", display(arena, a)),
        Node::Cos(a) => format!("(cos {})", display(arena, a)),
        Node::Analytic { func, order, arg } => {
            let name = match func {
                Analytic::Fs => "fs",
                Analytic::Fc => "fc",
            };
            let order = if order == 0 {
                String::new()
            } else {
                format!("^{order}")
            };
            format!("({name}{order} {})", display(arena, arg))
        }
    }
}

/// Parses an expression, declaring unknown symbols. Errors name the offending token.
pub fn parse(arena: &mut Arena, text: &str) -> Result<Id, String> {
    let spaced = text.replace('(', " ( ").replace(')', " ) ");
    let tokens: Vec<&str> = spaced.split_whitespace().collect();
    let mut position = 0;
    let id = parse_at(arena, &tokens, &mut position)?;
    if position != tokens.len() {
        return Err(format!(
            "unexpected `{}` after the expression",
            tokens[position]
        ));
    }
    Ok(id)
}

fn symbol(arena: &mut Arena, name: &str) -> Id {
    match arena.find_symbol(name) {
        Some(id) => id,
        None => arena.symbol(name),
    }
}

fn parse_at(arena: &mut Arena, tokens: &[&str], position: &mut usize) -> Result<Id, String> {
    let Some(&token) = tokens.get(*position) else {
        return Err("unexpected end of expression".into());
    };
    *position += 1;
    if token == ")" {
        return Err("unexpected `)`".into());
    }
    if token != "(" {
        return Ok(match token.parse::<f64>() {
            Ok(value) => arena.constant(value),
            Err(_) => symbol(arena, token),
        });
    }
    let Some(&head) = tokens.get(*position) else {
        return Err("unexpected end after `(`".into());
    };
    *position += 1;
    let mut args = Vec::new();
    let mut integer = None;
    while tokens.get(*position) != Some(&")") {
        if tokens.get(*position).is_none() {
            return Err(format!("missing `)` for `({head}`"));
        }
        if head == "^" && args.len() == 1 {
            let text = tokens[*position];
            *position += 1;
            integer = Some(
                text.parse::<i32>()
                    .map_err(|_| format!("`{text}` is not an integer power"))?,
            );
            continue;
        }
        args.push(parse_at(arena, tokens, position)?);
    }
    *position += 1;
    let analytic = |name: &str| -> Option<(Analytic, u8)> {
        let (func, rest) = if let Some(rest) = name.strip_prefix("fs") {
            (Analytic::Fs, rest)
        } else {
            (Analytic::Fc, name.strip_prefix("fc")?)
        };
        let order = if rest.is_empty() {
            0
        } else {
            rest.strip_prefix('^')?.parse().ok()?
        };
        Some((func, order))
    };
    Ok(match (head, args.as_slice()) {
        ("+", [a, b]) => arena.add(*a, *b),
        ("-", [a]) => arena.neg(*a),
        ("-", [a, b]) => arena.sub(*a, *b),
        ("*", [a, b]) => arena.mul(*a, *b),
        ("/", [a, b]) => arena.div(*a, *b),
        ("^", [a]) => arena.powi(*a, integer.ok_or("`^` needs a power")?),
        ("sqrt", [a]) => arena.sqrt(*a),
        ("sin", [a]) => arena.sin(*a),
        ("cos", [a]) => arena.cos(*a),
        (name, [a]) if analytic(name).is_some() => {
            let (func, order) = analytic(name).unwrap_or((Analytic::Fs, 0));
            arena.analytic(func, order, *a)
        }
        _ => {
            return Err(format!(
                "`({head} …)` with {} arguments is not an expression",
                args.len()
            ));
        }
    })
}
