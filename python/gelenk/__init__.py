"""gelenk: constraint-based Lagrangian multibody dynamics in generalized coordinates.

Models (URDF, MJCF, built in code), the dynamics algorithms on numpy arrays (RNEA, ABA, CRBA,
kinematics, Jacobians, energies), worlds with contacts, limits, motors and loop closures, batched
rollouts on every core, and the constraint problems of the steps for solver authors
(:mod:`gelenk.problems`). Conventions are Pinocchio's: SI units, z up, gravity (0, 0, -9.81)
m/s², spatial vectors linear part first, quaternions (x, y, z, w), joints numbered depth-first.

    >>> import gelenk, numpy as np
    >>> model = gelenk.load_urdf("models/ur5_robot.urdf")
    >>> data = gelenk.Data(model)
    >>> q = model.neutral(); v = np.zeros(model.nv); tau = np.zeros(model.nv)
    >>> ddq = gelenk.aba(model, data, q, v, tau)
"""

from ._gelenk import (
    Data,
    Model,
    ModelBuilder,
    StepError,
    World,
    __version__,
    aba,
    center_of_mass,
    crba,
    difference,
    export_problems,
    forward_kinematics,
    frame_jacobian,
    frame_placement,
    frame_pose,
    generalized_gravity,
    integrate,
    kinetic_energy,
    load_mjcf,
    load_scene,
    load_urdf,
    mass_matrix,
    nonlinear_effects,
    potential_energy,
    rnea,
    rollout,
)
from . import problems

__all__ = [
    "Data",
    "Model",
    "ModelBuilder",
    "StepError",
    "World",
    "__version__",
    "aba",
    "center_of_mass",
    "crba",
    "difference",
    "export_problems",
    "forward_kinematics",
    "frame_jacobian",
    "frame_placement",
    "frame_pose",
    "generalized_gravity",
    "integrate",
    "kinetic_energy",
    "load_mjcf",
    "load_scene",
    "load_urdf",
    "mass_matrix",
    "nonlinear_effects",
    "potential_energy",
    "problems",
    "rnea",
    "rollout",
]
