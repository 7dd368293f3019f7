"""Ragdoll drops spread over a Ray cluster: a parameter sweep (one seed per drop: drop height and
spin) cut into batches, each batch a ``ray.remote`` task that loads the scene and calls
``gelenk.rollout`` on the cores Ray gives it; the driver gathers the results.

    python python/examples/ray_rollouts.py --drops 1000 --steps 1000 --batch 50
    python python/examples/ray_rollouts.py --address auto ...   # an existing Ray cluster

A task's result depends only on its seeds, not on the machine or the number of threads that ran
it (``gelenk.rollout`` is bit-for-bit deterministic), so the sweep gives the same numbers on one
laptop and on a cluster. Needs ``pip install ray``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Dict, Optional, Sequence

import numpy as np

import gelenk

SCENE = Path(__file__).resolve().parents[2] / "models" / "ragdoll_fall.toml"


def initial_states(world: gelenk.World, seeds: Sequence[int]) -> np.ndarray:
    """One initial state per seed: the scene's ragdoll raised by up to 1 m and spun about a
    random axis (root angular velocity ~ N(0, 3 rad/s) per component)."""
    x = np.tile(world.get_state(), (len(seeds), 1))
    for i, seed in enumerate(seeds):
        rng = np.random.default_rng(seed)
        x[i, 2] += rng.uniform(0.0, 1.0)
        x[i, world.nq + 3 : world.nq + 6] = rng.normal(0.0, 3.0, 3)
    return x


def drop_batch(
    scene: str, seeds: Sequence[int], steps: int, threads: Optional[int] = None
) -> Dict[str, np.ndarray]:
    """Rolls out one batch of drops and sums each up: the root's final height (m), the deepest
    penetration (m), the contact points summed over the steps, and the final states."""
    world = gelenk.load_scene(scene)
    states, stats = gelenk.rollout(
        world, initial_states(world, seeds), steps=steps, threads=threads, stats=True
    )
    return {
        "seeds": np.asarray(seeds),
        "final_height": states[:, -1, 2].copy(),
        "max_penetration": stats["max_penetration"].max(axis=1),
        "contacts": stats["contacts"].sum(axis=1),
        "final_state": states[:, -1].copy(),
    }


def sweep(
    scene: str, seeds: Sequence[int], steps: int, batch: int, threads_per_task: int = 1
) -> Dict[str, np.ndarray]:
    """The drops of ``seeds`` in batches of ``batch``, one Ray task each (``threads_per_task``
    CPUs and rollout threads per task), gathered in seed order. Ray must be initialized."""
    import ray

    task = ray.remote(num_cpus=threads_per_task)(drop_batch)
    futures = [
        task.remote(scene, list(seeds[i : i + batch]), steps, threads_per_task)
        for i in range(0, len(seeds), batch)
    ]
    parts = ray.get(futures)
    return {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}


def main(argv: Optional[Sequence[str]] = None) -> Dict[str, np.ndarray]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--drops", type=int, default=200, help="number of drops (seeds 0..N-1)")
    parser.add_argument("--steps", type=int, default=1000, help="steps per drop")
    parser.add_argument("--batch", type=int, default=25, help="drops per Ray task")
    parser.add_argument("--threads-per-task", type=int, default=1)
    parser.add_argument("--workers", type=int, default=2, help="CPUs of a local Ray instance")
    parser.add_argument("--address", default=None, help="address of an existing Ray cluster")
    parser.add_argument("--scene", default=str(SCENE))
    args = parser.parse_args(argv)

    import ray

    if args.address:
        ray.init(address=args.address, log_to_driver=False)
    else:
        ray.init(num_cpus=args.workers, include_dashboard=False, log_to_driver=False)
    try:
        start = time.perf_counter()
        result = sweep(args.scene, list(range(args.drops)), args.steps, args.batch, args.threads_per_task)
        wall = time.perf_counter() - start
    finally:
        ray.shutdown()
    steps = args.drops * args.steps
    print(
        f"{args.drops} drops x {args.steps} steps in {wall:.2f} s ({steps / wall:,.0f} steps/s) "
        f"on {len(range(0, args.drops, args.batch))} tasks"
    )
    print(
        f"final root height: mean {result['final_height'].mean():.3f} m, "
        f"min {result['final_height'].min():.3f} m, max {result['final_height'].max():.3f} m; "
        f"deepest penetration {result['max_penetration'].max() * 1e3:.2f} mm"
    )
    return result


if __name__ == "__main__":
    main()
