#!/usr/bin/env python3
"""Generates tests/data/mjcf_reference.json: MuJoCo's own numbers for the MJCF scenes that
gelenk's MJCF loader (src/io/mjcf.rs) must reproduce. Run offline, by hand:

    pip install mujoco          # the committed data was made with the version recorded in the JSON
    python3 tests/data/gen_mjcf_reference.py

CI never runs this script: tests/mjcf.rs only reads the JSON, which also embeds the XML text of
every case (so the test does not depend on files outside the crate).

Cases: the three peer scenes of benches/peers (pendulum5, humanoid_fall, box_stack10) and two
hand-written scenes exercising the rest of the loader's subset (orientations, defaults classes,
slide/ball joints, joint `pos`, welded bodies, `<frame>`, `<inertial>`, fromto boxes, radians and
other Euler sequences).

For each case and each of a few random states, MuJoCo (armature forced to 0, since gelenk has no
armature) computes the mass matrix (mj_fullM), the bias forces qfrc_bias = C(q, v) v + g(q) and the
gravity term (qfrc_bias at v = 0). They are converted to gelenk's conventions:

* joint order: MuJoCo orders bodies depth-first in document order and joints in body order, as
  gelenk does (a body with several joints becomes a chain in MJCF order); the script checks that
  MuJoCo's qpos/dof addresses are increasing in that order and records them per joint;
* q: a free joint's MuJoCo qpos (x y z qw qx qy qz) becomes (x y z qx qy qz qw), a ball joint's
  (qw qx qy qz) becomes (qx qy qz qw);
* v: MuJoCo's free-joint velocity is (linear velocity of the body origin in world axes, angular
  velocity in body axes); gelenk's is (both in body axes). With R the body rotation,
  v_mj = J v_gl where J = diag(R, I) on each free joint's 6 dofs and the identity elsewhere. Then
  M_gl = Jᵀ M_mj J,  g_gl = Jᵀ g_mj,  nle_gl = Jᵀ (bias_mj(q, J v_gl) + M_mj J̇ v_gl),
  where (J̇ v_gl) on a free joint's linear block is R (ω × v_lin) (ω, v_lin: gelenk's body-frame
  angular and linear velocity), zero elsewhere.
"""

import json
import os
import sys

import mujoco
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
PEERS = os.path.normpath(os.path.join(HERE, "..", "..", "benches", "peers"))
OUT = os.path.join(HERE, "mjcf_reference.json")
SEED = 20240611
STATES = 3

FEATURES_DEGREE = """<mujoco model="features_degree">
  <option timestep="0.005" gravity="0.5 -1 -9"/>
  <default>
    <joint damping="0.3" armature="0.02"/>
    <geom density="800" friction="0.9 0.01 0.001"/>
    <default class="heavy">
      <geom density="3000"/>
      <default class="heavier">
        <geom density="5000" contype="0" conaffinity="0"/>
        <joint damping="2"/>
      </default>
    </default>
  </default>
  <worldbody>
    <geom name="floor" type="plane" size="0 0 1" pos="0 0 -2" euler="5 0 0"/>
    <geom name="wall" type="box" size="1 0.1 1" pos="2 0 0"/>
    <body name="stand" pos="0 0 0.5" euler="0 0 30">
      <geom type="cylinder" size="0.05 0.2"/>
      <body name="base" pos="0.1 0 0.3" quat="0.9 0.1 0.2 0.3">
        <joint name="slide1" type="slide" axis="1 1 0" range="-0.5 0.5"/>
        <joint name="hinge1" type="hinge" axis="0 0 1" pos="0.05 0.02 0"/>
        <geom type="box" size="0.1 0.05 0.02" pos="0.02 0 0" euler="10 20 30"/>
        <geom type="sphere" size="0.04" pos="0 0.1 0" mass="0.7"/>
        <body name="arm" pos="0.2 0 0" axisangle="1 1 0 40" childclass="heavy">
          <joint name="ball1" type="ball" pos="0 0 0.03"/>
          <geom type="capsule" fromto="0 0 0 0.3 0.1 -0.2" size="0.02"/>
          <geom type="box" fromto="0 0 0 0.1 0.2 0.3" size="0.01 0.02"/>
          <body name="hand" pos="0.3 0.1 -0.2" xyaxes="0 1 0 -1 0 0">
            <geom class="heavier" type="cylinder" fromto="0 0 0 0 0.1 0" size="0.03"/>
            <body name="finger" zaxis="1 1 1" pos="0 0.1 0">
              <joint name="f1" axis="1 0 0" class="heavier"/>
              <inertial pos="0.01 0.02 0.03" quat="0.8 0.2 0.1 0.3" mass="0.2" diaginertia="0.001 0.002 0.0025"/>
              <geom type="sphere" size="0.01"/>
            </body>
          </body>
        </body>
        <frame pos="0 0 -0.1" euler="0 90 0">
          <body name="side" pos="0.05 0 0">
            <joint name="side_hinge" axis="0 1 0" range="-30 30"/>
            <geom type="capsule" size="0.02 0.05" quat="1 1 0 0"/>
          </body>
        </frame>
      </body>
    </body>
    <body name="float" pos="1 1 1" euler="30 0 0">
      <freejoint name="float_root"/>
      <geom type="box" size="0.1 0.2 0.3"/>
      <body name="pend" pos="0 0 -0.3">
        <joint name="pend_hinge" axis="1 0 0" pos="0 0 0.1"/>
        <geom type="capsule" size="0.03" fromto="0 0 0 0 0 -0.4"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""

FEATURES_RADIAN = """<mujoco model="features_radian">
  <compiler angle="radian" eulerseq="ZYX"/>
  <option gravity="0 0 -3"/>
  <default>
    <default class="link">
      <joint type="hinge" axis="0 1 0" range="-1 1" frictionloss="0.1"/>
      <geom type="capsule" size="0.03 0.1" mass="0.5"/>
    </default>
  </default>
  <worldbody>
    <body name="a" pos="0.1 0.2 0.3" euler="0.3 -0.2 0.5" childclass="link">
      <joint name="a_x" type="slide" axis="1 0 0" range="-0.2 0.2"/>
      <joint name="a_y" type="slide" axis="0 1 0"/>
      <joint name="a_ball" type="ball" range="0 1.2"/>
      <geom pos="0 0 -0.1"/>
      <body name="b" pos="0 0 -0.3" axisangle="0 0 1 0.7">
        <joint name="b_h"/>
        <joint name="b_h2" axis="1 0 0" pos="0 0.02 0.01"/>
        <geom type="cylinder" size="0.04 0.05" euler="1.0 0.5 0.2"/>
        <geom type="box" size="0.02 0.03 0.04" pos="0.05 0 0" mass="0.25"/>
        <body name="c" pos="0 0 -0.2">
          <joint name="c_h" type="hinge" axis="1 2 3" limited="false" damping="0.05"/>
          <geom type="sphere" size="0.05" density="2000"/>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""

JOINT_TYPES = {0: "free", 1: "ball", 2: "slide", 3: "hinge"}


def name_of(m, kind, i):
    n = mujoco.mj_id2name(m, kind, i)
    return n if n else None


def random_state(m, rng):
    qpos = np.zeros(m.nq)
    qvel = rng.normal(size=m.nv)
    for j in range(m.njnt):
        a = m.jnt_qposadr[j]
        t = m.jnt_type[j]
        if t == 0:
            qpos[a:a + 3] = rng.uniform(-1.0, 1.0, 3)
            quat = rng.normal(size=4)
            qpos[a + 3:a + 7] = quat / np.linalg.norm(quat)
        elif t == 1:
            quat = rng.normal(size=4)
            qpos[a:a + 4] = quat / np.linalg.norm(quat)
        elif t == 2:
            qpos[a] = rng.uniform(-0.3, 0.3)
        else:
            qpos[a] = rng.uniform(-1.2, 1.2)
    return qpos, qvel


def to_gelenk_q(m, qpos):
    q = qpos.copy()
    for j in range(m.njnt):
        a = m.jnt_qposadr[j]
        if m.jnt_type[j] == 0:
            q[a + 3:a + 7] = [qpos[a + 4], qpos[a + 5], qpos[a + 6], qpos[a + 3]]
        elif m.jnt_type[j] == 1:
            q[a:a + 4] = [qpos[a + 1], qpos[a + 2], qpos[a + 3], qpos[a]]
    return q


def velocity_map(m, qpos, v_gl):
    """J (v_mj = J v_gl) and J̇ v_gl."""
    jac = np.eye(m.nv)
    jdot_v = np.zeros(m.nv)
    for j in range(m.njnt):
        if m.jnt_type[j] != 0:
            continue
        a, d = m.jnt_qposadr[j], m.jnt_dofadr[j]
        r = np.zeros(9)
        mujoco.mju_quat2Mat(r, qpos[a + 3:a + 7] / np.linalg.norm(qpos[a + 3:a + 7]))
        r = r.reshape(3, 3)
        jac[d:d + 3, d:d + 3] = r
        jdot_v[d:d + 3] = r @ np.cross(v_gl[d + 3:d + 6], v_gl[d:d + 3])
    return jac, jdot_v


def bias(m, d, qpos, qvel):
    d.qpos[:] = qpos
    d.qvel[:] = qvel
    d.qacc[:] = 0
    mujoco.mj_forward(m, d)
    return d.qfrc_bias.copy()


def case(name, xml, rng):
    m = mujoco.MjModel.from_xml_string(xml)
    armature = m.dof_armature.copy()
    m.dof_armature[:] = 0.0
    d = mujoco.MjData(m)

    # Depth-first document order of bodies and joints = MuJoCo's body and joint ids; the loader
    # follows the same order, so qpos/dof addresses must increase with the joint id.
    assert all(np.diff(m.jnt_qposadr) > 0) and all(np.diff(m.jnt_dofadr) > 0)
    assert all(m.body_parentid[b] < b for b in range(1, m.nbody))

    joints = []
    for j in range(m.njnt):
        t = int(m.jnt_type[j])
        dof = int(m.jnt_dofadr[j])
        joints.append({
            "name": name_of(m, mujoco.mjtObj.mjOBJ_JOINT, j),
            "body": name_of(m, mujoco.mjtObj.mjOBJ_BODY, int(m.jnt_bodyid[j])),
            "type": JOINT_TYPES[t],
            "idx_q": int(m.jnt_qposadr[j]),
            "idx_v": dof,
            "damping": float(m.dof_damping[dof]),
            "frictionloss": float(m.dof_frictionloss[dof]),
            "armature": float(armature[dof]),
            "limited": bool(m.jnt_limited[j]),
            "range": [float(x) for x in m.jnt_range[j]],
        })
    bodies = []
    for b in range(1, m.nbody):
        bodies.append({
            "name": name_of(m, mujoco.mjtObj.mjOBJ_BODY, b),
            "mass": float(m.body_mass[b]),
            "subtree_mass": float(m.body_subtreemass[b]),
            "welded_to_world": bool(m.body_weldid[b] == 0),
        })
    moving_mass = float(sum(m.body_mass[b] for b in range(1, m.nbody) if m.body_weldid[b] != 0))

    states = []
    for _ in range(STATES):
        qpos, v_gl = random_state(m, rng)
        jac, jdot_v = velocity_map(m, qpos, v_gl)
        qvel = jac @ v_gl
        d.qpos[:] = qpos
        mujoco.mj_forward(m, d)
        m_mj = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, d, m_mj)
        poses = [{"xpos": d.xpos[b].tolist(), "xmat": d.xmat[b].tolist()} for b in range(1, m.nbody)]
        b_mj = bias(m, d, qpos, qvel)
        g_mj = bias(m, d, qpos, np.zeros(m.nv))
        states.append({
            "q": to_gelenk_q(m, qpos).tolist(),
            "v": v_gl.tolist(),
            "mass_matrix": (jac.T @ m_mj @ jac).tolist(),
            "nle": (jac.T @ (b_mj + m_mj @ jdot_v)).tolist(),
            "gravity": (jac.T @ g_mj).tolist(),
            "body_poses": poses,
            "mujoco": {
                "qpos": qpos.tolist(),
                "qvel": qvel.tolist(),
                "qfrc_bias": b_mj.tolist(),
                "gravity": g_mj.tolist(),
            },
        })
    return {
        "name": name,
        "xml": xml,
        "nq": int(m.nq),
        "nv": int(m.nv),
        "timestep": float(m.opt.timestep),
        "gravity": [float(x) for x in m.opt.gravity],
        "moving_mass": moving_mass,
        "total_mass": float(sum(m.body_mass[1:])),
        "qpos0": to_gelenk_q(m, m.qpos0).tolist(),
        "joints": joints,
        "bodies": bodies,
        "states": states,
    }


def main():
    rng = np.random.default_rng(SEED)
    cases = []
    for name in ["pendulum5", "humanoid_fall", "box_stack10"]:
        with open(os.path.join(PEERS, name + ".xml"), encoding="utf-8") as f:
            cases.append(case(name, f.read(), rng))
    cases.append(case("features_degree", FEATURES_DEGREE, rng))
    cases.append(case("features_radian", FEATURES_RADIAN, rng))
    out = {
        "generator": "tests/data/gen_mjcf_reference.py",
        "mujoco_version": mujoco.__version__,
        "python": sys.version.split()[0],
        "seed": SEED,
        "conventions": "gelenk's: q quaternions (x y z w); free-joint v = [v; w] in the body frame; "
                       "M, nle, gravity transformed accordingly (see the generator's docstring). "
                       "Armature set to 0. `mujoco` holds MuJoCo's raw qpos, qvel, qfrc_bias, gravity.",
        "cases": cases,
    }
    with open(OUT, "w", encoding="utf-8") as f:
        json.dump(out, f, indent=1)
        f.write("\n")
    print(f"wrote {OUT}: " + ", ".join(f"{c['name']} (nq {c['nq']}, nv {c['nv']})" for c in cases))


if __name__ == "__main__":
    main()
