"""Worlds through Python: the state layout and its labels, stepping and resetting are
deterministic, forces, impulses, motors and servos act, contacts carry their impulses, the
statistics and energies are those of the step."""

import numpy as np
import pytest

import gelenk


@pytest.fixture
def ragdoll(repo):
    return gelenk.load_scene(repo / "models/ragdoll_fall.toml")


def test_the_state_layout_and_labels_describe_the_flat_vector(ragdoll):
    w = ragdoll
    assert (w.nq, w.nv, w.nstate) == (47, 39, 86)
    labels = w.state_labels()
    assert len(labels) == w.nstate
    index = w.joint_index()
    assert sum(j["nq"] for j in index) == w.nq and sum(j["nv"] for j in index) == w.nv
    root = index[0]
    assert root["type"] == "free" and (root["qpos"], root["nq"], root["qvel"], root["nv"]) == (0, 7, 0, 6)
    name = f"{root['multibody']}.{root['joint']}"
    assert labels[:7] == [f"{name}.{c}" for c in ("x", "y", "z", "qx", "qy", "qz", "qw")]
    assert labels[w.nq : w.nq + 6] == [f"{name}.{c}" for c in ("vx", "vy", "vz", "wx", "wy", "wz")]
    state = w.get_state()
    assert np.array_equal(state[: w.nq], w.qpos) and np.array_equal(state[w.nq :], w.qvel)
    m = w.model(0)
    assert (m.nq, m.nv) == (w.nq, w.nv)
    assert np.array_equal(w.q(0), w.qpos) and np.array_equal(w.q(w.multibody_names[0]), w.qpos)


def test_stepping_is_deterministic_and_reset_starts_over(ragdoll):
    w = ragdoll
    start = w.get_state()
    w.step(300)
    after = w.get_state()
    assert w.time == pytest.approx(300 * w.dt) and w.stats["step"] == 300
    assert not np.array_equal(after, start)
    w.reset()
    assert w.time == 0.0 and np.array_equal(w.get_state(), start)
    for _ in range(300):
        w.step()
    assert np.array_equal(w.get_state(), after), "300 single steps equal step(300), bit for bit"


def test_set_state_round_trips_and_moves_the_bodies(ragdoll):
    w = ragdoll
    x = w.get_state()
    x[2] += 1.0  # the root one metre higher
    x[w.nq] = 0.5  # moving along x
    w.set_state(x)
    assert np.array_equal(w.get_state(), x)
    w.qvel = np.zeros(w.nv)
    assert np.array_equal(w.qvel, np.zeros(w.nv)) and np.array_equal(w.qpos, x[: w.nq])
    w.step()
    assert w.q(0)[2] < x[2], "it falls"


def test_a_force_an_impulse_and_joint_forces_act(repo):
    w = gelenk.load_scene(repo / "models/ragdoll_fall.toml")
    free = gelenk.load_scene(repo / "models/ragdoll_fall.toml")
    w.apply_impulse(0, 1, np.array([10.0, 0.0, 0.0]), w.q(0)[:3].copy())
    assert w.qvel[0] > 0.0, "the impulse changes the velocity at once"
    w2 = gelenk.load_scene(repo / "models/ragdoll_fall.toml")
    w2.apply_force(0, 1, np.array([0.0, 500.0, 0.0]), w2.q(0)[:3].copy())
    w2.step()
    free.step()
    assert w2.qvel[1] > free.qvel[1] + 1e-3
    w3 = gelenk.load_scene(repo / "models/ragdoll_fall.toml")
    tau = np.zeros(w3.nv)
    tau[6] = 50.0
    w3.tau = tau
    assert np.array_equal(w3.tau, tau)
    w3.step()
    assert w3.qvel[6] != free.qvel[6]


def test_a_motor_drives_its_joint(repo):
    model = gelenk.load_urdf(repo / "models/ur5_robot.urdf")
    w = gelenk.World(model, dt=0.001, missing_meshes="skip")
    w.set_motor(0, 0, 1.0, max_force=1000.0)
    w.step(200)
    assert w.qvel[0] == pytest.approx(1.0, abs=1e-6)
    w.set_motor(0, 0, None)
    w.set_servo(0, 1, 0.3, gain=20.0, max_force=1e4)
    w.step(2000)
    assert w.qpos[1] == pytest.approx(0.3, abs=1e-3)


def test_contacts_carry_their_impulses(repo):
    w = gelenk.World.builtin("box-flat")
    w.step(5)
    c = w.contacts()
    k = len(c["distance"])
    assert k == 4 and c["point_a"].shape == (4, 3) and c["impulse"].shape == (4, 3)
    assert np.allclose(np.abs(c["normal"][:, 2]), 1.0)
    assert np.all(c["depth"] >= 0.0) and np.array_equal(c["depth"], np.maximum(-c["distance"], 0))
    # The normal impulses hold the 2 kg box up against gravity over one step.
    assert c["impulse"][:, 0].sum() == pytest.approx(2.0 * 9.81 * w.dt, rel=1e-3)
    assert np.all(c["multibody_b"] == -1) and np.all(c["multibody_a"] == 0)
    p = w.problem()
    assert p["A"].shape == (w.stats["rows"],) * 2 and len(p["normal_rows"]) == 4
    assert np.array_equal(w.impulses()[p["normal_rows"]], c["impulse"][:, 0])
    assert w.stats["contacts"] == 4 and w.stats["rows"] == 12


def test_energy_advance_and_a_model_world(repo):
    model = gelenk.load_urdf(repo / "models/double_pendulum_simple.urdf")
    w = gelenk.World(model, dt=0.001, missing_meshes="skip")
    x = w.get_state()
    x[0] = 1.0
    w.set_state(x)
    e0 = w.energy()
    alpha = w.advance(0.0055)
    assert w.stats["step"] == 5 and alpha == pytest.approx(0.5)
    w.advance(1.0)  # at most max_substeps (8) steps per frame; the backlog is dropped
    assert w.stats["step"] == 13
    assert w.energy() == pytest.approx(e0, rel=1e-2) and w.kinetic_energy() > 0.0
    data = gelenk.Data(model)
    assert w.energy() == pytest.approx(
        gelenk.kinetic_energy(model, data, w.qpos, w.qvel) + gelenk.potential_energy(model, data, w.qpos)
    )
