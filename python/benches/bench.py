"""Benchmarks of the Python package (not a test: prints markdown tables for docs/python.md).

1. Call overhead: ``gelenk.aba(model, data, q, v, tau)`` beside ``pinocchio.aba`` in the same
   process, on ur5, panda and solo12 (free base), and the Rust call's own time on the same
   inputs in the same process (a loop in Rust: ``gelenk._gelenk._time_aba``): the difference is
   what the binding costs.
2. Rollouts: ``gelenk.rollout`` of B drops x T steps on 1 and 2 threads, beside
   ``mujoco.rollout`` on the same MJCF scene with the same B, T and threads: MuJoCo's humanoid
   (benches/peers/humanoid_fall.xml) in both engines, and gelenk's ragdoll
   (models/ragdoll_fall.toml) beside the same ragdoll in MJCF for MuJoCo
   (benches/ragdoll_mjcf.py).

The host is shared and noisy: every figure is the median over rounds, and within a round the
engines run back to back, so compare ratios measured in one run.

Usage:
    python python/benches/bench.py [--batch 64] [--steps 1000] [--rounds 3]
Needs ``pip install pin mujoco`` for the peers (their rows are left out otherwise).
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import gelenk
from gelenk._gelenk import _time_aba

REPO = Path(__file__).resolve().parents[2]
MODELS = [("ur5", "ur5_robot.urdf", False), ("panda", "panda.urdf", False), ("solo12", "solo12.urdf", True)]


def per_call_ns(call, calls=20000, rounds=9):
    """Median over rounds of the mean ns per call."""
    times = []
    for _ in range(rounds):
        start = time.perf_counter()
        for _ in range(calls):
            call()
        times.append((time.perf_counter() - start) / calls * 1e9)
    return statistics.median(times)


def overhead(rounds):
    try:
        import pinocchio as pin
    except ImportError:
        pin = None
    rows = []
    for name, urdf, floating in MODELS:
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            model = gelenk.load_urdf(REPO / "models" / urdf, floating=floating)
        data = gelenk.Data(model)
        rng = np.random.default_rng(0)
        q = model.random_configuration(seed=0)
        v, tau = rng.normal(size=model.nv), rng.normal(size=model.nv)
        ours, rust, theirs = [], [], []
        if pin is not None:
            path = str(REPO / "models" / urdf)
            pm = pin.buildModelFromUrdf(path, pin.JointModelFreeFlyer()) if floating else pin.buildModelFromUrdf(path)
            pd = pm.createData()
            pq = pin.randomConfiguration(pm)
            pv, ptau = rng.normal(size=pm.nv), rng.normal(size=pm.nv)
        for _ in range(rounds):
            ours.append(per_call_ns(lambda: gelenk.aba(model, data, q, v, tau)))
            rust.append(statistics.median(_time_aba(model, data, q, v, tau, 20000) for _ in range(9)))
            if pin is not None:
                theirs.append(per_call_ns(lambda: pin.aba(pm, pd, pq, pv, ptau)))
        median = statistics.median
        rows.append((name, model.nq, model.nv, median(ours), median(rust), median(theirs) if theirs else None))
    print("| model | nq/nv | gelenk.aba from Python (ns) | the Rust call (ns) | binding overhead (ns) | pinocchio.aba from Python (ns) |")
    print("|---|---|---:|---:|---:|---:|")
    for name, nq, nv, py, rust, pin_ns in rows:
        rust_s, over = f"{rust:.0f}", f"{py - rust:.0f}"
        pin_s = f"{pin_ns:.0f}" if pin_ns is not None else "—"
        print(f"| {name} | {nq}/{nv} | {py:.0f} | {rust_s} | {over} | {pin_s} |")


def ragdoll_mjcf_file(directory):
    path = Path(directory) / "ragdoll_fall.xml"
    text = subprocess.run(
        [sys.executable, str(REPO / "benches/ragdoll_mjcf.py"), "--seed", "7"],
        capture_output=True, text=True, check=True,
    ).stdout
    path.write_text(text)
    return path


def gelenk_drops(world, batch, seed=0):
    """B initial states: the scene's, each raised by up to 0.5 m."""
    x = np.tile(world.get_state(), (batch, 1))
    x[:, 2] += np.random.default_rng(seed).uniform(0.0, 0.5, batch)
    return x


def mujoco_drops(mujoco, model, batch, seed=0):
    """The same for MuJoCo's full physics state ([time, qpos, qvel, ...]; the root's z is
    qpos[2]), from keyframe 0 when the file has one."""
    data = mujoco.MjData(model)
    if model.nkey > 0:
        mujoco.mj_resetDataKeyframe(model, data, 0)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state = np.zeros(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data, state, spec)
    x = np.tile(state, (batch, 1))
    x[:, 1 + 2] += np.random.default_rng(seed).uniform(0.0, 0.5, batch)
    return x


def rollouts(batch, steps, rounds):
    try:
        import mujoco
        from mujoco import rollout as mj_rollout
    except ImportError:
        mujoco = None
    with tempfile.TemporaryDirectory() as tmp:
        scenes = [
            ("humanoid_fall.xml (MuJoCo's humanoid)", gelenk.load_mjcf(REPO / "benches/peers/humanoid_fall.xml"),
             REPO / "benches/peers/humanoid_fall.xml"),
            ("ragdoll_fall (gelenk's ragdoll; MuJoCo: benches/ragdoll_mjcf.py)",
             gelenk.load_scene(REPO / "models/ragdoll_fall.toml"), ragdoll_mjcf_file(tmp) if mujoco else None),
        ]
        print(f"| scene | engine | threads | wall (s), {batch} x {steps} steps | steps/s | speed-up 2 vs 1 thread |")
        print("|---|---|---:|---:|---:|---:|")
        for label, world, mjcf in scenes:
            x0 = gelenk_drops(world, batch)
            mj = None
            if mujoco is not None and mjcf is not None:
                model = mujoco.MjModel.from_xml_path(str(mjcf))
                mj = (model, mujoco_drops(mujoco, model, batch))
            times = {("gelenk", 1): [], ("gelenk", 2): [], ("MuJoCo", 1): [], ("MuJoCo", 2): []}
            for _ in range(rounds):
                for threads in (1, 2):
                    start = time.perf_counter()
                    gelenk.rollout(world, x0, steps=steps, threads=threads)
                    times[("gelenk", threads)].append(time.perf_counter() - start)
                    if mj is not None:
                        model, mx0 = mj
                        datas = [mujoco.MjData(model) for _ in range(threads)]
                        start = time.perf_counter()
                        mj_rollout.rollout(model, datas, mx0, nstep=steps)
                        times[("MuJoCo", threads)].append(time.perf_counter() - start)
            for engine in ("gelenk", "MuJoCo"):
                if not times[(engine, 1)]:
                    continue
                one, two = statistics.median(times[(engine, 1)]), statistics.median(times[(engine, 2)])
                for threads, wall in ((1, one), (2, two)):
                    speedup = f"{one / two:.2f}x" if threads == 2 else ""
                    print(f"| {label} | {engine} | {threads} | {wall:.2f} | {batch * steps / wall:,.0f} | {speedup} |")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batch", type=int, default=64)
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--only", choices=["overhead", "rollout"])
    args = parser.parse_args()
    if args.only in (None, "overhead"):
        overhead(args.rounds)
        print()
    if args.only in (None, "rollout"):
        rollouts(args.batch, args.steps, args.rounds)


if __name__ == "__main__":
    main()
