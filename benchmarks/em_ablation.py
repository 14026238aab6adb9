"""What each of EM's searches and restarts buys, now that the sensor's mount is modelled (issue 73).

    python benchmarks/em_ablation.py [--mrclam-robots 1 2 3 4 5] [--seconds 450] [--out ablation.json]

Runs each scenario with its full settings, then once with each heuristic turned off, and prints per run
the bars cleared (the real-data bars of ``evaluate.bars.robot_checks``, against the truth), the path's
median off the truth, the log-likelihood and the time. Scenarios: simulated differential drives (the
default camera robot, one whose camera sits 220 mm ahead and sees about five landmarks a frame at 10 Hz,
a robot that side-steps, a range-only robot with eight anchors) and MRCLAM Dataset 6's robots when
../shared/data (or $SENSACT_DATA) holds them. A heuristic that no scenario needs is one to drop.
"""

from __future__ import annotations

import argparse
import json
import time

from sensact.evaluate.bars import robot_checks
from sensact.experiments.diffdrive import SimulatedRobot
from sensact.experiments.real import evaluate_mrclam, mrclam_folder
from sensact.learn.em import EMConfig, fit_em
from sensact.presets import mrclam_config, simulator_settings
from sensact.sim.diffdrive import DiffDriveConfig, simulate_diffdrive

# each heuristic, and the settings that turn it off
OFF = {
    "start race": {"start_candidates": 1},
    "ridge search": {"ridge_search_mm": None},
    "delay search": {"delay_search": False},
    "turn restarts": {"turn_restarts": 0},
    "prune when freed": {"prune_when_freed": False},
}


def scenarios(seconds: float, robots: list[int]):
    sims = {
        "diffdrive": DiffDriveConfig(seconds=seconds, seed=0),
        "camera 220 mm ahead, 10 Hz": DiffDriveConfig(
            seconds=seconds,
            seed=1,
            mounted_at=(220.0, 0.0, 0.0),
            frame_period_s=0.1,
            detect_probability=0.9,
            fov_deg=100.0,
            landmarks_per_side=7,
        ),
        "side-stepper": DiffDriveConfig(seconds=seconds, seed=2, sidestep_mm_s=60.0),
        "range-only": DiffDriveConfig(seconds=seconds, seed=3, sensor="radio", landmarks_per_side=2),
    }
    for name, sim in sims.items():
        run = simulate_diffdrive(sim)
        yield name, SimulatedRobot(run.log(name), run.poses), simulator_settings(sim)
    folder = mrclam_folder()
    if folder.is_dir():
        from sensact.io.mrclam import read_mrclam

        for r in robots:
            yield f"MRCLAM robot {r}", read_mrclam(folder, r), mrclam_config()


def run_one(log, cfg: EMConfig) -> dict:
    t0 = time.perf_counter()
    res = fit_em(log.data, None, cfg)
    sc = evaluate_mrclam(log, res)
    checks = robot_checks(sc)
    return {
        "bars": f"{sum(c.cleared for c in checks)}/{len(checks)}",
        "missed": [c.key for c in checks if not c.cleared],
        "path_mm": sc["path"]["median_mm"],
        "loglik": res.loglik_best,
        "seconds": time.perf_counter() - t0,
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--mrclam-robots", type=int, nargs="*", default=[1, 2, 3, 4, 5])
    p.add_argument("--seconds", type=float, default=450.0, help="length of each simulated log")
    p.add_argument("--out", default=None, help="write the table as JSON here")
    args = p.parse_args()
    table = {}
    for name, log, cfg in scenarios(args.seconds, args.mrclam_robots):
        rows = {"full": run_one(log, cfg)}
        for heuristic, off in OFF.items():
            changed = cfg.replace(**off)  # EMConfig.replace takes the flat names
            rows[heuristic] = run_one(log, changed) if changed != cfg else None  # None: not in this scenario
        table[name] = rows
        for k, r in rows.items():
            line = (
                "not used"
                if r is None
                else (
                    f"bars {r['bars']}, path {r['path_mm']:.0f} mm, log-lik. {r['loglik']:.1f}, {r['seconds']:.0f} s"
                    + (f" (missed {', '.join(r['missed'])})" if r["missed"] else "")
                )
            )
            print(f"{name:28s} {k:17s} {line}", flush=True)
    if args.out:
        with open(args.out, "w") as f:
            json.dump(table, f, indent=1)


if __name__ == "__main__":
    main()
