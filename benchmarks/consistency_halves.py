"""Issue 94's consistency bar, measured on the run we have: a model learned on the first half of MRCLAM
Dataset 6's robot k, run on the second half as `evaluate log` runs it on another run (placed by the E-step
with the model held, under the settings it was learned with), its one-step-ahead innovations scored against
its predictive law and its placed path against the Vicon poses.

The bar is checked on another dataset's run of the same robot, which is not in ../shared/data; the second
half is the nearest stand-in (another stretch of the room, another start, the model never saw it).

    SENSACT_DATA=../shared/data python benchmarks/consistency_halves.py [--robots 1 2 3 4 5] [--set K=V ...]

Prints, per robot, the share of ranges and bearings inside the model's 90 % interval and their NIS mean,
on the half it was learned on and on the other, and the placed path's median distance from the truth;
writes ``results/consistency_halves.json``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from sensact.app import calibrate
from sensact.app.logs import OpenedLandmarkLog, data_root, open_landmark_log
from sensact.app.monitor import after_step
from sensact.evaluate.landmark_truth import path_offset
from sensact.io.atomic import write_text
from sensact.learn.em.uses.consistency import consistency
from sensact.learn.em.uses.place import localize

CLI = "import sys; from sensact.cli import main; sys.argv[0] = 'sensact'; main()"
BAR = (0.85, 0.95)
PATH_BAR_MM = 80.0


def _before_step(log: OpenedLandmarkLog, step: int) -> OpenedLandmarkLog:
    data = log.data.slice_steps(0, step)
    folder = log.folder
    gt = folder.groundtruth
    cut = None if gt is None else {k: np.asarray(v)[:step] for k, v in gt.items()}
    return replace(log, data=data, folder=replace(folder, data=data, groundtruth=cut))


def robot(k: int, root: Path, scratch: Path, sets: list[str]) -> dict:
    folder = scratch / f"robot{k}"  # the user's `convert mrclam`, into a folder of its own
    argv = ["convert", "mrclam", str(root / "mrclam" / "MRCLAM_Dataset6"), "--robot", str(k), "--out", str(folder)]
    subprocess.run([sys.executable, "-c", CLI, *argv], check=True, stdout=subprocess.DEVNULL)
    log = open_landmark_log(folder)
    half = log.data.n_steps // 2
    first, second = _before_step(log, half), after_step(log, half)
    t0 = time.perf_counter()
    cal = calibrate(first, sets=sets)
    placed = localize(cal.model, second.data, cal.config)
    out = consistency(placed.model, second.data)
    path = path_offset(placed.posteriors.mean_gamma, *second.folder.truth_poses())
    return {
        "robot": k,
        "learned_on": cal.consistency.to_dict(),
        "next_half": out.to_dict(),
        "path_median_mm": path["median_mm"],
        "seconds": time.perf_counter() - t0,
        "within_bar": all(BAR[0] <= r.coverage90 <= BAR[1] for r in out.readings.values())
        and path["median_mm"] <= PATH_BAR_MM,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robots", type=int, nargs="+", default=[1, 2, 3, 4, 5])
    ap.add_argument("--set", action="append", default=[], help="a learn em setting, as `learn em --set`")
    args = ap.parse_args()
    root = data_root()
    rows = []
    with tempfile.TemporaryDirectory() as d:
        for k in args.robots:
            r = robot(k, root, Path(d), args.set)
            rows.append(r)
            nxt, own = r["next_half"], r["learned_on"]
            print(
                f"robot {k}: next half range {nxt['range']['coverage90']:.3f} (NIS {nxt['range']['nis_mean']:.2f}), "
                f"bearing {nxt['bearing']['coverage90']:.3f} (NIS {nxt['bearing']['nis_mean']:.2f}); learned-on half "
                f"range {own['range']['coverage90']:.3f}, bearing {own['bearing']['coverage90']:.3f}; path median "
                f"{r['path_median_mm']:.1f} mm; {'within' if r['within_bar'] else 'OUTSIDE'} the bars "
                f"({r['seconds']:.0f} s)",
                flush=True,
            )
    out = Path("results") / "consistency_halves.json"
    out.parent.mkdir(exist_ok=True)
    write_text(out, json.dumps({"bar": BAR, "path_bar_mm": PATH_BAR_MM, "robots": rows}, indent=1) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
