"""Bad input raises the right Python exception with the library's message, never a crash:
wrong dtype (TypeError), bad shapes, NaN and degenerate quaternions (ValueError), missing files
(FileNotFoundError), failed steps (gelenk.StepError), unknown names (KeyError), indices out of
range (IndexError)."""

import numpy as np
import pytest

import gelenk


@pytest.fixture(scope="module")
def ur5(repo):
    model = gelenk.load_urdf(repo / "models/ur5_robot.urdf")
    return model, gelenk.Data(model)


def test_wrong_dtype_is_a_type_error_naming_the_argument(ur5):
    model, data = ur5
    q, v = model.neutral(), np.zeros(model.nv)
    for bad in (q.astype(np.float32), q.astype(np.int64), list(q), (1.0,) * 6, "q", None):
        with pytest.raises(TypeError, match="^q: expected a numpy array of float64"):
            gelenk.aba(model, data, bad, v, v)
    with pytest.raises(TypeError, match="^tau: "):
        gelenk.aba(model, data, q, v, np.zeros(model.nv, dtype=np.float32))


def test_bad_shapes_are_value_errors(ur5):
    model, data = ur5
    q, v = model.neutral(), np.zeros(model.nv)
    with pytest.raises(ValueError, match=r"^q: expected 6 entries, got 5$"):
        gelenk.rnea(model, data, q[:5], v, v)
    with pytest.raises(ValueError, match=r"^a: expected 6 entries, got 7$"):
        gelenk.rnea(model, data, q, v, np.zeros(7))
    with pytest.raises(ValueError, match=r"^q: expected a 1-D array, got shape \[1, 6\]$"):
        gelenk.crba(model, data, q.reshape(1, 6))
    # A strided view is read correctly, not refused.
    wide = np.zeros(12)
    wide[::2] = q
    assert np.array_equal(gelenk.crba(model, data, wide[::2]), gelenk.crba(model, data, q))


def test_nan_is_a_value_error_naming_the_joint(ur5):
    model, data = ur5
    q, v = model.neutral(), np.zeros(model.nv)
    q[2] = np.nan
    with pytest.raises(ValueError, match=r"^q\[2\] \(joint `elbow_joint`\) is not finite$"):
        gelenk.aba(model, data, q, v, v)
    v = v.copy()
    v[4] = np.inf
    with pytest.raises(ValueError, match=r"^v\[4\] \(joint `wrist_2_joint`\) is not finite$"):
        gelenk.kinetic_energy(model, data, model.neutral(), v)


def test_a_degenerate_quaternion_is_a_value_error(repo):
    model = gelenk.load_urdf(repo / "models/solo12.urdf", floating=True)
    data = gelenk.Data(model)
    q = model.neutral()
    q[3:7] = 0.0
    with pytest.raises(ValueError, match="quaternion"):
        gelenk.crba(model, data, q)
    with pytest.raises(ValueError, match="quaternion"):
        gelenk.integrate(model, q, np.zeros(model.nv))
    with pytest.raises(ValueError, match=r"^dt is not finite \(NaN\)$"):
        gelenk.integrate(model, model.neutral(), np.zeros(model.nv), float("nan"))


def test_data_of_another_model_is_refused(repo, ur5):
    model, _ = ur5
    other = gelenk.load_urdf(repo / "models/double_pendulum_simple.urdf")
    with pytest.raises(ValueError, match="data was made for a model with"):
        gelenk.crba(model, gelenk.Data(other), model.neutral())


def test_missing_files_are_file_not_found_errors(tmp_path):
    missing = tmp_path / "missing"
    with pytest.raises(FileNotFoundError, match=r"missing\.urdf: cannot read: No such file"):
        gelenk.load_urdf(missing.with_suffix(".urdf"))
    with pytest.raises(FileNotFoundError, match=r"missing\.toml: cannot read"):
        gelenk.load_scene(missing.with_suffix(".toml"))
    with pytest.raises(FileNotFoundError, match=r"missing\.xml: cannot read"):
        gelenk.load_mjcf(missing.with_suffix(".xml"))
    with pytest.raises(FileNotFoundError):
        gelenk.problems.load(missing)
    with pytest.raises(FileNotFoundError):
        gelenk.problems.corpus(missing)


def test_invalid_files_are_value_errors_with_the_clis_message(tmp_path):
    urdf = tmp_path / "bad.urdf"
    urdf.write_text("<robot name='r'><link name='a'/><joint name='j' type='revolute'>"
                    "<parent link='a'/><child link='nowhere'/></joint></robot>")
    with pytest.raises(ValueError, match=r"bad\.urdf: joint `j`"):
        gelenk.load_urdf(urdf)
    scene = tmp_path / "bad.toml"
    scene.write_text("[[body]]\nshape = \"box\"\nsize = [1, 1, 1]\nmass = -1\n")
    with pytest.raises(ValueError, match=r"bad\.toml: line 4, column 8, `body\[0\]\.mass`: expected a positive number, got -1"):
        gelenk.load_scene(scene)
    with pytest.raises(ValueError, match="unknown joint type"):
        gelenk.ModelBuilder().add_body("b", "universe", "screw")


def test_loader_warnings_are_python_warnings(repo):
    with pytest.warns(UserWarning, match="unknown element <material>"):
        gelenk.load_urdf(repo / "models/solo12.urdf")
    with pytest.raises(ValueError, match="not a valid URDF document"):
        gelenk.load_urdf(repo / "models/solo12.urdf", strict=True)


def test_unknown_names_and_indices(ur5, repo):
    model, data = ur5
    with pytest.raises(KeyError, match="no frame named `nope`"):
        gelenk.frame_pose(model, data, "nope")
    with pytest.raises(IndexError, match="out of range"):
        gelenk.frame_pose(model, data, 10_000)
    with pytest.raises(ValueError, match="reference"):
        gelenk.frame_jacobian(model, data, model.neutral(), 1, "sideways")
    world = gelenk.load_scene(repo / "models/ragdoll_fall.toml")
    with pytest.raises(KeyError, match="no multibody named `nobody`"):
        world.q("nobody")
    with pytest.raises(IndexError):
        world.q(5)
    with pytest.raises(IndexError, match="out of range"):
        world.apply_force(0, 10_000, np.zeros(3), np.zeros(3))
    with pytest.raises(IndexError, match="dof 1000"):
        world.set_motor(0, 1000, 1.0)


def test_a_failed_step_is_a_step_error_and_the_state_stays(repo):
    world = gelenk.load_scene(repo / "models/ragdoll_fall.toml")
    state = world.get_state()
    with pytest.raises(ValueError, match="is not finite"):
        bad = state.copy()
        bad[world.nq + 3] = np.nan
        world.set_state(bad)
    with pytest.raises(ValueError, match=r"^tau\[4\] is not finite \(NaN\)$"):
        bad = np.zeros(world.nv)
        bad[4] = np.nan
        world.tau = bad
    assert np.array_equal(world.get_state(), state), "a refused state changes nothing"
    assert np.array_equal(world.tau, np.zeros(world.nv)), "refused forces change nothing"
    # Joint forces of 1e300 N·m overflow the dynamics: the step fails, the state is kept.
    tau = np.full(world.nv, 1e300)
    world.tau = tau
    with pytest.raises(gelenk.StepError, match=r"^step 1 \(t = 0 s\): .*(NaN|infinit|not finite)"):
        world.step()
    assert np.array_equal(world.get_state(), state)
    assert issubclass(gelenk.StepError, RuntimeError)


NAN, INF = float("nan"), float("inf")


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda w: w.set_servo(0, 1, 0.3, gain=NAN), r"^gain is not finite \(NaN\)$"),
        (lambda w: w.set_servo(0, 1, 0.3, gain=-1.0), r"^gain must be ≥ 0, got -1$"),
        (lambda w: w.set_servo(0, 1, INF), r"^target_position is not finite \(inf\)$"),
        (lambda w: w.set_servo(0, 1, 0.3, max_velocity=NAN), r"^max_velocity is not a number \(NaN\)$"),
        (lambda w: w.set_servo(0, 1, 0.3, max_force=-INF), r"^max_force must be ≥ 0 \(or inf: no bound\), got -inf$"),
        (lambda w: w.set_motor(0, 1, NAN), r"^target_velocity is not finite \(NaN\)$"),
        (lambda w: w.set_motor(0, 1, 1.0, max_force=NAN), r"^max_force is not a number \(NaN\)$"),
        (lambda w: w.advance(INF), r"^frame_dt is not finite \(inf\)$"),
        (lambda w: w.apply_force(0, 1, np.array([0.0, NAN, 0.0]), np.zeros(3)), r"^force\[1\] is not finite \(NaN\)$"),
        (lambda w: w.apply_force(0, 1, np.zeros(3), np.zeros(3), np.array([0, 0, -INF])),
         r"^torque\[2\] is not finite \(-inf\)$"),
        (lambda w: w.apply_impulse(0, 1, np.zeros(3), np.array([INF, 0, 0])), r"^point\[0\] is not finite \(inf\)$"),
    ],
)
def test_every_float_argument_of_a_world_is_checked_by_name(repo, call, message):
    world = gelenk.load_scene(repo / "models/ragdoll_fall.toml")
    state = world.get_state()
    with pytest.raises(ValueError, match=message):
        call(world)
    world.step()
    reference = gelenk.load_scene(repo / "models/ragdoll_fall.toml")
    reference.step()
    assert np.array_equal(world.get_state(), reference.get_state()), "a refused call changes nothing"
    assert not np.array_equal(world.get_state(), state)


def test_float_arguments_of_constructors_are_checked_by_name(ur5):
    model, _ = ur5
    with pytest.raises(ValueError, match=r"^dt must be > 0, got 0$"):
        gelenk.World(model, dt=0.0)
    with pytest.raises(ValueError, match=r"^dt is not finite \(NaN\)$"):
        gelenk.World(model, dt=NAN)
    with pytest.raises(ValueError, match=r"^gravity\[2\] is not finite \(NaN\)$"):
        gelenk.World(model, gravity=[0.0, 0.0, NAN])
    with pytest.raises(ValueError, match=r"^gravity\[0\] is not finite \(inf\)$"):
        gelenk.ModelBuilder(gravity=[INF, 0.0, 0.0])
    builder = gelenk.ModelBuilder()
    good = dict(axis=[0.0, 0.0, 1.0], mass=1.0, inertia=[[0.1, 0, 0], [0, 0.1, 0], [0, 0, 0.1]])
    for bad, message in [
        (dict(mass=NAN), r"^mass is not finite \(NaN\)$"),
        (dict(axis=[0.0, NAN, 1.0]), r"^axis\[1\] is not finite \(NaN\)$"),
        (dict(translation=[0.0, 0.0, INF]), r"^translation\[2\] is not finite \(inf\)$"),
        (dict(com=[NAN, 0.0, 0.0]), r"^com\[0\] is not finite \(NaN\)$"),
        (dict(inertia=[[0.1, 0, 0], [0, 0.1, NAN], [0, 0, 0.1]]), r"^inertia\[1\]\[2\] is not finite \(NaN\)$"),
        (dict(quaternion=[0.0, 0.0, 0.0, NAN]), r"^quaternion\[3\] is not finite \(NaN\)$"),
    ]:
        with pytest.raises(ValueError, match=message):
            builder.add_body("link", "universe", "hinge", **{**good, **bad})
    builder.add_body("link", "universe", "hinge", **good)
    assert builder.build().nv == 1, "refused bodies were not added"
