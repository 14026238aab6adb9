"""How far the wheels-and-lidar fit moves when its input moves by one ulp: the floor below which no change to
its arithmetic (another frame, another order of the same sums) can be told from the fit's own sensitivity.

    python benchmarks/lidar2d_determinism.py [--seconds 300] [--seed 3] [--log DIR]

Learns a lidar2d log (simulated, or ``--log``), then the same log with every range one ulp larger, and prints
each parameter's difference relative to its value and in its sd. Before each parameter's finite-difference step
was sized to its scale, a delay near 0 s moved by 3 % of itself this way.
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
from pathlib import Path

import numpy as np

from sensact.io.lidar2d_folder import read_lidar2d_log, write_lidar2d_log
from sensact.learn.wheel_lidar import PARAMETERS, learn_wheel_lidar
from sensact.sim.lidar2d import Lidar2DConfig, simulate_lidar2d


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=300.0)
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--log", type=Path, default=None)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.log
        if folder is None:
            run = simulate_lidar2d(Lidar2DConfig(seconds=args.seconds, seed=args.seed))
            folder = Path(tmp) / "log"
            write_lidar2d_log(folder, run.log(str(folder)), run.tables())
        log = read_lidar2d_log(folder)
        a = learn_wheel_lidar(log).fit
        b = learn_wheel_lidar(dataclasses.replace(log, ranges_mm=np.nextafter(log.ranges_mm, np.inf))).fit
    print(f"{'parameter':24s} {'value':>16s} {'relative':>10s} {'in sd':>10s}")
    for name, x, y, sd in zip(PARAMETERS, a.params, b.params, a.sd, strict=True):
        print(f"{name:24s} {x:16.10g} {abs(x - y) / abs(x):10.2e} {abs(x - y) / sd:10.2e}")


if __name__ == "__main__":
    main()
