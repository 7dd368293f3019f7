"""Benchmarks of the Python package (not a test: prints markdown tables for docs/python.md).

1. Call overhead: ``gelenk.aba(model, data, q, v, tau)`` beside ``pinocchio.aba`` in the same
   process, on ur5, panda and solo12 (free base), and the Rust call's own time on the same
   inputs in the same process (a loop in Rust: ``gelenk._gelenk._aba_loop``): the difference is
   what the binding costs. Timed by the process's CPU clock (``time.process_time``), so that
   time the shared host gives to other processes is not counted.
2. Rollouts: ``gelenk.rollout`` of B drops x T steps on 1 and 2 threads, beside
   ``mujoco.rollout`` on the same MJCF scene with the same B, T and threads (its persistent
   thread pool, as gelenk keeps its own): MuJoCo's humanoid
   (benches/peers/humanoid_fall.xml) in both engines, and gelenk's ragdoll
   (models/ragdoll_fall.toml) beside the same ragdoll in MJCF for MuJoCo
   (benches/ragdoll_mjcf.py).

The host is shared and noisy: every figure is the median over rounds, and within a round the
engines run back to back, so compare ratios measured in one run. The rollout table gives wall
time (what a user waits for), the process's CPU time (all threads) and the CPU time of its
busiest thread: when other processes hold the cores, two threads cannot halve the wall time,
but the busiest thread's CPU time is the wall time on free cores, so the speed-up on free
cores is the one-thread CPU time over it. The load average is printed with the tables.

Usage:
    python python/benches/bench.py [--batch 64] [--steps 1000] [--rounds 3]
Needs ``pip install pin mujoco`` for the peers (their rows are left out otherwise).
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

# numpy's OpenBLAS starts a thread per core that spins while idle, and that CPU time is the
# process's: with one BLAS thread the CPU clocks below count only the engines' work.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402 (after the variable above)

import gelenk  # noqa: E402
from gelenk._gelenk import _aba_loop  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
MODELS = [("ur5", "ur5_robot.urdf", False), ("panda", "panda.urdf", False), ("solo12", "solo12.urdf", True)]


def per_call_ns(call, calls=20000, rounds=9):
    """Median over rounds of the mean CPU ns per call."""
    times = []
    for _ in range(rounds):
        start = time.process_time_ns()
        for _ in range(calls):
            call()
        times.append((time.process_time_ns() - start) / calls)
    return statistics.median(times)


def loop_ns(loop, calls=20000, rounds=9):
    """Median over rounds of the mean CPU ns per iteration of ``loop(calls)``."""
    times = []
    for _ in range(rounds):
        start = time.process_time_ns()
        loop(calls)
        times.append((time.process_time_ns() - start) / calls)
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
            pq = pin.randomConfiguration(pm, -np.ones(pm.nq), np.ones(pm.nq))
            pv, ptau = rng.normal(size=pm.nv), rng.normal(size=pm.nv)
        for _ in range(rounds):
            ours.append(per_call_ns(lambda: gelenk.aba(model, data, q, v, tau)))
            rust.append(loop_ns(lambda calls: _aba_loop(model, data, q, v, tau, calls)))
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


def thread_cpu():
    """CPU seconds (user + system) of each thread of this process, by thread id (Linux:
    /proc/self/task/*/stat, in clock ticks of 10 ms)."""
    tick = os.sysconf("SC_CLK_TCK")
    out = {}
    for task in Path("/proc/self/task").iterdir():
        try:
            fields = (task / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue  # the thread ended meanwhile
        out[task.name] = (int(fields[11]) + int(fields[12])) / tick
    return out


def timed(run):
    """(wall s, process CPU s, CPU s of the busiest thread) of ``run()``. The busiest thread's
    CPU time is the wall time the run would take on idle cores (nothing waits for another
    process), so CPU / busiest is the speed-up the threads reach when the cores are free."""
    before = thread_cpu()
    wall, cpu = time.perf_counter(), time.process_time()
    run()
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    after = thread_cpu()
    busiest = max(after[t] - before.get(t, 0.0) for t in after)
    return wall, cpu, busiest


def rollouts(batch, steps, rounds):
    try:
        import mujoco
        from mujoco import rollout as mj_rollout
    except ImportError:
        mujoco = None
    with tempfile.TemporaryDirectory() as tmp:
        humanoid = REPO / "benches/peers/humanoid_fall.xml"
        scenes = [
            ("humanoid_fall.xml (MuJoCo's humanoid)", gelenk.load_mjcf(humanoid), humanoid),
            ("ragdoll_fall (gelenk's ragdoll; MuJoCo: benches/ragdoll_mjcf.py)",
             gelenk.load_scene(REPO / "models/ragdoll_fall.toml"), ragdoll_mjcf_file(tmp) if mujoco else None),
        ]
        print("| scene | engine | threads | wall (s) | CPU (s) | busiest thread's CPU (s) | steps per CPU s "
              "| speed-up 2 vs 1 thread: wall | on free cores (CPU 1 thread / busiest) "
              "| steps per CPU s, gelenk ÷ MuJoCo |")
        print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|")
        for label, world, mjcf in scenes:
            x0 = gelenk_drops(world, batch)
            mj = None
            if mujoco is not None and mjcf is not None:
                model = mujoco.MjModel.from_xml_path(str(mjcf))
                mj = (model, mujoco_drops(mujoco, model, batch))
            times = {key: [] for key in [("gelenk", 1), ("gelenk", 2), ("MuJoCo", 1), ("MuJoCo", 2)]}
            for _ in range(rounds):
                for threads in (1, 2):
                    times[("gelenk", threads)].append(
                        timed(lambda: gelenk.rollout(world, x0, steps=steps, threads=threads)))
                    if mj is not None:
                        model, mx0 = mj
                        datas = [mujoco.MjData(model) for _ in range(threads)]
                        times[("MuJoCo", threads)].append(
                            timed(lambda: mj_rollout.rollout(model, datas, mx0, nstep=steps,
                                                             persistent_pool=threads > 1)))
            # Per engine and thread count: the medians of wall, CPU and busiest thread's CPU time.
            medians = {
                key: [statistics.median(r[k] for r in runs) for k in range(3)] for key, runs in times.items() if runs
            }
            for engine in ("gelenk", "MuJoCo"):
                if (engine, 1) not in medians:
                    continue
                for n in (1, 2):
                    (wall, cpu, busiest), (wall1, cpu1, _) = medians[(engine, n)], medians[(engine, 1)]
                    wall_speedup = f"{wall1 / wall:.2f}x" if n == 2 else ""
                    free_speedup = f"{cpu1 / busiest:.2f}x" if n == 2 and busiest > 0 else ""
                    versus = ""
                    if engine == "gelenk" and ("MuJoCo", n) in medians:
                        versus = f"{medians[('MuJoCo', n)][1] / cpu:.2f}"
                    print(f"| {label} | {engine} | {n} | {wall:.2f} | {cpu:.2f} | {busiest:.2f} "
                          f"| {batch * steps / cpu:,.0f} | {wall_speedup} | {free_speedup} | {versus} |")


def peers():
    found = ""
    for module, name in (("pinocchio", "pinocchio"), ("mujoco", "mujoco")):
        try:
            found += f"{name} {__import__(module).__version__}, "
        except ImportError:
            pass
    return found


def load():
    return "load average (1, 5, 15 min): " + ", ".join(f"{x:.1f}" for x in os.getloadavg())


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batch", type=int, default=64)
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--only", choices=["overhead", "rollout"])
    args = parser.parse_args()
    print(f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores; {load()}; "
          f"gelenk {gelenk.__version__}, {peers()}python {platform.python_version()}")
    print()
    if args.only in (None, "overhead"):
        overhead(args.rounds)
        print()
    if args.only in (None, "rollout"):
        rollouts(args.batch, args.steps, args.rounds)
    print()
    print(load())


if __name__ == "__main__":
    main()
