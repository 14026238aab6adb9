"""EM on real robots (beyond the thesis): MRCLAM (Dataset 6 here; every dataset under the data folder's
``mrclam/``), all five robots, and the Turtlebot in 1-D.

MRCLAM settings are the choices a user makes for a differential-drive robot with a range-and-bearing
camera, not fits to Dataset 6:

* an affine action model in (v, omega) with a learned command delay of up to 0.5 s, and no sideways
  mean velocity (a differential drive cannot side-step);
* learned shared Sigma_m, starting from 3 mm and 0.01 rad per 1/30 s step (the thesis's 10 mm and
  0.1 rad let the smoother explain range noise as motion on this data), held for the first 100
  iterations (``refine_from``);
* a range channel with two bearing terms (a camera reads range from apparent size, distorted away from
  the image centre: the range error about the truth is 90 % a function of the bearing);
* a poor straight-line start for the range function (0.6 d + 500 mm, sigma 1 m), Student-t range and
  bearing (4 degrees of freedom: the dataset has gross outliers; Gaussian until ``refine_from``), and
  the start-pose search over the first 30 s with its race of 6 candidates on the whole log.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from sensact.app.logs import data_root
from sensact.config import config_to_dict
from sensact.engine import Engine, InProcess, Job
from sensact.errors import LogFormatError
from sensact.evaluate.bars import BARS, BarCheck, bar_checks, robot_checks  # the real-data bars
from sensact.evaluate.landmark_truth import path_offset, score_against_truth
from sensact.experiments.shared_data import turtlebot_logs
from sensact.io.mrclam import MrclamLog, read_mrclam
from sensact.learn.em import EMConfig, EMResult, fit_em
from sensact.models.em_model import EMModel
from sensact.models.polynomial import Polynomial1D
from sensact.presets import mrclam_config
from sensact.records import JsonObject

ROBOTS = (1, 2, 3, 4, 5)


def mrclam_folder(root: Path | None = None) -> Path:
    return (root or data_root()) / "mrclam" / "MRCLAM_Dataset6"


def mrclam_datasets(root: Path) -> list[Path]:
    """Every MRCLAM dataset folder under ``root/mrclam`` (one holding ``Robot1_Odometry.dat``), in
    order, so that the same command runs on whichever datasets a data folder holds."""
    base = root / "mrclam"
    if not base.is_dir():
        return []
    return sorted(d for d in base.iterdir() if d.is_dir() and (d / "Robot1_Odometry.dat").is_file())


def mrclam_row_key(dataset: Path, robot: int, several: bool) -> str:
    """``robotN`` when one dataset is run (real.json's keys for Dataset 6 alone), else ``<dataset>/robotN``."""
    return f"{dataset.name}/robot{robot}" if several else f"robot{robot}"


def evaluate_mrclam(ml: MrclamLog | Any, res: EMResult) -> JsonObject:
    """``score_against_truth`` with the smoothed path's offset and the bars, for any log with ``data`` and
    ``truth_poses()``: an MRCLAM robot against Vicon, or a simulated one (experiments/diffdrive.py)."""
    poses, valid = ml.truth_poses()
    sc = score_against_truth(res.model, ml.data, poses, valid)
    sc["path"] = path_offset(res.posteriors.mean_gamma, poses, valid)
    sc["bars"] = bar_checks(sc)
    return sc


def scorecard(summary: JsonObject) -> list[BarCheck]:
    """Issue 5's bars on ``real.json``: every MRCLAM robot's, then each Turtlebot log's."""
    from sensact.evaluate.turtlebot_em import scorecard as turtlebot_scorecard

    checks = [c for key, row in summary["mrclam"].items() for c in robot_checks(row["score"], key)]
    if "turtlebot" in summary:
        checks += turtlebot_scorecard(summary["turtlebot"])
    for name, more in summary.get("turtlebot_more_logs", {}).items():
        checks += turtlebot_scorecard(more, name)
    return checks


# how far the truth-informed restart's start may be from the truth's first pose
RESTART_PRIOR_SD = (50.0, 50.0, 0.05)


def truth_informed_start(
    model: EMModel, range_from_truth: JsonObject, start_pose: np.ndarray, prior_sd: tuple = RESTART_PRIOR_SD
) -> EMModel:
    """``model`` with its range function and bearing terms replaced by From-Truth's and its prior on the
    truth's start pose: EM's own answer moved into the truth's basin, where it only differs in what a
    poor start could have got wrong (the range function's constant trades with a path shifted along
    the camera's view, ``path_offset``)."""
    ch = model.sensor.channels[0]
    f = Polynomial1D.from_dict(range_from_truth["from_truth_function"], source="From-Truth")
    terms = tuple(range_from_truth["from_truth_bearing_terms"])
    rest = [(c.function, c.sigma, c.bearing_terms) for c in model.sensor.channels[1:]]
    sensor = model.sensor.with_fits([(f, ch.sigma, terms), *rest], model.sensor.sigma_bearing_rad)
    return model.replace(
        sensor=sensor, prior_mean=np.asarray(start_pose, dtype=float), prior_cov=np.diag(np.square(prior_sd))
    )


def restart_from_truth(ml: MrclamLog, res: EMResult, score: JsonObject, config: EMConfig) -> JsonObject:
    """A diagnostic that needs the truth: EM again from ``truth_informed_start``, nothing held. If it
    ends at a higher likelihood than the run from the poor start, that run stopped in a local optimum,
    and its scores are those of the wrong basin. The prior (on step 0) is Vicon's first valid pose,
    whose step is recorded as ``truth_start_step``: 0 on every robot of Dataset 6."""
    poses, valid = ml.truth_poses()
    first = int(np.flatnonzero(valid)[0])
    start = truth_informed_start(res.model, score["range"], poses[first])
    cfg = config.replace(start_search_s=None, refine_from=0)
    again = fit_em(ml.data, start, cfg)
    sc = evaluate_mrclam(ml, again)
    return {
        "truth_start_step": first,
        "loglik_best": again.loglik_best,
        "loglik_poor_start": res.loglik_best,
        "sightings_used": int(again.posteriors.obs_used.sum()),
        "sightings_used_poor_start": int(res.posteriors.obs_used.sum()),
        "em": again.summary(),
        "score": sc,
    }


def run_mrclam_robot(
    folder: Path,
    robot: int,
    config: EMConfig | None = None,
    progress: Callable | None = None,
    truth_restart: bool = False,
    on_race: Callable[[int, int], None] | None = None,
) -> tuple[JsonObject, MrclamLog, EMResult]:
    """EM on one robot from the poor start, scored against Vicon; with ``truth_restart`` also
    ``restart_from_truth`` (row ``truth_restart``). ``progress`` and ``on_race`` are ``fit_em``'s."""
    cfg = config or mrclam_config()
    ml = read_mrclam(folder, robot)
    res = fit_em(ml.data, None, cfg, on_iteration=progress, on_race=on_race)
    row = {
        "summary_line": ml.summary_line(),
        "rows": ml.summary,
        "em": res.summary(),
        "learned": {
            "action": res.model.action.to_dict(),
            "motion_sd": res.model.motion_sd.tolist(),
            "turn_var": res.model.turn_var,
            "range_sigma_mm": res.model.sensor.channels[0].sigma,
            "bearing_sigma_rad": res.model.sensor.sigma_bearing_rad,
        },
        "score": evaluate_mrclam(ml, res),
    }
    if truth_restart:
        row["truth_restart"] = restart_from_truth(ml, res, row["score"], cfg)
    return row, ml, res


def fleet_of_dataset(folder: Path, runs: JsonObject, several: bool, config: EMConfig) -> JsonObject | None:
    """Each robot's learned model of one dataset scored on every robot's log of it, against Vicon and by
    the likelihood with each model placed by the E-step alone under ``config``, the settings it was learned
    with (``fleet.score_fleet``; docs/em-real.md, "One robot's model on another robot"), or None
    with fewer than two robots."""
    from sensact.app.fleet import score_fleet

    keys = [k for k in runs if not several or k.startswith(f"{folder.name}/")]
    if len(keys) < 2:
        return None
    name = {k: k.rsplit("/", 1)[-1] for k in keys}
    return score_fleet(
        {name[k]: runs[k][1].model for k in keys},
        {name[k]: runs[k][0] for k in keys},
        {name[k]: name[k] for k in keys},
        configs={name[k]: config for k in keys},
    )


def robot_job(
    folder: Path, robot: int, config: EMConfig, truth_restart: bool, key: str, *, progress: Any = None
) -> tuple[JsonObject | str, MrclamLog | None, EMResult | None]:
    """``run_mrclam_robot`` as a job of an engine, saying where it is as it goes (a robot's fit takes 20-40 s
    on Dataset 6: the race, then each iteration); a log that cannot be learned is its line, ``(why, None,
    None)``."""
    label = f"MRCLAM {key}" + (" (and its restart from the truth)" if truth_restart else "")
    if progress:
        progress(label, 0, None)

    def on_iteration(it: int, ll: float, best: float, since: int) -> None:
        if progress:
            progress(f"{label}: EM iteration {it}, best log-likelihood {best:.1f}", it + 1, None)

    def on_race(done: int, planned: int) -> None:
        if progress:
            progress(f"{label}: start race, trial {done} of at most {planned}", done, planned)

    try:
        return run_mrclam_robot(folder, robot, config, on_iteration, truth_restart=truth_restart, on_race=on_race)
    except LogFormatError as exc:
        return str(exc), None, None


def run_real(
    root: Path | None = None,
    robots: tuple[int, ...] = ROBOTS,
    progress: Callable[[str], None] | None = None,
    config: EMConfig | None = None,
    truth_restart: bool = False,
    engine: Engine | None = None,
) -> tuple[JsonObject, JsonObject]:
    """Every robot of every MRCLAM dataset under ``root/mrclam`` (Dataset 6 here; with ``config``,
    default ``mrclam_config()``) and every Turtlebot training log (``turtlebot_logs``); skips what is
    missing. ``truth_restart`` adds ``restart_from_truth`` per robot. Rows are keyed ``robotN``, or
    ``<dataset>/robotN`` when the folder holds more than one dataset. The robots are jobs of ``engine``
    (``sensact.engine``; here, one after another, by default)."""
    from sensact.experiments.turtlebot_em import run_turtlebot_em

    t0 = time.perf_counter()
    root = root or data_root()
    out: JsonObject = {"experiment": "real", "data": str(root), "bars": BARS, "mrclam": {}, "skipped": []}
    artifacts: JsonObject = {"mrclam": {}}
    datasets = mrclam_datasets(root)
    if datasets:
        cfg = config or mrclam_config()
        out["mrclam_config"] = config_to_dict(cfg)
        out["mrclam_datasets"] = [str(d) for d in datasets]
        runs = [
            (folder, robot, mrclam_row_key(folder, robot, len(datasets) > 1)) for folder in datasets for robot in robots
        ]
        missing = [(f, r, k) for f, r, k in runs if not (f / f"Robot{r}_Odometry.dat").is_file()]
        for folder, robot, key in missing:
            out["skipped"].append(f"MRCLAM {key}: {folder / f'Robot{robot}_Odometry.dat'} not found")
        runs = [run for run in runs if run not in missing]
        jobs = [Job(robot_job, (folder, robot, cfg, truth_restart, key), key) for folder, robot, key in runs]
        status = None if progress is None else (lambda i, desc, done, total: progress(desc))
        done = (engine or InProcess()).run(jobs, on_progress=status)
        for (folder, _, key), (row, ml, res) in zip(runs, done, strict=True):
            if isinstance(row, str):  # this robot's log (e.g. no landmark sightings), not the settings
                out["skipped"].append(f"MRCLAM {key}: {row}")
                continue
            out["mrclam"][key] = {"dataset": folder.name, **row}
            artifacts["mrclam"][key] = (ml, res)
        for folder in datasets:
            if progress:
                progress(f"MRCLAM {folder.name}: each robot's model on every robot's log")
            fleet = fleet_of_dataset(folder, artifacts["mrclam"], len(datasets) > 1, cfg)
            if fleet is not None:
                out.setdefault("fleet", {})[folder.name] = fleet
    else:
        out["skipped"].append(f"MRCLAM: no dataset folder (one holding Robot1_Odometry.dat) in {root / 'mrclam'}")
    from sensact.experiments.turtlebot import run_turtlebot

    # the first log run is real.json's "turtlebot" (the training1.csv); any others, each with the
    # same bars, go under "turtlebot_more_logs" by file stem
    for tb in turtlebot_logs(root):
        if progress:
            progress(f"Turtlebot EM on {tb.name}")
        try:
            summary, run = run_turtlebot_em(tb)
        except LogFormatError as exc:  # this log (e.g. no range to score against), not the settings
            out["skipped"].append(f"Turtlebot {tb.name}: {exc}")
            continue
        ch3, _ = run_turtlebot(tb, ("sonar1",))
        summary["chapter3_sonar1"] = ch3["rows"]["sonar1"]
        if "turtlebot" not in out:
            out["turtlebot"], artifacts["turtlebot"] = summary, run
        else:
            out.setdefault("turtlebot_more_logs", {})[tb.stem] = summary
            artifacts.setdefault("turtlebot_more_logs", {})[tb.stem] = run
    if "turtlebot" not in out:
        out["skipped"].append(f"Turtlebot: no training*.csv in {root / 'turtlebot1d'}")
    out["scorecard"] = [c.to_dict() for c in scorecard(out)]
    out["seconds"] = time.perf_counter() - t0
    return out, artifacts
