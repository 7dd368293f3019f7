//! After construction, a step of every integrator (explicit, semi-implicit and implicit Euler,
//! velocity Verlet, RK4, adaptive Dormand–Prince with rejections, Gragg–Bulirsch–Stoer)
//! performs zero heap allocations (counting global allocator), on a tree with a free base, ball,
//! hinge, planar, damping and a hinge2 suspension.

use gelenk::integrators::{DormandPrince45, IntegratorKind};
use gelenk::math::{Transform, Vec3};
use gelenk::model::{BodySpec, Joint, JointDynamics, ModelBuilder, RigidInertia, Suspension};
use gelenk::prelude::*;
use nalgebra::DVector;

#[path = "common/counting_allocator.rs"]
mod counting_allocator;
use counting_allocator::allocations_in;

fn model() -> Model {
    let body = RigidInertia::solid_box(1.0, Vec3::new(0.1, 0.2, 0.3));
    let offset = Transform::new(nalgebra::Matrix3::identity(), Vec3::new(0.0, 0.0, -0.3));
    let mut b = ModelBuilder::new();
    b.add_body(BodySpec::new("base", "universe", Joint::Free, Transform::identity(), body));
    b.add_body(BodySpec::new("ball", "base", Joint::Ball, offset, body));
    let mut hinge = BodySpec::new("hinge", "ball", Joint::hinge(Vec3::y()), offset, body);
    hinge.dynamics = JointDynamics { damping: 0.3, friction: 0.0 };
    b.add_body(hinge);
    b.add_body(BodySpec::new("planar", "hinge", Joint::Planar, offset, body));
    let wheel = Joint::Hinge2 {
        axis1: Vec3::z(),
        axis2: Vec3::y(),
        suspension: Some(Suspension { stiffness: 2e4, damping: 50.0 }),
    };
    b.add_body(BodySpec::new("wheel", "base", wheel, offset, body));
    b.build().unwrap()
}

#[test]
fn integrator_steps_do_not_allocate() {
    let model = model();
    let mut data = Data::new(&model);
    let tau = DVector::from_fn(model.nv(), |i, _| 0.1 * i as f64);
    let kinds = [
        IntegratorKind::ExplicitEuler,
        IntegratorKind::SemiImplicitEuler,
        IntegratorKind::VelocityVerlet,
        IntegratorKind::Rk4,
        IntegratorKind::Rk6,
        IntegratorKind::Rk8,
        IntegratorKind::DormandPrince45 { rtol: 1e-8, atol: 1e-8 },
        IntegratorKind::GraggBulirschStoer { columns: 6 },
        IntegratorKind::ImplicitEuler,
    ];
    for kind in kinds {
        let mut integrator = kind.build(&model);
        let mut state = State::new(&model);
        state.v.fill(0.5);
        let (count, result) = allocations_in(|| {
            for _ in 0..20 {
                integrator.step(&model, &mut data, &mut state, &tau, 2e-3)?;
            }
            Ok::<_, gelenk::integrators::IntegratorError>(())
        });
        result.unwrap();
        assert!(state.q.iter().all(|x| x.is_finite()));
        assert_eq!(count, 0, "{} allocated {count} times in 20 steps", kind.label());
    }
    // Rejected steps (first trial far too large) do not allocate either.
    let mut dopri = DormandPrince45::new(&model, 1e-9, 1e-9);
    dopri.h = 0.5;
    let mut state = State::new(&model);
    state.v.fill(0.5);
    let (count, result) = allocations_in(|| dopri.advance_to(&model, &mut data, &mut state, &tau, 0.1));
    result.unwrap();
    assert!(dopri.stats().rejected > 0);
    assert_eq!(count, 0, "DOPRI with rejections allocated {count} times");
}
