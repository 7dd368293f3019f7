"""MuJoCo on the stability report's piles: stack10, stack20 (0.1 m, 1 kg cubes) and pyramid10
(55 cubes, base 10, 2 mm gaps), MuJoCo's default Newton solver at its 2 ms step, friction 0.8.
Prints the wall time per step and per simulated second and the top box's largest drift.

    pip install mujoco numpy && python3 benches/peers/mujoco_piles.py
"""

import time

import mujoco
import numpy as np

CUBE = '<freejoint/><geom type="box" size="0.05 0.05 0.05" mass="1"/>'


def stack(count):
    return "".join(f'<body name="box{k}" pos="0 0 {0.05 + 0.1 * k:.4f}">{CUBE}</body>' for k in range(count))


def pyramid():
    side, gap, bodies = 0.1, 0.002, []
    for row in range(10):
        for k in range(10 - row):
            x = (k - (9 - row) / 2) * (side + gap)
            bodies.append(f'<body name="b{row}_{k}" pos="{x:.4f} 0 {0.05 + side * row:.4f}">{CUBE}</body>')
    return "".join(bodies)


def scene(bodies):
    return (
        '<mujoco><option timestep="0.002"/><default><geom friction="0.8" condim="3"/></default>'
        f'<worldbody><geom name="floor" type="plane" size="5 5 0.1"/>{bodies}</worldbody></mujoco>'
    )


for name, bodies, duration in [("stack10", stack(10), 10.0), ("stack20", stack(20), 10.0), ("pyramid10", pyramid(), 10.0)]:
    model = mujoco.MjModel.from_xml_string(scene(bodies))
    data = mujoco.MjData(model)
    top = model.nbody - 1
    mujoco.mj_forward(model, data)
    start = data.xpos[top].copy()
    steps = int(round(duration / model.opt.timestep))
    drift, elapsed = 0.0, 0.0
    for _ in range(steps):
        t = time.perf_counter()
        mujoco.mj_step(model, data)
        elapsed += time.perf_counter() - t
        drift = max(drift, float(np.linalg.norm(data.xpos[top] - start)))
    print(
        f"{name}: {1e6 * elapsed / steps:.0f} µs per step, {elapsed / duration:.3f} s per simulated s, "
        f"top drift {drift:.2e} m, {data.ncon} contacts"
    )
