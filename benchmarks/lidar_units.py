"""Chapter 5 on each spinning lidar: the laser angles Algorithm 3 learns from each unit's simulated drive.

    python benchmarks/lidar_units.py [--seconds 200] [--models HDL-32E,VLP-16] [--seed 0] [--json out.json]

For each model (HDL-64E, HDL-32E, VLP-32C, VLP-16, OS-1) it simulates the same drive with that unit on the
car (its geometry from the shared data's calibration where there is one, else its datasheet's), writes its
real packets, reads them back as ``sensact learn car`` does and runs Algorithm 3. Printed per unit: the
learned angles' RMS error against the truth (theta_l + theta_b; issue 77's bar: 0.25°), split into the
common offset C's error and the spread about it (sec. 5.1's part), and the seconds it took.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from sensact.app.velodyne_car import learn_from_log, simulate_car_log
from sensact.evaluate.velodyne_car import laser_angle_error
from sensact.io.velodyne_car_folder import read_car_log
from sensact.models.spinning_lidar import UNITS
from sensact.sim.velodyne_car import CarConfig

BAR_DEG = 0.25


def run(model: str, seconds: float, seed: int) -> dict[str, float | str | int]:
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        sim = simulate_car_log(CarConfig(seconds=seconds, seed=seed, lidar=model), Path(tmp) / "car")
        t1 = time.perf_counter()
        log = read_car_log(Path(tmp) / "car")
        res = learn_from_log(log)
        t2 = time.perf_counter()
    truth = sim.true_laser_angles_rad
    err = np.angle(np.exp(1j * (res.laser_angles_rad - truth)))
    offset = float(np.angle(np.mean(np.exp(1j * err))))
    return {
        "model": model,
        "lasers": int(log.distance_m.shape[1]),
        "laser_angle_rms_deg": laser_angle_error(res.laser_angles_rad, sim.true_laser_angles_rad)[
            "laser_angle_rms_deg"
        ],
        "offset_error_deg": float(np.degrees(offset)),
        "spread_rms_deg": float(np.degrees(np.sqrt(np.mean((err - offset) ** 2)))),
        "iterations": res.iterations,
        "simulate_s": t1 - t0,
        "learn_s": t2 - t1,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=200.0, help="length of each simulated drive")
    ap.add_argument("--models", type=str, default=",".join(UNITS), help="comma-separated: " + ", ".join(UNITS))
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", type=str, default=None, help="also write the numbers here")
    args = ap.parse_args()
    rows = []
    for model in args.models.split(","):
        if model not in UNITS:
            sys.exit(f"unknown model {model!r}: one of {', '.join(UNITS)}")
        r = run(model, args.seconds, args.seed)
        rows.append(r)
        met = "met" if float(r["laser_angle_rms_deg"]) <= BAR_DEG else "MISSED"
        rms = r["laser_angle_rms_deg"]
        print(
            f"{model:8s} {r['lasers']:3d} lasers: laser angles {rms:.3f}° RMS ({met}: ≤ {BAR_DEG}°; "
            f"C off {r['offset_error_deg']:+.3f}°, spread {r['spread_rms_deg']:.3f}°), {r['iterations']} iterations, "
            f"simulated in {r['simulate_s']:.0f} s, learned in {r['learn_s']:.0f} s",
            flush=True,
        )
    if args.json:
        Path(args.json).write_text(json.dumps({"seconds": args.seconds, "seed": args.seed, "units": rows}, indent=2))


if __name__ == "__main__":
    main()
