//! `gelenk dynamics`: M, nle, gravity, RNEA, ABA, energies and centre of mass of a URDF model on
//! states read from a JSON file, printed as JSON.

use gelenk::prelude::*;
use nalgebra::DVector;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

// Arguments of `gelenk dynamics`.
#[derive(clap::Args)]
pub struct DynamicsArgs {
    /// URDF file.
    model: PathBuf,
    #[command(flatten)]
    urdf: crate::UrdfArgs,
    /// JSON file `{"states":[{"q":[…],"v":[…],"a":[…],"tau":[…]}]}` (v, a, tau default to 0).
    #[arg(long)]
    states: PathBuf,
}

/// Runs `gelenk dynamics`.
pub fn run(args: &DynamicsArgs) -> Result<(), String> {
    dynamics(&args.model, &args.urdf, &args.states)
}

fn vector(
    state: &Value,
    key: &str,
    len: usize,
    index: usize,
    required: bool,
) -> Result<DVector<f64>, String> {
    match state.get(key) {
        None if !required => Ok(DVector::zeros(len)),
        None => Err(format!("state {index}: missing \"{key}\"")),
        Some(v) => {
            let items = v.as_array().ok_or_else(|| format!("state {index}: \"{key}\" is not an array"))?;
            if items.len() != len {
                return Err(format!(
                    "state {index}: \"{key}\" has {} entries, the model needs {len}",
                    items.len()
                ));
            }
            items
                .iter()
                .map(|x| x.as_f64().ok_or_else(|| format!("state {index}: \"{key}\" holds a non-number")))
                .collect::<Result<Vec<f64>, String>>()
                .map(DVector::from_vec)
        }
    }
}

fn dynamics(path: &Path, urdf: &crate::UrdfArgs, states_path: &Path) -> Result<(), String> {
    let gelenk::io::urdf::Loaded { model, warnings } = crate::load_urdf(path, urdf)?;
    for w in &warnings {
        eprintln!("gelenk: warning: {w}");
    }
    let text = std::fs::read_to_string(states_path)
        .map_err(|e| format!("{}: cannot read: {e}", states_path.display()))?;
    let doc: Value =
        serde_json::from_str(&text).map_err(|e| format!("{}: not valid JSON: {e}", states_path.display()))?;
    let states = doc
        .get("states")
        .and_then(Value::as_array)
        .ok_or_else(|| format!("{}: expected {{\"states\": [...]}}", states_path.display()))?;
    let mut data = Data::new(&model);
    let (nq, nv) = (model.nq(), model.nv());
    let mut results = Vec::with_capacity(states.len());
    for (k, s) in states.iter().enumerate() {
        let q = vector(s, "q", nq, k, true)?;
        let v = vector(s, "v", nv, k, false)?;
        let a = vector(s, "a", nv, k, false)?;
        let tau = vector(s, "tau", nv, k, false)?;
        let fail = |e: DynamicsError| format!("state {k}: {e}");
        let m = crba(&model, &mut data, &q).map_err(fail)?;
        let rows: Vec<Vec<f64>> = m.row_iter().map(|r| r.iter().copied().collect()).collect();
        let nle = nonlinear_effects(&model, &mut data, &q, &v).map_err(fail)?.as_slice().to_vec();
        let gravity = generalized_gravity(&model, &mut data, &q).map_err(fail)?.as_slice().to_vec();
        let tau_id = rnea(&model, &mut data, &q, &v, &a).map_err(fail)?.as_slice().to_vec();
        // A singular mass matrix (a massless moving subtree) leaves ABA undefined: null, with the reason.
        let (ddq, aba_error) = match aba(&model, &mut data, &q, &v, &tau) {
            Ok(a) => (Some(a.as_slice().to_vec()), None),
            Err(e) => (None, Some(e.to_string())),
        };
        let ke = kinetic_energy(&model, &mut data, &q, &v).map_err(fail)?;
        let pe = potential_energy(&model, &mut data, &q).map_err(fail)?;
        let com = center_of_mass(&model, &mut data, &q).map_err(fail)?;
        results.push(json!({
            "mass_matrix": rows, "nle": nle, "gravity": gravity, "rnea": tau_id, "aba": ddq, "aba_error": aba_error,
            "kinetic_energy": ke, "potential_energy": pe, "com": [com.x, com.y, com.z],
            "mass": model.total_mass(),
        }));
    }
    let out = json!({"nq": nq, "nv": nv, "joints": crate::inspect::joints_json(&model), "results": results});
    println!("{}", serde_json::to_string(&out).map_err(|e| e.to_string())?);
    Ok(())
}
