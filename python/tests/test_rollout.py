"""gelenk.rollout equals stepping each world alone, bit for bit, for any number of threads;
controls are the joint forces of each step; statistics are the steps'; bad input is refused."""

import numpy as np
import pytest

import gelenk


@pytest.fixture(scope="module")
def ragdoll(repo):
    return gelenk.load_scene(repo / "models/ragdoll_fall.toml")


def drops(world, batch, seed=0):
    """Initial states: the scene's, each dropped from a different height with a random spin."""
    rng = np.random.default_rng(seed)
    x = np.tile(world.get_state(), (batch, 1))
    x[:, 2] += rng.uniform(0.0, 0.5, batch)
    x[:, world.nq + 3 : world.nq + 6] = rng.normal(0.0, 2.0, (batch, 3))
    return x


def sequential(world, x0, steps, controls=None):
    """Each world alone: rebuilt, its state set, stepped with its controls."""
    out = np.zeros((len(x0), steps, world.nstate))
    for b in range(len(x0)):
        world.reset()
        world.set_state(x0[b])
        for t in range(steps):
            if controls is not None:
                world.tau = controls[b, t]
            world.step()
            out[b, t] = world.get_state()
    return out


def test_rollout_equals_sequential_steps_for_any_thread_count(ragdoll):
    x0 = drops(ragdoll, 6)
    steps = 400  # the ragdoll reaches the ground: contacts, limits, the solver
    want = sequential(ragdoll, x0, steps)
    for threads in (None, 1, 2, 3):
        got = gelenk.rollout(ragdoll, x0, steps=steps, threads=threads)
        assert got.shape == (6, steps, ragdoll.nstate) and got.dtype == np.float64
        assert np.array_equal(got, want), f"threads={threads}"
    _, stats = gelenk.rollout(ragdoll, x0, steps=steps, stats=True)
    assert stats["contacts"].shape == (6, steps) and stats["contacts"].max() > 0
    assert stats["rows"].max() > 0 and np.all(stats["max_penetration"] >= 0.0)


def test_controls_are_joint_forces_applied_before_each_step(repo):
    model = gelenk.load_urdf(repo / "models/ur5_robot.urdf")
    world = gelenk.World(model, dt=0.001, missing_meshes="skip")
    rng = np.random.default_rng(1)
    x0 = np.zeros((3, world.nstate))
    x0[:, : world.nq] = rng.uniform(-1.0, 1.0, (3, world.nq))
    controls = rng.normal(0.0, 5.0, (3, 50, world.nv))
    got = gelenk.rollout(world, x0, controls)
    assert np.array_equal(got, sequential(world, x0, 50, controls))
    # The model alone rolls out in the same default world as World(model) with its time step.
    by_model = gelenk.rollout(model, x0, controls)
    assert by_model.shape == got.shape and not np.array_equal(by_model, got), "dt 0.002 vs 0.001"
    assert np.array_equal(by_model, gelenk.rollout(gelenk.World(model, missing_meshes="skip"), x0, controls))
    zero = gelenk.rollout(world, x0, np.zeros_like(controls))
    assert not np.array_equal(zero, got)


def test_an_mjcf_scene_rolls_out(repo):
    world = gelenk.load_mjcf(repo / "benches/peers/humanoid_fall.xml")
    x0 = np.tile(world.get_state(), (2, 1))
    x0[1, 2] += 0.2
    got = gelenk.rollout(world, x0, steps=100, threads=2)
    assert np.array_equal(got, sequential(world, x0, 100))
    assert got[1, -1, 2] != got[0, -1, 2]


def test_bad_input_is_refused(ragdoll):
    x0 = drops(ragdoll, 2)
    with pytest.raises(ValueError, match=r"initial_states: expected shape \(B, 86\)"):
        gelenk.rollout(ragdoll, x0[:, :-1], steps=3)
    with pytest.raises(ValueError, match="steps: required"):
        gelenk.rollout(ragdoll, x0)
    with pytest.raises(ValueError, match=r"controls: expected shape \(2, 5, 39\)"):
        gelenk.rollout(ragdoll, x0, np.zeros((2, 5, 38)), steps=5)
    with pytest.raises(TypeError, match="initial_states: expected a numpy array of float64"):
        gelenk.rollout(ragdoll, x0.astype(np.float32), steps=3)
    with pytest.raises(TypeError, match="scene: expected a gelenk.World or a gelenk.Model"):
        gelenk.rollout("models/ragdoll_fall.toml", x0, steps=3)
    with pytest.raises(ValueError, match="threads: at least 1"):
        gelenk.rollout(ragdoll, x0, steps=3, threads=0)
    bad = x0.copy()
    bad[1, 0] = np.nan
    with pytest.raises(ValueError, match=r"^initial_states\[1\]: multibody `ragdoll.*` is not finite \(NaN\)$"):
        gelenk.rollout(ragdoll, bad, steps=3)
    controls = np.zeros((2, 3, ragdoll.nv))
    controls[1, 2, 5] = np.inf
    with pytest.raises(ValueError, match=r"^controls\[1, 2, 5\] is not finite \(inf\)$"):
        gelenk.rollout(ragdoll, x0, controls)
    controls[1, 2, 5] = 0.0
    controls[0, 2, 7] = 1e300
    with pytest.raises(gelenk.StepError, match=r"^rollout 0, step 3 \(t = 0.004"):
        gelenk.rollout(ragdoll, x0, controls)
    assert gelenk.rollout(ragdoll, x0, steps=0).shape == (2, 0, 86)
