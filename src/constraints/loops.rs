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
        let (_, row) = builder.push_row(RowLaw::Bilateral, -c.erp * error / h, 0.0, origin);
        add_point_direction_row(model_a, data_a, c.body_a, &point_a, &d, 1.0, row, col_a);
        add_point_direction_row(model_b, data_b, c.body_b, &point_b, &d, -1.0, row, col_b);
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
        let (_, row) = builder.push_row(RowLaw::Bilateral, -c.erp * error / h, 0.0, origin);
        add_angular_direction_row(model_a, data_a, c.body_a, &d, 1.0, row, col_a);
        add_angular_direction_row(model_b, data_b, c.body_b, &d, -1.0, row, col_b);
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
