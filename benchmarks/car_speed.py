"""Speed of chapter 5: simulating the 200 s drive, and each stage of Algorithm 3 on it.

    python benchmarks/car_speed.py [--seconds 200] [--json out.json]

Goals on a 2-core machine: the full 200 s simulation (about 100 million returns, written as a real pcap)
<= 2 minutes; the laser-angle stage <= 60 s; the whole of Algorithm 3 <= 10 minutes. The thesis's times
(2.79 GHz Pentium 4) are printed beside ours: 83 minutes for the angles (10.7 with a 23° bound) and 34
minutes per iteration; and, as a baseline measured in the same run, the angle stage with the 23° bound.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

from sensact.app.velodyne_car import learn_from_log, simulate_car_log
from sensact.io.velodyne_car_folder import read_car_log
from sensact.learn.spinning_lidar_intrinsics import IntrinsicsConfig, learn_relative_angles
from sensact.learn.velodyne_car_dynamics import CarLearningConfig
from sensact.sim.velodyne_car import CarConfig

THESIS_S = {"laser_angles": 83 * 60, "laser_angles_23deg": 10.7 * 60, "per_iteration": 34 * 60}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=200.0, help="length of the simulated drive")
    ap.add_argument("--json", type=str, default=None, help="also write the numbers here")
    args = ap.parse_args()
    cfg = CarConfig(seconds=args.seconds)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "car"
        t0 = time.perf_counter()
        simulate_car_log(cfg, folder)
        sim_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        log = read_car_log(folder)
        read_s = time.perf_counter() - t0
        returns = log.distance_m.size
    t0 = time.perf_counter()
    learn_relative_angles(
        log.distance_m, log.vertical_rad, log.firing_hz, log.omega_rad_s, IntrinsicsConfig(max_difference_deg=23.0)
    )
    bounded_s = time.perf_counter() - t0
    res = learn_from_log(log, CarLearningConfig())
    st = res.seconds_by_stage
    total = sum(st.values())
    per_it = (st["scan_matching"] + st["regression"]) / res.iterations
    out = {
        "seconds_of_driving": args.seconds,
        "returns": int(returns),
        "simulate_and_write_pcap_s": sim_s,
        "read_pcap_s": read_s,
        "laser_angles_s": st["laser_angles"],
        "laser_angles_23deg_s": bounded_s,
        "per_iteration_s": per_it,
        "iterations": res.iterations,
        "algorithm_3_s": total,
        "thesis_s": THESIS_S,
    }
    print(f"{args.seconds:.0f} s drive, {returns / 1e6:.1f} million returns")
    print(f"simulate + write pcap   {sim_s:7.1f} s   goal <= 120 s")
    print(f"read the pcap           {read_s:7.1f} s")
    thesis_min = THESIS_S["laser_angles"] / 60
    print(f"laser angles            {st['laser_angles']:7.1f} s   goal <= 60 s; thesis {thesis_min:.0f} min")
    print(f"  with the 23° bound    {bounded_s:7.1f} s   thesis {THESIS_S['laser_angles_23deg'] / 60:.1f} min")
    print(f"one iteration           {per_it:7.1f} s   thesis {THESIS_S['per_iteration'] / 60:.0f} min")
    print(f"Algorithm 3, all        {total:7.1f} s   goal <= 600 s ({res.iterations} iterations; thesis 4, 3 h 40 min)")
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
