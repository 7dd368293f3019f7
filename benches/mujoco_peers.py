"""MuJoCo's whole-step time on the peer scenes (benches/peers/*.xml), for a back-to-back
comparison with `gelenk bench world SCENE`: the host's speed varies by ±40 % between runs
minutes apart, so figures measured at different times cannot be compared, ratios measured
back to back can. Not part of CI (needs `pip install mujoco`).

Usage: python3 benches/mujoco_peers.py benches/peers/box_stack10.xml benches/peers/humanoid_fall.xml

Per scene: 5 episodes of 2500 steps from the initial state (keyframe 0 if the file has one) (`mj_step` with `nstep`, the loop
runs in C), the mean µs per step of each episode and their median: the same statistic as
gelenk's "episode mean".
"""
import statistics
import sys
import time

import mujoco


def episode_means(model, episodes=5, steps=2500):
    """Mean µs per step of each of `episodes` runs of `steps` `mj_step`s from the initial state
    (keyframe 0 if the model has one)."""
    means = []
    for _ in range(episodes):
        data = mujoco.MjData(model)
        if model.nkey > 0:
            # A scene with an initial velocity (benches/ragdoll_mjcf.py) keeps it in key 0.
            mujoco.mj_resetDataKeyframe(model, data, 0)
        mujoco.mj_forward(model, data)
        start = time.perf_counter()
        mujoco.mj_step(model, data, nstep=steps)
        means.append((time.perf_counter() - start) / steps * 1e6)
    return means


def main():
    for path in sys.argv[1:]:
        model = mujoco.MjModel.from_xml_path(path)
        means = episode_means(model)
        episodes = ", ".join(f"{x:.1f}" for x in means)
        print(
            f"{path}: MuJoCo {mujoco.__version__}, dt = {model.opt.timestep} s: "
            f"{statistics.median(means):.1f} µs/step (median episode mean; episodes {episodes})"
        )


if __name__ == "__main__":
    main()
