"""Every quantity of every state of tests/data/reference (Pinocchio 4.1.0) is reproduced through
the Python API to 1e-9 relative to max(1, |reference|): mass matrix, nonlinear effects, gravity,
RNEA, ABA, energies, centre of mass, mass, joint placements and the last joint's local
Jacobian; and the joint layout (idx_v, nv) is Pinocchio's."""

import json

import numpy as np
import pytest

import gelenk


TOL = 1e-9


def cases(repo):
    files = sorted((repo / "tests/data/reference").glob("*.json"))
    assert len(files) >= 8, files
    return [(f.stem, json.loads(f.read_text())) for f in files]


def model_of(repo, case):
    """The model of a reference case: its URDF, or its tree built with ModelBuilder."""
    if case["source"] == "urdf":
        return gelenk.load_urdf(repo / case["urdf"], floating=case["floating_base"])
    builder = gelenk.ModelBuilder(gravity=case["gravity"])
    for b in case["tree"]:
        joint = b["joint"]
        kind = joint["type"]
        extra = {}
        if kind in ("hinge", "slider"):
            extra["axis"] = joint["axis"]
        if kind in ("universal", "hinge2"):
            extra["axis1"], extra["axis2"] = joint["axis1"], joint["axis2"]
        if kind == "hinge2" and joint["suspension"]:
            extra["suspension"] = (0.0, 0.0)
        p, body = b["placement_in_parent"], b["body"]
        builder.add_body(
            b["name"],
            b["parent"],
            kind,
            translation=p["translation"],
            quaternion=p["quaternion_xyzw"],
            mass=body["mass"],
            com=body["com"],
            inertia=body["inertia_about_com"],
            **extra,
        )
    return builder.build()


def check(name, k, what, got, want):
    got, want = np.asarray(got, dtype=float), np.asarray(want, dtype=float)
    assert got.shape == want.shape, f"{name} state {k}: {what} has shape {got.shape}, want {want.shape}"
    err = np.max(np.abs(got - want) / np.maximum(1.0, np.abs(want)), initial=0.0)
    assert err <= TOL, f"{name} state {k}: {what} differs by {err:e} (relative)\n got  {got}\n want {want}"


def test_joint_layout_matches_pinocchio(repo):
    for name, case in cases(repo):
        model = model_of(repo, case)
        assert model.nv == case["nv"], name
        layout = {j["name"]: j for j in model.joints}
        assert len(layout) == len(case["joints"]), name
        for j in case["joints"]:
            mine = layout[j["name"]]
            assert (mine["idx_v"], mine["nv"]) == (j["idx_v"], j["nv"]), f"{name}: {j['name']}"


def test_dynamics_match_pinocchio(repo):
    checked = 0
    for name, case in cases(repo):
        model = model_of(repo, case)
        data = gelenk.Data(model)
        last = case["joints"][-1]["name"]
        last_frame = model.frame_id(last, kind="joint")
        for k, s in enumerate(case["states"]):
            q, v, a, tau = (np.array(s[key], dtype=float) for key in ("q", "v", "a", "tau"))
            check(name, k, "mass_matrix", gelenk.crba(model, data, q), s["mass_matrix"])
            check(name, k, "mass_matrix (body frames)", gelenk.mass_matrix(model, gelenk.Data(model), q), s["mass_matrix"])
            check(name, k, "nle", gelenk.nonlinear_effects(model, data, q, v), s["nle"])
            check(name, k, "gravity", gelenk.generalized_gravity(model, data, q), s["gravity"])
            check(name, k, "rnea", gelenk.rnea(model, data, q, v, a), s["rnea"])
            check(name, k, "aba", gelenk.aba(model, data, q, v, tau), s["aba"])
            check(name, k, "kinetic_energy", gelenk.kinetic_energy(model, data, q, v), s["kinetic_energy"])
            check(name, k, "potential_energy", gelenk.potential_energy(model, data, q), s["potential_energy"])
            check(name, k, "com", gelenk.center_of_mass(model, data, q), s["com"])
            check(name, k, "mass", model.mass, s["mass"])
            gelenk.forward_kinematics(model, data, q)
            for p in s["placements"]:
                frame = model.frame_id(p["joint"], kind="joint")
                pose = gelenk.frame_pose(model, data, frame)
                check(name, k, f"translation of {p['joint']}", pose[:3], p["translation"])
                want = np.array(p["quaternion_xyzw"])
                if np.dot(want, pose[3:]) < 0:
                    want = -want
                check(name, k, f"rotation of {p['joint']}", pose[3:], want)
                h = gelenk.frame_placement(model, data, frame)
                assert np.array_equal(h[:3, 3], pose[:3]) and np.array_equal(h[3], [0, 0, 0, 1])
            jacobian = gelenk.frame_jacobian(model, data, q, last_frame, "local")
            check(name, k, "jacobian_last_joint_local", jacobian, s["jacobian_last_joint_local"])
            checked += 1
    assert checked >= 40, f"only {checked} reference states were checked"


def test_a_wrong_value_is_caught(repo):
    """The comparison can fail: a perturbed reference value is reported."""
    name, case = cases(repo)[0]
    model = model_of(repo, case)
    data = gelenk.Data(model)
    s = case["states"][0]
    q, v, tau = (np.array(s[key], dtype=float) for key in ("q", "v", "tau"))
    want = np.array(s["aba"]) * (1 + 1e-7) + 1e-7
    with pytest.raises(AssertionError, match="aba differs"):
        check(name, 0, "aba", gelenk.aba(model, data, q, v, tau), want)
