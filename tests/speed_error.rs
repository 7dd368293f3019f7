//! The speed–error report's pieces: the Pareto front keeps exactly the points no cheaper point
//! beats, and MuJoCo's pendulum figures are read from benches/peers/README.md as printed there.

mod common;

use gelenk::report::speed_error::{pareto_front, read_mujoco_points};

#[test]
fn pareto_front_keeps_the_undominated_points() {
    // (cost, error): 1 is beaten by 0 (cheaper and better), 3 by 2.
    let points = [(1.0, 1e-2), (2.0, 5e-2), (3.0, 1e-4), (4.0, 1e-3), (10.0, 1e-9)];
    assert_eq!(pareto_front(&points), vec![0, 2, 4]);
    assert!(pareto_front(&[]).is_empty());
}

#[test]
fn mujoco_figures_are_read_from_the_peers_readme() {
    let points = read_mujoco_points(&common::peers_dir().join("README.md"));
    assert_eq!(points.len(), 7, "{points:?}");
    let rk4 = points.iter().find(|p| p.integrator == "RK4" && p.dt == 1e-3).unwrap();
    assert_eq!((rk4.cost_us, rk4.error, rk4.energy), (7400.0, 2.0e-8, -8.5e-11));
    let euler = points.iter().find(|p| p.integrator == "semi-implicit Euler" && p.dt == 1e-2).unwrap();
    assert_eq!((euler.cost_us, euler.error, euler.energy), (240.0, 0.10, 0.22));
    assert!(read_mujoco_points(std::path::Path::new("/nonexistent/README.md")).is_empty());
}
