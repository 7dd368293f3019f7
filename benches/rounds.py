"""Alternating rounds of `gelenk bench world` (one or more builds) and MuJoCo on the same host, with
medians of per-round ratios: on a shared machine whose speed drifts by ±40 % within minutes, only
figures measured back to back compare, and the median over many short rounds is what a README
row should quote. Not part of CI (MuJoCo: `pip install mujoco`).

Usage:
  python3 benches/rounds.py --rounds 25 \
      --gelenk new=target/release/gelenk:models/ragdoll_fall.toml \
      --gelenk old=/tmp/old/gelenk:/tmp/old_ragdoll_fall.toml \
      --mujoco hum=benches/peers/humanoid_fall.xml \
      --mujoco rag=ragdoll_seed7.xml

Each `--gelenk NAME=BINARY:SCENE` runs `BINARY bench world SCENE --rounds 5` (median over five
episodes of each episode's mean µs per step); each `--mujoco NAME=FILE` runs five episodes of
2500 `mj_step`s from keyframe 0 if the file has one (the statistic of benches/mujoco_peers.py).
Prints every round, then per entry the median and range of its episode means, and the median
and range of every gelenk entry's per-round ratio to every other entry. `--sleep TOL` runs both
sides with sleeping on: gelenk's `bench world --sleep` (thresholds 0.01 m/s and rad/s), MuJoCo's
`mjENBL_SLEEP` with `sleep_tolerance = TOL` (its default, 1e-3, never puts the humanoid of
benches/peers to sleep within the 5 s).
"""
import argparse
import re
import statistics
import subprocess

EPISODE_MEAN = re.compile(r"([0-9.]+) µs/step \(episode mean\)")


def gelenk_mean(binary, scene, sleep):
    command = [binary, "bench", "world", scene, "--rounds", "5"] + (["--sleep"] if sleep else [])
    try:
        out = subprocess.run(command, check=True, capture_output=True, text=True).stdout
    except FileNotFoundError:
        raise SystemExit(f"no gelenk binary at {binary}")
    except subprocess.CalledProcessError as e:
        raise SystemExit(f"{binary} bench world {scene} failed:\n{e.stderr}")
    match = EPISODE_MEAN.search(out)
    if match is None:
        raise SystemExit(f"{binary} bench world {scene}: no episode mean in its output:\n{out}")
    return float(match.group(1))


def mujoco_mean(model):
    from mujoco_peers import episode_means  # benches/, the script's own directory

    return statistics.median(episode_means(model))


def named(text, what):
    name, sep, rest = text.partition("=")
    if not sep or not name or not rest:
        raise argparse.ArgumentTypeError(f"{what} must be NAME=...: {text!r}")
    return name, rest


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--rounds", type=int, default=10)
    parser.add_argument("--gelenk", action="append", default=[], type=lambda t: named(t, "--gelenk"))
    parser.add_argument("--mujoco", action="append", default=[], type=lambda t: named(t, "--mujoco"))
    parser.add_argument(
        "--sleep",
        type=float,
        metavar="TOL",
        help="sleeping on both sides: `bench world --sleep` for gelenk (its default thresholds, "
        "0.01 m/s and rad/s), MuJoCo's mjENBL_SLEEP with sleep_tolerance TOL",
    )
    args = parser.parse_args()
    entries = []
    for name, rest in args.gelenk:
        binary, sep, scene = rest.rpartition(":")
        if not sep:
            raise SystemExit(f"--gelenk {name}: expected BINARY:SCENE, got {rest!r}")
        entries.append((name, lambda b=binary, s=scene: gelenk_mean(b, s, args.sleep is not None)))
    if args.mujoco:
        import mujoco

        for name, path in args.mujoco:
            model = mujoco.MjModel.from_xml_path(path)
            if args.sleep is not None:
                model.opt.enableflags |= int(mujoco.mjtEnableBit.mjENBL_SLEEP)
                model.opt.sleep_tolerance = args.sleep
            entries.append((name, lambda m=model: mujoco_mean(m)))
    if not entries or args.rounds < 1:
        raise SystemExit("nothing to run: give --gelenk and/or --mujoco entries and --rounds ≥ 1")
    rounds = []
    for r in range(args.rounds):
        figures = {name: run() for name, run in entries}
        rounds.append(figures)
        print(f"round {r + 1}: " + ", ".join(f"{n} {x:.1f}" for n, x in figures.items()), flush=True)
    print("episode mean, µs per step (median over rounds, range):")
    for name, _ in entries:
        xs = [f[name] for f in rounds]
        print(f"  {name}: {statistics.median(xs):.1f} ({min(xs):.1f}–{max(xs):.1f})")
    print("per-round ratios (median, range):")
    gelenk_names = [n for n, _ in args.gelenk]
    for a in gelenk_names:
        for b, _ in entries:
            if a != b:
                ratios = [f[a] / f[b] for f in rounds]
                print(f"  {a} / {b}: {statistics.median(ratios):.3f} ({min(ratios):.2f}–{max(ratios):.2f})")


if __name__ == "__main__":
    main()
