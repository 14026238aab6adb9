"""EM on real robots, in simulation: the MRCLAM settings (``experiments.real.mrclam_config``, or
``planar_config``'s for a side-stepper's commands) on simulated differential drives (``sim.diffdrive``)
whose true model is known, scored by the very code and bars that score the MRCLAM robots against Vicon
(docs/em-real.md). Where a real robot misses a bar, this says whether the learner would clear it on a robot
that is what its model families assume.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from sensact.config import config_to_dict
from sensact.engine import Engine, InProcess, Job, untagged
from sensact.evaluate.bars import BarCheck
from sensact.evaluate.simulated_robot import score_against_simulated
from sensact.experiments.real import evaluate_mrclam, robot_checks
from sensact.learn.em import EMConfig, EMResult, fit_em
from sensact.learn.em.progress import iteration_progress
from sensact.logs.landmark_log import LandmarkLog
from sensact.presets import simulator_settings
from sensact.progress import Progress
from sensact.records import JsonObject
from sensact.sim.diffdrive import DiffDriveConfig, simulate_diffdrive


@dataclass(frozen=True)
class DiffDriveExperiment:
    """``learner`` None: the settings ``sensact simulate diffdrive`` writes for the simulator's logged
    commands (``simulator_settings``)."""

    trials: int = 3
    seed: int = 0
    simulator: DiffDriveConfig = field(default_factory=DiffDriveConfig)
    learner: EMConfig | None = None

    @property
    def learner_config(self) -> EMConfig:
        return self.learner or simulator_settings(self.simulator)


@dataclass(frozen=True, eq=False)
class SimulatedRobot:
    """A simulated log with its true poses, read by the scorers and figures as a recorded log is."""

    data: LandmarkLog
    poses: np.ndarray

    def truth_poses(self) -> tuple[np.ndarray, np.ndarray]:
        return self.poses, np.ones(len(self.poses), dtype=bool)


def scorecard(summary: JsonObject) -> list[BarCheck]:
    """Issue 5's MRCLAM bars on every seed (``experiments.real.robot_checks``)."""
    return [c for key, row in summary["seeds"].items() for c in robot_checks(row["score"], key)]


def run_diffdrive(
    exp: DiffDriveExperiment | None = None, progress: Progress | None = None, engine: Engine | None = None
) -> tuple[JsonObject, JsonObject]:
    """Returns (``diffdrive.json`` content, artifacts for figures: ``robots`` {key: (SimulatedRobot, EMResult)}).
    Each seed is a job of ``engine`` (``sensact.engine``; here, one after another, by default)."""
    exp = exp or DiffDriveExperiment()
    t0 = time.perf_counter()
    sims = [replace(exp.simulator, seed=exp.seed + k) for k in range(exp.trials)]
    jobs = [Job(run_seed, (sim, exp.learner_config), f"seed{sim.seed}") for sim in sims]
    done = (engine or InProcess()).run(jobs, on_progress=untagged(progress))
    seeds = {f"seed{sim.seed}": row for sim, (row, _, _) in zip(sims, done, strict=True)}
    robots = {f"seed{sim.seed}": (robot, res) for sim, (_, robot, res) in zip(sims, done, strict=True)}
    out: JsonObject = {
        "experiment": "diffdrive",
        "seeds": seeds,
        "config": {"simulator": config_to_dict(exp.simulator), "learner": config_to_dict(exp.learner_config)},
        "seconds": time.perf_counter() - t0,
    }
    out["scorecard"] = [c.to_dict() for c in scorecard(out)]
    return out, {"robots": robots}


def run_seed(
    sim: DiffDriveConfig, learner: EMConfig, *, progress: Progress | None = None
) -> tuple[JsonObject, SimulatedRobot, EMResult]:
    """One seed of ``run_diffdrive``: the robot simulated, learned by EM and scored (its row of
    diffdrive.json), the robot and EM's result."""
    key = f"seed{sim.seed}"
    run = simulate_diffdrive(sim)
    robot = SimulatedRobot(run.log(f"simulated {sim.robot_kind}, seed {sim.seed}"), run.poses)

    on_iteration = iteration_progress(
        progress, lambda it, ll, best: f"diffdrive {key}: EM iteration {it}, log-likelihood {ll:.1f}", learner.thesis
    )

    def on_race(done: int, planned: int) -> None:
        if progress:
            progress(f"diffdrive {key}: start race", done, planned)

    res = fit_em(robot.data, None, learner, on_iteration=on_iteration, on_race=on_race)
    row = {
        "em": res.summary(),
        "score": evaluate_mrclam(robot, res),  # as a real robot is scored against Vicon
        "simulated": score_against_simulated(res.model, sim.truth(), sim.dt_s),
        "sightings": int(robot.data.n_observations),
        "misread": int(run.obs_misread.sum()),
    }
    return row, robot, res
