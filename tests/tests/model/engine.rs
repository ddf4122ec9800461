//! Table tests of the symbolic engine: simplification and derivative rules, tangents, and
//! common-subexpression elimination leaving every output unchanged.

use rand::RngExt;
use softcbf_codegen::diff::{Differentiator, Tangent};
use softcbf_codegen::expr::{Arena, Id};
use softcbf_codegen::program::schedule;
use softcbf_codegen::sexpr::{display, parse};
use softcbf_tests::evaluate::{analytic_by_series, eval_program, eval_tree};

/// Each row: an input and what the simplifying constructors must turn it into.
const SIMPLIFICATIONS: &[(&str, &str)] = &[
    ("(+ 2 3)", "5"),
    ("(+ x 0)", "x"),
    ("(+ 0 x)", "x"),
    ("(* x 1)", "x"),
    ("(* 1 x)", "x"),
    ("(* x 0)", "0"),
    ("(* 0 (sin x))", "0"),
    ("(* -1 x)", "(- x)"),
    ("(- (- x))", "x"),
    ("(- 3)", "-3"),
    ("(+ x (- x))", "0"),
    ("(- x x)", "0"),
    ("(+ x x)", "(* 2 x)"),
    ("(* x x)", "(^ x 2)"),
    ("(* 2 (* 3 x))", "(* 6 x)"),
    ("(* x 2)", "(* 2 x)"),
    ("(* y x)", "(* x y)"),
    ("(+ y x)", "(+ x y)"),
    ("(* (- x) y)", "(- (* x y))"),
    ("(+ (- x) (- y))", "(- (+ x y))"),
    ("(- (* 2 x))", "(* -2 x)"),
    ("(^ x 1)", "x"),
    ("(^ x 0)", "1"),
    ("(^ (^ x 2) 3)", "(^ x 6)"),
    ("(^ (- x) 2)", "(^ x 2)"),
    ("(^ (- x) 3)", "(- (^ x 3))"),
    ("(^ 2 10)", "1024"),
    ("(/ x x)", "1"),
    ("(/ x 1)", "x"),
    ("(/ x -1)", "(- x)"),
    ("(/ x 4)", "(* 0.25 x)"),
    ("(/ 0 x)", "0"),
    ("(/ 6 4)", "1.5"),
    ("(sqrt 9)", "3"),
    ("(sin 0)", "0"),
    ("(cos 0)", "1"),
];

/// Each row: `(symbol, expression, derivative)`.
const DERIVATIVES: &[(&str, &str, &str)] = &[
    ("x", "5", "0"),
    ("x", "x", "1"),
    ("x", "y", "0"),
    ("x", "(+ x y)", "1"),
    ("x", "(* x y)", "y"),
    ("x", "(* x x)", "(* 2 x)"),
    ("x", "(^ x 3)", "(* 3 (^ x 2))"),
    ("x", "(- x)", "-1"),
    ("x", "(sin x)", "(cos x)"),
    ("x", "(cos x)", "(- (sin x))"),
    ("x", "(sin (* 2 x))", "(* 2 (cos (* 2 x)))"),
    ("x", "(sqrt x)", "(/ 1 (* 2 (sqrt x)))"),
    ("x", "(/ x y)", "(/ 1 y)"),
    ("y", "(/ x y)", "(/ (- (/ x y)) y)"),
    ("x", "(fs x)", "(fs^1 x)"),
    ("x", "(fc^2 x)", "(fc^3 x)"),
    ("x", "(fs (^ x 2))", "(* (* 2 x) (fs^1 (^ x 2)))"),
    ("y", "(fs (^ x 2))", "0"),
    (
        "x",
        "(* (fs x) (fc x))",
        "(+ (* (fs^1 x) (fc x)) (* (fs x) (fc^1 x)))",
    ),
];

fn same(arena: &mut Arena, got: Id, expected: &str) -> bool {
    let expected = parse(arena, expected).expect("expected side parses");
    got == expected
}

#[test]
fn simplification_rules() {
    for (input, expected) in SIMPLIFICATIONS {
        let mut arena = Arena::new();
        let got = parse(&mut arena, input).expect("row parses");
        assert!(
            same(&mut arena, got, expected),
            "{input} became {} instead of {expected}",
            display(&arena, got)
        );
    }
}

#[test]
fn derivative_rules() {
    for (symbol, input, expected) in DERIVATIVES {
        let mut arena = Arena::new();
        let expr = parse(&mut arena, input).expect("row parses");
        let x = parse(&mut arena, symbol).expect("symbol parses");
        let got = Differentiator::new().derivative(&mut arena, expr, x);
        assert!(
            same(&mut arena, got, expected),
            "d/d{symbol} {input} gave {} instead of {expected}",
            display(&arena, got)
        );
    }
}

#[test]
fn tangent_is_the_chain_rule_along_rates() {
    // d/dt fs(x·x) with ẋ = v, and a symbol without a rate stays constant.
    let mut arena = Arena::new();
    let expr = parse(&mut arena, "(* c (fs (* x x)))").unwrap();
    let x = arena.find_symbol("x").unwrap();
    let v = arena.symbol("v");
    let mut tangent = Tangent::new();
    tangent.set_rate(x, v);
    let got = tangent.tangent(&mut arena, expr);
    assert!(
        same(&mut arena, got, "(* c (* (* v (* 2 x)) (fs^1 (^ x 2))))"),
        "got {}",
        display(&arena, got)
    );
}

#[test]
fn derivatives_match_central_differences() {
    // The rules above, numerically: every row's derivative against a central difference.
    for (symbol, input, _) in DERIVATIVES {
        let mut arena = Arena::new();
        let expr = parse(&mut arena, input).unwrap();
        let x = parse(&mut arena, symbol).unwrap();
        let derivative = Differentiator::new().derivative(&mut arena, expr, x);
        let n = arena.symbol_count();
        let mut values: Vec<f64> = (0..n).map(|k| 0.3 + 0.17 * k as f64).collect();
        let index = (0..n)
            .find(|&k| arena.find_symbol(arena.symbol_name(k as u32)) == Some(x))
            .unwrap();
        let analytic = eval_tree(&arena, derivative, &values, analytic_by_series);
        let h = 1e-6;
        values[index] += h;
        let plus = eval_tree(&arena, expr, &values, analytic_by_series);
        values[index] -= 2.0 * h;
        let minus = eval_tree(&arena, expr, &values, analytic_by_series);
        let numeric = (plus - minus) / (2.0 * h);
        assert!(
            (analytic - numeric).abs() <= 1e-7 * (1.0 + analytic.abs()),
            "d/d{symbol} {input}: {analytic} vs finite difference {numeric}"
        );
    }
}

#[test]
fn cse_leaves_every_output_unchanged() {
    // Random expression graphs with much sharing: the straight-line program must give
    // bit-identical outputs to a naive evaluation of each output's tree.
    let mut rng = softcbf_tests::rng(7);
    for round in 0..200 {
        let mut arena = Arena::new();
        let mut pool: Vec<Id> = (0..4).map(|k| arena.symbol(&format!("s{k}"))).collect();
        pool.push(arena.constant(0.5));
        for _ in 0..25 {
            let a = pool[rng.random_range(0..pool.len())];
            let b = pool[rng.random_range(0..pool.len())];
            let node = match rng.random_range(0..9) {
                0 => arena.add(a, b),
                1 => arena.sub(a, b),
                2 => arena.mul(a, b),
                3 => arena.neg(a),
                4 => arena.sin(a),
                5 => arena.cos(b),
                6 => {
                    let square = arena.powi(a, 2);
                    arena.fs(square)
                }
                7 => {
                    let square = arena.powi(b, 2);
                    arena.analytic(softcbf_codegen::expr::Analytic::Fc, 2, square)
                }
                _ => arena.powi(a, 3),
            };
            pool.push(node);
        }
        let outputs: Vec<Id> = pool[pool.len() - 6..].to_vec();
        let program = schedule(&arena, &outputs);
        let values = [0.3, -0.7, 1.1, 0.05];
        let scheduled = eval_program(&arena, &program, &values, analytic_by_series);
        for (k, &output) in outputs.iter().enumerate() {
            let tree = eval_tree(&arena, output, &values, analytic_by_series);
            assert_eq!(
                tree.to_bits(),
                scheduled[k].to_bits(),
                "round {round}, output {k}: {}",
                display(&arena, output)
            );
        }
        // Each needed node is evaluated once.
        let mut steps = program.steps.clone();
        steps.dedup();
        assert_eq!(steps.len(), program.steps.len());
    }
}

#[test]
fn cse_leaves_the_model_outputs_unchanged() {
    use softcbf_description::robot::{Routing, Structure};
    let structure = Structure::new(vec![6, 4], vec![3, 3], Routing::Local);
    let mut model = softcbf_codegen::model::build(&structure);
    let terms = model.barrier_term_exprs();
    let mut outputs = Vec::new();
    for (b, gradient, jdot) in &terms {
        outputs.push(*b);
        outputs.extend(gradient);
        outputs.push(*jdot);
    }
    let arena = model.arena();
    let program = schedule(arena, &outputs);
    let values: Vec<f64> = (0..arena.symbol_count())
        .map(|k| 0.01 + 0.013 * k as f64)
        .collect();
    let scheduled = eval_program(arena, &program, &values, analytic_by_series);
    for (k, &output) in outputs.iter().enumerate() {
        let tree = eval_tree(arena, output, &values, analytic_by_series);
        assert_eq!(tree.to_bits(), scheduled[k].to_bits(), "output {k}");
    }
}
