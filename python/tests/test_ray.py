"""The Ray example (python/examples/ray_rollouts.py) on a local Ray instance with 2 workers:
the sweep's results, gathered from remote tasks, equal the same drops rolled out in this process
bit for bit. Skipped only where Ray is not installed (`pip install ray`)."""

import importlib.util

import numpy as np
import pytest

ray = pytest.importorskip("ray", reason="ray is not installed here (pip install ray)")


def example(repo):
    spec = importlib.util.spec_from_file_location("ray_rollouts", repo / "python/examples/ray_rollouts.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_sweep_on_two_ray_workers_equals_local_rollouts(repo):
    rr = example(repo)
    result = rr.main(["--drops", "8", "--steps", "500", "--batch", "3", "--workers", "2"])
    assert list(result["seeds"]) == list(range(8))
    local = rr.drop_batch(str(rr.SCENE), list(range(8)), 500, threads=1)
    for key in ("final_height", "max_penetration", "contacts", "final_state"):
        assert np.array_equal(result[key], local[key]), key
    assert np.all(result["contacts"] > 0), "every ragdoll reaches the ground within 1 s"
    assert len(set(result["final_height"])) == 8, "the seeds give different drops"
