//! Every quantity of every state in tests/data/reference (Pinocchio 4.1.0) is reproduced to 1e-9
//! relative to max(1, |reference|): mass matrix (world-frame CRBA and body-frame `mass_matrix`), nonlinear effects, gravity, RNEA, ABA, CRBA-based
//! forward dynamics, energies, centre of mass, mass, joint placements and the last joint's local
//! Jacobian; and the joint index layout is Pinocchio's.

mod common;

use common::*;
use gelenk::prelude::*;
use nalgebra::DVector;

const TOL: f64 = 1e-9;

fn check(case: &str, state: usize, what: &str, got: &[f64], want: &[f64]) {
    let err = max_rel_err(got, want);
    assert!(
        err <= TOL,
        "{case} state {state}: {what} differs by {err:e} (relative)\n got  {got:?}\n want {want:?}"
    );
}

#[test]
fn joint_layout_matches_pinocchio() {
    for (name, case) in reference_cases() {
        let model = model_of(&case);
        assert_eq!(model.nv(), case["nv"].as_u64().unwrap() as usize, "{name}: nv");
        for j in case["joints"].as_array().unwrap() {
            let jname = j["name"].as_str().unwrap();
            let id = model.joint_id(jname).unwrap_or_else(|| panic!("{name}: joint {jname} missing"));
            assert_eq!(model.idx_v(id), j["idx_v"].as_u64().unwrap() as usize, "{name}: idx_v of {jname}");
            assert_eq!(model.joint(id).nv(), j["nv"].as_u64().unwrap() as usize, "{name}: nv of {jname}");
        }
        assert_eq!(model.nbodies() - 1, case["joints"].as_array().unwrap().len(), "{name}: joint count");
    }
}

#[test]
fn dynamics_match_pinocchio() {
    let mut cases = 0;
    for (name, case) in reference_cases() {
        let model = model_of(&case);
        let mut data = Data::new(&model);
        for (k, s) in case["states"].as_array().unwrap().iter().enumerate() {
            let (q, v, a, tau) = (dvec(&s["q"]), dvec(&s["v"]), dvec(&s["a"]), dvec(&s["tau"]));
            let m = crba(&model, &mut data, &q).unwrap().clone();
            check(&name, k, "mass_matrix", m.as_slice(), dmat(&s["mass_matrix"]).as_slice());
            // M alone, in body frames, from its own fresh workspace and from the one the other
            // algorithms use.
            let local = mass_matrix(&model, &mut Data::new(&model), &q).unwrap().clone();
            check(
                &name,
                k,
                "mass_matrix (body frames)",
                local.as_slice(),
                dmat(&s["mass_matrix"]).as_slice(),
            );
            check(&name, k, "mass_matrix (body frames) against crba", local.as_slice(), m.as_slice());
            assert_eq!(&local, mass_matrix(&model, &mut data, &q).unwrap(), "{name} state {k}");
            check(
                &name,
                k,
                "nle",
                nonlinear_effects(&model, &mut data, &q, &v).unwrap().as_slice(),
                dvec(&s["nle"]).as_slice(),
            );
            check(
                &name,
                k,
                "gravity",
                generalized_gravity(&model, &mut data, &q).unwrap().as_slice(),
                dvec(&s["gravity"]).as_slice(),
            );
            check(
                &name,
                k,
                "rnea",
                rnea(&model, &mut data, &q, &v, &a).unwrap().as_slice(),
                dvec(&s["rnea"]).as_slice(),
            );
            check(
                &name,
                k,
                "aba",
                aba(&model, &mut data, &q, &v, &tau).unwrap().as_slice(),
                dvec(&s["aba"]).as_slice(),
            );
            check(
                &name,
                k,
                "forward_dynamics_crba",
                forward_dynamics_crba(&model, &mut data, &q, &v, &tau).unwrap().as_slice(),
                dvec(&s["aba"]).as_slice(),
            );
            let ke = kinetic_energy(&model, &mut data, &q, &v).unwrap();
            check(&name, k, "kinetic_energy", &[ke], &[s["kinetic_energy"].as_f64().unwrap()]);
            let pe = potential_energy(&model, &mut data, &q).unwrap();
            check(&name, k, "potential_energy", &[pe], &[s["potential_energy"].as_f64().unwrap()]);
            let com = center_of_mass(&model, &mut data, &q).unwrap();
            check(&name, k, "com", com.as_slice(), dvec(&s["com"]).as_slice());
            check(&name, k, "mass", &[model.total_mass()], &[s["mass"].as_f64().unwrap()]);

            forward_kinematics(&model, &mut data, &q).unwrap();
            for p in s["placements"].as_array().unwrap() {
                let jname = p["joint"].as_str().unwrap();
                let x = data.x_wb[model.joint_id(jname).unwrap()];
                check(
                    &name,
                    k,
                    &format!("translation of {jname}"),
                    x.translation.as_slice(),
                    dvec(&p["translation"]).as_slice(),
                );
                let got = x.quaternion_xyzw();
                let mut want = dvec(&p["quaternion_xyzw"]);
                if want.dot(&DVector::from_row_slice(&got)) < 0.0 {
                    want = -want;
                }
                check(&name, k, &format!("rotation of {jname}"), &got, want.as_slice());
            }

            let last = case["joints"].as_array().unwrap().last().unwrap()["name"].as_str().unwrap();
            let frame = model
                .frames()
                .iter()
                .position(|f| f.name == last && f.kind == gelenk::model::FrameKind::Joint)
                .unwrap();
            compute_joint_jacobians(&model, &mut data, &q).unwrap();
            let j = frame_jacobian(&model, &mut data, frame, JacobianFrame::Local).unwrap();
            check(
                &name,
                k,
                "jacobian_last_joint_local",
                j.as_slice(),
                dmat(&s["jacobian_last_joint_local"]).as_slice(),
            );
            cases += 1;
        }
    }
    assert!(cases >= 40, "only {cases} reference states were checked");
}
