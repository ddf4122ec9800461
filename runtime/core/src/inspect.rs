//! `softcbf model`: every generated and dynamic quantity at one state, as one JSON object.
//! Used to inspect a robot file and to compare against other implementations.
//!
//! Besides the values, the object says what each barrier is twice: `barrier_table` (the
//! generated table: kind as generated code names it, the corner, the parameters read) and
//! `barrier_info` (the kind's key, margin, unit, limits and whether each is the domain's
//! default, obstacle geometry and watched point, with the robot's numbers, from
//! [`crate::barrier_info::describe_all`]).

use serde_json::{Value, json};

use crate::barrier_info::describe_all;
use crate::dynamics::{
    BarrierTerms, DynamicsError, DynamicsWorkspace, elastic_energy, gravity_energy, kinetic_energy,
    model_terms,
};
use crate::model::Model;

fn rows(flat: &[f64], columns: usize) -> Vec<Vec<f64>> {
    flat.chunks(columns).map(<[f64]>::to_vec).collect()
}

/// What each barrier is, in the order of the barrier arrays: its kind, module and, for a
/// plate corner, the corner (1-based, as in `summary.json`), label and the names of the
/// parameters it reads.
fn barrier_table(model: &Model) -> Value {
    let names = model.generated.param_names();
    let rows: Vec<Value> = model
        .generated
        .barrier_table()
        .iter()
        .map(|b| {
            let params: Vec<&str> = b
                .params
                .iter()
                .filter_map(|&k| names.get(k).copied())
                .collect();
            let mut row = json!({
                "kind": format!("{:?}", b.kind),
                "module": b.module + 1,
                "label": b.label,
                "params": params,
            });
            // The corner (1-based) of a plate-corner barrier; other kinds describe their
            // points in `barrier_info`.
            if let (Some(j), Some(map)) = (b.corner(), row.as_object_mut()) {
                map.insert("point".into(), json!(j + 1));
            }
            row
        })
        .collect();
    Value::Array(rows)
}

/// The model at `(q, q̇)` (`nq` entries each, \[m\], \[m/s\]; another length is
/// [`DynamicsError::Size`]), from the same single evaluation the control tick makes.
pub fn model_report(model: &Model, q: &[f64], qd: &[f64]) -> Result<Value, DynamicsError> {
    let (n, nq) = (model.n_modules(), model.nq());
    let generated = model.generated;
    let mut ws = DynamicsWorkspace::new(model);
    let mut terms = BarrierTerms::new(model);
    model_terms(model, &mut ws, &mut terms, q, qd)?;
    let mut poses = vec![[[0.0; 4]; 4]; n];
    generated.plate_poses(&model.params, q, &mut poses);
    let elastic: Vec<f64> = q.iter().zip(&model.stiffness).map(|(x, k)| k * x).collect();
    let damping: Vec<f64> = qd.iter().zip(&model.damping).map(|(x, d)| d * x).collect();
    let uncertainty = &model.robot.uncertainty;
    Ok(json!({
        "robot": model.robot.name,
        // The robot file's `[uncertainty]` (fractions; force in N): all zero when none.
        "uncertainty": {
            "stiffness": uncertainty.stiffness,
            "damping": uncertainty.damping,
            "mass": uncertainty.mass,
            "force": uncertainty.force,
            // Each module's box (its own `uncertainty = { … }` over the table):
            // [bending, axial] stiffness and damping, and mass.
            "modules": (0..n).map(|i| {
                let b = model.robot.module_box(i);
                json!({"stiffness": b.stiffness, "damping": b.damping, "mass": b.mass})
            }).collect::<Vec<_>>(),
        },
        "generated_model": generated.name(),
        "n": n,
        "q": q,
        "qd": qd,
        "plate_poses": poses,
        "barrier_table": barrier_table(model),
        "barrier_info": describe_all(model),
        "barriers": terms.values(),
        "barrier_jacobian": rows(terms.jacobian(), nq),
        "barrier_jdot_qd": terms.jdot_qd(),
        "mass_matrix": rows(&ws.mass_matrix, nq),
        "bias": ws.bias,
        "gravity": ws.gravity,
        "elastic": elastic,
        "damping": damping,
        "energy": {
            "kinetic": kinetic_energy(model, &ws)?,
            "gravity": gravity_energy(model, &ws)?,
            "elastic": elastic_energy(model, q)?,
        },
    }))
}
