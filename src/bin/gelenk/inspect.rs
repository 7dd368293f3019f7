//! `gelenk inspect`: the kinematic tree of a URDF model, its masses, index ranges and collision
//! geometry, as a table or JSON; warnings on stderr.

use gelenk::model::{GeometryRole, GeometrySpec, Shape};
use gelenk::Model;
use serde_json::{json, Value};
use std::path::PathBuf;

// Arguments of `gelenk inspect`.
#[derive(clap::Args)]
pub struct InspectArgs {
    /// URDF file.
    model: PathBuf,
    #[command(flatten)]
    urdf: crate::UrdfArgs,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
}

/// Runs `gelenk inspect`.
pub fn run(args: &InspectArgs) -> Result<(), String> {
    let gelenk::io::urdf::Loaded { model, warnings } = crate::load_urdf(&args.model, &args.urdf)?;
    if args.json {
        print_json(&model, &warnings)?;
    } else {
        print_table(&model);
        for w in &warnings {
            println!("warning: {w}");
        }
    }
    print_warnings(&model);
    Ok(())
}

/// The joints of `model` as JSON objects (name, type, parent, index ranges).
pub fn joints_json(model: &Model) -> Vec<Value> {
    (1..model.nbodies())
        .map(|i| {
            json!({
                "name": model.joint_name(i),
                "type": model.joint(i).kind_name(),
                "parent": model.joint_name(model.parent(i)),
                "idx_q": model.idx_q(i),
                "nq": model.joint(i).nq(),
                "idx_v": model.idx_v(i),
                "nv": model.joint(i).nv(),
            })
        })
        .collect()
}

fn print_json(model: &Model, warnings: &[gelenk::io::urdf::UrdfWarning]) -> Result<(), String> {
    let collision: Vec<Value> = collision_geometry(model)
        .map(|(g, resolved)| {
            json!({"body": model.body_name(g.body), "link": g.link, "shape": g.shape.kind_name(),
                   "parameters": g.shape.summary(), "xyz": g.placement.translation.as_slice(),
                   "mesh_file": resolved})
        })
        .collect();
    let warnings: Vec<Value> = warnings
        .iter()
        .map(|w| json!({"element": w.element, "line": w.line, "message": w.to_string()}))
        .collect();
    let out = json!({"nq": model.nq(), "nv": model.nv(), "mass": model.total_mass(),
                     "joints": joints_json(model), "collision": collision, "warnings": warnings});
    println!("{}", serde_json::to_string_pretty(&out).map_err(|e| e.to_string())?);
    Ok(())
}

fn print_table(model: &Model) {
    println!(
        "model `{}`: {} moving bodies, nq = {}, nv = {}",
        model.name(),
        model.nbodies() - 1,
        model.nq(),
        model.nv()
    );
    println!(
        "{:<24} {:<24} {:<9} {:<24} {:>10} {:>7} {:>7}",
        "body", "joint", "kind", "parent", "mass [kg]", "q", "v"
    );
    for i in 1..model.nbodies() {
        let j = model.joint(i);
        let range = |start: usize, n: usize| format!("{}..{}", start, start + n);
        println!(
            "{:<24} {:<24} {:<9} {:<24} {:>10} {:>7} {:>7}",
            model.body_name(i),
            model.joint_name(i),
            j.kind_name(),
            model.body_name(model.parent(i)),
            mass_text(model.inertia(i).mass, 4),
            range(model.idx_q(i), j.nq()),
            range(model.idx_v(i), j.nv()),
        );
    }
    println!("total mass: {} kg; {} named frames", mass_text(model.total_mass(), 6), model.frames().len());
    let mut geometry = collision_geometry(model).peekable();
    if geometry.peek().is_none() {
        println!("collision geometry: none");
    } else {
        println!("collision geometry:");
        println!("{:<24} {:<24} {:<11} parameters", "body", "link", "shape");
    }
    for (g, resolved) in geometry {
        let file = match (&g.shape, resolved) {
            (Shape::Mesh { .. }, Some(path)) => format!(" -> {path}"),
            (Shape::Mesh { .. }, None) => " -> NOT FOUND".to_string(),
            _ => String::new(),
        };
        println!(
            "{:<24} {:<24} {:<11} {}{}",
            model.body_name(g.body),
            g.link,
            g.shape.kind_name(),
            g.shape.summary(),
            file
        );
    }
}

/// Warnings about the model, on stderr: subtrees without mass or inertia.
fn print_warnings(model: &Model) {
    let massless = model.massless_subtrees();
    for i in massless {
        eprintln!(
            "gelenk: warning: joint `{}` moves a subtree without mass or inertia: the mass matrix is singular and forward dynamics will refuse it",
            model.joint_name(i)
        );
    }
}

/// Collision geometry of the model with, for meshes, the file the URI resolves to (if any).
fn collision_geometry(model: &Model) -> impl Iterator<Item = (&GeometrySpec, Option<String>)> + '_ {
    model.geometries().iter().filter(|g| g.role == GeometryRole::Collision).map(|g| {
        let resolved = match &g.shape {
            Shape::Mesh { uri, .. } => {
                gelenk::collision::mesh::resolve(&g.link, uri, model.source_dir(), &[])
                    .ok()
                    .map(|p| p.display().to_string())
            }
            _ => None,
        };
        (g, resolved)
    })
}

/// A mass (kg) with `decimals` places, in exponent form outside 1e-3 … 1e6 kg (a mass of 1e300 kg
/// is 301 digits in fixed form).
fn mass_text(mass: f64, decimals: usize) -> String {
    if mass == 0.0 || (1e-3..1e6).contains(&mass.abs()) {
        format!("{mass:.decimals$}")
    } else {
        format!("{mass:.decimals$e}")
    }
}
