"""How the cost of a step grows with the crowd: piles of N = 1 … 64 ragdolls (MJCF written by
benches/ragdoll_mjcf.py, read by both engines), CPU time per step per ragdoll for gelenk and for
MuJoCo in the same run, at dt = 2 ms and 1/60 s. Writes the plot docs/crowd_scaling.png and the
table it is drawn from into docs/performance.md (between its `crowd-scaling:begin` and
`crowd-scaling:end` markers; nothing else changes).

gelenk runs the chain of models/ragdoll_crowd.toml with the compliance of MuJoCo's default
impedance (`--solver newton,clarabel --softness 0.1`, sleeping off: every step does the full work); MuJoCo its defaults (Newton, soft
constraints, `implicitfast`), elliptic cones in both. Each run starts at the drop and lasts
`--seconds` simulated seconds, so the heap forms during it.

Not part of CI (needs `pip install mujoco matplotlib` and minutes of CPU).

Usage:
    cargo build --release
    python3 benches/crowd_scaling.py [--gelenk target/release/gelenk] [--seconds 2] [--no-write]
"""
import argparse
import os
import tempfile

from crowds import ROOT, PILE_SETTINGS, bench_gelenk, bench_mujoco, write_doc, write_pile

DOC = os.path.join(ROOT, "docs", "performance.md")
PLOT = os.path.join(ROOT, "docs", "crowd_scaling.png")
BEGIN, END = "<!-- crowd-scaling:begin -->", "<!-- crowd-scaling:end -->"
COUNTS = [1, 2, 4, 8, 16, 32, 64]
DTS = [("2 ms", 0.002), ("1/60 s", 1 / 60)]


def plot(rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.2), dpi=110)
    styles = {"2 ms": "-", "1/60 s": "--"}
    for label, _ in DTS:
        mine = [(r["n"], r["gelenk"] / r["n"]) for r in rows if r["dt"] == label]
        theirs = [(r["n"], r["mujoco"] / r["n"]) for r in rows if r["dt"] == label]
        ax.plot(*zip(*mine), styles[label], marker="o", color="tab:blue", label=f"gelenk, dt {label}")
        ax.plot(*zip(*theirs), styles[label], marker="s", color="tab:orange", label=f"MuJoCo, dt {label}")
        for r in rows:
            if r["dt"] == label and not r["stable"]:
                ax.annotate("unstable", (r["n"], r["mujoco"] / r["n"]), textcoords="offset points",
                            xytext=(4, 4), fontsize=8, color="tab:orange")
    ax.set_xscale("log", base=2)
    ax.set_yscale("log")
    ax.set_xticks(COUNTS)
    ax.set_xticklabels([str(n) for n in COUNTS])
    ax.set_xlabel("ragdolls in the pile")
    ax.set_ylabel("CPU µs per step per ragdoll")
    ax.set_title("Cost of a step per ragdoll, piles dropped from the 2 × 2 columns")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--gelenk", default=os.path.join(ROOT, "target", "release", "gelenk"))
    parser.add_argument("--seconds", type=float, default=2.0, help="simulated seconds per run, from the drop")
    parser.add_argument("--no-write", action="store_true", help="print the table; write no file")
    args = parser.parse_args()
    rows = []
    version = "?"
    with tempfile.TemporaryDirectory() as tmp:
        for label, dt in DTS:
            steps = int(round(args.seconds / dt))
            for n in COUNTS:
                path = os.path.join(tmp, f"pile{n}.xml")
                write_pile(path, n, dt)
                mujoco_us, unstable, version = bench_mujoco(path, steps)
                ours = bench_gelenk(args.gelenk, path, steps, PILE_SETTINGS)
                rows.append({"n": n, "dt": label, "steps": steps, "gelenk": ours["cpu_us_per_step"],
                             "mujoco": mujoco_us, "stable": not unstable, "fallbacks": ours["fallbacks"]})
                r = rows[-1]
                print(f"N {n:3} dt {label}: gelenk {r['gelenk']:.0f} µs, MuJoCo {r['mujoco']:.0f} µs", flush=True)
    command = "python3 benches/crowd_scaling.py" + (f" --seconds {args.seconds:g}" if args.seconds != 2.0 else "")
    lines = [
        "### Crowd scaling",
        "",
        f"`{command}`: piles of N ragdolls (`benches/ragdoll_mjcf.py --count N`), {args.seconds:g} s from the "
        f"drop, CPU µs per step and per ragdoll, gelenk (release build, `{' '.join(PILE_SETTINGS)}`, sleeping off) and "
        f"MuJoCo {version} on the same file in the same run. Plot: [crowd_scaling.png](crowd_scaling.png).",
        "",
        "![CPU time per step per ragdoll against the number of ragdolls](crowd_scaling.png)",
        "",
        "| N | dt | steps | gelenk µs/step | per ragdoll | MuJoCo µs/step | per ragdoll | gelenk / MuJoCo "
        "| gelenk fallbacks | MuJoCo stable |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['n']} | {r['dt']} | {r['steps']} | {r['gelenk']:.0f} | {r['gelenk'] / r['n']:.0f} "
            f"| {r['mujoco']:.0f} | {r['mujoco'] / r['n']:.0f} | {r['gelenk'] / r['mujoco']:.2f}× "
            f"| {r['fallbacks']} | {'yes' if r['stable'] else 'no'} |"
        )
    for label, _ in DTS:
        per = [r["gelenk"] / r["n"] for r in rows if r["dt"] == label]
        lines.append("")
        lines.append(f"gelenk at {label}: per-ragdoll cost from {min(per):.0f} to {max(per):.0f} µs "
                     f"({max(per) / min(per):.2f}× between the cheapest and the dearest N).")
    lines.append("")
    section = "\n".join(lines)
    if args.no_write:
        print(section)
        return
    plot(rows, PLOT)
    write_doc(section, BEGIN, END)
    print(f"written to {os.path.relpath(DOC)} and {os.path.relpath(PLOT)}")


if __name__ == "__main__":
    main()
