"""Issue 92's bars, measured: a map-free fit beside the same fit with the map, in one process, through the
routes a user takes (`convert ... --no-map` then `learn em DIR`, as ``sensact.app.calibrate``).

    python benchmarks/map_free.py mrclam [--dataset DIR] [--robots 1 2 3 4 5]
    python benchmarks/map_free.py sim [--seconds 900] [--seeds 1 2]

``mrclam``: each robot converted twice (with the map, and with --no-map); ``sim``: `simulate diffdrive`
with its map hidden, as MRCLAM (range in mm, 30 Hz, 15 landmarks, a camera on the axle) and as the
held-out robot the issue names (camera 22 cm ahead of the axle, 10 Hz, 18 landmarks, ~5 a frame), each
with a metric range sensor (gain 1). Prints, per log: map RMS and placed, path median with and without
the map and their ratio, the action ratios and the range sigma ratio, and the time ratio; writes
``results/map_free_<what>.json``.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from sensact.app import calibrate, open_log
from sensact.io.landmark_folder import write_landmark_log

HELD_OUT = {
    "mounted_at": (220.0, 0.0, 0.0),
    "dt_s": 0.1,
    "frame_period_s": 0.1,
    "landmarks_per_side": 6,
    "fov_deg": 90.0,
    "detect_probability": 0.6,
}


def scored(folder: Path) -> tuple[dict, float]:
    t0 = time.perf_counter()
    cal = calibrate(open_log(folder))
    secs = time.perf_counter() - t0
    ev = cal.scores.evaluation if hasattr(cal.scores, "evaluation") else {}
    return ev, secs


def row(name: str, free: dict, fs: float, given: dict, gs: float) -> dict:
    m = free.get("map") or {}
    p_free, p_given = free["path"]["median_mm"], given["path"]["median_mm"]
    return {
        "log": name,
        "map_rms_mm": m.get("rms_mm"),
        "placed": f"{m.get('landmarks_placed')}/{m.get('landmarks_total')}",
        "seen_enough_not_placed": m.get("seen_enough_not_placed"),
        "map_scale": m.get("scale"),
        "path_median_mm": p_free,
        "path_median_with_map_mm": p_given,
        "path_ratio": p_free / p_given,
        # issue 106: the map-free path after a similarity alignment, against the surveyed fit's
        "path_similarity_median_mm": free["path"]["similarity"]["median_mm"],
        "path_similarity_ratio": free["path"]["similarity"]["median_mm"] / p_given,
        "ratio_translation": free["action"]["ratio_translation"],
        "ratio_rotation": free["action"]["ratio_rotation"],
        "range_sigma_ratio": free["range"]["sigma_ratio"],
        "seconds": fs,
        "seconds_with_map": gs,
        "time_ratio": fs / gs,
    }


def mrclam(dataset: Path, robots: list[int], work: Path) -> list[dict]:
    from sensact.io.mrclam import read_mrclam

    rows = []
    for r in robots:
        ml = read_mrclam(dataset, r)
        d = ml.data
        write_landmark_log(work / f"r{r}", d, groundtruth=ml.groundtruth)
        hidden = d.with_landmarks(np.full_like(d.landmarks_xy, np.nan))
        write_landmark_log(work / f"r{r}_free", hidden, groundtruth=ml.groundtruth, survey_xy=d.landmarks_xy)
        for folder in (work / f"r{r}", work / f"r{r}_free"):  # as `convert mrclam` names the preset
            (folder / "em_config.yaml").write_text("preset: differential_drive_camera\n")
        given, gs = scored(work / f"r{r}")
        free, fs = scored(work / f"r{r}_free")
        rows.append(row(f"{dataset.name} robot {r}", free, fs, given, gs))
        print(json.dumps(rows[-1]), flush=True)
    return rows


def sim(seconds: float, seeds: list[int], work: Path) -> list[dict]:
    from sensact.presets import settings_yaml, simulator_settings
    from sensact.sim.diffdrive import DiffDriveConfig, simulate_diffdrive

    rows = []
    for kind, extra in (("mrclam-like", {}), ("held-out-like", HELD_OUT)):
        for seed in seeds:
            cfg = DiffDriveConfig(seconds=seconds, seed=seed, range_gain=1.0, **extra)
            run = simulate_diffdrive(cfg)
            d = run.log()
            for name, log, survey in (
                ("given", d, None),
                ("free", d.with_landmarks(np.full_like(d.landmarks_xy, np.nan)), d.landmarks_xy),
            ):
                folder = work / f"{kind}_{seed}_{name}"
                write_landmark_log(
                    folder, log, groundtruth=run.groundtruth(), meta_extra={"truth": cfg.truth()}, survey_xy=survey
                )
                (folder / "em_config.yaml").write_text(
                    settings_yaml("differential_drive_camera", simulator_settings(cfg), log, "")
                )
            given, gs = scored(work / f"{kind}_{seed}_given")
            free, fs = scored(work / f"{kind}_{seed}_free")
            rows.append(row(f"{kind} seed {seed}", free, fs, given, gs))
            print(json.dumps(rows[-1]), flush=True)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("what", choices=("mrclam", "sim"))
    ap.add_argument("--dataset", type=Path, default=Path("../shared/data/mrclam/MRCLAM_Dataset6"))
    ap.add_argument("--robots", type=int, nargs="+", default=[1, 2, 3, 4, 5])
    ap.add_argument("--seconds", type=float, default=900.0)
    ap.add_argument("--seeds", type=int, nargs="+", default=[1])
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        rows = mrclam(a.dataset, a.robots, Path(tmp)) if a.what == "mrclam" else sim(a.seconds, a.seeds, Path(tmp))
    out = Path("results") / f"map_free_{a.what}.json"  # as `sensact reproduce` writes results/
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps(rows, indent=1) + "\n")
    keys = (
        "map_rms_mm",
        "map_scale",
        "path_median_mm",
        "path_median_with_map_mm",
        "path_ratio",
        "path_similarity_ratio",
        "ratio_translation",
        "ratio_rotation",
        "range_sigma_ratio",
        "time_ratio",
    )
    print("| log | placed | " + " | ".join(keys) + " |")
    for r in rows:
        print(f"| {r['log']} | {r['placed']} | " + " | ".join(f"{r[k]:.3g}" for k in keys) + " |")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
