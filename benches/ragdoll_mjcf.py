"""models/ragdoll.urdf as MJCF, so that MuJoCo can be timed on the same ragdoll as
`gelenk bench world models/ragdoll_fall.toml` (MuJoCo's passive humanoid of
benches/peers/humanoid_fall.xml is a smaller model; this measures the same one).
Not part of CI (the timing needs `pip install mujoco`; the conversion itself needs only Python).

Usage:
    python3 benches/ragdoll_mjcf.py [--seed N] [--cone elliptic|pyramidal] > /tmp/ragdoll_fall.xml
    python3 benches/mujoco_peers.py /tmp/ragdoll_fall.xml
    python3 benches/ragdoll_mjcf.py --count 16 [--dt 0.016666666666666666] > /tmp/pile16.xml

With `--count N` (N > 1), a pile as models/ragdoll_crowd.toml drops one: N ragdolls lying face
down in T-pose in min(N, 4) columns (2 × 2, 1.9 m and 2.0 m apart: the T-pose spans 1.8 m), layers 0.35 m apart from
0.45 m up, each shifted by up to 4 cm and spinning at 1 rad/s about a random axis; names get a
prefix `rK_` per ragdoll.

What carries over from the URDF and models/ragdoll_fall.toml: bodies, masses, CoMs and diagonal
inertias; capsule and box collision shapes; joint frames; hinge axes and ranges; damping and
dry friction (`frictionloss`, per dof like gelenk's bounded friction rows); the drop (pelvis
origin 1.936 m up, T-pose) and a 2 rad/s spin about a random axis (numpy's generator seeded
with N, not gelenk's: the episodes are chaotic either way, compare statistics over seeds);
μ = 0.8; dt = 2 ms with MuJoCo's `implicitfast` integrator (damping treated implicitly, as
gelenk does); self-collision of all bodies except parent and child (both engines filter those).

What differs, because MuJoCo has no such joint or limit:
- gelenk's ball joints limit a swing cone and a twist range (up to two rows); MuJoCo's ball
  range bounds the total rotation angle (one row): the range here is the larger of the swing
  and twist limits.
- gelenk's universal joints (wrists, ankles) are two hinges here: the URDF axis, then x of the
  child frame, with gelenk's ranges.
- gelenk's speculative contacts (margin 2 cm) and limit rows 0.1 rad before the stop have no
  counterpart: MuJoCo's constraints are soft (solref 0.02 s) and act from contact on.
"""
import argparse
import math
import os
import sys
import xml.etree.ElementTree as ET

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
URDF = os.path.join(HERE, "..", "models", "ragdoll.urdf")


def floats(text, default="0 0 0"):
    return [float(x) for x in (text or default).split()]


def fmt(values):
    return " ".join(f"{v:.9g}" for v in values)


def rpy_to_quat(r, p, y):
    """URDF's fixed-axis roll-pitch-yaw as a MuJoCo quaternion (w x y z)."""
    cr, sr = math.cos(r / 2), math.sin(r / 2)
    cp, sp = math.cos(p / 2), math.sin(p / 2)
    cy, sy = math.cos(y / 2), math.sin(y / 2)
    return [
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    ]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--cone", choices=["elliptic", "pyramidal"], default="pyramidal")
    parser.add_argument("--count", type=int, default=1, help="ragdolls (a pile when more than 1)")
    parser.add_argument("--dt", type=float, default=0.002, help="time step (s)")
    args = parser.parse_args()
    if args.count < 1:
        raise SystemExit(f"--count must be at least 1, got {args.count}")
    if not args.dt > 0.0:
        raise SystemExit(f"--dt must be positive, got {args.dt}")
    robot = ET.parse(URDF).getroot()
    links = {link.get("name"): link for link in robot.findall("link")}
    joints = {j.find("child").get("link"): j for j in robot.findall("joint")}
    extensions = {g.get("joint"): g for g in robot.findall("gelenk")}
    children = {}
    for j in robot.findall("joint"):
        children.setdefault(j.find("parent").get("link"), []).append(j.find("child").get("link"))
    root = next(name for name in links if name not in joints)

    def body_xml(name, indent, prefix=""):
        pad = " " * indent
        link = links[name]
        out = []
        inertial = link.find("inertial")
        com = floats(inertial.find("origin").get("xyz"))
        mass = float(inertial.find("mass").get("value"))
        i = inertial.find("inertia")
        diag = [float(i.get(k)) for k in ("ixx", "iyy", "izz")]
        out.append(f'{pad}  <inertial pos="{fmt(com)}" mass="{mass:.9g}" diaginertia="{fmt(diag)}"/>')
        if name == root:
            out.append(f'{pad}  <freejoint name="{prefix}root"/>')
        else:
            j = joints[name]
            kind = j.get("type")
            jname = prefix + j.get("name")
            dynamics = j.find("dynamics")
            damping = float(dynamics.get("damping", "0")) if dynamics is not None else 0.0
            friction = float(dynamics.get("friction", "0")) if dynamics is not None else 0.0
            common = f'damping="{damping:.9g}" frictionloss="{friction:.9g}"'
            ext = extensions.get(j.get("name"))
            if kind == "spherical":
                swing = float(ext.get("swing")) if ext is not None else math.pi
                twist = max(abs(float(ext.get("twist_lower", "0"))), abs(float(ext.get("twist_upper", "0"))))
                out.append(
                    f'{pad}  <joint name="{jname}" type="ball" limited="true" '
                    f'range="0 {max(swing, twist):.9g}" {common}/>'
                )
            elif kind == "revolute":
                axis = floats(j.find("axis").get("xyz"))
                lim = j.find("limit")
                out.append(
                    f'{pad}  <joint name="{jname}" type="hinge" axis="{fmt(axis)}" limited="true" '
                    f'range="{float(lim.get("lower")):.9g} {float(lim.get("upper")):.9g}" {common}/>'
                )
                if ext is not None and ext.get("type") == "universal":
                    axis2 = floats(ext.get("axis2"))
                    out.append(
                        f'{pad}  <joint name="{jname}_2" type="hinge" axis="{fmt(axis2)}" limited="true" '
                        f'range="{float(ext.get("lower2")):.9g} {float(ext.get("upper2")):.9g}" {common}/>'
                    )
            else:
                raise SystemExit(f"joint {jname}: type {kind} not converted")
        for c in link.findall("collision"):
            origin = c.find("origin")
            xyz = floats(origin.get("xyz") if origin is not None else None)
            quat = rpy_to_quat(*floats(origin.get("rpy") if origin is not None else None))
            g = c.find("geometry")[0]
            if g.tag == "box":
                half = [x / 2 for x in floats(g.get("size"))]
                shape = f'type="box" size="{fmt(half)}"'
            elif g.tag == "capsule":
                shape = f'type="capsule" size="{float(g.get("radius")):.9g} {float(g.get("length")) / 2:.9g}"'
            else:
                raise SystemExit(f"link {name}: geometry {g.tag} not converted")
            out.append(f'{pad}  <geom {shape} pos="{fmt(xyz)}" quat="{fmt(quat)}"/>')
        for child in children.get(name, []):
            pos = floats(joints[child].find("origin").get("xyz"))
            out.append(f'{pad}  <body name="{prefix}{child}" pos="{fmt(pos)}">')
            out.extend(body_xml(child, indent + 2, prefix))
            out.append(f"{pad}  </body>")
        return out

    rng = np.random.default_rng(args.seed)

    def spin_axis():
        while True:
            axis = rng.uniform(-1.0, 1.0, 3)
            if 0.1 < np.linalg.norm(axis) <= 1.0:
                return axis / np.linalg.norm(axis)

    # The joints' rest coordinates and velocities after the free joint's.
    rest_q, rest_v = [], []
    for n in _dfs(root, children):
        if n == root:
            continue
        j = joints[n]
        if j.get("type") == "spherical":
            rest_q += [1, 0, 0, 0]
            rest_v += [0, 0, 0]
        else:
            count = 2 if extensions.get(j.get("name")) is not None else 1
            rest_q += [0] * count
            rest_v += [0] * count
    pile = args.count > 1
    lines = [
        # (No "--" inside an XML comment: strict parsers such as gelenk's refuse it.)
        f"<!-- Generated by benches/ragdoll_mjcf.py (seed {args.seed}, cone {args.cone}, "
        f"count {args.count}) from models/ragdoll.urdf. -->",
        f'<mujoco model="{"ragdoll_pile" if pile else "ragdoll_fall"}">',
        # The ranges below are the URDF's, in radians (MJCF's default unit is the degree).
        '  <compiler angle="radian"/>',
        f'  <option timestep="{args.dt:.17g}" integrator="implicitfast" cone="{args.cone}"/>',
        "  <default>",
        '    <geom condim="3" friction="0.8" contype="1" conaffinity="1"/>',
        "  </default>",
        "  <worldbody>",
        '    <geom name="ground" type="plane" size="40 40 0.1"/>',
    ]
    qpos, qvel = [], []
    for k in range(args.count):
        prefix = f"r{k}_" if pile else ""
        if pile:
            columns = min(args.count, 4)
            column, layer = k % columns, k // columns
            x = (column % 2 - 0.5) * 1.9 if columns > 1 else 0.0
            y = (column // 2 - 0.5) * 2.0 if columns > 2 else 0.0
            shift = rng.uniform(-0.04, 0.04, 2)
            pos = [x + shift[0], y + shift[1], 0.45 + 0.35 * layer]
            # Face down: the standing T-pose pitched by 90° about y.
            quat = [math.cos(math.pi / 4), 0.0, math.sin(math.pi / 4), 0.0]
            omega = 1.0 * spin_axis()
        else:
            pos, quat = [0.0, 0.0, 1.936], [1.0, 0.0, 0.0, 0.0]
            omega = 2.0 * spin_axis()
        lines.append(f'    <body name="{prefix}{root}" pos="{fmt(pos)}" quat="{fmt(quat)}">')
        lines.extend(body_xml(root, 4, prefix))
        lines.append("    </body>")
        # The spin as the free joint's initial velocity (linear: world frame, 0; angular: body
        # frame).
        qpos += [*pos, *quat, *rest_q]
        qvel += [0, 0, 0, *omega, *rest_v]
    lines.append("  </worldbody>")
    lines.append("  <keyframe>")
    lines.append(f'    <key name="drop" qpos="{fmt(qpos)}" qvel="{fmt(qvel)}"/>')
    lines.append("  </keyframe>")
    lines.append("</mujoco>")
    sys.stdout.write("\n".join(lines) + "\n")


def _dfs(name, children):
    yield name
    for c in children.get(name, []):
        yield from _dfs(c, children)


if __name__ == "__main__":
    main()
