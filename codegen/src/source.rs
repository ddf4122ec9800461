//! The Rust source of a symbolic model ([`crate::model`]): what each generated function
//! writes where, the inputs it reads, and the whole file emitted through
//! [`crate::emit`] (syn/quote/prettyplease). The symbolic model itself is `model`'s.

use proc_macro2::{Literal, TokenStream};
use quote::{format_ident, quote};

use crate::analytic;
use crate::emit::{FunctionSpec, Scalar, emit_function, format_file};
use crate::expr::Id;
use crate::model::{Point, SymbolicModel, build};
use crate::program::OpCount;
use crate::robot::Structure;

/// The outputs of each generated function, in the order its emitted code writes them
/// ([`SymbolicModel::function_outputs`]).
#[derive(Clone, Debug)]
pub struct FunctionOutputs {
    /// `segment_transforms`: per module, per row `r` of 0–2, `R[r][0..3]` then `t[r]`.
    pub segment_transforms: Vec<Id>,
    /// `barriers`: each barrier's value.
    pub barriers: Vec<Id>,
    /// `barrier_terms`: per barrier, `b`, its Jacobian row (`nq` entries), `J̇q̇`.
    pub barrier_terms: Vec<Id>,
    /// `joint_terms`: per module, per row `r` of 0–2 `R[r][0..3]` then `t[r]`, then per
    /// row `r` of 0–5 `S[r][0..3]` then `c_J[r]`.
    pub joint_terms: Vec<Id>,
    /// `model_terms`: the joint terms, then the barrier terms.
    pub model_terms: Vec<Id>,
}

/// A generated model file and what it costs.
pub struct GeneratedSource {
    /// The formatted Rust source.
    pub text: String,
    /// Operation count of each emitted function.
    pub ops: Vec<(String, OpCount)>,
}

impl SymbolicModel {
    fn bindings(&self, with_velocity: bool) -> Vec<(Id, TokenStream)> {
        let mut inputs = Vec::new();
        for &(id, index) in &self.params {
            let index = Literal::usize_unsuffixed(index);
            inputs.push((id, quote!(p[#index])));
        }
        for (i, m) in self.modules.iter().enumerate() {
            for k in 0..3 {
                let index = Literal::usize_unsuffixed(3 * i + k);
                inputs.push((m.q[k], quote!(q[#index])));
                if with_velocity {
                    inputs.push((m.qd[k], quote!(qd[#index])));
                }
            }
        }
        inputs
    }

    /// The places and values `segment_transforms` writes (rows 0–2 of each `T_i`).
    fn segment_outputs(&self) -> Vec<(TokenStream, Id)> {
        let mut outputs = Vec::new();
        for (i, m) in self.modules.iter().enumerate() {
            let i_lit = Literal::usize_unsuffixed(i);
            for r in 0..3 {
                let r_lit = Literal::usize_unsuffixed(r);
                for c in 0..3 {
                    let c_lit = Literal::usize_unsuffixed(c);
                    outputs.push((quote!(transforms[#i_lit][#r_lit][#c_lit]), m.rotation[r][c]));
                }
                outputs.push((quote!(transforms[#i_lit][#r_lit][3]), m.translation[r]));
            }
        }
        outputs
    }

    /// The outputs of every generated function as expressions, built exactly as
    /// [`SymbolicModel::emit`] builds them and in the order its code writes them: what the
    /// interpreter of the generated model evaluates.
    pub fn function_outputs(&mut self) -> FunctionOutputs {
        let ids = |outputs: Vec<(TokenStream, Id)>| outputs.into_iter().map(|(_, id)| id).collect();
        let segment_transforms = ids(self.segment_outputs());
        let barriers = self.barrier_exprs();
        // The order `emit` follows: barrier terms first, then the joint terms.
        let barrier_terms: Vec<Id> = ids(self.barrier_term_outputs());
        let joint_terms: Vec<Id> = ids(self.joint_outputs());
        let model_terms = joint_terms.iter().chain(&barrier_terms).copied().collect();
        FunctionOutputs {
            segment_transforms,
            barriers,
            barrier_terms,
            joint_terms,
            model_terms,
        }
    }

    /// The places and values `barrier_terms` writes: each barrier, its Jacobian row (zero
    /// past the barrier's module) and `J̇q̇`.
    fn barrier_term_outputs(&mut self) -> Vec<(TokenStream, Id)> {
        let nq = self.nq();
        let zero = self.arena.constant(0.0);
        let mut outputs = Vec::new();
        for (k, (b, gradient, jdot)) in self.barrier_term_exprs().into_iter().enumerate() {
            let k_lit = Literal::usize_unsuffixed(k);
            outputs.push((quote!(barriers[#k_lit]), b));
            for col in 0..nq {
                let c_lit = Literal::usize_unsuffixed(col);
                let value = gradient.get(col).copied().unwrap_or(zero);
                outputs.push((quote!(jacobian[#k_lit][#c_lit]), value));
            }
            outputs.push((quote!(jdot_qd[#k_lit]), jdot));
        }
        outputs
    }

    /// The places and values `joint_terms` writes, module by module.
    fn joint_outputs(&mut self) -> Vec<(TokenStream, Id)> {
        let mut outputs = Vec::new();
        for i in 0..self.modules.len() {
            let (subspace, bias) = self.joint_exprs(i);
            let m = &self.modules[i];
            let i_lit = Literal::usize_unsuffixed(i);
            for r in 0..3 {
                let r_lit = Literal::usize_unsuffixed(r);
                for c in 0..3 {
                    let c_lit = Literal::usize_unsuffixed(c);
                    outputs.push((quote!(rotation[#i_lit][#r_lit][#c_lit]), m.rotation[r][c]));
                }
                outputs.push((quote!(translation[#i_lit][#r_lit]), m.translation[r]));
            }
            for (r, row) in subspace.iter().enumerate() {
                let r_lit = Literal::usize_unsuffixed(r);
                for (c, &value) in row.iter().enumerate() {
                    let c_lit = Literal::usize_unsuffixed(c);
                    outputs.push((quote!(motion_subspace[#i_lit][#r_lit][#c_lit]), value));
                }
                outputs.push((quote!(bias_acceleration[#i_lit][#r_lit]), bias[r]));
            }
        }
        outputs
    }

    /// Emits the whole model as one Rust source file (items only, to be `include!`d).
    pub fn emit(&mut self, source_label: &str) -> GeneratedSource {
        let n = Literal::usize_unsuffixed(self.modules.len());
        let nq_value = self.nq();
        let nq = Literal::usize_unsuffixed(nq_value);
        let nb = Literal::usize_unsuffixed(self.nb());
        let np = Literal::usize_unsuffixed(self.params.len());
        let n_modules = self.modules.len();
        let mut functions = Vec::new();
        let mut ops = Vec::new();
        let mut orders = std::collections::BTreeSet::new();
        let mut interval_emitted = Vec::new();
        let mut push = |name: &str, emitted: crate::emit::Emitted| {
            ops.push((name.to_string(), emitted.ops));
            orders.extend(emitted.analytic_orders);
            functions.push(emitted.tokens);
        };

        // Segment transforms T_i.
        let outputs = self.segment_outputs();
        let spec = FunctionSpec {
            name: format_ident!("segment_transforms"),
            doc: vec![
                " Segment transforms `T_i` (4×4, rows): tip coordinates → segment base coordinates.".into(),
            ],
            args: quote!(p: &[f64; NP], q: &[f64; NQ], transforms: &mut [[[f64; 4]; 4]; N_MODULES]),
            inputs: self.bindings(false),
            outputs,
            epilogue: quote! {
                for transform in transforms.iter_mut() {
                    transform[3] = [0.0, 0.0, 0.0, 1.0];
                }
            },
            scalar: Scalar::F64,
        };
        push("segment_transforms", emit_function(&self.arena, &spec));

        // Barriers alone.
        let barriers = self.barrier_exprs();
        let outputs = barriers
            .iter()
            .enumerate()
            .map(|(k, &b)| {
                let k = Literal::usize_unsuffixed(k);
                (quote!(barriers[#k]), b)
            })
            .collect();
        let spec = FunctionSpec {
            name: format_ident!("barriers"),
            doc: vec![
                " Every barrier value \\[m\\], in the order of [`BARRIERS`] (a plate corner's is"
                    .into(),
                " `b_ij = c_ij − ε_ij`).".into(),
            ],
            args: quote!(p: &[f64; NP], q: &[f64; NQ], barriers: &mut [f64; NB]),
            inputs: self.bindings(false),
            outputs,
            epilogue: TokenStream::new(),
            scalar: Scalar::F64,
        };
        push("barriers", emit_function(&self.arena, &spec));

        // The argument groups the three term functions share.
        let state_args = quote!(p: &[f64; NP], q: &[f64; NQ], qd: &[f64; NQ]);
        let joint_args = quote!(
            rotation: &mut [[[f64; 3]; 3]; N_MODULES],
            translation: &mut [[f64; 3]; N_MODULES],
            motion_subspace: &mut [[[f64; 3]; 6]; N_MODULES],
            bias_acceleration: &mut [[f64; 6]; N_MODULES]
        );
        let barrier_args = quote!(
            barriers: &mut [f64; NB],
            jacobian: &mut [[f64; NQ]; NB],
            jdot_qd: &mut [f64; NB]
        );

        // Barriers with Jacobian rows and J̇q̇.
        let barrier_outputs = self.barrier_term_outputs();
        let spec = FunctionSpec {
            name: format_ident!("barrier_terms"),
            doc: vec![
                " Every barrier `b` \\[m\\], its gradient row `J = ∂b/∂q` and `J̇q̇ = q̇ᵀ ∇²b q̇`."
                    .into(),
            ],
            args: quote!(#state_args, #barrier_args),
            inputs: self.bindings(true),
            outputs: barrier_outputs.clone(),
            epilogue: TokenStream::new(),
            scalar: Scalar::F64,
        };
        push("barrier_terms", emit_function(&self.arena, &spec));

        // Joint quantities for the recursive dynamics.
        let joint_outputs = self.joint_outputs();
        let spec = FunctionSpec {
            name: format_ident!("joint_terms"),
            doc: vec![
                " Per segment: rotation `R_i` and translation `t_i` of `T_i`, the motion subspace".into(),
                " `S_i` (6×3; rows ω then v, in tip coordinates, so the tip's body twist relative".into(),
                " to the segment base is `S_i q̇_i`) and `c_J,i = Ṡ_i q̇_i` (derivative in tip coordinates).".into(),
            ],
            args: quote!(#state_args, #joint_args),
            inputs: self.bindings(true),
            outputs: joint_outputs.clone(),
            epilogue: TokenStream::new(),
            scalar: Scalar::F64,
        };
        push("joint_terms", emit_function(&self.arena, &spec));

        // Both at once: one program, the kinematics and series shared.
        let spec = FunctionSpec {
            name: format_ident!("model_terms"),
            doc: vec![
                " Everything the control tick needs at one state in one pass: the outputs of"
                    .into(),
                " [`joint_terms`] and of [`barrier_terms`], same layouts, every shared term".into(),
                " (segment kinematics, `f_s`, `f_c` and their derivatives) computed once.".into(),
            ],
            args: quote!(#state_args, #joint_args, #barrier_args),
            inputs: self.bindings(true),
            outputs: joint_outputs
                .iter()
                .cloned()
                .chain(barrier_outputs.iter().cloned())
                .collect(),
            epilogue: TokenStream::new(),
            scalar: Scalar::F64,
        };
        push("model_terms", emit_function(&self.arena, &spec));

        let dual_joint_outputs = joint_outputs.clone();
        // Enclosures over boxes of states: the certified filter's remainder bounds
        // (docs/model.md §5). Parameters stay numbers; q and q̇ are intervals.
        let interval_state_args = quote!(p: &[f64; NP], q: &[Interval; NQ], qd: &[Interval; NQ]);
        let spec = FunctionSpec {
            name: format_ident!("barrier_terms_interval"),
            doc: vec![
                " Enclosures of [`barrier_terms`]' outputs over every state in the boxes `q`, `q̇`."
                    .into(),
            ],
            args: quote!(
                #interval_state_args,
                barriers: &mut [Interval; NB],
                jacobian: &mut [[Interval; NQ]; NB],
                jdot_qd: &mut [Interval; NB]
            ),
            inputs: self.bindings(true),
            outputs: barrier_outputs,
            epilogue: TokenStream::new(),
            scalar: Scalar::Interval,
        };
        interval_emitted.push(("barrier_terms_interval", emit_function(&self.arena, &spec)));
        let spec = FunctionSpec {
            name: format_ident!("joint_terms_interval"),
            doc: vec![
                " Enclosures of [`joint_terms`]' outputs over every state in the boxes `q`, `q̇`."
                    .into(),
            ],
            args: quote!(
                #interval_state_args,
                rotation: &mut [[[Interval; 3]; 3]; N_MODULES],
                translation: &mut [[Interval; 3]; N_MODULES],
                motion_subspace: &mut [[[Interval; 3]; 6]; N_MODULES],
                bias_acceleration: &mut [[Interval; 6]; N_MODULES]
            ),
            inputs: self.bindings(true),
            outputs: joint_outputs.clone(),
            epilogue: TokenStream::new(),
            scalar: Scalar::Interval,
        };
        interval_emitted.push(("joint_terms_interval", emit_function(&self.arena, &spec)));
        let spec = FunctionSpec {
            name: format_ident!("joint_terms_dual"),
            doc: vec![
                " Jets of [`joint_terms`]' outputs: enclosures over every state in the boxes"
                    .into(),
                " `q`, `q̇` (the jets' values) and of their derivatives along the jets' slopes."
                    .into(),
            ],
            args: quote!(
                p: &[f64; NP],
                q: &[Dual; NQ],
                qd: &[Dual; NQ],
                rotation: &mut [[[Dual; 3]; 3]; N_MODULES],
                translation: &mut [[Dual; 3]; N_MODULES],
                motion_subspace: &mut [[[Dual; 3]; 6]; N_MODULES],
                bias_acceleration: &mut [[Dual; 6]; N_MODULES]
            ),
            inputs: self.bindings(true),
            outputs: dual_joint_outputs,
            epilogue: TokenStream::new(),
            scalar: Scalar::Dual,
        };
        let dual = emit_function(&self.arena, &spec);
        let dual_orders: Vec<usize> = dual.analytic_orders.iter().copied().collect();
        interval_emitted.push(("joint_terms_dual", dual));
        let mut interval_orders = std::collections::BTreeSet::new();
        for (name, emitted) in interval_emitted {
            ops.push((name.to_string(), emitted.ops));
            if name != "joint_terms_dual" {
                interval_orders.extend(emitted.analytic_orders);
            }
            functions.push(emitted.tokens);
        }
        for &k in &dual_orders {
            orders.insert(k + 1);
            interval_orders.insert(k + 1);
        }

        let plate_poses = quote! {
            /// World poses `W_i = T_1 ⋯ T_i` of every module's top plate (4×4, rows).
            pub fn plate_poses(p: &[f64; NP], q: &[f64; NQ], poses: &mut [[[f64; 4]; 4]; N_MODULES]) {
                segment_transforms(p, q, poses);
                for i in 1..N_MODULES {
                    let parent = poses[i - 1];
                    let local = poses[i];
                    for r in 0..3 {
                        for c in 0..4 {
                            let mut sum = if c == 3 { parent[r][3] } else { 0.0 };
                            for k in 0..3 {
                                sum += parent[r][k] * local[k][c];
                            }
                            poses[i][r][c] = sum;
                        }
                    }
                }
            }
        };

        let analytic_functions = orders
            .iter()
            .map(|&k| analytic::emit(k))
            .chain(interval_orders.iter().map(|&k| analytic::emit_interval(k)))
            .chain(dual_orders.iter().map(|&k| analytic::emit_dual(k)));
        let names = self.param_names.iter().map(String::as_str);
        let corners = self
            .structure
            .corners
            .iter()
            .map(|&c| Literal::usize_unsuffixed(c));
        let tendons = self
            .structure
            .tendons
            .iter()
            .map(|&c| Literal::usize_unsuffixed(c));
        let barrier_table = self.barriers.iter().map(|b| {
            let kind = format_ident!("{}", b.kind.name());
            let module = Literal::usize_unsuffixed(b.module);
            let point = match b.point {
                None => quote!(None),
                Some(Point::Corner(j)) => {
                    let j = Literal::usize_unsuffixed(j);
                    quote!(Some(Point::Corner(#j)))
                }
                Some(Point::Centre) => quote!(Some(Point::Centre)),
                Some(Point::Listed(k)) => {
                    let k = Literal::usize_unsuffixed(k);
                    quote!(Some(Point::Listed(#k)))
                }
                Some(Point::Arc(k)) => {
                    let k = Literal::usize_unsuffixed(k);
                    quote!(Some(Point::Arc(#k)))
                }
            };
            let obstacle = match b.obstacle {
                None => quote!(None),
                Some(o) => {
                    let o = Literal::usize_unsuffixed(o);
                    quote!(Some(#o))
                }
            };
            let label = &b.label;
            let params = b.params.iter().map(|&k| Literal::usize_unsuffixed(k));
            quote! {
                BarrierInfo {
                    kind: BarrierKind::#kind,
                    module: #module,
                    point: #point,
                    obstacle: #obstacle,
                    label: #label,
                    params: &[#(#params),*],
                }
            }
        });
        let tokens = quote! {
            use crate::{BarrierInfo, BarrierKind, Dual, Interval, Point};
            /// Number of modules.
            pub const N_MODULES: usize = #n;
            /// Number of generalized coordinates (3 per module).
            pub const NQ: usize = #nq;
            /// Number of barriers.
            pub const NB: usize = #nb;
            /// Length of the parameter vector.
            pub const NP: usize = #np;
            /// Name of each parameter, in parameter-vector order.
            pub const PARAM_NAMES: [&str; NP] = [#(#names),*];
            /// Corners per plate, one entry per module.
            pub const CORNERS: [usize; N_MODULES] = [#(#corners),*];
            /// Tendons per module.
            pub const TENDONS: [usize; N_MODULES] = [#(#tendons),*];
            /// Every barrier, in the order of the barrier arrays (module and point 0-based).
            pub const BARRIERS: [BarrierInfo; NB] = [#(#barrier_table),*];
            #(#analytic_functions)*
            #(#functions)*
            #plate_poses
        };
        let mut header = format!(
            "// Generated by softcbf-codegen from {source_label}; do not edit by hand.\n\
             // Regenerate: cargo run -p softcbf-codegen -- --robot {source_label} --out FILE.rs\n\
             // Structure: {n_modules} modules, corners {:?}, tendons {:?}, routing {:?}.\n\
             // Operations per call (add, mul, div, sqrt/trig, analytic):\n",
            self.structure.corners, self.structure.tendons, self.structure.routing
        );
        {
            let corners: usize = self.structure.corners.iter().sum();
            let watched: usize = self.structure.obstacles.iter().map(|o| o.watch.len()).sum();
            let at = header.find("// Operations").unwrap_or(header.len());
            header.insert_str(
                at,
                &format!(
                    "// Barriers: {} ({corners} plate corners, {} limits: 3 per module, \
                     {watched} obstacle points).\n",
                    self.barriers.len(),
                    3 * n_modules,
                ),
            );
        }
        for (name, count) in &ops {
            header.push_str(&format!(
                "//   {name}: {} ({}, {}, {}, {}, {})\n",
                count.total(),
                count.add,
                count.mul,
                count.div,
                count.special,
                count.analytic
            ));
        }
        header.push('\n');
        GeneratedSource {
            text: header + &format_file(tokens),
            ops,
        }
    }
}

/// Generates the model source for a structure in one call.
pub fn generate(structure: &Structure, source_label: &str) -> GeneratedSource {
    build(structure).emit(source_label)
}
