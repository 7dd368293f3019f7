"""`gelenk bench dynamics` beside Pinocchio's C++ RNEA, CRBA and ABA in alternating rounds on the
same host, with medians of per-round ratios: the host's speed drifts by ±40 % within minutes, so
only figures measured back to back compare. Not part of CI (needs `pip install pin` 4.x, which
brings Pinocchio's headers, Eigen and Boost, and g++).

Usage:
  python3 benches/dynamics_peers.py --rounds 9 [--gelenk target/release/gelenk] [--talos-anymal]

Pinocchio is compiled header-only from benches/peers/pinocchio_dynamics.cpp with
g++ -O3 -march=native (this repository's builds target the host's CPU too), into --build-dir
(target/peers), once; nothing links against the wheel's shared libraries. Each model is read by
Pinocchio's own URDF parser (Python bindings) and written as the harness's joint list; the
harness rebuilds it through Pinocchio's C++ model API and its mass matrix at the neutral
configuration is checked against the Python bindings' (relative 1e-9), and nq/nv against
gelenk's.

Per round and model, in alternating order: `gelenk bench dynamics URDF --rounds INNER` and the
harness with `--rounds INNER`, both the median over INNER passes of the mean ns per call over
1000 random states. Ratios are gelenk's time over Pinocchio's, per round; the table gives their
median and range.

CRBA compares two ways. `pinocchio::crba` writes the upper triangle of M only, in either of its
conventions: LOCAL (its default) computes M alone, in body frames; WORLD also the joints' world
poses, the world Jacobian and the centroidal momentum map. `gelenk::algorithms::crba` computes
the world poses, the world Jacobian columns and the whole symmetric M (and checks that M is
finite): like for like is Pinocchio's WORLD followed by the copy of the upper triangle into the
lower one ("CRBA, same outputs"). `gelenk::algorithms::mass_matrix` computes M alone in body
frames, both triangles, and checks it is finite: "M alone" is against LOCAL's upper triangle.
RNEA: `pinocchio::rnea`. ABA: the faster of `pinocchio::aba`'s LOCAL and WORLD conventions in
each round.
"""
import argparse
import json
import math
import os
import re
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
HARNESS = ROOT / "benches" / "peers" / "pinocchio_dynamics.cpp"
# The compile definitions the wheel's pinocchioConfig.cmake exports for its headers target.
DEFINES = [
    "-DBOOST_MPL_LIMIT_LIST_SIZE=30",
    "-DBOOST_MPL_LIMIT_VECTOR_SIZE=30",
    "-DBOOST_MPL_CFG_NO_PREPROCESSED_HEADERS",
    "-DBOOST_FUSION_INVOKE_MAX_ARITY=12",
]
GELENK_LINE = re.compile(r"^(rnea|crba|mass_matrix|aba|nle)\s+([0-9.]+) ns/call", re.M)
GELENK_DIMS = re.compile(r"\(nq = (\d+), nv = (\d+)\)")


def cmeel_prefix():
    import cmeel

    prefix = Path(cmeel.__file__).resolve().parent.parent / "cmeel.prefix"
    if not (prefix / "include" / "pinocchio").is_dir():
        raise SystemExit(f"no Pinocchio headers under {prefix} (pip install pin)")
    return prefix


def example_robot_data(relative):
    return cmeel_prefix() / "share" / "example-robot-data" / "robots" / relative


def build_harness(build_dir):
    binary = build_dir / "pinocchio_dynamics"
    if binary.exists() and binary.stat().st_mtime > HARNESS.stat().st_mtime:
        return binary
    build_dir.mkdir(parents=True, exist_ok=True)
    prefix = cmeel_prefix()
    command = (
        ["g++", "-O3", "-march=native", "-DNDEBUG", "-std=c++17"]
        + DEFINES
        + [f"-I{prefix / 'include'}", f"-I{prefix / 'include' / 'eigen3'}", str(HARNESS), "-o", str(binary)]
    )
    print("building", " ".join(command), file=sys.stderr, flush=True)
    subprocess.run(command, check=True)
    return binary


def export_model(urdf, floating, out):
    """Pinocchio's model of `urdf` as the harness's joint list; returns (nq, nv, the sum of the
    upper triangle of M at the neutral configuration)."""
    import numpy as np
    import pinocchio as pin

    model = pin.buildModelFromUrdf(str(urdf), pin.JointModelFreeFlyer()) if floating else pin.buildModelFromUrdf(str(urdf))
    lower, upper = model.lowerPositionLimit.copy(), model.upperPositionLimit.copy()
    lines = [f"{model.nq} {model.nv} {model.njoints}"]
    for i in range(1, model.njoints):
        joint = model.joints[i]
        name = joint.shortname()
        axis = getattr(joint.extract(), "axis", np.zeros(3))
        placement, inertia = model.jointPlacements[i], model.inertias[i]
        numbers = (
            list(axis)
            + list(placement.rotation.flatten())
            + list(placement.translation)
            + [inertia.mass]
            + list(inertia.lever)
            + list(inertia.inertia.flatten())
        )
        lines.append(f"{model.parents[i]} {name} " + " ".join(repr(float(x)) for x in numbers))
        # Unlimited coordinates: [-π, π] for angles, [-1, 1] m for lengths, as gelenk draws them.
        angle = name.startswith(("JointModelR", "JointModelRevolute"))
        for k in range(joint.idx_q, joint.idx_q + joint.nq):
            if not (abs(lower[k]) < 1e300 and abs(upper[k]) < 1e300):
                lower[k], upper[k] = (-math.pi, math.pi) if angle else (-1.0, 1.0)
    lines.append(" ".join(repr(float(x)) for x in lower))
    lines.append(" ".join(repr(float(x)) for x in upper))
    out.write_text("\n".join(lines) + "\n")
    mass = pin.crba(model, model.createData(), pin.neutral(model))
    return model.nq, model.nv, float(np.triu(mass).sum())


def run_gelenk(binary, urdf, floating, inner):
    command = [str(binary), "bench", "dynamics", str(urdf), "--rounds", str(inner)] + (["--floating"] if floating else [])
    try:
        out = subprocess.run(command, check=True, capture_output=True, text=True).stdout
    except FileNotFoundError:
        raise SystemExit(f"no gelenk binary at {binary}")
    except subprocess.CalledProcessError as e:
        raise SystemExit(f"{' '.join(command)} failed:\n{e.stderr}")
    dims = GELENK_DIMS.search(out)
    times = {name: float(ns) for name, ns in GELENK_LINE.findall(out)}
    if dims is None or set(times) != {"rnea", "crba", "mass_matrix", "aba", "nle"}:
        raise SystemExit(f"{' '.join(command)}: unexpected output:\n{out}")
    return (int(dims.group(1)), int(dims.group(2))), times


def run_pinocchio(binary, model_file, inner):
    out = subprocess.run([str(binary), str(model_file), "--rounds", str(inner)], check=True, capture_output=True, text=True)
    return json.loads(out.stdout)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--rounds", type=int, default=9, help="alternating rounds (default 9)")
    parser.add_argument("--inner", type=int, default=11, help="timed passes per run, median reported (default 11)")
    parser.add_argument("--gelenk", default=str(ROOT / "target" / "release" / "gelenk"))
    parser.add_argument("--build-dir", default=str(ROOT / "target" / "peers"))
    parser.add_argument(
        "--talos-anymal",
        action="store_true",
        help="also Talos (talos_reduced.urdf) and ANYmal B from pip's example-robot-data, free base",
    )
    args = parser.parse_args()
    if args.rounds < 1 or args.inner < 1:
        raise SystemExit("--rounds and --inner must be at least 1")
    build_dir = Path(args.build_dir)
    harness = build_harness(build_dir)
    models = [
        ("UR5", ROOT / "models" / "ur5_robot.urdf", False),
        ("Panda", ROOT / "models" / "panda.urdf", False),
        ("Solo-12, free base", ROOT / "models" / "solo12.urdf", True),
    ]
    if args.talos_anymal:
        models += [
            ("Talos, free base", example_robot_data("talos_data/robots/talos_reduced.urdf"), True),
            ("ANYmal B, free base", example_robot_data("anymal_b_simple_description/robots/anymal.urdf"), True),
        ]
    prepared = []
    for label, urdf, floating in models:
        model_file = build_dir / (re.sub(r"[^a-z0-9]+", "_", label.lower()).strip("_") + ".txt")
        nq, nv, checksum = export_model(urdf, floating, model_file)
        probe = run_pinocchio(harness, model_file, 1)
        if abs(probe["mass_checksum"] - checksum) > 1e-9 * max(1.0, abs(checksum)):
            raise SystemExit(f"{label}: the harness's M differs from Pinocchio's Python bindings'")
        dims, _ = run_gelenk(args.gelenk, urdf, floating, 1)
        if dims != (nq, nv):
            raise SystemExit(f"{label}: gelenk's nq/nv {dims} differ from Pinocchio's {(nq, nv)}")
        prepared.append((label, urdf, floating, model_file, nq, nv))

    samples = {label: [] for label, *_ in prepared}
    for r in range(args.rounds):
        for label, urdf, floating, model_file, *_ in prepared:
            if r % 2 == 0:
                _, ours = run_gelenk(args.gelenk, urdf, floating, args.inner)
                theirs = run_pinocchio(harness, model_file, args.inner)
            else:
                theirs = run_pinocchio(harness, model_file, args.inner)
                _, ours = run_gelenk(args.gelenk, urdf, floating, args.inner)
            sample = {
                "ours": ours,
                "pinocchio": {
                    "rnea": theirs["rnea_ns"],
                    "crba": theirs["crba_world_symmetric_ns"],
                    "mass_matrix": theirs["crba_local_ns"],
                    "aba": min(theirs["aba_local_ns"], theirs["aba_world_ns"]),
                },
            }
            samples[label].append(sample)
            print(
                f"round {r + 1} {label}: gelenk rnea/crba/mass_matrix/aba "
                f"{ours['rnea']:.0f}/{ours['crba']:.0f}/{ours['mass_matrix']:.0f}/{ours['aba']:.0f} ns; "
                f"Pinocchio rnea {theirs['rnea_ns']:.0f}, crba world+mirror {theirs['crba_world_symmetric_ns']:.0f}, "
                f"world {theirs['crba_world_ns']:.0f}, local {theirs['crba_local_ns']:.0f}, "
                f"aba {sample['pinocchio']['aba']:.0f} ns",
                flush=True,
            )

    def spread(values, digits=0):
        return f"{statistics.median(values):.{digits}f} ({min(values):.{digits}f}–{max(values):.{digits}f})"

    print()
    print(f"{args.rounds} alternating rounds, medians (range) of per-round figures, ns per call")
    print("| model (nq/nv) | algorithm | gelenk | Pinocchio | gelenk ÷ Pinocchio |")
    print("|---|---|---:|---:|---:|")
    names = {"rnea": "RNEA", "crba": "CRBA, same outputs", "mass_matrix": "M alone", "aba": "ABA"}
    for label, _, _, _, nq, nv in prepared:
        rows = samples[label]
        for algorithm, name in names.items():
            ours = [s["ours"][algorithm] for s in rows]
            theirs = [s["pinocchio"][algorithm] for s in rows]
            ratios = [a / b for a, b in zip(ours, theirs)]
            print(f"| {label} ({nq}/{nv}) | {name} | {spread(ours)} | {spread(theirs)} | {spread(ratios, 2)} |")

if __name__ == "__main__":
    main()
