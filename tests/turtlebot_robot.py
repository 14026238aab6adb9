"""A seeded 1-D robot in the Turtlebot's CSV format, for the tests of the readers and commands that take one."""

from __future__ import annotations

import numpy as np


def write_turtlebot_csv(
    path,
    *,
    with_range: bool,
    seed: int = 7,
    one_speed: bool = False,
    drop: tuple[str, ...] = (),
    gain: float = 0.9,
) -> None:
    """A seeded robot in the Turtlebot's CSV format: it backs away from and drives at a wall, obeying its
    command with ``gain`` (0.9) and 2 steps (0.12 s) late (the move from step k - 1 to k follows the command of
    step k - 3); sonar1 reads the distance in m with 5 % outliers, each IR sensor a falling curve of it.
    ``one_speed``: it backs away at 0.01 m/s instead, apart from a 1-s stop every 30 s (like
    turtlebot1d's calibration.csv)."""
    rng = np.random.default_rng(seed)
    n, dt = 2500, 0.06
    t = 0.1 + dt * np.arange(n)
    period = 14.0  # whole periods of a sine out and back, at 0.2, 0.3 and 0.4 m/s: 400 to 2000 mm
    cmd = np.sin(2 * np.pi * t / period) * (0.2 + 0.1 * ((t // period) % 3))
    if one_speed:
        cmd = np.where(t % 30.0 < 1.0, 0.0, 0.01)
    d = np.empty(n)
    d[0] = 400.0
    for k in range(1, n):
        d[k] = d[k - 1] + gain * 1000.0 * cmd[max(k - 3, 0)] * dt + rng.normal(0.0, 2.0)
    sonar = d / 1000.0 + rng.normal(0.0, 0.01, n)
    bad = rng.random(n) < 0.05
    sonar[bad] = rng.uniform(0.1, 5.0, bad.sum())
    ir = [
        a * np.exp(-d / s) + 0.3 + rng.normal(0.0, 0.02, n)
        for a, s in ((3.0, 600), (2.5, 150), (3.0, 400), (2.5, 2500))
    ]
    cols = {"time": t, "range": d / 1000.0, "velocity_command": cmd}
    cols |= {f"raw_ir{i + 1}": v for i, v in enumerate(ir)} | {"sonar1": sonar, "sonar2": d / 1000.0}
    for name in (*drop, *(() if with_range else ("range",))):
        del cols[name]
    rows = [",".join(["", *cols])] + [",".join([str(k), *(f"{v[k]:.6f}" for v in cols.values())]) for k in range(n)]
    path.write_text("\n".join(rows) + "\n")
