"""Issue 94's acceleration bar: `learn em` on each MRCLAM Dataset 6 robot with `--set accelerate=true`
and plain on the same map (`--set pose_draws=sigma_points`), in the same process, one after the other;
the ratios of their E-steps and seconds, and the difference of their best log-likelihoods.

    SENSACT_DATA=../shared/data python benchmarks/squarem_speed.py [--robots 1 2 3 4 5] [--thesis]

Both fits run the same deterministic map, so they are after the same fixed point. ``--thesis`` adds a
third fit, ``--set accelerate=false``: the thesis's EM (one pose drawn per sighting), whose best likelihood
is the best of a noisy walk that stops by patience, and compares the accelerated fit's time, path and range
sigma with it. Writes ``results/squarem_speed.json``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from sensact.app import calibrate
from sensact.app.logs import data_root, open_landmark_log
from sensact.io.atomic import write_text

CLI = "import sys; from sensact.cli import main; sys.argv[0] = 'sensact'; main()"
RUNS = {"accelerated": ["accelerate=true"], "plain": ["pose_draws=sigma_points"], "thesis": ["accelerate=false"]}


def fit(folder: Path, sets: list[str]) -> dict:
    cal = calibrate(open_landmark_log(folder), sets=sets)
    s, m = cal.result.summary(), cal.model
    return {
        "seconds": s["seconds"],
        "e_steps": s["e_steps"],
        "forward_passes": s["forward_passes"],
        "iterations": s["iterations"],
        "loglik_best": s["loglik_best"],
        "accelerated_steps": s["accelerated_steps"],
        "stopped_because": s["stopped_because"],
        "path_median_mm": ((cal.scores.evaluation or {}).get("path") or {}).get("median_mm"),
        "action": np.asarray(m.action.parameters).ravel().tolist(),
        "sigma": [c.sigma for c in m.sensor.channels] + [m.sensor.sigma_bearing_rad],
        "motion_sd": m.motion_sd.ravel().tolist(),
        "mount": m.sensor.mount.as_array().tolist(),
    }


def robot(k: int, root: Path, scratch: Path, runs: list[str]) -> dict:
    folder = scratch / f"robot{k}"
    argv = ["convert", "mrclam", str(root / "mrclam" / "MRCLAM_Dataset6"), "--robot", str(k), "--out", str(folder)]
    subprocess.run([sys.executable, "-c", CLI, *argv], check=True, stdout=subprocess.DEVNULL)
    fits = {name: fit(folder, RUNS[name]) for name in runs}
    fast, plain = fits["accelerated"], fits["plain"]
    return {
        "robot": k,
        "fits": fits,
        "e_steps_ratio": fast["e_steps"] / plain["e_steps"],
        "seconds_ratio": fast["seconds"] / plain["seconds"],
        "loglik_gain": fast["loglik_best"] - plain["loglik_best"],
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robots", type=int, nargs="+", default=[1, 2, 3, 4, 5])
    ap.add_argument("--thesis", action="store_true", help="also the thesis's EM (random draws, plain)")
    args = ap.parse_args()
    runs = ["plain", "accelerated"] + (["thesis"] if args.thesis else [])
    rows = []
    with tempfile.TemporaryDirectory() as d:
        for k in args.robots:
            row = robot(k, data_root(), Path(d), runs)
            rows.append(row)
            line = (
                f"robot {k}: E-steps {row['fits']['accelerated']['e_steps']} / {row['fits']['plain']['e_steps']} "
                f"= {row['e_steps_ratio']:.2f}x, seconds {row['fits']['accelerated']['seconds']:.1f} / "
                f"{row['fits']['plain']['seconds']:.1f} = {row['seconds_ratio']:.2f}x, "
                f"log-likelihood {row['loglik_gain']:+.2f}"
            )
            if args.thesis:
                th, fast = row["fits"]["thesis"], row["fits"]["accelerated"]
                line += (
                    f" (the thesis's EM: {th['loglik_best'] - row['fits']['plain']['loglik_best']:+.2f}); against the "
                    f"thesis's: seconds {fast['seconds']:.1f} / {th['seconds']:.1f}"
                    f" = {fast['seconds'] / th['seconds']:.2f}x,"
                    f" path median {fast['path_median_mm']:.1f} / {th['path_median_mm']:.1f} mm, range sigma "
                    f"{fast['sigma'][0]:.2f} / {th['sigma'][0]:.2f} mm, stopped by {fast['stopped_because']}"
                )
            print(line, flush=True)
    out = Path("results") / "squarem_speed.json"
    out.parent.mkdir(exist_ok=True)
    write_text(out, json.dumps({"robots": rows}, indent=1))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
