//! `gelenk dynamics`: M, nle, gravity, RNEA, ABA, energies and centre of mass of a URDF model on
//! states read from a JSON file, printed as JSON.

use gelenk::prelude::*;
use serde_json::json;
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

fn dynamics(path: &Path, urdf: &crate::UrdfArgs, states_path: &Path) -> Result<(), String> {
    let gelenk::io::urdf::Loaded { model, warnings } = crate::load_urdf(path, urdf)?;
    for w in &warnings {
        eprintln!("gelenk: warning: {w}");
    }
    let (nq, nv) = (model.nq(), model.nv());
    let states =
        gelenk::io::states::read_file(states_path, nq, nv, &Default::default()).map_err(|e| e.to_string())?;
    let mut data = Data::new(&model);
    let mut results = Vec::with_capacity(states.len());
    for (k, s) in states.iter().enumerate() {
        let (q, v, a, tau) = (&s.q, &s.v, &s.a, &s.tau);
        let fail = |e: DynamicsError| format!("state {k}: {e}");
        let m = crba(&model, &mut data, q).map_err(fail)?;
        let rows: Vec<Vec<f64>> = m.row_iter().map(|r| r.iter().copied().collect()).collect();
        let nle = nonlinear_effects(&model, &mut data, q, v).map_err(fail)?.as_slice().to_vec();
        let gravity = generalized_gravity(&model, &mut data, q).map_err(fail)?.as_slice().to_vec();
        let tau_id = rnea(&model, &mut data, q, v, a).map_err(fail)?.as_slice().to_vec();
        // A singular mass matrix (a massless moving subtree) leaves ABA undefined: null, with the
        // reason; any other failure (a non-finite result) is an error.
        let (ddq, aba_error) = match aba(&model, &mut data, q, v, tau) {
            Ok(a) => (Some(a.as_slice().to_vec()), None),
            Err(e @ DynamicsError::SingularMassMatrix { .. }) => (None, Some(e.to_string())),
            Err(e) => return Err(fail(e)),
        };
        let ke = kinetic_energy(&model, &mut data, q, v).map_err(fail)?;
        let pe = potential_energy(&model, &mut data, q).map_err(fail)?;
        let com = center_of_mass(&model, &mut data, q).map_err(fail)?;
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
