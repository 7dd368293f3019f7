"""Crowds at game rates: the tables of docs/performance.md's section "Crowds", measured and
written in place (between its `crowds:begin` and `crowds:end` markers; nothing else changes).

1. Every step answered: `gelenk simulate SCENE --dt DT --duration D --json` for the pile scenes
   (models/ragdoll_pile.toml, models/pile.toml, models/ragdoll_crowd.toml) with their own solver
   chains, and `gelenk bench world FILE.xml --json` for the MJCF piles of N = 4, 16, 64 ragdolls
   with an MJCF world's own options (hard rows, the default chain), at dt = 1/60, 1/240 and
   1/500 s: steps above the chain's tolerance, the largest certified residual, the deepest
   penetration, islands, and the CPU time per step.
   The pile scenes again for 10 s with sleeping on, as they ship: from when every multibody slept
   (`asleep_from` of `gelenk simulate --json`).
2. Against MuJoCo in the same run: piles of N = 4, 16, 64 ragdolls written as MJCF by
   benches/ragdoll_mjcf.py, stepped by `gelenk bench world FILE.xml --json` (sleeping off, every
   step does the full work) and by MuJoCo (`mj_step`, the same file, the same steps from the same
   keyframe), at dt = 2 ms and 1/60 s: time per step and the ratio gelenk / MuJoCo.

Not part of CI (needs `pip install mujoco` and minutes of CPU).

Usage:
    cargo build --release
    python3 benches/crowds.py [--gelenk target/release/gelenk] [--duration 1.5] [--quick] [--no-write]
"""
import argparse
import json
import math
import os
import resource
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.join(HERE, "..")
DOC = os.path.join(ROOT, "docs", "performance.md")
BEGIN, END = "<!-- crowds:begin -->", "<!-- crowds:end -->"
DTS = [("1/60", 1 / 60), ("1/240", 1 / 240), ("1/500", 1 / 500)]
# Simulated seconds of the sleep runs (the bound: asleep within 10 s).
SLEEP_SECONDS = 10.0
# The chain and softness of the MJCF piles (which carry no gelenk settings: the world's default
# rows are hard, MuJoCo's soft): the ragdoll crowd's chain, with the softness of MuJoCo's default
# impedance (d = 0.9 gives R = (1 - d) / d · A = 0.11 A), so that both engines solve rows of
# about the same compliance.
PILE_SETTINGS = ["--solver", "newton,clarabel", "--softness", "0.1"]
# Scenes, with the flags they are run with.
SCENES = [("ragdoll_pile", []), ("pile", []), ("ragdoll_crowd", [])]


def child_cpu():
    """CPU seconds used by finished child processes so far (user + system)."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def simulate(gelenk, scene, dt, duration, flags):
    """The run's summary, with `cpu_per_step` (s): the process's CPU time over its steps."""
    before = child_cpu()
    out = subprocess.run(
        [gelenk, "simulate", os.path.join(ROOT, "models", f"{scene}.toml"), "--dt", repr(dt),
         "--duration", repr(duration), "--json", *flags],
        check=True, capture_output=True, text=True,
    ).stdout
    summary = json.loads(out)
    summary["cpu_per_step"] = (child_cpu() - before) / max(summary["steps"], 1)
    return summary


def bench_gelenk(gelenk, path, steps, extra):
    """`bench world`'s summary, with `cpu_us_per_step`: the process's CPU time over the two
    runs of the episode that `bench world` makes (one timed from outside, one per step)."""
    before = child_cpu()
    out = subprocess.run(
        [gelenk, "bench", "world", path, "--steps", str(steps), "--rounds", "1", "--json", *extra],
        check=True, capture_output=True, text=True,
    ).stdout
    summary = json.loads(out)
    summary["cpu_us_per_step"] = (child_cpu() - before) / (2 * steps) * 1e6
    return summary


def bench_mujoco(path, steps):
    """CPU µs per step of `steps` `mj_step`s from keyframe 0, and whether MuJoCo reported
    instability (bad accelerations) or non-finite states."""
    import mujoco
    import numpy as np

    model = mujoco.MjModel.from_xml_path(path)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    mujoco.mj_forward(model, data)
    start = time.process_time()
    mujoco.mj_step(model, data, nstep=steps)
    elapsed = time.process_time() - start
    unstable = data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number > 0 or not np.all(np.isfinite(data.qpos))
    return elapsed / steps * 1e6, unstable, mujoco.__version__


def answered_row(name, label, summary, cpu_ms):
    """A row of the every-step table from a `simulate` or `bench world` summary (the same keys)
    and the CPU milliseconds per step."""
    s = summary
    usage = ", ".join(f"{k} {v}" for k, v in s["solver_usage"].items())
    return (
        f"| {name} | {label} | {s['steps']} | {s['steps_above_tolerance']} | {s['max_residual']:.1e} "
        f"| {1e3 * s['max_penetration']:.1f} | {s['max_islands']}, {s['largest_island']} "
        f"| {cpu_ms:.1f} | {usage} |"
    )


def write_doc(section, begin=BEGIN, end=END):
    """Puts `section` between the markers `begin` and `end` of docs/performance.md (appended
    with them when they are missing); nothing else changes."""
    text = open(DOC).read()
    if begin in text and end in text:
        head, rest = text.split(begin, 1)
        _, tail = rest.split(end, 1)
        text = head + begin + "\n" + section + end + tail
    else:
        text = text.rstrip("\n") + "\n\n" + begin + "\n" + section + end + "\n"
    open(DOC, "w").write(text)


def write_pile(path, n, dt):
    """Writes the MJCF pile of `n` ragdolls at time step `dt` (s), elliptic cones, to `path`."""
    with open(path, "w") as f:
        subprocess.run(
            [sys.executable, os.path.join(HERE, "ragdoll_mjcf.py"), "--count", str(n), "--dt", repr(dt),
             "--cone", "elliptic"],
            check=True, stdout=f,
        )


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--gelenk", default=os.path.join(ROOT, "target", "release", "gelenk"))
    parser.add_argument("--duration", type=float, default=1.5, help="simulated seconds per scene run")
    parser.add_argument("--quick", action="store_true", help="only 1/60 s, N = 4 and 16 (a smoke run)")
    parser.add_argument("--no-write", action="store_true", help="print the section instead of writing it")
    args = parser.parse_args()
    command = "python3 benches/crowds.py" + (f" --duration {args.duration:g}" if args.duration != 1.5 else "")
    dts = DTS[:1] if args.quick else DTS
    lines = [
        "### Crowds: every step answered (each scene's own chain unless flags are shown)",
        "",
        f"`{command}` (the release build's `gelenk`; {args.duration:g} s simulated per run, from the drop).",
        "",
        "| scene | dt | steps | above tolerance | max residual (m/s) | deepest penetration (mm) "
        "| islands (most, largest rows) | CPU ms per step | solvers |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for scene, flags in SCENES:
        for label, dt in dts:
            s = simulate(args.gelenk, scene, dt, args.duration, flags)
            name = f"{scene} `{' '.join(flags)}`" if flags else scene
            lines.append(answered_row(name, label, s, 1e3 * s["cpu_per_step"]))
            print(lines[-1], flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        for n in [4, 16] if args.quick else [4, 16, 64]:
            for label, dt in dts:
                path = os.path.join(tmp, f"pile{n}.xml")
                write_pile(path, n, dt)
                s = bench_gelenk(args.gelenk, path, int(round(args.duration / dt)), [])
                lines.append(answered_row(f"MJCF pile of {n}", label, s, 1e-3 * s["cpu_us_per_step"]))
                print(lines[-1], flush=True)
    lines += [
        "",
        "MJCF piles: `python3 benches/ragdoll_mjcf.py --count N --dt DT --cone elliptic`, stepped by "
        "`gelenk bench world FILE.xml` with the file's own world (hard rows, the default chain; sleeping "
        "off, so that every step does the full work).",
        "",
        "### Crowds: asleep within 10 s (sleeping on, as the scenes ship)",
        "",
        f"`gelenk simulate SCENE --dt DT --duration {SLEEP_SECONDS:g} --json`: `asleep_from`, the simulated time from "
        f"which every multibody slept to the end of the run (\"awake\" when one was still awake at {SLEEP_SECONDS:g} s).",
        "",
        "| scene | dt | asleep from (s) | steps with rows | deepest penetration (mm) | above tolerance "
        "| CPU s for the run |",
        "|---|---|---|---|---|---|---|",
    ]
    for scene, flags in SCENES:
        for label, dt in dts:
            s = simulate(args.gelenk, scene, dt, SLEEP_SECONDS, flags)
            asleep = "awake" if s["asleep_from"] is None else f"{s['asleep_from']:.2f}"
            lines.append(
                f"| {scene} | {label} | {asleep} | {s['solved_steps']} of {s['steps']} "
                f"| {1e3 * s['max_penetration']:.1f} | {s['steps_above_tolerance']} "
                f"| {s['cpu_per_step'] * s['steps']:.1f} |"
            )
            print(lines[-1], flush=True)
    lines += [
        "",
        "### Crowds against MuJoCo (the same MJCF file, the same run)",
        "",
        "Piles of N ragdolls from `python3 benches/ragdoll_mjcf.py --count N --dt DT --cone elliptic` (the 2 × 2 columns "
        "of models/ragdoll_crowd.toml), stepped from the drop by `gelenk bench world FILE.xml` "
        f"(sleeping off, ragdoll_crowd's chain with MuJoCo's default compliance: `{' '.join(PILE_SETTINGS)}`) and by MuJoCo's "
        "`mj_step` (its default Newton solver and soft constraints, `implicitfast`); elliptic friction "
        "cones in both (Newton's method solves cones).",
        "",
        "| N | dt | steps | MuJoCo CPU µs/step | gelenk CPU µs/step | gelenk / MuJoCo | gelenk fallbacks "
        "| MuJoCo stable |",
        "|---|---|---|---|---|---|---|---|",
    ]
    counts = [4, 16] if args.quick else [4, 16, 64]
    version = "?"
    with tempfile.TemporaryDirectory() as tmp:
        for label, dt, seconds in [("2 ms", 0.002, 0.6), ("1/60", 1 / 60, 2.0)]:
            steps = int(round(seconds / dt))
            for n in counts:
                path = os.path.join(tmp, f"pile{n}.xml")
                write_pile(path, n, dt)
                mujoco_us, unstable, version = bench_mujoco(path, steps)
                soft = bench_gelenk(args.gelenk, path, steps, PILE_SETTINGS)
                s = soft["cpu_us_per_step"]
                lines.append(
                    f"| {n} | {label} | {steps} | {mujoco_us:.0f} | {s:.0f} | {s / mujoco_us:.2f}× "
                    f"| {soft['fallbacks']} | {'no' if unstable else 'yes'} |"
                )
                print(lines[-1], flush=True)
    lines += [
        "",
        f"MuJoCo {version}. Times are CPU time (of the `gelenk` process, of MuJoCo's `mj_step` loop), "
        "so that a busy host slows neither side's figure by waiting; both on one core, back to back.",
        "",
    ]
    section = "\n".join(lines)
    if args.no_write:
        print(section)
    else:
        write_doc(section)
        print(f"written to {os.path.relpath(DOC)}")


if __name__ == "__main__":
    main()
