"""Issue 93's bars, measured: a simulated TurtleBot's bag (300 s, /scan 5 Hz of 360 beams with 10 mm noise,
/joint_states 30 Hz, /odom from the nominal wheels, a URDF mount a few centimetres and degrees off) through
the user's route (`convert bag` then `learn em DIR`, as the app functions they call), scored against the
simulator's truth, beside Censi, Franchi, Marchionni and Oriolo's closed form (2013) on the same scans
(consecutive pairs, as their tool matches them); and the rover's two runs (ticks, a 240-degree Hokuyo at
10 Hz 15 cm ahead, 70 s each) compared with each other.

    python benchmarks/lidar2d_vs_censi.py [--seeds 1 2 3 4 5] [--format mcap|ros1] [--rover-seeds 21 22]

Prints each run's errors (ours and Censi et al.'s, in mm, per cent and degrees), the error in its own sd, the
range noise ratio and the time of convert + learn; writes ``results/lidar2d_vs_censi.json``.
"""

from __future__ import annotations

import argparse
import json
import math
import tempfile
import time
from pathlib import Path

import numpy as np

from sensact.app.lidar2d import calibrate_lidar2d, convert_lidar_bag
from sensact.io.lidar2d_folder import read_lidar2d_log, write_lidar2d_log
from sensact.io.rosbag import bag_topics, open_bag
from sensact.io.rosbag_lidar2d import lidar_roles
from sensact.io.rosbag_write import write_lidar_bag
from sensact.learn.wheel_lidar import PARAMETERS
from sensact.sim.lidar2d import Lidar2DConfig, simulate_lidar2d

ROVER = {
    "seconds": 70.0,
    "beams": 682,
    "fov_deg": 240.0,
    "scan_hz": 10.0,
    "mount": (150.0, 0.0, 0.0),
    "urdf_mount": (130.0, 10.0, 0.03),
    "encoder_positions": "ticks",
    "ticks_per_rev": 2000,
    "range_max_mm": 5600.0,
}


def truth_vector(cfg: Lidar2DConfig) -> np.ndarray:
    t = cfg.truth()
    m = t["lidar"]["mount"]
    d = t["drive"]
    return np.array(
        [
            d["wheel_radius_left_mm"],
            d["wheel_radius_right_mm"],
            d["axle_mm"],
            m["forward_mm"],
            m["left_mm"],
            m["yaw_rad"],
        ]
    )


def errors(est: np.ndarray, truth: np.ndarray) -> dict:
    e = est[:6] - truth
    return {
        "radius_left_pct": 100 * e[0] / truth[0],
        "radius_right_pct": 100 * e[1] / truth[1],
        "axle_pct": 100 * e[2] / truth[2],
        "forward_mm": e[3],
        "left_mm": e[4],
        "yaw_deg": math.degrees(e[5]),
    }


BAR = {
    "radius_left_pct": 0.3,
    "radius_right_pct": 0.3,
    "axle_pct": 0.5,
    "forward_mm": 10,
    "left_mm": 10,
    "yaw_deg": 0.5,
}


def turtlebot(seed: int, fmt: str, root: Path) -> dict:
    cfg = Lidar2DConfig(seed=seed)
    run = simulate_lidar2d(cfg)
    bag = root / (f"tb{seed}.bag" if fmt == "ros1" else f"tb{seed}")
    write_lidar_bag(bag, fmt, run)
    t0 = time.perf_counter()
    reader = open_bag(bag)
    try:
        topics = bag_topics(reader)
        convert_lidar_bag(bag, root / f"log{seed}", reader, topics, lidar_roles(bag, topics, {}))
    finally:
        reader.close()
    cal = calibrate_lidar2d(read_lidar2d_log(root / f"log{seed}"))
    seconds = time.perf_counter() - t0
    truth = truth_vector(cfg)
    fit = cal.result.fit
    ours, censi = errors(fit.params, truth), errors(cal.result.closed_form, truth)
    return {
        "seed": seed,
        "scans": int(run.scan_t.size),
        "ours": ours,
        "censi": censi,
        "ours_in_bars": sum(abs(v) / BAR[k] for k, v in ours.items()),
        "censi_in_bars": sum(abs(v) / BAR[k] for k, v in censi.items()),
        "error_in_sd": dict(zip(PARAMETERS[:6], ((fit.params[:6] - truth) / fit.sd[:6]).tolist(), strict=True)),
        "range_sigma_ratio": cal.result.range.sigma_mm / cfg.range_sd_mm,
        "range_sigma_error_in_sd": (cal.result.range.sigma_mm - cfg.range_sd_mm) / cal.result.range.sd_mm,
        "within_bars": all(abs(v) <= BAR[k] for k, v in ours.items()),
        "seconds_convert_and_learn": seconds,
        "flags": [f.code for f in cal.health.flags],
    }


def rover(seeds: list[int], root: Path) -> dict:
    fits = []
    for seed in seeds:
        cfg = Lidar2DConfig(seed=seed, **ROVER)
        run = simulate_lidar2d(cfg)
        write_lidar2d_log(root / f"rover{seed}", run.log(str(root / f"rover{seed}")), run.tables())
        cal = calibrate_lidar2d(read_lidar2d_log(root / f"rover{seed}"))
        fits.append((cal.result.fit.params[:5], cal.result.fit.sd[:5], [f.code for f in cal.health.flags]))
    (a, sa, fa), (b, sb, fb) = fits
    diff_sd = (a - b) / np.hypot(sa, sb)
    share = np.abs(a - b) / np.abs(np.where(np.arange(5) < 3, a, 150.0))
    return {
        "seeds": seeds,
        "params": [a.tolist(), b.tolist()],
        "sd": [sa.tolist(), sb.tolist()],
        "difference_in_sd": dict(zip(PARAMETERS[:5], diff_sd.tolist(), strict=True)),
        "difference_share": dict(zip(PARAMETERS[:5], share.tolist(), strict=True)),
        "flags": [fa, fb],
    }


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3, 4, 5])
    ap.add_argument("--format", default="mcap", choices=("mcap", "ros1", "sqlite3"))
    ap.add_argument("--rover-seeds", type=int, nargs=2, default=[21, 22])
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        runs = []
        for seed in args.seeds:
            r = turtlebot(seed, args.format, root)
            runs.append(r)
            o, c = r["ours"], r["censi"]
            print(
                f"seed {seed}: ours "
                + ", ".join(f"{k} {v:+.3f}" for k, v in o.items())
                + f" ({r['ours_in_bars']:.2f} bars)\n        censi "
                + ", ".join(f"{k} {v:+.3f}" for k, v in c.items())
                + f" ({r['censi_in_bars']:.2f} bars)\n        error/sd "
                + ", ".join(f"{v:+.2f}" for v in r["error_in_sd"].values())
                + f"; range sigma x{r['range_sigma_ratio']:.3f} ({r['range_sigma_error_in_sd']:+.2f} sd); "
                f"{r['seconds_convert_and_learn']:.1f} s for {r['scans']} scans; within bars: {r['within_bars']}"
            )
        rv = rover(args.rover_seeds, root)
        print("rover: difference in sd " + ", ".join(f"{k} {v:+.2f}" for k, v in rv["difference_in_sd"].items()))
        print("rover: difference share " + ", ".join(f"{k} {100 * v:.2f} %" for k, v in rv["difference_share"].items()))
    out = Path("results") / "lidar2d_vs_censi.json"
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps({"format": args.format, "turtlebot": runs, "rover": rv}, indent=1))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
