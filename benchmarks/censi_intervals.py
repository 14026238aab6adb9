"""Issue 107's Censi bars, measured on the authors' own data: their three sets (one Khepera III, the lidar
mounted three ways: ``l90``, ``lmov``, ``lstraight``), each whole and in its three thirds, through the user's
route (``sensact convert intervals FILE`` then ``sensact learn em DIR``), against the answer their tool
published beside the data (``X_results.json``: diameters and metres, and a covariance over the radii, the
axle and the lidar's pose).

    python benchmarks/censi_intervals.py REFERENCE_OUTPUT_DIR [--out results/censi_intervals.json]

REFERENCE_OUTPUT_DIR is ``reference-output/`` of github.com/AndreaCensi/calibration (the tuples and
results; nothing of it is kept here). Prints, per set and parameter, sensact's value and sd, the authors'
value and sd, the difference in the authors' sd, and the spread of the three thirds against sensact's sd
of a third; the geometric mean of those ratios is the second bar.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

SETS = ("l90", "lmov", "lstraight")
KEYS = (
    ("drive", "wheel_radius_left_mm"),
    ("drive", "wheel_radius_right_mm"),
    ("drive", "axle_mm"),
    ("lidar.mount", "forward_mm"),
    ("lidar.mount", "left_mm"),
    ("lidar.mount", "yaw_rad"),
)


def theirs(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """The authors' answer in sensact's units (mm, rad) and its sd, from their covariance (radii, axle, pose)."""
    r = json.loads(path.read_text())
    value = np.array(
        [r["l_diam"] / 2 * 1e3, r["r_diam"] / 2 * 1e3, r["axle"] * 1e3, r["l_x"] * 1e3, r["l_y"] * 1e3, r["l_theta"]]
    )
    sd = np.sqrt(np.diag(np.asarray(r["covariance"], dtype=float))) * np.array([1e3] * 5 + [1.0])
    return value, sd


def ours(tuples: Path, work: Path) -> tuple[np.ndarray, np.ndarray]:
    """sensact's answer and sd, through the two commands a user runs."""
    log, model = work / tuples.stem, work / f"{tuples.stem}.json"
    for args in (
        ["convert", "intervals", str(tuples), "--out", str(log)],
        ["learn", "em", str(log), "--out", str(model)],
    ):
        done = subprocess.run([sys.executable, "-m", "sensact", *args], capture_output=True, text=True)
        if done.returncode not in (0, 3):
            raise SystemExit(f"sensact {' '.join(args)} failed ({done.returncode}): {done.stderr.strip()}")
    m = json.loads(model.read_text())
    value, sd = [], []
    for group, key in KEYS:
        node = m
        for part in group.split("."):
            node = node[part]
        value.append(node[key])
        sd.append(node[f"{key}_sd"])
    return np.array(value), np.array(sd)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("reference", type=Path, help="reference-output/ of AndreaCensi/calibration")
    ap.add_argument("--out", type=Path, default=Path("results/censi_intervals.json"))
    args = ap.parse_args()
    rows, ratios = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for name in SETS:
            v, sd = ours(args.reference / f"{name}.tuple", Path(tmp))
            tv, tsd = theirs(args.reference / f"{name}_results.json")
            thirds = [ours(args.reference / f"{name}_{i}.tuple", Path(tmp)) for i in range(3)]
            spread = np.std([t[0] for t in thirds], axis=0, ddof=1)
            third_sd = np.sqrt(np.mean([t[1] ** 2 for t in thirds], axis=0))
            for k, (_, key) in enumerate(KEYS):
                row = {
                    "set": name,
                    "parameter": key,
                    "sensact": float(v[k]),
                    "sensact_sd": float(sd[k]),
                    "censi": float(tv[k]),
                    "censi_sd": float(tsd[k]),
                    "off_in_censi_sd": float(abs(v[k] - tv[k]) / tsd[k]),
                    "thirds_spread": float(spread[k]),
                    "thirds_sd": float(third_sd[k]),
                    "spread_over_sd": float(spread[k] / third_sd[k]),
                }
                rows.append(row)
                ratios.append(row["spread_over_sd"])
                print(
                    f"{name:9s} {key:22s} sensact {v[k]:10.4f} ± {sd[k]:.4f}  censi {tv[k]:10.4f} ± {tsd[k]:.4f}"
                    f"  off {row['off_in_censi_sd']:.2f} sd   thirds spread {spread[k]:.4f} / sd {third_sd[k]:.4f}"
                    f" = {row['spread_over_sd']:.2f}"
                )
    worst = max(r["off_in_censi_sd"] for r in rows)
    gmean = float(math.exp(np.mean(np.log(ratios))))
    print(f"worst difference: {worst:.2f} of the authors' sd (bar 1.5)")
    print(f"thirds' spread / sd, geometric mean {gmean:.2f} (bar 0.5-2)")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    summary = {"worst_off_in_censi_sd": worst, "spread_over_sd_geometric_mean": gmean}
    args.out.write_text(json.dumps({"rows": rows, **summary}, indent=1) + "\n")


if __name__ == "__main__":
    main()
