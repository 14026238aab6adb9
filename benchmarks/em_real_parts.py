"""EM from the poor start on parts of real logs: does it still find the robot when the log is short?

    python benchmarks/em_real_parts.py [--parts 4] [--robots 1 2 3 4 5] [--range-start-sigma MM]
                                       [--turn-restarts N]

Cuts each robot's MRCLAM Dataset 6 log (about 15 minutes) into ``--parts`` equal spans of steps and
runs `sensact reproduce real`'s EM on each alone, from the same poor start. Prints, per part, how far
the smoothed path is from Vicon (median), whether the learned range function turns over or bends within
its fitted distances or EM did not settle (learn/em/checks/lost_signs.py, the signs a user sees without ground
truth; ``fall/sighting``: how far the kept fit's likelihood fell on average after its best, per
sighting used, unsettled over 0.1), how many times EM started again because of them
(``turn_restarts``, 2 by default) and which run was kept, the log-likelihood and the time; then how
many parts lost the robot (median over 500 mm). ``--parts 1`` runs the whole logs.
``--range-start-sigma`` replaces the range channel's start sigma (100 mm by default) and
``--turn-restarts`` the number of restarts (0: none); docs/em-real.md "Short logs".
Needs ../shared/data/mrclam (or $SENSACT_DATA). About 3 minutes for 20 quarters on 2 cores.
"""

from __future__ import annotations

import argparse
import itertools
import sys
import time
from dataclasses import replace

import numpy as np

from sensact.evaluate.landmark_truth import path_offset
from sensact.experiments.real import mrclam_folder
from sensact.io.mrclam import read_mrclam
from sensact.learn.em import fit_em
from sensact.learn.em.checks.lost_signs import lost_fit_signs
from sensact.learn.em.result import fall_per_sighting
from sensact.presets import mrclam_config

LOST_MM = 500.0  # a path this far from Vicon (median) has lost the robot: a start-search cell


def _kinds(signs: list) -> str:
    """What the kept fit showed: ``turns``, ``bends``, ``unsettled``, those joined by ``+``, or ``no``."""
    kinds = {t.sign for t in signs}
    return "+".join(k for k in ("turns", "bends", "unsettled") if k in kinds) or "no"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--parts", type=int, default=4, help="equal spans to cut each log into")
    parser.add_argument("--robots", type=int, nargs="+", default=[1, 2, 3, 4, 5], help="MRCLAM robots (default all)")
    parser.add_argument("--range-start-sigma", type=float, default=None, help="the range start sigma, mm (default 100)")
    parser.add_argument("--turn-restarts", type=int, default=None, help="restarts of a lost fit (default 2)")
    args = parser.parse_args()
    folder = mrclam_folder()
    if not folder.is_dir():
        sys.exit(f"MRCLAM data not found at {folder}; set SENSACT_DATA")
    cfg = mrclam_config()
    if args.range_start_sigma is not None:
        cfg = replace(cfg, channels=(replace(cfg.channels[0], start_sigma=args.range_start_sigma),))
    if args.turn_restarts is not None:
        cfg = cfg.replace(turn_restarts=args.turn_restarts)
    print(
        f"range channel start sigma {cfg.channels[0].start_sigma:g} mm; at most {cfg.search.turn_restarts} restarts "
        f"while f turns or bends or EM does not settle; {args.parts} parts per robot"
    )
    print(
        "robot part  steps  sightings  path off Vicon mm        lost sign  fall/sighting  restarts (kept)  "
        "log-likelihood  iterations  seconds"
    )
    lost = total = 0
    for robot in args.robots:
        ml = read_mrclam(folder, robot)
        poses, valid = ml.truth_poses()
        edges = np.linspace(0, ml.data.n_steps, args.parts + 1).round().astype(int)
        for k, (a, b) in enumerate(itertools.pairwise(edges)):
            part = ml.data.slice_steps(int(a), int(b))
            t0 = time.perf_counter()
            res = fit_em(part, None, cfg)
            seconds = time.perf_counter() - t0
            off = path_offset(res.posteriors.mean_gamma, poses[a:b], valid[a:b])["median_mm"]
            turns = lost_fit_signs(res.model, res.posteriors, part, res.loglik_history, res.best_iteration)
            per = fall_per_sighting(res.loglik_history, res.best_iteration, res.n_used)
            settle = "-" if per is None else f"{per:.4f}"
            runs = res.restarts or []
            restarted = f"{len(runs) - 1} ({next(i for i, r in enumerate(runs) if r.kept)})" if runs else "0"
            lost += off > LOST_MM
            total += 1
            print(
                f"{robot:5d} {k + 1:4d} {part.n_steps:6d} {part.n_observations:10d} {off:18.0f}  "
                f"{_kinds(turns):>15s} {settle:>14s} {restarted:>16s} {res.loglik_best:15.1f} {res.iterations:11d} "
                f"{seconds:8.1f}",
                flush=True,
            )
    print(f"lost the robot (path over {LOST_MM:g} mm from Vicon): {lost} of {total} parts")


if __name__ == "__main__":
    main()
