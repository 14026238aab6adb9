"""EM's bars through a ROS bag, in each format (issue 75's bar).

    python benchmarks/bag_route.py [--seconds 450] [--seed 1] [--out bag_route.json]

Simulates a differential drive whose camera sits 220 mm ahead and reads about five tags a frame at 10 Hz
(issue 73's conditions), writes it as a ROS 2 MCAP bag, a ROS 2 sqlite3 bag and a ROS 1 bag (/cmd_vel
Twists, the tags on /tf in the camera's optical frame, /tf_static, motion capture as a PoseStamped), and
runs on each exactly `sensact convert bag BAG --landmarks map.csv --out DIR`, `sensact learn em DIR --out
model.json` and `sensact export model.json --format tum`. Prints per format the bars cleared, the mount,
the path's median off the truth, and the TUM files' median distance (numpy, unaligned), and the seconds
each step took.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np
from typer.testing import CliRunner

from sensact.cli import app
from sensact.io.rosbag_write import FORMATS, recording_of, write_map_csv, write_robot_bag
from sensact.sim.diffdrive import DiffDriveConfig, simulate_diffdrive

ROBOT = dict(
    mounted_at=(220.0, 0.0, 0.0), frame_period_s=0.1, detect_probability=0.9, fov_deg=100.0, landmarks_per_side=7
)


def _run(args: list) -> float:
    t0 = time.perf_counter()
    res = CliRunner().invoke(app, [str(a) for a in args])
    if res.exit_code != 0:
        raise SystemExit(res.output)
    return time.perf_counter() - t0


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seconds", type=float, default=450.0)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--out", default=None, help="write the table as JSON here")
    args = p.parse_args()
    run = simulate_diffdrive(DiffDriveConfig(seconds=args.seconds, seed=args.seed, **ROBOT))
    rec = recording_of(run)
    table = {}
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        grid = write_map_csv(root / "map.csv", rec.map_xy_m)
        for fmt in FORMATS:
            bag = write_robot_bag(root / f"run_{fmt}", fmt, rec)
            log, model = root / f"log_{fmt}", root / f"model_{fmt}.json"
            seconds = {
                "convert": _run(["convert", "bag", bag, "--landmarks", grid, "--out", log]),
                "learn": _run(["learn", "em", log, "--out", model]),
                "export": _run(["export", model, "--format", "tum"]),
            }
            doc = json.loads(model.read_text())
            ev = doc["evaluation"]
            est, ref = np.loadtxt(model.with_suffix(".tum")), np.loadtxt(model.with_name(f"{model.stem}_truth.tum"))
            both = np.intersect1d(np.round(est[:, 0], 6), np.round(ref[:, 0], 6))
            e = est[np.isin(np.round(est[:, 0], 6), both)]
            r = ref[np.isin(np.round(ref[:, 0], 6), both)]
            mount = doc["model"]["sensor"]["mount"]
            table[fmt] = {
                "bars": ev["bars"],
                "cleared": f"{sum(ev['bars'].values())}/{len(ev['bars'])}",
                "mount_forward_mm": mount["forward_mm"],
                "path_median_mm": ev["path"]["median_mm"],
                "tum_median_mm": 1000 * float(np.median(np.linalg.norm(e[:, 1:3] - r[:, 1:3], axis=1))),
                "seconds": seconds,
            }
            row = table[fmt]
            print(
                f"{fmt:8s} bars {row['cleared']}, mount {row['mount_forward_mm']:.0f} mm forward (true 220), path "
                f"{row['path_median_mm']:.1f} mm, TUM files {row['tum_median_mm']:.1f} mm; convert "
                f"{seconds['convert']:.1f} s, learn {seconds['learn']:.1f} s, export {seconds['export']:.1f} s",
                flush=True,
            )
    if args.out:
        Path(args.out).write_text(json.dumps(table, indent=1))


if __name__ == "__main__":
    main()
