//! Loop closures: a constraint joint between frames on any two bodies (or a body and the world),
//! as bilateral rows of their relative velocity, with Baumgarte-style position correction
//! (`u* = −erp · error / h`). They close kinematic loops (four-bar linkages, parallel mechanisms)
//! that a tree cannot express.

use super::{ProblemBuilder, RowLaw, RowOrigin};
use crate::collision::{add_angular_direction_row, add_point_direction_row, tangents};
use crate::data::Data;
use crate::math::{log3, Transform, Vec3};
use crate::model::Model;

/// Which relative motions a loop closure removes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LoopKind {
    /// The frame origins coincide (3 rows).
    Ball,
    /// Origins coincide and the frames may only rotate about `axis` (unit, in frame A) (5 rows).
    Hinge {
        /// Hinge axis in frame A.
        axis: Vec3,
    },
    /// Orientations coincide and the origins may only slide along `axis` (in frame A) (5 rows).
    Slider {
        /// Slide axis in frame A.
        axis: Vec3,
    },
    /// The frames coincide (6 rows).
    Weld,
}

/// A constraint joint between frame A (pose `frame_a` in body `body_a`) and frame B (pose
/// `frame_b` in body `body_b`); body 0 is the world.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LoopClosure {
    /// Body carrying frame A.
    pub body_a: usize,
    /// Frame A in body A.
    pub frame_a: Transform,
    /// Body carrying frame B.
    pub body_b: usize,
    /// Frame B in body B.
    pub frame_b: Transform,
    /// What the joint constrains.
    pub kind: LoopKind,
    /// Fraction of the position error removed per step.
    pub erp: f64,
}

/// The position error of a loop closure between bodies of two multibodies, from their poses
/// `data_a.x_wb` and `data_b.x_wb`, as [`loop_error`].
pub fn loop_error_between(data_a: &Data, data_b: &Data, c: &LoopClosure) -> (Vec3, Vec3) {
    let (xa, xb) = (data_a.x_wb[c.body_a] * c.frame_a, data_b.x_wb[c.body_b] * c.frame_b);
    (xa.translation - xb.translation, log3(&(xa.rotation * xb.rotation.transpose())))
}

/// The position error of a loop closure at the poses in `data.x_wb`: (translation error p_A − p_B
/// in world axes (m), rotation vector of frame A relative to frame B in world axes (rad)).
pub fn loop_error(data: &Data, c: &LoopClosure) -> (Vec3, Vec3) {
    loop_error_between(data, data, c)
}

/// Appends the rows of loop closure `c` (index `index`, for [`RowOrigin::Loop`]) of a model whose
/// velocities start at column `col`; `data` must hold `x_wb` and `j_world` at the current q.
pub fn add_loop_closure_rows(
    builder: &mut ProblemBuilder,
    model: &Model,
    data: &Data,
    col: usize,
    c: &LoopClosure,
    index: usize,
    h: f64,
) {
    add_loop_closure_rows_between(builder, (model, data, col), (model, data, col), c, index, h);
}

/// One side of a loop closure: the multibody carrying the body, its kinematics (`x_wb` and
/// `j_world` at the current q) and the column where its velocities start.
pub type LoopSide<'a> = (&'a Model, &'a Data, usize);

/// Appends the rows of loop closure `c` whose body A belongs to multibody `side_a` and body B to
/// `side_b` (which may be the same), as [`add_loop_closure_rows`]: rows of the relative velocity
/// of frame A with respect to frame B, with `u* = −erp · error / h`.
pub fn add_loop_closure_rows_between(
    builder: &mut ProblemBuilder,
    side_a: LoopSide<'_>,
    side_b: LoopSide<'_>,
    c: &LoopClosure,
    index: usize,
    h: f64,
) {
    let ((model_a, data_a, col_a), (model_b, data_b, col_b)) = (side_a, side_b);
    let (xa, xb) = (data_a.x_wb[c.body_a] * c.frame_a, data_b.x_wb[c.body_b] * c.frame_b);
    let (p_a, p_b) = (xa.translation, xb.translation);
    let origin = RowOrigin::Loop(index);
    let linear = |builder: &mut ProblemBuilder, d: Vec3, point_a: Vec3, point_b: Vec3| {
        let error = d.dot(&(p_a - p_b));
        let (_, mut row) = builder.push_row(RowLaw::Bilateral, -c.erp * error / h, 0.0, origin);
        add_point_direction_row(model_a, data_a, c.body_a, &point_a, &d, 1.0, &mut row, col_a);
        add_point_direction_row(model_b, data_b, c.body_b, &point_b, &d, -1.0, &mut row, col_b);
    };
    let axes = [Vec3::x(), Vec3::y(), Vec3::z()];
    match c.kind {
        LoopKind::Ball | LoopKind::Hinge { .. } | LoopKind::Weld => {
            for d in axes {
                linear(builder, d, p_a, p_b);
            }
        }
        LoopKind::Slider { axis } => {
            let (t1, t2) = tangents(&(xa.rotation * axis).normalize());
            for d in [t1, t2] {
                linear(builder, d, p_b, p_b);
            }
        }
    }
    let angular = |builder: &mut ProblemBuilder, d: Vec3, error: f64| {
        let (_, mut row) = builder.push_row(RowLaw::Bilateral, -c.erp * error / h, 0.0, origin);
        add_angular_direction_row(model_a, data_a, c.body_a, &d, 1.0, &mut row, col_a);
        add_angular_direction_row(model_b, data_b, c.body_b, &d, -1.0, &mut row, col_b);
    };
    match c.kind {
        LoopKind::Ball => {}
        LoopKind::Weld | LoopKind::Slider { .. } => {
            let theta = log3(&(xa.rotation * xb.rotation.transpose()));
            for d in axes {
                angular(builder, d, d.dot(&theta));
            }
        }
        LoopKind::Hinge { axis } => {
            let (a_a, a_b) = ((xa.rotation * axis).normalize(), (xb.rotation * axis).normalize());
            let (t1, t2) = tangents(&a_a);
            let misalignment = a_b.cross(&a_a);
            for d in [t1, t2] {
                angular(builder, d, d.dot(&misalignment));
            }
        }
    }
}

/// World velocity and bias acceleration (the classical acceleration with q̈ = 0, gravity
/// removed) of the point `point` (world, m) fixed on body `body`, and the body's world angular
/// velocity and bias angular acceleration. Needs `data.x_wb` and `data.v`, `data.a` of
/// [`crate::algorithms::rnea`]`(q, v, 0)` at the same q (whose `a` carries the fictitious −g of
/// `gravity`). Body 0 (the world) is at rest.
fn body_point_motion(data: &Data, gravity: &Vec3, body: usize, point: &Vec3) -> [Vec3; 4] {
    if body == 0 {
        return [Vec3::zeros(); 4];
    }
    let x = &data.x_wb[body];
    let (v, a) = (&data.v[body], &data.a[body]);
    let r = x.rotation.tr_mul(&(point - x.translation));
    let velocity = v.linear + v.angular.cross(&r);
    // Classical acceleration of a body-fixed point: a + α × r + ω × (v + ω × r) (body axes).
    let acceleration = a.linear + a.angular.cross(&r) + v.angular.cross(&velocity);
    [
        x.rotation * velocity,
        x.rotation * acceleration + gravity,
        x.rotation * v.angular,
        x.rotation * a.angular,
    ]
}

/// The rate of change of [`crate::collision::tangents`]`(n)` when n moves at `n_dot`
/// (differentiated formula; constant sign branch).
fn tangents_rate(n: &Vec3, n_dot: &Vec3) -> (Vec3, Vec3) {
    let sign = 1f64.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let da = a * a * n_dot.z;
    let db = n_dot.x * n.y * a + n.x * n_dot.y * a + n.x * n.y * da;
    let dt1 = Vec3::new(sign * (2.0 * n.x * n_dot.x * a + n.x * n.x * da), sign * db, -sign * n_dot.x);
    let dt2 = Vec3::new(db, 2.0 * n.y * n_dot.y * a + n.y * n.y * da, -n_dot.y);
    (dt1, dt2)
}

/// The drift term `J̇ v` of each row of [`add_loop_closure_rows_between`] (same rows, same
/// order), written to `out` (m/s² or rad/s²); returns the number of rows. With it the closure
/// holds at the acceleration level, `J q̈ = −J̇ v`: the index-1 form of the constraint that a
/// smooth integrator needs ([`crate::world`]'s smooth steps). Each side's `data` must hold
/// `x_wb` and `v`, `a` of [`crate::algorithms::rnea`]`(q, v, 0)` at the current q and v (its
/// model's gravity is removed from `a` here).
///
/// Rows of a fixed world direction d on body-fixed points give `d · (a_A − a_B)` (classical
/// bias accelerations); hinge and slider rows turn with frame A's axis, adding `ḋ · w` for the
/// relative velocity w; a slider's rows are taken at the moving point p_B, adding
/// `d · ω_A × (v_B − v_A)`.
pub fn loop_closure_drift_between(
    side_a: (&Model, &Data),
    side_b: (&Model, &Data),
    c: &LoopClosure,
    out: &mut [f64],
) -> usize {
    let ((model_a, data_a), (model_b, data_b)) = (side_a, side_b);
    let (xa, xb) = (data_a.x_wb[c.body_a] * c.frame_a, data_b.x_wb[c.body_b] * c.frame_b);
    let (p_a, p_b) = (xa.translation, xb.translation);
    let [_, acc_a, omega_a, alpha_a] = body_point_motion(data_a, &model_a.gravity, c.body_a, &p_a);
    let [_, acc_b, omega_b, alpha_b] = body_point_motion(data_b, &model_b.gravity, c.body_b, &p_b);
    let axes = [Vec3::x(), Vec3::y(), Vec3::z()];
    let mut n = 0;
    let mut push = |value: f64| {
        out[n] = value;
        n += 1;
    };
    match c.kind {
        LoopKind::Ball | LoopKind::Hinge { .. } | LoopKind::Weld => {
            for d in axes {
                push(d.dot(&(acc_a - acc_b)));
            }
        }
        LoopKind::Slider { axis } => {
            let [vel_a_at_b, acc_a_at_b, _, _] = body_point_motion(data_a, &model_a.gravity, c.body_a, &p_b);
            let [vel_b, ..] = body_point_motion(data_b, &model_b.gravity, c.body_b, &p_b);
            let n_a = (xa.rotation * axis).normalize();
            let (t1, t2) = tangents(&n_a);
            let (dt1, dt2) = tangents_rate(&n_a, &omega_a.cross(&n_a));
            let w = vel_a_at_b - vel_b;
            let relative = acc_a_at_b + omega_a.cross(&(vel_b - vel_a_at_b)) - acc_b;
            for (d, dd) in [(t1, dt1), (t2, dt2)] {
                push(dd.dot(&w) + d.dot(&relative));
            }
        }
    }
    match c.kind {
        LoopKind::Ball => {}
        LoopKind::Weld | LoopKind::Slider { .. } => {
            for d in axes {
                push(d.dot(&(alpha_a - alpha_b)));
            }
        }
        LoopKind::Hinge { axis } => {
            let n_a = (xa.rotation * axis).normalize();
            let (t1, t2) = tangents(&n_a);
            let (dt1, dt2) = tangents_rate(&n_a, &omega_a.cross(&n_a));
            let w = omega_a - omega_b;
            for (d, dd) in [(t1, dt1), (t2, dt2)] {
                push(dd.dot(&w) + d.dot(&(alpha_a - alpha_b)));
            }
        }
    }
    n
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::algorithms::{compute_joint_jacobians, rnea};
    use crate::constraints::FrictionModel;
    use crate::model::{BodySpec, Joint, ModelBuilder, RigidInertia};
    use nalgebra::DVector;

    /// A chain of a ball joint, a hinge and a slider hanging from a free base: every joint kind
    /// whose rate enters a closure's rows.
    fn chain() -> Model {
        let inertia = RigidInertia::new(1.0, Vec3::new(0.1, 0.0, 0.0), nalgebra::Matrix3::identity() * 1e-2);
        let mut b = ModelBuilder::new();
        b.add_body(BodySpec::new("base", "universe", Joint::Free, Transform::identity(), inertia));
        let at = |x: f64| Transform::from_translation(Vec3::new(x, 0.05, -0.02));
        b.add_body(BodySpec::new("ball", "base", Joint::Ball, at(0.2), inertia));
        b.add_body(BodySpec::new(
            "hinge",
            "ball",
            Joint::hinge(Vec3::new(0.3, 1.0, 0.2).normalize()),
            at(0.3),
            inertia,
        ));
        b.add_body(BodySpec::new(
            "slider",
            "hinge",
            Joint::slider(Vec3::new(1.0, -0.2, 0.4).normalize()),
            at(0.25),
            inertia,
        ));
        b.build().unwrap()
    }

    /// `J(q) v` of closure `c`'s rows at q.
    fn rows_times_v(
        model: &Model,
        data: &mut Data,
        q: &DVector<f64>,
        v: &DVector<f64>,
        c: &LoopClosure,
    ) -> Vec<f64> {
        compute_joint_jacobians(model, data, q).unwrap();
        let mut builder = ProblemBuilder::new(model.nv(), FrictionModel::Cone);
        add_loop_closure_rows(&mut builder, model, data, 0, c, 0, 1.0);
        (0..builder.len()).map(|i| builder.row_dot(i, v.as_slice())).collect()
    }

    #[test]
    fn drift_equals_the_derivative_of_the_rows_along_the_motion() {
        // J̇v = d/dε J(q ⊕ εv) v at ε = 0, by central differences (error ~ε² + 1e-16/ε ≈ 1e-10).
        let model = chain();
        let mut data = Data::new(&model);
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let frame = |x: f64, y: f64| {
            Transform::new(
                crate::math::axis_angle(&Vec3::new(x, y, 1.0).normalize(), 0.7 * x),
                Vec3::new(0.1 * x, 0.05, -0.1 * y),
            )
        };
        let kinds = [
            LoopKind::Ball,
            LoopKind::Weld,
            LoopKind::Hinge { axis: Vec3::new(0.2, -0.4, 1.0).normalize() },
            LoopKind::Slider { axis: Vec3::new(-0.5, 0.3, 0.8).normalize() },
        ];
        for trial in 0..6 {
            let q = model.random_configuration(&mut rng);
            let v = DVector::from_fn(model.nv(), |_, _| rng.random_range(-2.0..2.0));
            let mut uniform = || rng.random_range(-1.0..1.0);
            for kind in kinds {
                let (body_a, body_b) = if trial % 2 == 0 { (4, 0) } else { (4, 2) };
                let c = LoopClosure {
                    body_a,
                    frame_a: frame(uniform(), uniform()),
                    body_b,
                    frame_b: frame(uniform(), uniform()),
                    kind,
                    erp: 0.2,
                };
                compute_joint_jacobians(&model, &mut data, &q).unwrap();
                rnea(&model, &mut data, &q, &v, &DVector::zeros(model.nv())).unwrap();
                let mut drift = [0.0; 6];
                let n = loop_closure_drift_between((&model, &data), (&model, &data), &c, &mut drift);
                let epsilon = 1e-5;
                let (mut plus, mut minus) = (q.clone(), q.clone());
                model.integrate(&q, &v, epsilon, &mut plus);
                model.integrate(&q, &v, -epsilon, &mut minus);
                let jp = rows_times_v(&model, &mut data, &plus, &v, &c);
                let jm = rows_times_v(&model, &mut data, &minus, &v, &c);
                assert_eq!(jp.len(), n);
                for i in 0..n {
                    let fd = (jp[i] - jm[i]) / (2.0 * epsilon);
                    assert!(
                        (fd - drift[i]).abs() < 1e-7 * (1.0 + fd.abs()),
                        "{kind:?} row {i}: {} vs {fd}",
                        drift[i]
                    );
                }
            }
        }
    }
}
