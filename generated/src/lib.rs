//! softcbf-generated: the robot models emitted by `softcbf-codegen` at build time.
//!
//! `build.rs` generates one module per robot structure found in the workspace's `robots/`
//! directory, registered in `robots/local.list` (`softcbf-codegen add FILE`) or listed in
//! `SOFTCBF_ROBOTS`; each module has array-typed functions
//! (`segment_transforms`, `plate_poses`, `barriers`, `barrier_terms`, `joint_terms`,
//! `model_terms`), the table `BARRIERS` of what each barrier is ([`BarrierInfo`]) and a
//! `Model` implementing [`GeneratedModel`], the slice-based interface the runtime uses,
//! and `SOURCE`, the generated text it was compiled from (`golden/paper_sim.rs` is the
//! checked-in copy of the paper robot's, compared by the `golden` test of softcbf-tests).
//! [`find`] picks the model of a structure. Numbers are never compiled in: every function
//! takes the parameter vector `p` laid out by `softcbf_description::layout`. The crate
//! `softcbf-interpreter` (`generated/interpreter`) gives the model of any structure,
//! evaluated at run time from the same expressions (several times slower).

pub use softcbf_description::barriers::{BarrierKind, KindGroup, Point};
pub use softcbf_interval::{Dual, Interval};

/// One row of a model's barrier table: which barrier sits at an index of the barrier
/// arrays (`barriers`, the Jacobian rows, `J̇q̇`). The rows are those of
/// `softcbf_description::barriers::barrier_list` for the model's structure, in its order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BarrierInfo {
    /// What it keeps apart.
    pub kind: BarrierKind,
    /// The module it belongs to, **0-based** (base first). Its Jacobian row is zero past
    /// this module's coordinates `3·module..3·module + 3`.
    pub module: usize,
    /// The watched point, **0-based** (for a plate corner: `Point::Corner(j)`); `None` for
    /// a limit.
    pub point: Option<Point>,
    /// The obstacle, **0-based** in the robot file's order, for an environment barrier.
    pub obstacle: Option<usize>,
    /// A short stable name for reports and logs, **1-based**: `module 1 corner 3`.
    pub label: &'static str,
    /// Parameter-vector indices the barrier reads, ascending.
    pub params: &'static [usize],
}

impl BarrierInfo {
    /// The corner index (0-based) for a plate-corner barrier.
    pub fn corner(&self) -> Option<usize> {
        match (self.kind, self.point) {
            (BarrierKind::PlateCorner, Some(Point::Corner(j))) => Some(j),
            _ => None,
        }
    }
}

/// A generated model behind slices, so the runtime can choose it at run time.
///
/// Every slice must have the length the model's sizes give (checked; a wrong length
/// panics, since it is a programming error of the caller, never a user input).
pub trait GeneratedModel: Sync {
    /// Module name inside this crate (e.g. `paper_sim`).
    fn name(&self) -> &'static str;
    /// The robot file it was generated from.
    fn source(&self) -> &'static str;
    /// Corners per plate, per module.
    fn corners(&self) -> &'static [usize];
    /// Tendons per module.
    fn tendons(&self) -> &'static [usize];
    /// Tendon routing, `"local"` or `"through"`.
    fn routing(&self) -> &'static str;
    /// The key of the structure it was generated for
    /// (`softcbf_description::Structure::key`).
    fn structure_key(&self) -> &'static str;
    /// Parameter names in parameter-vector order.
    fn param_names(&self) -> &'static [&'static str];
    /// Every barrier, in the order of the barrier arrays.
    fn barrier_table(&self) -> &'static [BarrierInfo];
    /// Number of modules.
    fn n_modules(&self) -> usize {
        self.corners().len()
    }
    /// Number of generalized coordinates.
    fn nq(&self) -> usize {
        3 * self.n_modules()
    }
    /// Number of barriers (rows of [`GeneratedModel::barrier_table`]).
    fn nb(&self) -> usize {
        self.barrier_table().len()
    }
    /// Segment transforms `T_i`.
    fn segment_transforms(&self, p: &[f64], q: &[f64], transforms: &mut [[[f64; 4]; 4]]);
    /// World plate poses `W_i`.
    fn plate_poses(&self, p: &[f64], q: &[f64], poses: &mut [[[f64; 4]; 4]]);
    /// Barrier values.
    fn barriers(&self, p: &[f64], q: &[f64], barriers: &mut [f64]);
    /// Barriers, Jacobian rows (row-major `nb × nq`) and `J̇q̇`.
    fn barrier_terms(
        &self,
        p: &[f64],
        q: &[f64],
        qd: &[f64],
        barriers: &mut [f64],
        jacobian: &mut [f64],
        jdot_qd: &mut [f64],
    );
    /// Everything the control tick needs from the model at one state, in one generated
    /// pass (the segment kinematics and the small-θ series evaluated once): the joint terms
    /// of [`GeneratedModel::joint_terms`] and the barrier terms of
    /// [`GeneratedModel::barrier_terms`], same layouts.
    #[allow(clippy::too_many_arguments)]
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
    );
    /// Per-segment `R_i`, `t_i`, motion subspace `S_i` and `c_J,i = Ṡ_i q̇_i`.
    #[allow(clippy::too_many_arguments)]
    fn joint_terms(
        &self,
        p: &[f64],
        q: &[f64],
        qd: &[f64],
        rotation: &mut [[[f64; 3]; 3]],
        translation: &mut [[f64; 3]],
        motion_subspace: &mut [[[f64; 3]; 6]],
        bias_acceleration: &mut [[f64; 6]],
    );
    /// Enclosures of [`GeneratedModel::barrier_terms`] over every state in the boxes `q`,
    /// `q̇` (`nq` intervals each, \[m\], \[m/s\]): each barrier \[m\] (`nb`), its Jacobian
    /// row-major (`nb × nq`) and `J̇q̇` \[m/s²\] (`nb`). Parameters `p` are numbers.
    /// Panics on wrong lengths, like the `f64` functions.
    #[allow(clippy::too_many_arguments)]
    fn barrier_terms_interval(
        &self,
        p: &[f64],
        q: &[Interval],
        qd: &[Interval],
        barriers: &mut [Interval],
        jacobian: &mut [Interval],
        jdot_qd: &mut [Interval],
    );
    /// Enclosures of [`GeneratedModel::joint_terms`] over every state in the boxes `q`,
    /// `q̇` (same layouts, one entry per module).
    #[allow(clippy::too_many_arguments)]
    fn joint_terms_interval(
        &self,
        p: &[f64],
        q: &[Interval],
        qd: &[Interval],
        rotation: &mut [[[Interval; 3]; 3]],
        translation: &mut [[Interval; 3]],
        motion_subspace: &mut [[[Interval; 3]; 6]],
        bias_acceleration: &mut [[Interval; 6]],
    );
    /// Jets of [`GeneratedModel::joint_terms`] (value enclosures over the boxes `q`, `q̇`
    /// and enclosures of their derivatives along the inputs' slopes).
    #[allow(clippy::too_many_arguments)]
    fn joint_terms_dual(
        &self,
        p: &[f64],
        q: &[Dual],
        qd: &[Dual],
        rotation: &mut [[[Dual; 3]; 3]],
        translation: &mut [[Dual; 3]],
        motion_subspace: &mut [[[Dual; 3]; 6]],
        bias_acceleration: &mut [[Dual; 6]],
    );
}

/// Implements [`GeneratedModel`] for the functions of a generated module.
#[macro_export]
#[doc(hidden)]
macro_rules! impl_generated_model {
    ($model:ident, $name:literal, $source:literal, $routing:literal) => {
        fn sized<'a, T, const N: usize>(s: &'a [T], what: &str) -> &'a [T; N] {
            s.try_into()
                .unwrap_or_else(|_| panic!("{what}: length {} instead of {N}", s.len()))
        }
        fn sized_mut<'a, T, const N: usize>(s: &'a mut [T], what: &str) -> &'a mut [T; N] {
            let len = s.len();
            s.try_into()
                .unwrap_or_else(|_| panic!("{what}: length {len} instead of {N}"))
        }
        impl $crate::GeneratedModel for $model {
            fn name(&self) -> &'static str {
                $name
            }
            fn source(&self) -> &'static str {
                $source
            }
            fn corners(&self) -> &'static [usize] {
                &CORNERS
            }
            fn tendons(&self) -> &'static [usize] {
                &TENDONS
            }
            fn routing(&self) -> &'static str {
                $routing
            }
            fn structure_key(&self) -> &'static str {
                STRUCTURE_KEY
            }
            fn param_names(&self) -> &'static [&'static str] {
                &PARAM_NAMES
            }
            fn barrier_table(&self) -> &'static [$crate::BarrierInfo] {
                &BARRIERS
            }
            fn segment_transforms(&self, p: &[f64], q: &[f64], transforms: &mut [[[f64; 4]; 4]]) {
                segment_transforms(
                    sized(p, "p"),
                    sized(q, "q"),
                    sized_mut(transforms, "transforms"),
                )
            }
            fn plate_poses(&self, p: &[f64], q: &[f64], poses: &mut [[[f64; 4]; 4]]) {
                plate_poses(sized(p, "p"), sized(q, "q"), sized_mut(poses, "poses"))
            }
            fn barriers(&self, p: &[f64], q: &[f64], b: &mut [f64]) {
                barriers(sized(p, "p"), sized(q, "q"), sized_mut(b, "barriers"))
            }
            fn barrier_terms(
                &self,
                p: &[f64],
                q: &[f64],
                qd: &[f64],
                b: &mut [f64],
                jacobian: &mut [f64],
                jdot_qd: &mut [f64],
            ) {
                let (rows, rest) = jacobian.as_chunks_mut::<NQ>();
                assert!(rest.is_empty(), "jacobian: length not a multiple of {NQ}");
                barrier_terms(
                    sized(p, "p"),
                    sized(q, "q"),
                    sized(qd, "qd"),
                    sized_mut(b, "barriers"),
                    sized_mut(rows, "jacobian"),
                    sized_mut(jdot_qd, "jdot_qd"),
                )
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
                b: &mut [f64],
                jacobian: &mut [f64],
                jdot_qd: &mut [f64],
            ) {
                let (rows, rest) = jacobian.as_chunks_mut::<NQ>();
                assert!(rest.is_empty(), "jacobian: length not a multiple of {NQ}");
                model_terms(
                    sized(p, "p"),
                    sized(q, "q"),
                    sized(qd, "qd"),
                    sized_mut(rotation, "rotation"),
                    sized_mut(translation, "translation"),
                    sized_mut(motion_subspace, "motion_subspace"),
                    sized_mut(bias_acceleration, "bias_acceleration"),
                    sized_mut(b, "barriers"),
                    sized_mut(rows, "jacobian"),
                    sized_mut(jdot_qd, "jdot_qd"),
                )
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
                joint_terms(
                    sized(p, "p"),
                    sized(q, "q"),
                    sized(qd, "qd"),
                    sized_mut(rotation, "rotation"),
                    sized_mut(translation, "translation"),
                    sized_mut(motion_subspace, "motion_subspace"),
                    sized_mut(bias_acceleration, "bias_acceleration"),
                )
            }
            fn barrier_terms_interval(
                &self,
                p: &[f64],
                q: &[$crate::Interval],
                qd: &[$crate::Interval],
                b: &mut [$crate::Interval],
                jacobian: &mut [$crate::Interval],
                jdot_qd: &mut [$crate::Interval],
            ) {
                let (rows, rest) = jacobian.as_chunks_mut::<NQ>();
                assert!(rest.is_empty(), "jacobian: length not a multiple of {NQ}");
                barrier_terms_interval(
                    sized(p, "p"),
                    sized(q, "q"),
                    sized(qd, "qd"),
                    sized_mut(b, "barriers"),
                    sized_mut(rows, "jacobian"),
                    sized_mut(jdot_qd, "jdot_qd"),
                )
            }
            fn joint_terms_interval(
                &self,
                p: &[f64],
                q: &[$crate::Interval],
                qd: &[$crate::Interval],
                rotation: &mut [[[$crate::Interval; 3]; 3]],
                translation: &mut [[$crate::Interval; 3]],
                motion_subspace: &mut [[[$crate::Interval; 3]; 6]],
                bias_acceleration: &mut [[$crate::Interval; 6]],
            ) {
                joint_terms_interval(
                    sized(p, "p"),
                    sized(q, "q"),
                    sized(qd, "qd"),
                    sized_mut(rotation, "rotation"),
                    sized_mut(translation, "translation"),
                    sized_mut(motion_subspace, "motion_subspace"),
                    sized_mut(bias_acceleration, "bias_acceleration"),
                )
            }
            fn joint_terms_dual(
                &self,
                p: &[f64],
                q: &[$crate::Dual],
                qd: &[$crate::Dual],
                rotation: &mut [[[$crate::Dual; 3]; 3]],
                translation: &mut [[$crate::Dual; 3]],
                motion_subspace: &mut [[[$crate::Dual; 3]; 6]],
                bias_acceleration: &mut [[$crate::Dual; 6]],
            ) {
                joint_terms_dual(
                    sized(p, "p"),
                    sized(q, "q"),
                    sized(qd, "qd"),
                    sized_mut(rotation, "rotation"),
                    sized_mut(translation, "translation"),
                    sized_mut(motion_subspace, "motion_subspace"),
                    sized_mut(bias_acceleration, "bias_acceleration"),
                )
            }
        }
    };
}

include!(concat!(env!("OUT_DIR"), "/models.rs"));

/// The model generated for a structure (corners, tendons, routing, limits and obstacles).
pub fn find(structure: &softcbf_description::Structure) -> Option<&'static dyn GeneratedModel> {
    let key = structure.key();
    MODELS.iter().copied().find(|m| m.structure_key() == key)
}
