"""EM on MRCLAM Dataset 6 with fewer landmarks: does each robot still find itself, and do the bars hold?

    python benchmarks/em_real_landmarks.py [--maps 8:2 6:0 6:1] [--robots 1 2 3 4 5] [--turn-restarts N]
                                           [--start-from-robot N]

Each map ``K:S`` keeps K of the dataset's 15 landmarks, drawn by ``numpy.random.default_rng(S)``
without replacement; a scratch copy of the dataset (links to its files, ``Landmark_Groundtruth.dat``
cut to the kept landmarks) is read as `sensact reproduce real` reads it, so the sightings of the
other landmarks are dropped as unknown barcodes. Runs `reproduce real`'s EM (``mrclam_config()``)
on each robot and prints, per robot, the sightings kept, how far the smoothed path is from Vicon
(median), the restarts (``turn_restarts``, 2 by default, 0 none: each run's start sigma and
log-likelihood, the kept one marked), the kept fit's mean fall of the likelihood after its best per
sighting used (``fall/sighting``; learn/em/checks/lost_signs.py calls a fit unsettled over 0.1), the
log-likelihood and which bars failed; then each map's bars cleared. With ``--start-from-robot N``, robot
N learns first, from the poor start, and every other robot from N's model (``learn em --start-from``:
learn/em/uses/warm_start.py), as a fleet on that map would.
Needs ../shared/data/mrclam (or $SENSACT_DATA). About 1.5 minutes a map on 2 cores.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from sensact.errors import LogFormatError
from sensact.experiments.real import evaluate_mrclam, mrclam_folder, run_mrclam_robot
from sensact.io.mrclam import MrclamLog, read_mrclam
from sensact.learn.em import EMConfig, EMResult, fit_em
from sensact.learn.em.result import fall_per_sighting
from sensact.learn.em.uses.warm_start import start_from_model
from sensact.models.em_model import EMModel
from sensact.presets import mrclam_config
from sensact.report.tables_real import kept_run_cell, restart_runs_cell

LANDMARK_FILE = "Landmark_Groundtruth.dat"


def landmark_ids(path: Path) -> list[int]:
    return [int(line.split()[0]) for line in path.read_text().splitlines() if line.strip() and not line.startswith("#")]


def cut_copy(dataset: Path, keep: list[int], dest: Path) -> Path:
    """``dest/<dataset name>``: links to every file of ``dataset`` but the landmark file, which keeps the
    comment lines and the rows of ``keep``."""
    out = dest / dataset.name
    out.mkdir(parents=True)
    for f in dataset.iterdir():
        if f.name != LANDMARK_FILE:
            (out / f.name).symlink_to(f.resolve())
    lines = (dataset / LANDMARK_FILE).read_text().splitlines()
    kept = [ln for ln in lines if ln.startswith("#") or not ln.strip() or int(ln.split()[0]) in keep]
    (out / LANDMARK_FILE).write_text("\n".join(kept) + "\n")
    return out


def parse_map(text: str) -> tuple[int, int]:
    try:
        keep, seed = (int(v) for v in text.split(":"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: give a map as KEEP:SEED, e.g. 6:1") from None
    if keep < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: keep at least one landmark")
    return keep, seed


def run_from_model(dataset: Path, robot: int, model: EMModel, cfg: EMConfig) -> tuple[dict, MrclamLog, EMResult]:
    """``run_mrclam_robot``'s row, score and fit for ``robot`` learned from ``model`` (placed first)."""
    ml = read_mrclam(dataset, robot)
    placed, warm = start_from_model(model, ml.data, cfg)
    res = fit_em(ml.data, placed.model, warm)
    return {"score": evaluate_mrclam(ml, res)}, ml, res


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--maps",
        type=parse_map,
        nargs="+",
        default=[(8, 2), (6, 0), (6, 1)],
        help="maps as KEEP:SEED: keep KEEP of the 15 landmarks, drawn with that seed (default 8:2 6:0 6:1)",
    )
    parser.add_argument("--robots", type=int, nargs="+", default=[1, 2, 3, 4, 5], help="MRCLAM robots (default all)")
    parser.add_argument("--turn-restarts", type=int, default=None, help="restarts of a lost fit (default 2)")
    parser.add_argument(
        "--start-from-robot",
        type=int,
        default=None,
        help="learn this robot first, from the poor start, and the others from its model (default: each from the "
        "poor start)",
    )
    args = parser.parse_args()
    folder = mrclam_folder()
    if not folder.is_dir():
        sys.exit(f"MRCLAM data not found at {folder}; set SENSACT_DATA")
    ids = landmark_ids(folder / LANDMARK_FILE)
    cfg = mrclam_config()
    if args.turn_restarts is not None:
        cfg = cfg.replace(turn_restarts=args.turn_restarts)
    source = args.start_from_robot
    robots = args.robots if source is None else [source, *(r for r in args.robots if r != source)]
    for keep, seed in args.maps:
        if keep > len(ids):
            sys.exit(f"map {keep}:{seed}: the dataset has {len(ids)} landmarks")
        kept = sorted(int(i) for i in np.random.default_rng(seed).choice(ids, keep, replace=False))
        print(f"map {keep}:{seed}: landmarks {', '.join(map(str, kept))}", flush=True)
        print(
            "robot  sightings  path off Vicon mm  fall/sighting  log-likelihood  seconds  bars failed  "
            "restarts (start sigma: log-likelihood)"
        )
        cleared = total = 0
        with tempfile.TemporaryDirectory() as tmp:
            copy = cut_copy(folder, kept, Path(tmp))
            learned = None
            for robot in robots:
                t0 = time.perf_counter()
                try:
                    if learned is not None and robot != source:
                        row, ml, res = run_from_model(copy, robot, learned, cfg)
                    else:
                        row, ml, res = run_mrclam_robot(copy, robot, cfg)
                except LogFormatError as exc:  # e.g. a robot that sees none of the kept landmarks
                    print(f"{robot:5d}  not run: {exc}", flush=True)
                    continue
                if robot == source:
                    learned = res.model
                bars = row["score"]["bars"]
                failed = [k for k, ok in bars.items() if not ok]
                cleared += sum(bool(ok) for ok in bars.values())
                total += len(bars)
                runs = "-"
                if res.restarts:
                    runs = f"{restart_runs_cell(res.restarts)}; kept {kept_run_cell(res.restarts)}"
                per = fall_per_sighting(res.loglik_history, res.best_iteration, res.n_used)
                settle = "-" if per is None else f"{per:.4f}"
                print(
                    f"{robot:5d} {ml.data.n_observations:10d} {row['score']['path']['median_mm']:18.0f} "
                    f"{settle:>14s} {res.loglik_best:15.1f} {time.perf_counter() - t0:8.1f}  "
                    f"{', '.join(failed) or 'none':11s}  {runs}",
                    flush=True,
                )
        after = "" if source is None else f" (robots other than {source} learned from its model)"
        print(f"map {keep}:{seed}: bars {cleared} of {total} cleared{after}", flush=True)


if __name__ == "__main__":
    main()
