"""Type stubs of the extension module gelenk._gelenk (re-exported by gelenk)."""

import os
from typing import Any, Dict, List, Literal, Optional, Sequence, Tuple, Union, overload

import numpy as np
import numpy.typing as npt

Array = npt.NDArray[np.float64]
PathLike = Union[str, os.PathLike]
Index = Union[int, str]

__version__: str

class StepError(RuntimeError):
    """A simulation step failed: a non-finite state, a singular mass matrix, every solver of the chain failing, ... The world's state is left as it was before the step."""

class Model:
    """A kinematic tree of rigid bodies (Pinocchio's `Model`): topology, joints, inertias, limits.
    Immutable. Body 0 is the universe; body i ≥ 1 is carried by joint i; joints are numbered
    depth-first. Units SI, z up, quaternions (x, y, z, w).
    """

    @property
    def name(self) -> str:
        """The model's name (the URDF robot's name)."""
    @property
    def nq(self) -> int:
        """Number of configuration coordinates."""
    @property
    def nv(self) -> int:
        """Number of velocity coordinates (degrees of freedom)."""
    @property
    def nbodies(self) -> int:
        """Number of bodies, the universe (body 0) included."""
    @property
    def joint_names(self) -> List[str]:
        """Names of the moving joints, in joint order (joint i carries body i; the universe's
        "joint" is left out, so entry k names joint k + 1).
        """
    @property
    def body_names(self) -> List[str]:
        """Names of the bodies, the universe first."""
    @property
    def frame_names(self) -> List[str]:
        """Names of the frames (links and joints, fused fixed links included), in frame order."""
    @property
    def joints(self) -> List[Dict[str, Any]]:
        """One dict per moving joint: `name`, `type`, `body` (its index), `parent` (parent body
        index), `idx_q`, `nq`, `idx_v`, `nv` — where its coordinates sit in q and v.
        """
    @property
    def lower_position_limit(self) -> Array:
        """Lower position limits (nq entries; −inf where unlimited)."""
    @property
    def upper_position_limit(self) -> Array:
        """Upper position limits (nq entries; +inf where unlimited)."""
    @property
    def velocity_limit(self) -> Array:
        """Velocity limits (nv entries, rad/s or m/s)."""
    @property
    def effort_limit(self) -> Array:
        """Effort limits (nv entries, N·m or N)."""
    @property
    def damping(self) -> Array:
        """Viscous joint damping (nv entries, N·m·s/rad or N·s/m)."""
    @property
    def friction(self) -> Array:
        """Coulomb joint friction (nv entries, N·m or N)."""
    @property
    def gravity(self) -> Array:
        """Gravity in the world frame (m/s²)."""
    @property
    def mass(self) -> float:
        """Total mass of the moving bodies (kg)."""
    def neutral(self) -> Array:
        """The neutral configuration: zero angles and offsets, identity quaternions."""
    def random_configuration(self, seed: Optional[int] = None) -> Array:
        """A random configuration within the position limits (uniform angles where unlimited,
        uniformly random unit quaternions), drawn from a generator seeded with `seed` (the same
        seed gives the same configuration), or seeded from the clock when `seed` is None.
        """
    def frame_id(self, name: str, kind: Optional[Literal["body", "joint"]] = None) -> int:
        """Index of the frame called `name`: a body (link) frame before a joint frame of the same
        name, unless `kind` is "body" or "joint". KeyError when there is none.
        """
    def body_id(self, name: str) -> int:
        """Index of the body called `name` (the universe is 0). KeyError when there is none."""
    def joint_id(self, name: str) -> int:
        """Index of the moving joint called `name` (= the index of the body it carries). KeyError
        when there is none.
        """
    def create_data(self) -> "Data":
        """A new `Data` for this model."""

class Data:
    """Every buffer the algorithms write for one model (Pinocchio's `Data`), allocated once. The
    algorithms take it as their second argument and leave their results in it as well as
    returning them.

    `Data(model)` (or `model.create_data()`): the buffers for `model`; a Data serves only models
    of the same sizes (ValueError otherwise).
    """

    def __init__(self, model: Model) -> None: ...
    @property
    def mass_matrix(self) -> Array:
        """The mass matrix M(q) of the last `crba` or `mass_matrix` (nv × nv, symmetric)."""
    @property
    def ddq(self) -> Array:
        """The accelerations of the last `aba` (nv)."""
    @property
    def tau(self) -> Array:
        """The joint forces of the last `rnea` (nv)."""
    @property
    def nle(self) -> Array:
        """The nonlinear effects of the last `nonlinear_effects` (nv)."""
    @property
    def com(self) -> Array:
        """The centre of mass of the last `center_of_mass` (m, world)."""

class ModelBuilder:
    """Builds a model body by body (parents may come after their children), as the URDF loader
    does; `build()` validates it and numbers the joints depth-first.

    `ModelBuilder(name="", gravity=(0, 0, -9.81))`: an empty model called `name` with gravity
    `gravity` (m/s², world frame).
    """

    def __init__(self, name: str = "", gravity: Sequence[float] = (0.0, 0.0, -9.81)) -> None: ...
    def add_body(
        self,
        name: str,
        parent: str,
        joint: Literal["hinge", "slider", "ball", "universal", "hinge2", "free", "planar", "fixed"],
        *,
        axis: Optional[Sequence[float]] = None,
        axis1: Optional[Sequence[float]] = None,
        axis2: Optional[Sequence[float]] = None,
        suspension: Optional[Tuple[float, float]] = None,
        translation: Sequence[float] = (0.0, 0.0, 0.0),
        quaternion: Sequence[float] = (0.0, 0.0, 0.0, 1.0),
        mass: float = 0.0,
        com: Sequence[float] = (0.0, 0.0, 0.0),
        inertia: Sequence[Sequence[float]] = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)),
        joint_name: Optional[str] = None,
    ) -> None:
        """Adds body `name` attached to body `parent` ("universe" for the world) by a joint of type
        `joint` ("hinge", "slider", "ball", "universal", "hinge2", "free", "planar", "fixed";
        hinge and slider take `axis`, universal and hinge2 `axis1`, `axis2`, hinge2 an optional
        `suspension` (stiffness N/m, damping N·s/m)). The joint frame sits at `translation` (m)
        and `quaternion` (x, y, z, w) in the parent's frame; the body has mass `mass` (kg),
        centre of mass `com` (m, body frame) and rotational inertia `inertia` (3×3 about the
        centre of mass, body axes, kg·m²). A number that is not finite is a ValueError naming
        the argument; everything else is checked by `build()`.
        """
    def build(self) -> Model:
        """Validates every body and joint and returns the model (ValueError naming the body or
        joint at fault).
        """

def load_urdf(
    path: PathLike, floating: bool = False, strict: bool = False, balance_inertia: bool = False
) -> Model:
    """Loads a URDF file. `floating`: attach the root link by a free joint (7 coordinates, 6
    dofs) instead of fixing it to the world. `strict`: every loader warning is an error;
    otherwise warnings (unknown elements, inconsistent inertias, ...) are issued as Python
    `UserWarning`s. `balance_inertia`: replace inconsistent link inertias by their balanced
    form (MuJoCo's balanceinertia). Raises FileNotFoundError, ValueError.
    """
def load_scene(path: PathLike) -> "World":
    """Loads a scene file (TOML, see docs/scenes.md): URDF models, bodies, grounds, materials,
    solver and time step. Raises FileNotFoundError, ValueError (naming the file, line and key).
    """
def load_mjcf(path: PathLike) -> "World":
    """Loads an MJCF file (MuJoCo's format) as a world: each of the model's trees (a top-level body
    and what hangs from it) a multibody at MuJoCo's `qpos0`, on its static geometry, with its
    time step, gravity and friction model. Raises FileNotFoundError, ValueError.
    """
def integrate(model: Model, q: Array, v: Array, dt: float = 1.0) -> Array:
    """`q ⊕ v·dt`: the configuration reached from `q` moving at `v` for `dt` seconds, joint by
    joint on the configuration manifold (quaternions stay unit).
    """
def difference(model: Model, q0: Array, q1: Array) -> Array:
    """`q1 ⊖ q0`: the velocity that `integrate` turns `q0` into `q1` with in unit time."""
def rnea(model: Model, data: Data, q: Array, v: Array, a: Array) -> Array:
    """Inverse dynamics (RNEA): the joint forces τ = M(q) a + C(q, v) v + g(q) (N·m or N) that give
    accelerations `a`.
    """
def aba(model: Model, data: Data, q: Array, v: Array, tau: Array) -> Array:
    """Forward dynamics (articulated-body algorithm): the accelerations q̈ = M(q)⁻¹ (τ − C(q, v) v −
    g(q)) under joint forces `tau`. ValueError for a singular mass matrix (a massless subtree).
    """
def crba(model: Model, data: Data, q: Array) -> Array:
    """The joint-space mass matrix M(q) (composite rigid-body algorithm), nv × nv, symmetric."""
def mass_matrix(model: Model, data: Data, q: Array) -> Array:
    """The joint-space mass matrix M(q) alone, nv × nv, symmetric: the same M as `crba`, computed
    in body frames without the world poses and Jacobian columns that `crba` also leaves in `data`.
    """
def nonlinear_effects(model: Model, data: Data, q: Array, v: Array) -> Array:
    """The nonlinear effects C(q, v) v + g(q) = rnea(q, v, 0)."""
def generalized_gravity(model: Model, data: Data, q: Array) -> Array:
    """The generalized gravity g(q) = rnea(q, 0, 0)."""
def forward_kinematics(model: Model, data: Data, q: Array) -> None:
    """Forward kinematics: every body's pose in the world at `q`, kept in `data` for
    `frame_placement` and `frame_pose`.
    """
def frame_placement(model: Model, data: Data, frame: Index) -> Array:
    """The pose of frame `frame` (an index or a name) in the world, from the last
    `forward_kinematics`, as a 4×4 homogeneous matrix `[R t; 0 1]`.
    """
def frame_pose(model: Model, data: Data, frame: Index) -> Array:
    """The pose of frame `frame` (an index or a name) in the world, from the last
    `forward_kinematics`, as 7 numbers: position (m), then the unit quaternion (x, y, z, w) —
    the layout of a free joint's q.
    """
def frame_jacobian(
    model: Model,
    data: Data,
    q: Array,
    frame: Index,
    reference: Literal["local", "local_world_aligned", "world"] = "local",
) -> Array:
    """The 6 × nv Jacobian of frame `frame` (an index or a name) at `q`, linear rows first, so that
    `J @ v` is the frame's velocity `[v; ω]` expressed as `reference` says: "local" (the frame's
    own axes, its origin's velocity), "local_world_aligned" (world axes, its origin's velocity)
    or "world" (world axes, about the world origin) — Pinocchio's LOCAL, LOCAL_WORLD_ALIGNED and
    WORLD.
    """
def kinetic_energy(model: Model, data: Data, q: Array, v: Array) -> float:
    """Kinetic energy at (q, v) (J)."""
def potential_energy(model: Model, data: Data, q: Array) -> float:
    """Potential energy in gravity at q (J), zero when every centre of mass is at the world
    origin's height.
    """
def center_of_mass(model: Model, data: Data, q: Array) -> Array:
    """Centre of mass of the moving bodies at q (m, world frame)."""

class World:
    """A simulated world: multibodies, static geometry, contacts, limits, motors and loop closures
    stepped together (`step`, `advance`). Its state is the flat vector `[qpos, qvel]` over its
    multibodies in order (`get_state`, `set_state`, `state_labels`, `joint_index`); each
    multibody's own q, v and joint forces τ are reachable by index or name.

    `World(model, dt=None, gravity=None, ground=False, missing_meshes="error")`: a world holding
    `model` as its only multibody, at the model's neutral configuration and at rest, with time
    step `dt` (s; default 0.002), gravity `gravity` (m/s²; default (0, 0, −9.81)) and, if
    `ground`, the ground plane z = 0. A collision mesh that cannot be found is an error, or with
    `missing_meshes="skip"` left out (listed in `warnings`). Scene files, MJCF files and the
    built-in scenes give worlds too: `load_scene`, `load_mjcf`, `World.builtin`.
    """

    def __init__(
        self,
        model: Model,
        dt: Optional[float] = None,
        gravity: Optional[Sequence[float]] = None,
        ground: bool = False,
        missing_meshes: Literal["error", "skip"] = "error",
    ) -> None: ...
    @staticmethod
    def builtin(name: str) -> "World":
        """A built-in scene ("box-drop", "box-flat", "stack2", "stack10", "sphere-incline",
        "four-bar", "limit-pendulum") as a world.
        """
    @property
    def name(self) -> str:
        """The scene's or model's name."""
    @property
    def dt(self) -> float:
        """Time step (s)."""
    @property
    def time(self) -> float:
        """Simulated time (s)."""
    @property
    def nq(self) -> int:
        """Total configuration coordinates (length of qpos)."""
    @property
    def nv(self) -> int:
        """Total velocity coordinates (length of qvel, and of the joint forces τ)."""
    @property
    def nstate(self) -> int:
        """Length of the state vector `[qpos, qvel]`."""
    @property
    def warnings(self) -> List[str]:
        """What was left out while loading (collision meshes skipped), one sentence each."""
    @property
    def multibody_names(self) -> List[str]:
        """Names of the multibodies, in order."""
    def joint_index(self) -> List[Dict[str, Any]]:
        """One dict per joint of every multibody: `multibody`, `joint`, `type`, `qpos` (first index in
        qpos and in the state), `nq`, `qvel` (first index in qvel; in the state add `nq`), `nv`.
        """
    def state_labels(self) -> List[str]:
        """A name for every entry of the state `[qpos, qvel]`: `multibody.joint` for a scalar
        joint's coordinate, `multibody.joint.component` otherwise (`x y z qx qy qz qw` of a free
        joint), velocities ending in `.v` or naming their component (`vx … wz`) — the columns of
        `gelenk simulate --out`.
        """
    def get_state(self) -> Array:
        """The state `[qpos, qvel]` (a new array of `nstate` entries)."""
    def set_state(self, state: Array) -> None:
        """Sets the state `[qpos, qvel]` (ValueError for the wrong length, a non-finite entry or a
        quaternion that cannot be normalized; nothing changes then) and wakes every multibody.
        """
    @property
    def qpos(self) -> Array:
        """Configuration of every multibody, laid end to end (nq entries; a new array)."""
    @qpos.setter
    def qpos(self, value: Array) -> None: ...
    @property
    def qvel(self) -> Array:
        """Velocity of every multibody, laid end to end (nv entries; a new array)."""
    @qvel.setter
    def qvel(self, value: Array) -> None: ...
    @property
    def tau(self) -> Array:
        """Joint forces τ of every multibody, laid end to end (nv entries, N·m or N), applied at
        every step until changed.
        """
    @tau.setter
    def tau(self, value: Array) -> None: ...
    def q(self, multibody: Index) -> Array:
        """Configuration q of one multibody (an index or a name)."""
    def v(self, multibody: Index) -> Array:
        """Velocity v of one multibody (an index or a name)."""
    def set_multibody_state(self, multibody: Index, q: Array, v: Optional[Array] = None) -> None:
        """Sets the configuration q (and, if given, the velocity v) of one multibody and wakes it."""
    def model(self, multibody: Index) -> Model:
        """The model of one multibody (an index or a name), for the dynamics functions."""
    def step(self, n: int = 1) -> None:
        """Takes `n` steps of `dt` (the GIL is released meanwhile). A scene file's vehicle commands
        are applied before each step whose time has come, as `gelenk simulate` does. Raises
        `gelenk.StepError` when a step fails, with the message `gelenk simulate` prints; the
        state is then the one before the failed step.
        """
    def advance(self, frame_dt: float) -> float:
        """Runs whole steps of `dt` for a frame of `frame_dt` seconds (at most `max_substeps` of
        them; the rest of the backlog is dropped) and returns the interpolation factor
        α ∈ [0, 1) between the last two states, for rendering.
        """
    def reset(self) -> None:
        """The world again at its initial state (the scene or model as loaded)."""
    @property
    def stats(self) -> Dict[str, Any]:
        """Statistics of the last step: `step`, `time` (s), `contacts`, `rows`, `solver`,
        `iterations`, `residual` (m/s), `fallbacks`, `max_penetration` (m), `asleep`, `energy`
        (J, or None unless diagnostics are on), `integrator`.
        """
    def energy(self) -> float:
        """Kinetic plus potential energy of every multibody at the current state (J)."""
    def kinetic_energy(self) -> float:
        """Kinetic energy of every multibody at the current state (J)."""
    def contacts(self) -> Dict[str, Any]:
        """The contacts of the last step as a dict of arrays, one row per contact point:
        `point_a`, `point_b` (k × 3, m, world: the nearest points of the two surfaces),
        `normal` (k × 3, unit, from B to A), `distance` (k, m: negative = penetration),
        `depth` (k, m: penetration depth, max(−distance, 0)), `impulse` (k × 3, N·s: normal
        then the two friction impulses; zero for a contact without rows), `multibody_a`,
        `body_a`, `multibody_b`, `body_b` (k; −1 for static geometry), `collider_a`,
        `collider_b` (names).
        """
    def impulses(self) -> Array:
        """Impulses of the last step's constraint rows (N·s), one per row of `problem()`."""
    def problem(self) -> Dict[str, Any]:
        """The last step's constraint problem `w = (A + R) λ + b`: `A` (rows × rows Delassus
        matrix), `R` (regularization), `b` (bias), `target`, `normal_rows` (row of each
        contact's normal), `mu`, `friction` ("cone" or "pyramidN").
        """
    def apply_force(
        self, multibody: Index, body: Index, force: Array, point: Array, torque: Optional[Array] = None
    ) -> None:
        """Applies the force `force` (N, world axes) at the world point `point` (m), and the
        torque `torque` (N·m, world axes), to body `body` (an index ≥ 1 or a name) of
        `multibody` during the next step.
        """
    def apply_impulse(self, multibody: Index, body: Index, impulse: Array, point: Array) -> None:
        """Applies the impulse `impulse` (N·s, world axes) at the world point `point` (m) to body
        `body` of `multibody`: an instant velocity change.
        """
    def set_motor(
        self, multibody: Index, dof: int, target_velocity: Optional[float], max_force: float = ...
    ) -> None:
        """Puts a velocity motor on dof `dof` of `multibody`: drive its rate to `target_velocity`
        (rad/s or m/s) with at most `max_force` (N·m or N); `target_velocity=None` removes it.
        """
    def set_servo(
        self,
        multibody: Index,
        dof: int,
        target_position: Optional[float],
        gain: float = 10.0,
        max_velocity: float = ...,
        max_force: float = ...,
    ) -> None:
        """Puts a position servo on dof `dof` of `multibody`: a motor whose target rate is
        `gain · (target_position − q)` (gain in 1/s), clamped to `max_velocity`, with force bound
        `max_force`; `target_position=None` removes it.
        """

@overload
def rollout(
    scene: Union[World, Model],
    initial_states: Array,
    controls: Optional[Array] = None,
    steps: Optional[int] = None,
    threads: Optional[int] = None,
    stats: Literal[False] = False,
) -> Array:
    """Rolls out B copies of `scene` (a `World`, rebuilt at its initial state as loaded, or a
    `Model` alone in a world without ground, its collision meshes that cannot be found left
    out) from `initial_states` (B × nstate, each a state
    `[qpos, qvel]` as `World.get_state` gives) for `steps` steps, applying the joint forces
    `controls[b, t]` (B × T × nv, N·m or N; None: the scene's own forces) before step t, on
    `threads` threads (None: one per core) with the GIL released. Returns the states after each
    step, B × T × nstate, and with `stats=True` also a dict of B × T arrays: `contacts`, `rows`,
    `iterations`, `residual` (m/s), `max_penetration` (m). The result is the same, bit for bit,
    for any number of threads, and equals stepping each world alone. Raises ValueError for bad
    shapes or a non-finite or degenerate initial state, `gelenk.StepError` when a step fails
    (naming the rollout and the step).
    """
@overload
def rollout(
    scene: Union[World, Model],
    initial_states: Array,
    controls: Optional[Array] = None,
    steps: Optional[int] = None,
    threads: Optional[int] = None,
    *,
    stats: Literal[True],
) -> Tuple[Array, Dict[str, np.ndarray]]: ...
def export_problems(
    scene: str, out: PathLike, steps: int, friction: str = "cone", only: Optional[Sequence[int]] = None
) -> int:
    """Steps a scene and writes the constraint problem of each step that has rows into
    `out/step-NNNN/` (problem.json, cone.json, lcp.npz, qp.npz for QPs, meta.json), as `gelenk
    export-problems` does. `scene`: a built-in scene's name, a scene file (.toml) or an MJCF file
    (.xml); `friction`: "cone", "pyramid" or "pyramidN"; `only`: the steps to write (default:
    every step with rows). Returns the number of problems written.
    """
def read_problem(path: PathLike) -> Dict[str, Any]:
    """Reads `problem.json` (a file, or a directory holding one) into the dict of `World.problem`
    (`A`, `R`, `b`, `target`, `J`, `laws`, `lo`, `hi`, `normal_rows`, `mu`, `mu2`,
    `friction`). Raises FileNotFoundError, ValueError (naming the file).
    """
