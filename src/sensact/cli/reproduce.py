"""``sensact reproduce``: the thesis's experiments and the real-data runs, each writing
RESULTS/<experiment>.json, a Markdown table and figures, and RESULTS/index.html over all of them."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from sensact.app.settings import merged, split_fields
from sensact.cli.base import (
    ConfigOpt,
    SchedulerOpt,
    SetOpt,
    WorkersOpt,
    app,
    console,
    friendly,
    print_verdict,
    progress_bar,
    write_results,
)
from sensact.errors import SensactError

EXPERIMENTS = ("track1d", "turtlebot", "field2d", "em1d", "monitor", "car", "diffdrive", "real")
# run only when named: long checks of what sensact adds to the thesis (about 20 minutes on two workers)
OPT_IN = ("uncertainty",)


def _data_dir(data: Path | None) -> Path:
    from sensact.app.logs import data_root

    return data if data is not None else data_root()


@app.command()
@friendly
def reproduce(
    experiment: Annotated[
        str | None,
        typer.Argument(
            help=f"One of {', '.join(EXPERIMENTS + OPT_IN)}; default: all but {', '.join(OPT_IN)} (run when named)."
        ),
    ] = None,
    out: Annotated[Path, typer.Option("--out", help="Results folder.")] = Path("results"),
    trials: Annotated[
        int | None,
        typer.Option(
            help="Trials: per Table 3.1 row (default 15), field2d seeds (default 5), monitor's sec. 4.4.3 seeds "
            "(default 5), diffdrive seeds (default 3) or uncertainty's simulated logs (default 20)."
        ),
    ] = None,
    seed: Annotated[int, typer.Option(help="Seed of the first trial.")] = 0,
    data: Annotated[
        Path | None, typer.Option(help="Real-data folder (default $SENSACT_DATA or ../shared/data).")
    ] = None,
    set_: SetOpt = None,
    config: ConfigOpt = None,
    truth_restart: Annotated[
        bool,
        typer.Option(
            "--truth-restart",
            help="real: also run each MRCLAM robot's EM again from the truth's range function and start pose "
            "(a local-optimum check; about doubles the time).",
        ),
    ] = False,
    workers: WorkersOpt = 1,
    scheduler: SchedulerOpt = None,
) -> None:
    """Run the thesis's experiments and write RESULTS/<experiment>.json, tables and figures.

    RESULTS/index.html then shows every table and figure in the folder on one page. With --workers N (or
    --scheduler), the trials, seeds and robots run on a Dask cluster, with the same results."""
    from sensact.errors import ConfigError

    if experiment is not None and experiment not in EXPERIMENTS + OPT_IN:
        raise ConfigError(
            f"unknown experiment {experiment!r}.",
            field="EXPERIMENT",
            fix=f"choose one of {', '.join(EXPERIMENTS + OPT_IN)}, or none for all but {', '.join(OPT_IN)}.",
        )
    if trials is not None and trials < 1:
        raise ConfigError(f"--trials {trials} runs nothing.", field="--trials", fix="give 1 or more.")
    from sensact.limits import MAX_TRIALS

    if trials is not None and trials > MAX_TRIALS:
        raise ConfigError(
            f"--trials {trials:,} is over the limit of {MAX_TRIALS:,} (SENSACT_MAX_TRIALS raises it).",
            field="--trials",
            fix="give fewer trials; a table's rows are usually 15.",
        )
    todo = [experiment] if experiment else list(EXPERIMENTS)
    from sensact.engine import open_engine

    with open_engine(workers, scheduler) as engine:
        if engine.workers > 1 or scheduler is not None:
            console.print(f"trials, seeds and robots on {engine.where}")
        _run_experiments(todo, experiment, out, trials, seed, data, set_, config, truth_restart, engine)
    from sensact.report.html_report import folder_scorecards, write_html_report

    cards = folder_scorecards(out)
    if len(cards) > 1:
        console.print(f"every experiment in {out}:")
        for name, _, checks in cards:
            print_verdict(f"  {name}", checks)
    page = write_html_report(out)
    if page is not None:
        console.print(f"wrote {page}: every table and figure in {out} on one page")


# each experiment's minutes with the default trials on this project's two-core machine, measured with
# `sensact reproduce` on 2026-11-29 (track1d's with the first compile of the kernels, turtlebot's and real's
# with ../shared/data; uncertainty's from docs/uncertainty.md): the ETA's weights, scaled by this run's pace
EXPECTED_MIN = {
    "track1d": 0.17,
    "turtlebot": 0.02,
    "field2d": 0.6,
    "em1d": 0.75,
    "monitor": 3.3,
    "car": 1.3,
    "diffdrive": 0.83,
    "uncertainty": 17.0,
    "real": 1.9,
}


class Overall:
    """One line as each of several experiments starts: which of how many, the time so far and an ETA, the
    remaining experiments' expected times scaled by how this machine's pace compares with them so far."""

    def __init__(self, todo: list[str]) -> None:
        import time

        self.todo, self.done, self.t0, self.clock = todo, [], time.perf_counter(), time.perf_counter

    def start(self, name: str) -> None:
        if len(self.todo) < 2 or name not in self.todo:
            return
        elapsed = self.clock() - self.t0
        expected_done = sum(EXPECTED_MIN[n] for n in self.done)
        pace = elapsed / 60 / expected_done if expected_done > 0 else 1.0
        left = pace * sum(EXPECTED_MIN[n] for n in self.todo[len(self.done) :])
        console.print(
            f"[bold]experiment {len(self.done) + 1} of {len(self.todo)}: {name}[/] "
            f"({_minutes(elapsed / 60)} elapsed, about {_minutes(left)} left)",
            highlight=False,
        )
        self.done.append(name)


def _minutes(m: float) -> str:
    return f"{m * 60:.0f} s" if m < 1 else f"{m:.0f} min"


def _run_experiments(
    todo: list[str],
    experiment: str | None,
    out: Path,
    trials: int | None,
    seed: int,
    data: Path | None,
    set_: list[str] | None,
    config: Path | None,
    truth_restart: bool,
    engine: Any,
) -> None:
    from sensact.experiments.shared_data import turtlebot_logs

    root = _data_dir(data)
    skipped = {"turtlebot": not turtlebot_logs(root), "real": not root.is_dir()}  # said as each is reached
    overall = Overall([n for n in todo if not skipped.get(n)])
    if "track1d" in todo:
        overall.start("track1d")
        _reproduce_track1d(out, trials or 15, seed, set_, config, engine)
    if "turtlebot" in todo:
        overall.start("turtlebot")
        from sensact.experiments.shared_data import turtlebot_logs

        root = _data_dir(data)
        folder, logs = root / "turtlebot1d", turtlebot_logs(root)
        if not logs:
            if experiment == "turtlebot":
                raise SensactError(
                    "no Turtlebot training log (training*.csv) found.",
                    file=folder,
                    fix="pass --data DIR (the folder holding turtlebot1d/) or set SENSACT_DATA.",
                )
            console.print(f"skipping turtlebot: no training*.csv in {folder} (pass --data DIR to include it)")
        else:
            _reproduce_turtlebot(out, logs)
    if "field2d" in todo:
        overall.start("field2d")
        _reproduce_field2d(out, trials or 5, seed, set_, config, engine)
    if "em1d" in todo:
        overall.start("em1d")
        _reproduce_em1d(out, seed, set_, config)
    if "monitor" in todo:
        overall.start("monitor")
        _reproduce_monitor(out, trials or 5, seed, _data_dir(data), set_, config, engine)
    if "car" in todo:
        overall.start("car")
        _reproduce_car(out, seed, set_, config)
    if "diffdrive" in todo:
        overall.start("diffdrive")
        _reproduce_diffdrive(out, trials or 3, seed, set_, config, engine)
    if "uncertainty" in todo:
        overall.start("uncertainty")
        _reproduce_uncertainty(out, trials or 20, seed, engine)
    if "real" in todo:
        overall.start("real")
        _reproduce_real(out, _data_dir(data), experiment == "real", set_, config, truth_restart, engine)


def _reproduce_real(
    out: Path,
    root: Path,
    required: bool,
    set_: list[str] | None,
    config: Path | None,
    truth_restart: bool = False,
    engine: Any = None,
) -> None:
    """MRCLAM's EM settings are ``mrclam_config()``, changed by the EM fields of ``--config``/``--set``
    (e.g. ``--set motion_noise=turning``); the Turtlebot's are fixed. ``truth_restart``: see
    ``experiments.real.restart_from_truth``."""
    from sensact.errors import ConfigError
    from sensact.experiments.real import run_real
    from sensact.learn.em import EMConfig
    from sensact.presets import mrclam_config
    from sensact.report import figures_real
    from sensact.report.tables_real import real_tables

    learner_f, other = split_fields(set_, config, EMConfig)
    if required and other:
        raise ConfigError(
            f"{', '.join(sorted(other))} is not an EM setting.",
            field="--set/--config",
            fix="give fields of the EM config (docs/em-real.md), e.g. --set motion_noise=turning.",
        )
    cfg = merged(EMConfig, mrclam_config(), learner_f)

    if not root.is_dir():
        if required:
            raise SensactError(
                "real-data folder not found.", file=root, fix="pass --data DIR (holding mrclam/ and turtlebot1d/)."
            )
        console.print(f"skipping real: {root} not found (pass --data DIR to include it)")
        return
    with console.status("EM on real robots") as status:
        res, art = run_real(
            root,
            progress=lambda msg: status.update(f"EM on real robots: {msg}"),
            config=cfg,
            truth_restart=truth_restart,
            engine=engine,
        )
    for line in res["skipped"]:
        console.print(f"skipped {line}")
    write_results(out, "real", res, real_tables(res))
    figures_real.write_all(art, res, out)


def _reproduce_diffdrive(
    out: Path, trials: int, seed: int, set_: list[str] | None, config: Path | None, engine: Any = None
) -> None:
    """MRCLAM's EM settings on simulated differential drives; ``--set`` reaches both the learner and the
    simulator (``sim.diffdrive.DiffDriveConfig``), whichever has the field."""
    from sensact.experiments.diffdrive import DiffDriveExperiment, run_diffdrive
    from sensact.learn.em import EMConfig
    from sensact.report import figures_real
    from sensact.report.tables_real import diffdrive_tables
    from sensact.sim.diffdrive import DiffDriveConfig

    learner_f, sim_f = split_fields(set_, config, EMConfig)
    simulator = merged(DiffDriveConfig, DiffDriveConfig(), sim_f)
    # the settings `simulate diffdrive` writes for the commands logged (wheel speeds, a side-stepper's)
    learner = merged(EMConfig, DiffDriveExperiment(simulator=simulator).learner_config, learner_f)
    exp = DiffDriveExperiment(trials=trials, seed=seed, simulator=simulator, learner=learner)
    with progress_bar() as progress:
        res, art = run_diffdrive(exp, progress, engine)
    write_results(out, "diffdrive", res, diffdrive_tables(res))
    robots = art["robots"]
    key, (robot, first) = next(iter(robots.items()))
    figures_real.write_robot(
        robot,
        first.model,
        res["seeds"][key]["score"],
        out / f"diffdrive_{key}",
        f"simulated {key}",
        first.posteriors,
        truth="simulated truth",
    )
    figures_real.figure_loglik({f"simulated {k}": r for k, (_, r) in robots.items()}, out / "diffdrive_loglik.png")
    console.print(
        f"wrote {out / 'diffdrive.json'}, {out / 'diffdrive.md'} and figures in {out} ({res['seconds']:.1f} s)"
    )


def _reproduce_monitor(
    out: Path, seeds: int, seed: int, root: Path, set_: list[str] | None, config: Path | None, engine: Any
) -> None:
    """`sensact monitor` on sec. 4.4.3's slowdown (``seeds`` runs, with and without it) and on each MRCLAM
    Dataset 6 robot with its own model, when the data folder holds them (experiments/monitor.py). --set and
    --config give the monitor's fields (docs/monitor.md)."""
    from sensact.experiments.monitor import MonitorExperiment, run_monitor_experiment
    from sensact.experiments.real import mrclam_folder
    from sensact.learn.em.uses.change_detect import MonitorConfig
    from sensact.report.figures_monitor import figure_monitor

    fields, _ = split_fields(set_, config, MonitorConfig)
    exp = MonitorExperiment(seeds=seeds, seed=seed, monitor=merged(MonitorConfig, MonitorConfig(), fields))
    folder = mrclam_folder(root)
    mrclam = folder if (folder / "Robot1_Odometry.dat").is_file() else None
    if mrclam is None:
        console.print(f"monitor: no MRCLAM Dataset 6 in {folder}; the real robots are left out (pass --data DIR)")
    with progress_bar() as progress:
        res, art = run_monitor_experiment(exp, mrclam, progress, engine)
    rows = [
        [
            str(r["seed"]),
            "none" if r["change"] is None else f"{r['change']['stream']} at {r['change']['alarm_s']:.0f} s",
            "-" if r["delay_s"] is None else f"{r['delay_s']:.0f} s",
            "none" if r["without_change"] is None else f"at {r['without_change']['alarm_s']:.0f} s",
            "-" if "relearned_on_after" not in r else f"{r['relearned_on_after']['action_rms_mm_s']:.1f} mm/s",
            "-" if "stale_on_after" not in r else f"{r['stale_on_after']['action_rms_mm_s']:.1f} mm/s",
        ]
        for r in res["track"]
    ]
    tables = [
        (
            f"sec. 4.4.3: the robot slows to 3/4 at {res['track'][0]['true_change_s']:.0f} s (flag within "
            f"{res['within_s']:.0f} s)",
            ["seed", "change flagged", "after the true change", "without the change", "relearned", "stale"],
            rows,
        )
    ]
    if res["planar"]:
        tables.append(
            (
                "a simulated differential drive learned on one run; another run slows to 3/4 (no bar)",
                ["learned on", "monitored", "change flagged", "after the true change", "without the change"],
                [
                    [
                        f"seed {r['learned_on_seed']}",
                        f"seed {r['monitored_seed']}, from {r['true_change_s']:.0f} s",
                        "none" if r["change"] is None else f"{r['change']['stream']} at {r['change']['alarm_s']:.0f} s",
                        "-" if r["delay_s"] is None else f"{r['delay_s']:.0f} s",
                        "none" if r["without_change"] is None else f"at {r['without_change']['alarm_s']:.0f} s",
                    ]
                    for r in res["planar"]
                ],
            )
        )
    if res["mrclam"]:
        tables.append(
            (
                "each MRCLAM Dataset 6 robot's own model over its own log (no alarm)",
                ["robot", "change", "episodes that did not persist"],
                [
                    [
                        k,
                        "none" if r["change"] is None else f"{r['change']['stream']} at {r['change']['alarm_s']:.0f} s",
                        str(r["episodes"]),
                    ]
                    for k, r in res["mrclam"].items()
                ],
            )
        )
    write_results(out, "monitor", res, tables)
    fig = figure_monitor(
        art["first"],
        out / "monitor_sec4_4_3.png",
        "sec. 4.4.3: the robot slows to 3/4 (first seed)",
        art["true_change_s"],
    )
    console.print(f"wrote {out / 'monitor.json'}, {out / 'monitor.md'} and {fig} ({res['seconds']:.1f} s)")


def _reproduce_uncertainty(out: Path, sims: int, seed: int, engine: Any) -> None:
    """`--uncertainty`'s 90 % intervals checked for calibration (experiments/coverage.py): ``sims`` logs
    drawn from a known model, each learned and given error bars both ways (the likelihood's; a bootstrap of
    20 replicates)."""
    from sensact.experiments.coverage import CoverageExperiment, run_coverage

    with progress_bar() as progress:
        res = run_coverage(CoverageExperiment(sims=sims, seed=seed), progress, engine)
    rows = [
        [method, family, str(c["covered"]), str(c["intervals"]), f"{100 * c['share']:.1f} %"]
        for method, m in res["methods"].items()
        for family, c in m["coverage"].items()
        if c["intervals"]
    ]
    title = (
        f"90 % intervals holding the truth over {res['sims']} simulated logs ({res['replicates']} bootstrap "
        f"replicates each; bar 85-95 %, Sigma_m's 85-97 %); chosen by coverage: {res['chosen']}"
    )
    write_results(out, "uncertainty", res, [(title, ["method", "family", "covered", "intervals", "share"], rows)])
    console.print(f"wrote {out / 'uncertainty.json'} and {out / 'uncertainty.md'} ({res['seconds']:.1f} s)")


def _reproduce_car(out: Path, seed: int, set_: list[str] | None, config: Path | None) -> None:
    import numpy as np

    from sensact.experiments.velodyne_car import CarExperiment, run_car
    from sensact.learn.velodyne_car_dynamics import CarLearningConfig
    from sensact.report import figures_velodyne_car
    from sensact.report.tables import car_tables
    from sensact.sim.velodyne_car import CarConfig

    learner_f, sim_f = split_fields(set_, config, CarLearningConfig)
    base = CarExperiment()
    exp = CarExperiment(
        simulator=merged(CarConfig, base.simulator, {**sim_f, "seed": seed}),
        learner=merged(CarLearningConfig, base.learner, learner_f),
    )
    with progress_bar() as progress:
        res, art = run_car(exp, out / "car_log", progress)
    write_results(out, "car", res, car_tables(res))
    log, r = art["log"], art["result"]
    figures_velodyne_car.figure_5_2(log, r.intrinsics.relative_rad, 40.0, 0.5, out / "fig5_2_scans.png")
    figures_velodyne_car.figure_5_3(
        r.laser_angles_rad,
        np.asarray(log.meta["truth"]["laser_angles_rad"]),
        log.vertical_rad,
        out / "fig5_3_laser_angles.png",
    )
    K = len(r.actions) - 1
    pred = r.model.predict(r.actions[:K], r.speed_m_s[0], exp.learner.odometry.dt_s)
    v, w, a = art["truth"]
    t = r.interval_times_s[:K]
    figures_velodyne_car.figure_5_4_5(t, (v[:K], w[:K], a[:K]), pred, out / "fig5_4_5_dynamics.png", (85.0, 110.0))
    console.print(
        f"wrote {out / 'car.json'}, {out / 'car.md'}, figures and the log in {out / 'car_log'} ({res['seconds']:.1f} s)"
    )


def _reproduce_field2d(
    out: Path, trials: int, seed: int, set_: list[str] | None, config: Path | None, engine: Any = None
) -> None:
    from sensact.config import config_from_dict
    from sensact.experiments.field2d import Field2DExperiment, run_field2d, velocity_rms_history
    from sensact.io.atomic import write_npz
    from sensact.learn.em import EMConfig
    from sensact.report import figures_em
    from sensact.report.tables import field2d_tables
    from sensact.sim.field2d import Field2DConfig

    base = Field2DExperiment()
    learner_f, sim_f = split_fields(set_, config, EMConfig)
    exp = Field2DExperiment(
        trials=trials,
        seed=seed,
        simulator=config_from_dict(Field2DConfig, sim_f, source="--set/--config"),
        learner=merged(EMConfig, base.learner, learner_f),
    )
    with progress_bar() as progress:
        res, art = run_field2d(exp, progress, engine)
    write_results(out, "field2d", res, field2d_tables(res))
    first = art["trials"][0]
    vr = velocity_rms_history(first)
    figures_em.figure_learning_curve(
        first, vr, out / "fig4_4_field2d_learning.png", f"simulation, seed {first.run.config.seed}", res["thesis"]
    )
    from sensact.learn.em.initial import starting_height

    f0 = starting_height(first.result.config)
    figures_em.figure_sensor(
        f0,
        first.result.model.sensor.height,
        first.run.config.height_px,
        out / "fig4_5_field2d_sensor.png",
        "sensor model f (simulation)",
    )
    arrays = {"loglik": first.result.loglik_history, "velocity_rms": vr}
    if "real" in art:
        real = art["real"]
        figures_em.figure_learning_curve(real, None, out / "fig4_2_real_robot_learning.png", "real-robot setting")
        figures_em.figure_sensor(
            f0,
            real.result.model.sensor.height,
            real.run.config.height_px,
            out / "fig4_3_real_robot_sensor.png",
            "sensor model f (real-robot setting)",
        )
        arrays["real_loglik"] = real.result.loglik_history
    write_npz(out / "field2d_curves.npz", **arrays)
    console.print(f"wrote {out / 'field2d.json'}, {out / 'field2d.md'} and figures in {out} ({res['seconds']:.1f} s)")


def _reproduce_em1d(out: Path, seed: int, set_: list[str] | None, config: Path | None) -> None:
    from sensact.experiments.em1d import EM1D_TRACK, EM1DExperiment, run_em1d
    from sensact.learn.em import EMConfig
    from sensact.report import figures_em
    from sensact.report.tables import em1d_tables
    from sensact.sim.track1d import Track1DConfig

    base = EM1DExperiment()
    learner_f, sim_f = split_fields(set_, config, EMConfig)
    exp = EM1DExperiment(
        seed=seed,
        simulator=merged(Track1DConfig, EM1D_TRACK, sim_f),
        learner=merged(EMConfig, base.learner, learner_f),
    )
    with progress_bar() as progress:
        res, art = run_em1d(exp, progress)
    write_results(out, "em1d", res, em1d_tables(res))
    sim = art["simulator"]
    levels = sim.levels_mm_s() / sim.command_max_mm_s
    h = art["halves"]
    figures_em.figure_track(
        h["before"].result.model,
        h["before"].true_velocities,
        sim.truth().height_px,
        levels,
        out / "fig4_6_em1d_learned.png",
        "before the change",
    )
    figures_em.figure_track(
        h["after"].result.model,
        h["after"].true_velocities,
        sim.truth().height_px,
        levels,
        out / "fig4_7_em1d_relearned.png",
        "after the change",
        stale=h["before"].result.model,
    )
    console.print(f"wrote {out / 'em1d.json'}, {out / 'em1d.md'} and figures in {out} ({res['seconds']:.1f} s)")


def _reproduce_track1d(
    out: Path, trials: int, seed: int, set_: list[str] | None, config: Path | None, engine: Any = None
) -> None:
    from sensact.config import config_from_dict
    from sensact.experiments.track1d import Track1DExperiment, run_track1d
    from sensact.io.atomic import write_npz
    from sensact.learn.bootstrap import BootstrapConfig
    from sensact.report import figures1d
    from sensact.report.tables import track1d_tables
    from sensact.sim.track1d import Track1DConfig

    learner_fields, sim_fields = split_fields(set_, config, BootstrapConfig)
    exp = Track1DExperiment(
        trials=trials,
        degree_trials=trials,
        seed=seed,
        learner=config_from_dict(BootstrapConfig, learner_fields, source="--set/--config"),
        simulator=config_from_dict(Track1DConfig, sim_fields, source="--set/--config"),
    )
    with progress_bar() as progress:
        res, art = run_track1d(exp, progress, engine)
    write_results(out, "track1d", res, track1d_tables(res))
    linear = art["trials"].get("linear") or next(iter(art["trials"].values()))
    figures1d.figure_3_7(linear[0], out / "fig3_7_location_estimates.png")
    figures1d.figure_3_8(linear[0], out / "fig3_8_learned_vs_measured.png")
    first = next(iter(res["rows"].values()))
    figures1d.figure_3_9(
        art["curves"],
        {"sensor": first["sensor_best_rms_mm"], "action": first["action_best_rms_mm_s"]},
        out / "fig3_9_learning_curves.png",
    )
    figures1d.figure_degree(art["degree_trials"], out / "fig_degree_selection.png")
    write_npz(
        out / "track1d_curves.npz",
        **{
            f"{row}_{name}": arr
            for row, c in art["curves"].items()
            for name, arr in zip(("t_s", "sensor_rms_mm", "action_rms_mm_s"), c, strict=True)
        },
    )
    console.print(f"wrote {out / 'track1d.json'}, {out / 'track1d.md'} and figures in {out} ({res['seconds']:.1f} s)")


def _reproduce_turtlebot(out: Path, logs: list[Path]) -> None:
    """Algorithm 1 on every training log: turtlebot.json and turtlebot_models.png for the first (the
    issue's training1.csv), ``more_logs`` and ``turtlebot_models_<stem>.png`` for the others."""
    from sensact.experiments.turtlebot import run_turtlebot_logs
    from sensact.report.figures1d import figure_real
    from sensact.report.tables import turtlebot_tables

    with console.status("Algorithm 1 on the Turtlebot") as status:
        res, runs = run_turtlebot_logs(logs, progress=status.update)
    for one in (res, *res.get("more_logs", {}).values()):
        if one["skipped_sensors"]:
            console.print(f"{one['file']} has no column {', '.join(one['skipped_sensors'])}: run without them")
    for line in res["skipped_logs"]:
        console.print(f"not run: {line}", markup=False)
    write_results(out, "turtlebot", res, turtlebot_tables(res))
    written = [out / "turtlebot.json", out / "turtlebot.md"]
    for i, (stem, by_sensor) in enumerate(runs.items()):
        name = "turtlebot_models.png" if i == 0 else f"turtlebot_models_{stem}.png"
        written.append(figure_real(by_sensor, out / name))
    console.print(f"wrote {', '.join(str(p) for p in written[:-1])} and {written[-1]}", markup=False)
