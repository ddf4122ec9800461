//! The expression arena: a flat, hash-consed list of nodes whose children come earlier.
//! Constructors fold constants and apply local algebraic simplifications as nodes are made.

use std::collections::HashMap;

/// Index of a node in an [`Arena`]. Children always have smaller ids than their parents.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Id(pub u32);

impl Id {
    /// Position in the arena.
    pub fn index(self) -> usize {
        self.0 as usize
    }
}

/// The analytic functions of docs/model.md §2, as first-class nodes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Analytic {
    /// `f_s(u) = sin(√u)/√u`.
    Fs,
    /// `f_c(u) = (1 − cos √u)/u`.
    Fc,
}

/// One node. Constants are stored as normalized bit patterns so they can be hashed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Node {
    /// A literal number (bits of an `f64`; `-0.0` is stored as `0.0`).
    Const(u64),
    /// An input, by index into the arena's symbol table.
    Symbol(u32),
    /// `a + b`, operands ordered by id.
    Add(Id, Id),
    /// `a · b`, operands ordered by id.
    Mul(Id, Id),
    /// `−a`.
    Neg(Id),
    /// `a / b`.
    Div(Id, Id),
    /// `a^n`, `n ∉ {0, 1}`.
    Powi(Id, i32),
    /// `√a`.
    Sqrt(Id),
    /// `sin a`.
    Sin(Id),
    /// `cos a`.
    Cos(Id),
    /// The `order`-th derivative of an analytic function, evaluated at `arg`.
    Analytic { func: Analytic, order: u8, arg: Id },
}

impl Node {
    /// The node's operands.
    pub fn children(&self) -> impl Iterator<Item = Id> {
        let (a, b) = match *self {
            Node::Const(_) | Node::Symbol(_) => (None, None),
            Node::Add(a, b) | Node::Mul(a, b) | Node::Div(a, b) => (Some(a), Some(b)),
            Node::Neg(a) | Node::Powi(a, _) | Node::Sqrt(a) | Node::Sin(a) | Node::Cos(a) => {
                (Some(a), None)
            }
            Node::Analytic { arg, .. } => (Some(arg), None),
        };
        a.into_iter().chain(b)
    }
}

/// A flat, deduplicated store of expression nodes plus the names of its symbols.
#[derive(Clone, Debug, Default)]
pub struct Arena {
    nodes: Vec<Node>,
    index: HashMap<Node, Id>,
    symbols: Vec<String>,
}

fn const_bits(value: f64) -> u64 {
    // One representation for zero so that `0.0` and `-0.0` hash alike.
    if value == 0.0 { 0 } else { value.to_bits() }
}

impl Arena {
    /// An empty arena.
    pub fn new() -> Arena {
        Arena::default()
    }

    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    /// True when no node has been made.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// The node behind an id.
    pub fn node(&self, id: Id) -> Node {
        self.nodes[id.index()]
    }

    /// The name of symbol number `index`.
    pub fn symbol_name(&self, index: u32) -> &str {
        &self.symbols[index as usize]
    }

    /// The node of the symbol called `name`, if one was declared.
    pub fn find_symbol(&self, name: &str) -> Option<Id> {
        let index = self.symbols.iter().position(|s| s == name)?;
        self.index.get(&Node::Symbol(index as u32)).copied()
    }

    /// Number of symbols declared.
    pub fn symbol_count(&self) -> usize {
        self.symbols.len()
    }

    /// The value of a constant node, if it is one.
    pub fn as_const(&self, id: Id) -> Option<f64> {
        match self.node(id) {
            Node::Const(bits) => Some(f64::from_bits(bits)),
            _ => None,
        }
    }

    fn intern(&mut self, node: Node) -> Id {
        if let Some(&id) = self.index.get(&node) {
            return id;
        }
        let id = Id(u32::try_from(self.nodes.len()).expect("expression arena exceeds 2^32 nodes"));
        self.nodes.push(node);
        self.index.insert(node, id);
        id
    }

    /// Declares a new input symbol (names must be unique) and returns its node.
    pub fn symbol(&mut self, name: &str) -> Id {
        assert!(
            !self.symbols.iter().any(|s| s == name),
            "symbol `{name}` declared twice"
        );
        let index = u32::try_from(self.symbols.len()).expect("too many symbols");
        self.symbols.push(name.to_string());
        self.intern(Node::Symbol(index))
    }

    /// A constant. Non-finite constants are refused: they would only hide a bug.
    pub fn constant(&mut self, value: f64) -> Id {
        assert!(value.is_finite(), "non-finite constant {value}");
        self.intern(Node::Const(const_bits(value)))
    }

    /// `a + b`.
    pub fn add(&mut self, a: Id, b: Id) -> Id {
        match (self.as_const(a), self.as_const(b)) {
            (Some(x), Some(y)) => return self.constant(x + y),
            (Some(0.0), None) => return b,
            (None, Some(0.0)) => return a,
            _ => {}
        }
        if a == b {
            let two = self.constant(2.0);
            return self.mul(two, a);
        }
        // x + (−x) = 0
        if self.node(a) == Node::Neg(b) || self.node(b) == Node::Neg(a) {
            return self.constant(0.0);
        }
        // (−x) + (−y) = −(x + y)
        if let (Node::Neg(x), Node::Neg(y)) = (self.node(a), self.node(b)) {
            let sum = self.add(x, y);
            return self.neg(sum);
        }
        let (a, b) = if a <= b { (a, b) } else { (b, a) };
        self.intern(Node::Add(a, b))
    }

    /// `a − b`.
    pub fn sub(&mut self, a: Id, b: Id) -> Id {
        let minus_b = self.neg(b);
        self.add(a, minus_b)
    }

    /// `−a`.
    pub fn neg(&mut self, a: Id) -> Id {
        match self.node(a) {
            Node::Const(bits) => self.constant(-f64::from_bits(bits)),
            Node::Neg(x) => x,
            // −(c·x) = (−c)·x keeps constants in one place.
            Node::Mul(x, y) if self.as_const(x).is_some() => {
                let c = self.as_const(x).unwrap_or_default();
                let minus_c = self.constant(-c);
                self.mul(minus_c, y)
            }
            _ => self.intern(Node::Neg(a)),
        }
    }

    /// `a · b`.
    pub fn mul(&mut self, a: Id, b: Id) -> Id {
        match (self.as_const(a), self.as_const(b)) {
            (Some(x), Some(y)) => return self.constant(x * y),
            (Some(0.0), _) | (_, Some(0.0)) => return self.constant(0.0),
            (Some(1.0), None) => return b,
            (None, Some(1.0)) => return a,
            (Some(-1.0), None) => return self.neg(b),
            (None, Some(-1.0)) => return self.neg(a),
            _ => {}
        }
        // Pull negations out: (−x)·y = −(x·y).
        if let Node::Neg(x) = self.node(a) {
            let product = self.mul(x, b);
            return self.neg(product);
        }
        if let Node::Neg(y) = self.node(b) {
            let product = self.mul(a, y);
            return self.neg(product);
        }
        // Keep a constant factor on the left and merge nested constant factors.
        let (a, b) = if self.as_const(b).is_some() {
            (b, a)
        } else {
            (a, b)
        };
        if let Some(c) = self.as_const(a) {
            if let Node::Mul(x, y) = self.node(b)
                && let Some(d) = self.as_const(x)
            {
                let cd = self.constant(c * d);
                return self.mul(cd, y);
            }
            return self.intern(Node::Mul(a, b));
        }
        if a == b {
            return self.powi(a, 2);
        }
        let (a, b) = if a <= b { (a, b) } else { (b, a) };
        self.intern(Node::Mul(a, b))
    }

    /// `a / b`.
    pub fn div(&mut self, a: Id, b: Id) -> Id {
        match (self.as_const(a), self.as_const(b)) {
            (Some(x), Some(y)) if y != 0.0 => return self.constant(x / y),
            (Some(0.0), _) => return self.constant(0.0),
            (None, Some(1.0)) => return a,
            (None, Some(-1.0)) => return self.neg(a),
            // Division by a power of two is exact as a multiplication.
            (None, Some(y)) if y != 0.0 && (1.0 / y) * y == 1.0 && is_power_of_two(y) => {
                let inverse = self.constant(1.0 / y);
                return self.mul(inverse, a);
            }
            _ => {}
        }
        if a == b {
            return self.constant(1.0);
        }
        self.intern(Node::Div(a, b))
    }

    /// `a^n` for an integer `n`.
    pub fn powi(&mut self, a: Id, n: i32) -> Id {
        if n == 0 {
            return self.constant(1.0);
        }
        if n == 1 {
            return a;
        }
        if let Some(x) = self.as_const(a) {
            return self.constant(x.powi(n));
        }
        match self.node(a) {
            Node::Powi(x, m) => match m.checked_mul(n) {
                Some(mn) => self.powi(x, mn),
                None => self.intern(Node::Powi(a, n)),
            },
            Node::Neg(x) => {
                let p = self.powi(x, n);
                if n % 2 == 0 { p } else { self.neg(p) }
            }
            _ => self.intern(Node::Powi(a, n)),
        }
    }

    /// `√a`.
    pub fn sqrt(&mut self, a: Id) -> Id {
        match self.as_const(a) {
            Some(x) if x >= 0.0 => self.constant(x.sqrt()),
            _ => self.intern(Node::Sqrt(a)),
        }
    }

    /// `sin a`.
    pub fn sin(&mut self, a: Id) -> Id {
        match self.as_const(a) {
            Some(0.0) => self.constant(0.0),
            _ => self.intern(Node::Sin(a)),
        }
    }

    /// `cos a`.
    pub fn cos(&mut self, a: Id) -> Id {
        match self.as_const(a) {
            Some(0.0) => self.constant(1.0),
            _ => self.intern(Node::Cos(a)),
        }
    }

    /// The `order`-th derivative of `func` at `arg`.
    pub fn analytic(&mut self, func: Analytic, order: u8, arg: Id) -> Id {
        self.intern(Node::Analytic { func, order, arg })
    }

    /// `f_s(arg)`.
    pub fn fs(&mut self, arg: Id) -> Id {
        self.analytic(Analytic::Fs, 0, arg)
    }

    /// `f_c(arg)`.
    pub fn fc(&mut self, arg: Id) -> Id {
        self.analytic(Analytic::Fc, 0, arg)
    }

    /// Sum of many terms (0 for none).
    pub fn sum(&mut self, terms: &[Id]) -> Id {
        let mut total = self.constant(0.0);
        for &t in terms {
            total = self.add(total, t);
        }
        total
    }

    /// Dot product of two equally long lists.
    pub fn dot(&mut self, a: &[Id], b: &[Id]) -> Id {
        assert_eq!(a.len(), b.len(), "dot of unequal lengths");
        let products: Vec<Id> = a.iter().zip(b).map(|(&x, &y)| self.mul(x, y)).collect();
        self.sum(&products)
    }
}

fn is_power_of_two(y: f64) -> bool {
    let magnitude = y.abs();
    magnitude.is_normal() && magnitude.to_bits() & ((1u64 << 52) - 1) == 0
}
