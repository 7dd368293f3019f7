//! Helpers for the integration tests: where the repository's data lives (every file a test reads is
//! inside the repository), the Pinocchio reference data of tests/data/reference, and model
//! construction from its tree descriptions.
#![allow(dead_code)]

use gelenk::math::Mat3;
use gelenk::prelude::*;
use nalgebra::{DMatrix, DVector};
use serde_json::Value;
use std::path::PathBuf;

/// The repository's root (the folder of Cargo.toml).
pub fn repo_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// `models/`: the scenes and robot descriptions (the example-robot-data URDFs among them).
pub fn models_dir() -> PathBuf {
    repo_dir().join("models")
}

/// `tests/data/reference/`: Pinocchio 4.1.0's values, one JSON file per case.
pub fn reference_dir() -> PathBuf {
    repo_dir().join("tests/data/reference")
}

/// `benches/peers/`: the MJCF peer scenes and MuJoCo's figures on them (README.md).
pub fn peers_dir() -> PathBuf {
    repo_dir().join("benches/peers")
}

/// Every reference case, parsed.
pub fn reference_cases() -> Vec<(String, Value)> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(reference_dir())
        .expect("tests/data/reference exists")
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "json"))
        .collect();
    files.sort();
    files
        .into_iter()
        .map(|p| {
            let text = std::fs::read_to_string(&p).unwrap();
            (p.file_stem().unwrap().to_string_lossy().into_owned(), serde_json::from_str(&text).unwrap())
        })
        .collect()
}

pub fn vec3(v: &Value) -> Vec3 {
    Vec3::new(v[0].as_f64().unwrap(), v[1].as_f64().unwrap(), v[2].as_f64().unwrap())
}

pub fn dvec(v: &Value) -> DVector<f64> {
    DVector::from_iterator(
        v.as_array().unwrap().len(),
        v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()),
    )
}

pub fn dmat(v: &Value) -> DMatrix<f64> {
    let rows = v.as_array().unwrap();
    let ncols = rows.first().map(|r| r.as_array().unwrap().len()).unwrap_or(0);
    DMatrix::from_fn(rows.len(), ncols, |r, c| rows[r][c].as_f64().unwrap())
}

fn mat3(v: &Value) -> Mat3 {
    Mat3::from_fn(|r, c| v[r][c].as_f64().unwrap())
}

fn joint_of(v: &Value) -> Joint {
    match v["type"].as_str().unwrap() {
        "hinge" => Joint::Hinge { axis: vec3(&v["axis"]) },
        "slider" => Joint::Slider { axis: vec3(&v["axis"]) },
        "ball" => Joint::Ball,
        "free" => Joint::Free,
        "planar" => Joint::Planar,
        "universal" => Joint::Universal { axis1: vec3(&v["axis1"]), axis2: vec3(&v["axis2"]) },
        "hinge2" => Joint::Hinge2 {
            axis1: vec3(&v["axis1"]),
            axis2: vec3(&v["axis2"]),
            suspension: v["suspension"]
                .as_bool()
                .unwrap()
                .then_some(Suspension { stiffness: 0.0, damping: 0.0 }),
        },
        other => panic!("unknown joint type {other}"),
    }
}

/// Builds the model of a reference case (URDF or tree).
pub fn model_of(case: &Value) -> Model {
    match case["source"].as_str().unwrap() {
        "urdf" => {
            let options =
                UrdfOptions { floating_base: case["floating_base"].as_bool().unwrap(), ..Default::default() };
            gelenk::io::urdf::load_file(repo_dir().join(case["urdf"].as_str().unwrap()), &options).unwrap()
        }
        "tree" => {
            let mut builder = ModelBuilder::new();
            builder.gravity(vec3(&case["gravity"]));
            for b in case["tree"].as_array().unwrap() {
                let p = &b["placement_in_parent"];
                let qv = &p["quaternion_xyzw"];
                let quat = [0, 1, 2, 3].map(|k| qv[k].as_f64().unwrap());
                let placement = Transform::from_translation_quaternion(vec3(&p["translation"]), quat);
                let body = &b["body"];
                let inertia = RigidInertia::new(
                    body["mass"].as_f64().unwrap(),
                    vec3(&body["com"]),
                    mat3(&body["inertia_about_com"]),
                );
                builder.add_body(BodySpec::new(
                    b["name"].as_str().unwrap(),
                    b["parent"].as_str().unwrap(),
                    joint_of(&b["joint"]),
                    placement,
                    inertia,
                ));
            }
            builder.build().unwrap()
        }
        other => panic!("unknown source {other}"),
    }
}

/// Largest error relative to max(1, |reference|) between two equally long slices.
pub fn max_rel_err(got: &[f64], want: &[f64]) -> f64 {
    assert_eq!(got.len(), want.len(), "length mismatch");
    got.iter().zip(want).map(|(g, w)| (g - w).abs() / w.abs().max(1.0)).fold(0.0, f64::max)
}
