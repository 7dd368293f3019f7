"""gelenk on the URDFs of two public collections, against Pinocchio and PyBullet.

Collections: example-robot-data 6.0.0 (`pip install example-robot-data`, its robots/ tree) and
pybullet_data 3.2.7 (`pip install pybullet`, every *.urdf under it). Needs `pin` (Pinocchio),
`pybullet` and a built `gelenk` binary (`cargo build --release --bin gelenk`). Not part of CI.

Stages (all by default; `--stages load,dynamics,drop`):

- load: per file, does Pinocchio load it (fixed base), does PyBullet load it (DIRECT), does
  `gelenk inspect --json` load it (default, lenient options), and how many warnings gelenk gives;
  gelenk's refusals are counted per kind of error.
- dynamics: every file Pinocchio loads, fixed and floating base (free flyer), at 3 random states:
  the joints (names, nq/nv per joint, order) and M, nle, RNEA and ABA from
  `gelenk dynamics` against Pinocchio's; the error of each quantity is
  max|gelenk - pinocchio| / (1 + max|pinocchio|), and a model agrees when every error is at most
  1e-9. Pinocchio's continuous joints are (cos, sin), its planar joints (x, y, cos, sin):
  converted to gelenk's angle. Models whose mass matrix Pinocchio finds singular (a massless
  subtree) are compared on M, nle and RNEA only (ABA is undefined), and said so.
- drop: every file PyBullet loads, as a floating base with its collision shapes and meshes, its
  lowest point 5 cm above a plane (from PyBullet's AABBs), 2 s at dt = 1/240 s through
  `gelenk simulate`: it passes without an error, a NaN, or a penetration of the ground beyond 1 cm.

`--out FILE` writes the per-file table (markdown) that docs/urdf_collections.md holds; the summary
goes to stdout. `--filter TEXT` keeps files whose path contains TEXT.

Usage: python3 benches/urdf_collections.py --out docs/urdf_collections.md
"""
import argparse
import collections
import importlib.metadata
import json
import math
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

TOL = 1e-9
DROP_DT = 1.0 / 240.0
DROP_DURATION = 2.0
DROP_CLEARANCE = 0.05
MAX_PENETRATION = 0.01


def collections_():
    """(collection name, root directory, sorted URDF paths) of both collections."""
    import pybullet_data

    erd = Path(
        importlib.metadata.distribution("example-robot-data").locate_file(
            "cmeel.prefix/share/example-robot-data/robots"
        )
    )
    pbd = Path(pybullet_data.getDataPath())
    return [
        ("example-robot-data", erd, sorted(erd.rglob("*.urdf"))),
        ("pybullet_data", pbd, sorted(pbd.rglob("*.urdf"))),
    ]


def gelenk_binary(arg):
    if arg:
        return arg
    target = os.environ.get("CARGO_TARGET_DIR", str(Path(__file__).resolve().parent.parent / "target"))
    return str(Path(target) / "release" / "gelenk")


def run(cmd, timeout=600):
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return None, f"timed out after {timeout} s"
    if p.returncode != 0:
        return None, (p.stderr.strip().splitlines() or ["exit code %d" % p.returncode])[-1]
    return p.stdout, p.stderr


# ---------------------------------------------------------------- load


def error_kind(message):
    """A short class of a gelenk load error, for the counts."""
    m = message
    for pattern, kind in [
        (r"triangle inequality", "inertia: triangle inequality"),
        (r"not positive semi-definite|not positive", "inertia: not positive semi-definite"),
        (r"unknown element <([\w:]+)>", "unknown element <{}>"),
        (r"unknown attribute `([\w:]+)`", "unknown attribute `{}`"),
        (r"found StartElement\((\w+)", "urdf-rs: unexpected <{}>"),
        (r"missing field `?(\w+)", "urdf-rs: missing field {}"),
        (r"duplicate field `?(\w+)", "urdf-rs: duplicate field {}"),
        (r"custom: (.*)", "urdf-rs: {}"),
    ]:
        found = re.search(pattern, m)
        if found:
            return kind.format(*found.groups()) if found.groups() else kind
    return m[-80:]


def pinocchio_load(path, floating=False):
    import pinocchio as pin

    try:
        if floating:
            return pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer()), None
        return pin.buildModelFromUrdf(str(path)), None
    except Exception as e:  # Pinocchio raises ValueError, RuntimeError
        return None, str(e).splitlines()[0]


def pybullet_load(client, path):
    import pybullet as p

    try:
        body = p.loadURDF(str(path), physicsClientId=client)
    except Exception as e:  # pybullet.error
        return None, str(e)
    return body, None


def lowest_point(client, body):
    """Lowest z of PyBullet's AABBs of the body's links, the model at the origin, joints at 0."""
    import pybullet as p

    low = p.getAABB(body, -1, physicsClientId=client)[0][2]
    for link in range(p.getNumJoints(body, physicsClientId=client)):
        low = min(low, p.getAABB(body, link, physicsClientId=client)[0][2])
    return low


class quiet_stdout:
    """Sends the C library's stdout (PyBullet's b3Warning lines) to /dev/null."""

    def __enter__(self):
        sys.stdout.flush()
        self.saved = os.dup(1)
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, 1)
        os.close(null)

    def __exit__(self, *exc):
        sys.stdout.flush()
        os.dup2(self.saved, 1)
        os.close(self.saved)


def stage_load(files, gelenk):
    with quiet_stdout():
        return stage_load_quiet(files, gelenk)


def stage_load_quiet(files, gelenk):
    import pybullet as p

    client = p.connect(p.DIRECT)
    rows = {}
    for coll, root, path in files:
        rel = f"{coll}/{path.relative_to(root)}"
        row = {"file": rel, "path": str(path)}
        model, err = pinocchio_load(path)
        row["pinocchio"] = err is None
        row["pinocchio_error"] = err
        body, err = pybullet_load(client, path)
        row["pybullet"] = err is None
        row["pybullet_error"] = err
        if body is not None:
            row["lowest"] = lowest_point(client, body)
            # PyBullet makes a base of mass 0 static: it is dropped fixed to the world.
            row["static_base"] = p.getDynamicsInfo(body, -1, physicsClientId=client)[0] == 0.0
            p.removeBody(body, physicsClientId=client)
        out, err = run([gelenk, "inspect", "--json", str(path)])
        row["gelenk"] = out is not None
        if out is None:
            row["gelenk_error"] = err
            row["gelenk_kind"] = error_kind(err)
        else:
            info = json.loads(out)
            row["warnings"] = info.get("warnings", [])
            row["collision_shapes"] = len(info.get("collision", []))
        rows[rel] = row
    p.disconnect(client)
    return rows


def summary_load(rows):
    lines = []
    for coll in ["example-robot-data", "pybullet_data"]:
        rs = [r for r in rows.values() if r["file"].startswith(coll + "/")]
        pin_ok = [r for r in rs if r["pinocchio"]]
        pb_ok = [r for r in rs if r["pybullet"]]
        either = [r for r in rs if r["pinocchio"] or r["pybullet"]]
        lines.append(
            f"{coll}: {len(rs)} URDFs; Pinocchio loads {len(pin_ok)}, PyBullet {len(pb_ok)}, "
            f"gelenk {sum(r['gelenk'] for r in rs)} "
            f"(of those Pinocchio loads: {sum(r['gelenk'] for r in pin_ok)}/{len(pin_ok)}; "
            f"of those PyBullet loads: {sum(r['gelenk'] for r in pb_ok)}/{len(pb_ok)}; "
            f"of those either loads: {sum(r['gelenk'] for r in either)}/{len(either)})"
        )
    kinds = collections.Counter(
        r["gelenk_kind"] for r in rows.values() if not r["gelenk"] and (r["pinocchio"] or r["pybullet"])
    )
    for kind, n in kinds.most_common():
        lines.append(f"  gelenk refuses {n}: {kind}")
    return lines


# ---------------------------------------------------------------- dynamics


def random_state(model, rng):
    """Pinocchio q, v, a, tau: positions uniform within the limits (±1 where unbounded)."""
    import pinocchio as pin

    lo = model.lowerPositionLimit.copy()
    hi = model.upperPositionLimit.copy()
    big = 1e300
    lo_f, hi_f = np.abs(lo) < big, np.abs(hi) < big
    lo2 = np.where(lo_f, lo, np.where(hi_f, hi - 2.0, -1.0))
    hi2 = np.where(hi_f, hi, lo2 + 2.0)
    q = pin.randomConfiguration(model, lo2, hi2)
    v = rng.uniform(-1, 1, model.nv)
    a = rng.uniform(-1, 1, model.nv)
    tau = rng.uniform(-1, 1, model.nv)
    return q, v, a, tau


def gelenk_q_part(joint, part):
    """One Pinocchio joint's q as gelenk's: (cos, sin) of a continuous joint → angle; planar
    (x, y, c, s) → (x, y, θ)."""
    name = joint.shortname()
    if "RevoluteUnbounded" in name or name.startswith("JointModelRUB"):
        return [math.atan2(part[1], part[0])]
    if "Planar" in name:
        return [part[0], part[1], math.atan2(part[3], part[2])]
    return list(part)


def pinocchio_joints(model):
    """(name, nv, parent joint name) per joint, Pinocchio's order."""
    return [(model.names[k], model.joints[k].nv, model.names[model.parents[k]]) for k in range(1, model.njoints)]


def compare(model, gelenk, path, floating, rng, states=3):
    """(agrees, max error, detail) of gelenk against Pinocchio on `states` random states.

    gelenk numbers sibling joints in the order the file lists them, Pinocchio (through urdfdom)
    by joint name: the joints must be the same (name, nv, parent joint), and vectors and M are
    compared through the permutation by name."""
    import pinocchio as pin

    out, err = run([gelenk, "inspect", "--json", str(path)] + (["--floating"] if floating else []))
    if out is None:
        return False, math.inf, f"gelenk: {err}"
    ours = json.loads(out)["joints"]
    theirs = pinocchio_joints(model)
    by_name = {j["name"]: j for j in ours}
    same = len(ours) == len(theirs) and all(
        n in by_name and by_name[n]["nv"] == nv and by_name[n]["parent"] == (p if p != "universe" else "universe")
        for n, nv, p in theirs
    )
    if not same:
        return False, math.inf, f"joints differ: gelenk {[j['name'] for j in ours][:4]}… Pinocchio {[t[0] for t in theirs][:4]}…"
    # perm[i]: gelenk's v index of Pinocchio's v index i.
    perm = np.zeros(model.nv, dtype=int)
    for k in range(1, model.njoints):
        j = by_name[model.names[k]]
        for d in range(model.joints[k].nv):
            perm[model.joints[k].idx_v + d] = j["idx_v"] + d
    order = sorted(range(1, model.njoints), key=lambda k: by_name[model.names[k]]["idx_q"])

    def ours_v(x):
        y = np.zeros(model.nv)
        y[perm] = x
        return y.tolist()

    data = model.createData()
    cases, refs = [], []
    for _ in range(states):
        q, v, a, tau = random_state(model, rng)
        m = pin.crba(model, data, q)
        m = np.triu(m) + np.triu(m, 1).T
        ref = {
            "mass_matrix": m.copy(),
            "nle": pin.nonLinearEffects(model, data, q, v).copy(),
            "rnea": pin.rnea(model, data, q, v, a).copy(),
        }
        singular = np.linalg.cond(m) > 1e12 if model.nv else False
        if not singular:
            ref["aba"] = pin.aba(model, data, q, v, tau).copy()
        refs.append(ref)
        gq = []
        for k in order:
            jm = model.joints[k]
            gq += gelenk_q_part(jm, q[jm.idx_q : jm.idx_q + jm.nq])
        cases.append({"q": gq, "v": ours_v(v), "a": ours_v(a), "tau": ours_v(tau)})
    with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
        json.dump({"states": cases}, f)
        states_file = f.name
    cmd = [gelenk, "dynamics", str(path), "--states", states_file] + (["--floating"] if floating else [])
    out, err = run(cmd)
    os.unlink(states_file)
    if out is None:
        return False, math.inf, f"gelenk: {err}"
    got = json.loads(out)
    worst, which = 0.0, ""
    singular = False
    for ref, res in zip(refs, got["results"]):
        if "aba" not in ref:
            singular = True
        for key, value in ref.items():
            if res[key] is None:
                return False, math.inf, f"gelenk: {res.get(key + '_error')}"
            g = np.array(res[key], dtype=float).reshape(value.shape)
            g = g[np.ix_(perm, perm)] if key == "mass_matrix" else g[perm]
            e = float(np.max(np.abs(g - value)) / (1.0 + np.max(np.abs(value)))) if value.size else 0.0
            if not e <= worst:
                worst, which = e, key
    detail = f"worst {which}" if which else ""
    if singular:
        detail += " (singular M: ABA not compared)"
    return worst <= TOL, worst, detail.strip()


def stage_dynamics(rows, gelenk):
    rng = np.random.default_rng(7)
    import pinocchio as pin

    pin.seed(7)
    for row in rows.values():
        if not row["pinocchio"]:
            continue
        for floating in (False, True):
            key = "floating" if floating else "fixed"
            model, err = pinocchio_load(row["path"], floating)
            if model is None:
                row[f"dyn_{key}"] = (False, math.inf, f"Pinocchio: {err}")
                continue
            row[f"dyn_{key}"] = compare(model, gelenk, row["path"], floating, rng)


def summary_dynamics(rows):
    done = [r for r in rows.values() if "dyn_fixed" in r]
    agree = [r for r in done if r["dyn_fixed"][0] and r["dyn_floating"][0]]
    worst = max((max(r["dyn_fixed"][1], r["dyn_floating"][1]) for r in agree), default=0.0)
    lines = [
        f"dynamics: {len(agree)}/{len(done)} files Pinocchio loads agree (fixed and floating base) "
        f"to {TOL:g}; worst error among them {worst:.1e}"
    ]
    for r in done:
        for key in ("fixed", "floating"):
            ok, e, detail = r[f"dyn_{key}"]
            if not ok:
                lines.append(f"  {r['file']} ({key}): error {e:.1e} {detail}")
    return lines


# ---------------------------------------------------------------- drop


SCENE = """name = "drop"
[world]
dt = {dt!r}
duration = {duration!r}

[[ground]]
kind = "plane"

[[urdf]]
path = {path}
floating = {floating}
position = [0, 0, {z!r}]
"""


def stage_drop(rows, gelenk):
    with tempfile.TemporaryDirectory() as tmp:
        scene = Path(tmp) / "drop.toml"
        for row in rows.values():
            if not row["pybullet"] or not row["gelenk"]:
                continue
            if row["collision_shapes"] == 0:
                row["drop"] = (None, "no collision shape: nothing meets the ground (as in PyBullet)")
                continue
            floating = not row["static_base"]
            z = DROP_CLEARANCE - row["lowest"]
            scene.write_text(
                SCENE.format(
                    dt=DROP_DT,
                    duration=DROP_DURATION,
                    path=json.dumps(row["path"]),
                    floating=str(floating).lower(),
                    z=z,
                )
            )
            out, err = run([gelenk, "simulate", "--json", str(scene)])
            if out is None:
                row["drop"] = (False, err)
                continue
            s = json.loads(out)
            pen = s["max_penetration"]
            ok = pen <= MAX_PENETRATION
            text = f"max penetration {pen * 100:.2f} cm" + ("" if ok else " (over 1 cm)")
            if not floating:
                text += "; fixed base (mass 0: PyBullet makes it static)"
            row["drop"] = (ok, text)


def drop_failure(text):
    """A short class of a failed drop, for the counts and the table."""
    for pattern, kind in [
        (r"has no mass or inertia along its motion", "singular mass matrix: a moving subtree without mass or inertia along its motion"),
        (r"could not be read", "a collision mesh gelenk cannot read"),
        (r"not found|no such|tried", "a collision mesh not found"),
        (r"every solver failed", "the contact solver fails"),
        (r"over 1 cm", "penetration over 1 cm"),
    ]:
        if re.search(pattern, text):
            return kind
    return text[-100:]


def summary_drop(rows):
    done = [r for r in rows.values() if "drop" in r and r["drop"][0] is not None]
    ok = [r for r in done if r["drop"][0]]
    skipped = [r for r in rows.values() if "drop" in r and r["drop"][0] is None]
    lines = [
        f"drop: {len(ok)}/{len(done)} files PyBullet loads (with a collision shape) fall 2 s on a plane "
        f"without error, NaN or 1 cm penetration; {len(skipped)} have no collision shape"
    ]
    fails = collections.Counter(drop_failure(r["drop"][1]) for r in done if not r["drop"][0])
    for kind, n in fails.most_common():
        lines.append(f"  {n}: {kind}")
    return lines


# ---------------------------------------------------------------- table


def cell(ok, text=""):
    return ("yes" if ok else "**no**") + (f": {text}" if text else "")


def table(rows, stages, summary):
    out = [
        "<!-- Generated by `python3 benches/urdf_collections.py --out docs/urdf_collections.md`; do not edit. -->",
        "# URDF collections: gelenk against Pinocchio and PyBullet",
        "",
        "Every URDF of example-robot-data 6.0.0 and pybullet_data 3.2.7. Columns: whether Pinocchio "
        "4.1 and PyBullet 3.2.7 load the file; whether gelenk loads it with its default (lenient) "
        "options and how many warnings it gives; the largest relative error of gelenk's M, nle, RNEA "
        "and ABA against Pinocchio's at 3 random states, fixed and floating base (must be ≤ 1e-9); "
        "the 2 s drop on a plane (floating base, collision shapes and meshes, dt = 1/240 s; must "
        "run without an error or NaN and penetrate the ground by at most 1 cm). The random objects "
        "of pybullet_data (`random_urdfs/`, 1000 files) are one row. See [urdf.md](urdf.md).",
        "",
        "```",
        *summary,
        "```",
        "",
        "| file | Pinocchio | PyBullet | gelenk loads | dynamics vs Pinocchio | drop 2 s |",
        "|---|---|---|---|---|---|",
    ]

    def dyn(r):
        if "dyn_fixed" not in r:
            return "—"
        (ok1, e1, d1), (ok2, e2, d2) = r["dyn_fixed"], r["dyn_floating"]
        e = max(e1, e2)
        d = "; ".join(x for x in (d1 if not ok1 else "", d2 if not ok2 else "") if x)
        singular = " (singular M: ABA not compared)" if "singular" in d1 + d2 else ""
        return cell(ok1 and ok2, f"{e:.0e}" + (f" {d}" if d else singular))

    def loads(r):
        if r["gelenk"]:
            w = len(r.get("warnings", []))
            return "yes" + (f" ({w} warning{'s' if w != 1 else ''})" if w else "")
        return cell(False, r["gelenk_kind"].replace("|", "\\|"))

    def drop(r):
        if "drop" not in r:
            return "—"
        ok, text = r["drop"]
        if ok is None:
            return "n/a: " + text
        if not ok and "over 1 cm" not in text:
            text = drop_failure(text)
        return cell(ok, text.replace("|", "\\|")[:160])

    random_rows = [r for r in rows.values() if "/random_urdfs/" in r["file"]]
    for r in rows.values():
        if "/random_urdfs/" in r["file"]:
            continue
        out.append(
            f"| {r['file']} | {'yes' if r['pinocchio'] else 'no'} | {'yes' if r['pybullet'] else 'no'} "
            f"| {loads(r)} | {dyn(r)} | {drop(r)} |"
        )
    if random_rows:
        n = len(random_rows)
        count = lambda f: sum(1 for r in random_rows if f(r))
        failing = [r["file"].split("/")[-1] for r in random_rows if "drop" in r and not r["drop"][0]]
        reasons = collections.Counter(drop_failure(r["drop"][1]) for r in random_rows if "drop" in r and not r["drop"][0])
        out.append(
            f"| pybullet_data/random_urdfs/*.urdf ({n} files) | {count(lambda r: r['pinocchio'])} | "
            f"{count(lambda r: r['pybullet'])} | {count(lambda r: r['gelenk'])} "
            f"({count(lambda r: r.get('warnings'))} with warnings) | — | "
            f"{count(lambda r: r.get('drop', (False,))[0])} pass"
            + (f"; {len(failing)} fail: " + "; ".join(f"{n} {k}" for k, n in reasons.most_common()) if failing else "")
            + " |"
        )
    return "\n".join(out) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--gelenk", help="gelenk binary (default: $CARGO_TARGET_DIR/release/gelenk)")
    ap.add_argument("--stages", default="load,dynamics,drop")
    ap.add_argument("--filter", default="")
    ap.add_argument("--out", help="write the markdown table here")
    ap.add_argument("--json", help="write every row as JSON here")
    args = ap.parse_args()
    gelenk = gelenk_binary(args.gelenk)
    stages = args.stages.split(",")
    files = [(c, root, p) for c, root, ps in collections_() for p in ps if args.filter in str(p)]
    rows = stage_load(files, gelenk)
    summary = summary_load(rows)
    if "dynamics" in stages:
        stage_dynamics(rows, gelenk)
        summary += summary_dynamics(rows)
    if "drop" in stages:
        stage_drop(rows, gelenk)
        summary += summary_drop(rows)
    print("\n".join(summary))
    if args.out:
        Path(args.out).write_text(table(rows, stages, summary))
    if args.json:
        Path(args.json).write_text(json.dumps(list(rows.values()), indent=1, default=str))


if __name__ == "__main__":
    sys.exit(main())
