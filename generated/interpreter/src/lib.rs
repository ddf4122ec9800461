//! softcbf-interpreter: the model of any structure evaluated at run time: codegen's
//! expressions for the structure, scheduled once, run by `softcbf_codegen::eval`.
//!
//! A slower fallback for a structure that was not compiled in: [`interpreted`] builds the
//! symbolic model (about 2 ms for three modules), schedules one program per generated
//! function and leaks the result once per structure key, so later calls return the same
//! model. Each call copies constants and inputs into a thread-local buffer (grown once per
//! thread, never per call) and runs the steps the emitted code would: the same operations
//! in the same order, so it agrees with the compiled model to the bit (tests/tests/model/interpreter.rs).

use std::cell::RefCell;
use std::sync::Mutex;

use softcbf_codegen::eval::Compiled;
use softcbf_codegen::model::build;
use softcbf_description::robot::{Routing, Structure};

use softcbf_generated::{BarrierInfo, Dual, GeneratedModel, Interval};

/// A structure's model run by the interpreter; see [`interpreted`].
pub struct Interpreted {
    corners: &'static [usize],
    tendons: &'static [usize],
    routing: &'static str,
    key: &'static str,
    param_names: &'static [&'static str],
    barrier_table: &'static [BarrierInfo],
    np: usize,
    segment_transforms: Compiled,
    barriers: Compiled,
    barrier_terms: Compiled,
    joint_terms: Compiled,
    model_terms: Compiled,
}

thread_local! {
    /// The value slots of the program being run on this thread (the longest any program
    /// of any interpreted model needs, grown on first use).
    static VALUES: RefCell<Vec<f64>> = const { RefCell::new(Vec::new()) };
    /// The interval functions' slots, and the parameters as point intervals.
    static INTERVALS: RefCell<(Vec<Interval>, Vec<Interval>)> =
        const { RefCell::new((Vec::new(), Vec::new())) };
    /// The same for the jets.
    static DUALS: RefCell<(Vec<Dual>, Vec<Dual>)> = const { RefCell::new((Vec::new(), Vec::new())) };
}

/// Models built so far, one per structure key (leaked: they live as long as the process).
static BUILT: Mutex<Vec<&'static Interpreted>> = Mutex::new(Vec::new());

/// The model of `structure` evaluated at run time from its expressions: the same values as
/// the generated code would compute (bit for bit), several times slower. Built on first use
/// per structure and kept for the life of the process.
pub fn interpreted(structure: &Structure) -> &'static dyn GeneratedModel {
    let key = structure.key();
    // A poisoned lock only means another thread panicked while building: the list itself
    // is always whole (a push is the only write).
    let mut built = BUILT.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(&model) = built.iter().find(|m| m.key == key) {
        return model;
    }
    let model: &'static Interpreted = Box::leak(Box::new(Interpreted::new(structure, key)));
    built.push(model);
    model
}

fn leak<T>(items: Vec<T>) -> &'static [T] {
    Box::leak(items.into_boxed_slice())
}

impl Interpreted {
    fn new(structure: &Structure, key: String) -> Interpreted {
        let mut symbolic = build(structure);
        let outputs = symbolic.function_outputs();
        let (params, q, qd) = symbolic.input_symbols();
        let arena = symbolic.arena();
        let positions: Vec<_> = params.iter().chain(&q).copied().collect();
        let states: Vec<_> = positions.iter().chain(&qd).copied().collect();
        let barrier_table = symbolic
            .barrier_list()
            .iter()
            .map(|b| BarrierInfo {
                kind: b.kind,
                module: b.module,
                point: b.point,
                obstacle: b.obstacle,
                label: Box::leak(b.label.clone().into_boxed_str()),
                params: leak(b.params.clone()),
            })
            .collect();
        let param_names = symbolic
            .param_names()
            .iter()
            .map(|name| &*Box::leak(name.clone().into_boxed_str()))
            .collect();
        Interpreted {
            corners: leak(structure.corners.clone()),
            tendons: leak(structure.tendons.clone()),
            routing: match structure.routing {
                Routing::Local => "local",
                Routing::Through => "through",
            },
            key: Box::leak(key.into_boxed_str()),
            param_names: leak(param_names),
            barrier_table: leak(barrier_table),
            np: params.len(),
            segment_transforms: Compiled::new(arena, &positions, &outputs.segment_transforms),
            barriers: Compiled::new(arena, &positions, &outputs.barriers),
            barrier_terms: Compiled::new(arena, &states, &outputs.barrier_terms),
            joint_terms: Compiled::new(arena, &states, &outputs.joint_terms),
            model_terms: Compiled::new(arena, &states, &outputs.model_terms),
        }
    }

    /// Checks the argument lengths, runs `program` and hands its outputs, in order, to
    /// `write`.
    fn run(
        &self,
        program: &Compiled,
        p: &[f64],
        q: &[f64],
        qd: Option<&[f64]>,
        write: impl FnOnce(&mut dyn Iterator<Item = f64>),
    ) {
        let nq = self.nq();
        assert_eq!(
            p.len(),
            self.np,
            "p: length {} instead of {}",
            p.len(),
            self.np
        );
        assert_eq!(q.len(), nq, "q: length {} instead of {nq}", q.len());
        if let Some(qd) = qd {
            assert_eq!(qd.len(), nq, "qd: length {} instead of {nq}", qd.len());
        }
        VALUES.with_borrow_mut(|values| {
            if values.len() < program.slots() {
                values.resize(program.slots(), 0.0);
            }
            match qd {
                Some(qd) => program.run(&[p, q, qd], values),
                None => program.run(&[p, q], values),
            }
            write(&mut program.output_values(values));
        });
    }
}

/// `slice` with its length checked against `len` (as the compiled models check theirs).
impl Interpreted {
    /// [`Interpreted::run`] on jets: the parameters as constants, `q`, `q̇` as jets.
    fn run_dual(
        &self,
        program: &Compiled,
        p: &[f64],
        q: &[Dual],
        qd: &[Dual],
        write: impl FnOnce(&mut dyn Iterator<Item = Dual>),
    ) {
        let nq = self.nq();
        assert_eq!(
            p.len(),
            self.np,
            "p: length {} instead of {}",
            p.len(),
            self.np
        );
        assert_eq!(q.len(), nq, "q: length {} instead of {nq}", q.len());
        assert_eq!(qd.len(), nq, "qd: length {} instead of {nq}", qd.len());
        DUALS.with_borrow_mut(|(values, params)| {
            if values.len() < program.slots() {
                values.resize(program.slots(), Dual::default());
            }
            params.clear();
            params.extend(p.iter().map(|&x| Dual::from(x)));
            program.run(&[&params[..], q, qd], values);
            write(&mut program.output_values(values));
        });
    }

    /// [`Interpreted::run`] on intervals: the parameters as points, `q`, `q̇` as boxes.
    fn run_interval(
        &self,
        program: &Compiled,
        p: &[f64],
        q: &[Interval],
        qd: &[Interval],
        write: impl FnOnce(&mut dyn Iterator<Item = Interval>),
    ) {
        let nq = self.nq();
        assert_eq!(
            p.len(),
            self.np,
            "p: length {} instead of {}",
            p.len(),
            self.np
        );
        assert_eq!(q.len(), nq, "q: length {} instead of {nq}", q.len());
        assert_eq!(qd.len(), nq, "qd: length {} instead of {nq}", qd.len());
        INTERVALS.with_borrow_mut(|(values, params)| {
            if values.len() < program.slots() {
                values.resize(program.slots(), Interval::ZERO);
            }
            params.clear();
            params.extend(p.iter().map(|&x| Interval::point(x)));
            program.run(&[&params[..], q, qd], values);
            write(&mut program.output_values(values));
        });
    }
}

fn sized<'a, T>(slice: &'a mut [T], len: usize, what: &str) -> &'a mut [T] {
    assert_eq!(
        slice.len(),
        len,
        "{what}: length {} instead of {len}",
        slice.len()
    );
    slice
}

/// Writes the joint terms, in [`softcbf_codegen::source::FunctionOutputs::joint_terms`]'s
/// order.
fn write_joint_terms<T>(
    values: &mut dyn Iterator<Item = T>,
    rotation: &mut [[[T; 3]; 3]],
    translation: &mut [[T; 3]],
    motion_subspace: &mut [[[T; 3]; 6]],
    bias_acceleration: &mut [[T; 6]],
) {
    let mut next = || values.next().expect("one value per output");
    let modules = rotation
        .iter_mut()
        .zip(translation.iter_mut())
        .zip(motion_subspace.iter_mut().zip(bias_acceleration.iter_mut()));
    for ((rotation, translation), (subspace, bias)) in modules {
        for (row, t) in rotation.iter_mut().zip(translation.iter_mut()) {
            row.iter_mut().for_each(|entry| *entry = next());
            *t = next();
        }
        for (row, c) in subspace.iter_mut().zip(bias.iter_mut()) {
            row.iter_mut().for_each(|entry| *entry = next());
            *c = next();
        }
    }
}

/// Writes the barrier terms, in [`softcbf_codegen::source::FunctionOutputs::barrier_terms`]'s
/// order.
fn write_barrier_terms<T>(
    values: &mut dyn Iterator<Item = T>,
    barriers: &mut [T],
    jacobian: &mut [T],
    jdot_qd: &mut [T],
) {
    let nq = jacobian.len() / barriers.len().max(1);
    let mut next = || values.next().expect("one value per output");
    for k in 0..barriers.len() {
        barriers[k] = next();
        for entry in &mut jacobian[k * nq..(k + 1) * nq] {
            *entry = next();
        }
        jdot_qd[k] = next();
    }
}

impl GeneratedModel for Interpreted {
    fn name(&self) -> &'static str {
        "interpreted"
    }
    fn source(&self) -> &'static str {
        "the structure's expressions, interpreted at run time"
    }
    fn corners(&self) -> &'static [usize] {
        self.corners
    }
    fn tendons(&self) -> &'static [usize] {
        self.tendons
    }
    fn routing(&self) -> &'static str {
        self.routing
    }
    fn structure_key(&self) -> &'static str {
        self.key
    }
    fn param_names(&self) -> &'static [&'static str] {
        self.param_names
    }
    fn barrier_table(&self) -> &'static [BarrierInfo] {
        self.barrier_table
    }
    fn segment_transforms(&self, p: &[f64], q: &[f64], transforms: &mut [[[f64; 4]; 4]]) {
        let transforms = sized(transforms, self.n_modules(), "transforms");
        self.run(&self.segment_transforms, p, q, None, |values| {
            for transform in transforms.iter_mut() {
                for row in transform.iter_mut().take(3) {
                    for entry in row.iter_mut() {
                        *entry = values.next().expect("one value per output");
                    }
                }
                transform[3] = [0.0, 0.0, 0.0, 1.0];
            }
        });
    }
    fn plate_poses(&self, p: &[f64], q: &[f64], poses: &mut [[[f64; 4]; 4]]) {
        // The generated `plate_poses`, line for line.
        self.segment_transforms(p, q, poses);
        for i in 1..poses.len() {
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
    fn barriers(&self, p: &[f64], q: &[f64], barriers: &mut [f64]) {
        let barriers = sized(barriers, self.nb(), "barriers");
        self.run(&self.barriers, p, q, None, |values| {
            for (b, v) in barriers.iter_mut().zip(values) {
                *b = v;
            }
        });
    }
    fn barrier_terms(
        &self,
        p: &[f64],
        q: &[f64],
        qd: &[f64],
        barriers: &mut [f64],
        jacobian: &mut [f64],
        jdot_qd: &mut [f64],
    ) {
        let (nb, nq) = (self.nb(), self.nq());
        let barriers = sized(barriers, nb, "barriers");
        let jacobian = sized(jacobian, nb * nq, "jacobian");
        let jdot_qd = sized(jdot_qd, nb, "jdot_qd");
        self.run(&self.barrier_terms, p, q, Some(qd), |values| {
            write_barrier_terms(values, barriers, jacobian, jdot_qd)
        });
    }
    fn model_terms(
        &self,
        p: &[f64],
        q: &[f64],
        qd: &[f64],
        rotation: &mut [[[f64; 3]; 3]],
        translation: &mut [[f64; 3]],
        motion_subspace: &mut [[[f64; 3]; 6]],
        bias_acceleration: &mut [[f64; 6]],
        barriers: &mut [f64],
        jacobian: &mut [f64],
        jdot_qd: &mut [f64],
    ) {
        let (n, nb, nq) = (self.n_modules(), self.nb(), self.nq());
        let rotation = sized(rotation, n, "rotation");
        let translation = sized(translation, n, "translation");
        let motion_subspace = sized(motion_subspace, n, "motion_subspace");
        let bias_acceleration = sized(bias_acceleration, n, "bias_acceleration");
        let barriers = sized(barriers, nb, "barriers");
        let jacobian = sized(jacobian, nb * nq, "jacobian");
        let jdot_qd = sized(jdot_qd, nb, "jdot_qd");
        self.run(&self.model_terms, p, q, Some(qd), |values| {
            write_joint_terms(
                values,
                rotation,
                translation,
                motion_subspace,
                bias_acceleration,
            );
            write_barrier_terms(values, barriers, jacobian, jdot_qd);
        });
    }
    fn joint_terms(
        &self,
        p: &[f64],
        q: &[f64],
        qd: &[f64],
        rotation: &mut [[[f64; 3]; 3]],
        translation: &mut [[f64; 3]],
        motion_subspace: &mut [[[f64; 3]; 6]],
        bias_acceleration: &mut [[f64; 6]],
    ) {
        let n = self.n_modules();
        let rotation = sized(rotation, n, "rotation");
        let translation = sized(translation, n, "translation");
        let motion_subspace = sized(motion_subspace, n, "motion_subspace");
        let bias_acceleration = sized(bias_acceleration, n, "bias_acceleration");
        self.run(&self.joint_terms, p, q, Some(qd), |values| {
            write_joint_terms(
                values,
                rotation,
                translation,
                motion_subspace,
                bias_acceleration,
            )
        });
    }
    fn barrier_terms_interval(
        &self,
        p: &[f64],
        q: &[Interval],
        qd: &[Interval],
        barriers: &mut [Interval],
        jacobian: &mut [Interval],
        jdot_qd: &mut [Interval],
    ) {
        let (nb, nq) = (self.nb(), self.nq());
        let barriers = sized(barriers, nb, "barriers");
        let jacobian = sized(jacobian, nb * nq, "jacobian");
        let jdot_qd = sized(jdot_qd, nb, "jdot_qd");
        self.run_interval(&self.barrier_terms, p, q, qd, |values| {
            write_barrier_terms(values, barriers, jacobian, jdot_qd)
        });
    }
    fn joint_terms_interval(
        &self,
        p: &[f64],
        q: &[Interval],
        qd: &[Interval],
        rotation: &mut [[[Interval; 3]; 3]],
        translation: &mut [[Interval; 3]],
        motion_subspace: &mut [[[Interval; 3]; 6]],
        bias_acceleration: &mut [[Interval; 6]],
    ) {
        let n = self.n_modules();
        let rotation = sized(rotation, n, "rotation");
        let translation = sized(translation, n, "translation");
        let motion_subspace = sized(motion_subspace, n, "motion_subspace");
        let bias_acceleration = sized(bias_acceleration, n, "bias_acceleration");
        self.run_interval(&self.joint_terms, p, q, qd, |values| {
            write_joint_terms(
                values,
                rotation,
                translation,
                motion_subspace,
                bias_acceleration,
            )
        });
    }
    fn joint_terms_dual(
        &self,
        p: &[f64],
        q: &[Dual],
        qd: &[Dual],
        rotation: &mut [[[Dual; 3]; 3]],
        translation: &mut [[Dual; 3]],
        motion_subspace: &mut [[[Dual; 3]; 6]],
        bias_acceleration: &mut [[Dual; 6]],
    ) {
        let n = self.n_modules();
        let rotation = sized(rotation, n, "rotation");
        let translation = sized(translation, n, "translation");
        let motion_subspace = sized(motion_subspace, n, "motion_subspace");
        let bias_acceleration = sized(bias_acceleration, n, "bias_acceleration");
        self.run_dual(&self.joint_terms, p, q, qd, |values| {
            write_joint_terms(
                values,
                rotation,
                translation,
                motion_subspace,
                bias_acceleration,
            )
        });
    }
}
