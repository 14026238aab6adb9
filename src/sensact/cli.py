"""The ``sensact`` command. The only place that configures logging or draws progress bars.

Heavy modules (numba kernels, matplotlib) are imported inside the commands so that ``sensact --help``
stays instant.
"""

from __future__ import annotations

import functools
import logging
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated, Any, TypeVar

import typer
from rich.console import Console
from rich.table import Table

from sensact.errors import SensactError

app = typer.Typer(
    name="sensact",
    help="Learn a mobile robot's action and sensor models from its own logs, with no ground truth "
    "(Stronger 2008). Start with `sensact reproduce`; see docs/commands.md.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
simulate_app = typer.Typer(help="Write a simulated log folder (with its ground truth).", no_args_is_help=True)
learn_app = typer.Typer(help="Learn models from a log.", no_args_is_help=True)
app.add_typer(simulate_app, name="simulate")
app.add_typer(learn_app, name="learn")
convert_app = typer.Typer(help="Turn a dataset into a sensact log folder.", no_args_is_help=True)
evaluate_app = typer.Typer(help="Score a learned model against a dataset's ground truth.", no_args_is_help=True)
app.add_typer(convert_app, name="convert")
app.add_typer(evaluate_app, name="evaluate")

# rich falls back to 80 columns when output is not a terminal; the result tables need more
console = Console(width=None if sys.stdout.isatty() else 160)
err_console = Console(stderr=True, width=None if sys.stderr.isatty() else 160)
_state = {"debug": False}
F = TypeVar("F", bound=Callable[..., Any])

SetOpt = Annotated[
    list[str] | None, typer.Option("--set", help="Override a config field: --set name=value (repeatable).")
]
ConfigOpt = Annotated[Path | None, typer.Option("--config", help="YAML file of config fields.")]


def _friendly(fn: F) -> F:
    """Bad input becomes one line and exit code 2; ``--debug`` shows the traceback instead."""

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return fn(*args, **kwargs)
        except SensactError as exc:
            if _state["debug"]:
                raise
            err_console.print(f"[bold red]error:[/] {exc}", highlight=False, soft_wrap=True)
            raise typer.Exit(2) from None
        except KeyboardInterrupt:
            err_console.print("interrupted; files already written are complete (atomic writes).")
            raise typer.Exit(130) from None

    return wrapper  # type: ignore[return-value]


@app.callback()
def _main(
    debug: Annotated[bool, typer.Option("--debug", help="Show full tracebacks.")] = False,
    verbose: Annotated[bool, typer.Option("--verbose", "-v", help="Log library messages.")] = False,
) -> None:
    _state["debug"] = debug
    logging.basicConfig(level=logging.DEBUG if verbose else logging.WARNING, format="%(name)s: %(message)s")


@contextmanager
def _progress() -> Iterator[Callable[[str, int, int], None]]:
    """A rich progress bar fed by the library's ``progress(description, done, total)`` callbacks."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    tasks: dict[str, Any] = {}
    with Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=err_console,
        transient=False,
        disable=not err_console.is_terminal,
    ) as bar:

        def update(desc: str, done: int, total: int) -> None:
            if desc not in tasks:
                tasks[desc] = bar.add_task(desc, total=total)
            bar.update(tasks[desc], completed=done, total=total)

        yield update


def _print_tables(tables: list[tuple[str, list[str], list[list[str]]]]) -> None:
    for title, headers, rows in tables:
        t = Table(title=title, title_justify="left")
        for h in headers:
            t.add_column(h)
        for r in rows:
            t.add_row(*r)
        console.print(t)


def _write_results(out: Path, name: str, res: dict[str, Any], tables: list[Any]) -> None:
    """``out/<name>.json`` and ``out/<name>.md``, and the tables on the console."""
    from sensact.io.atomic import write_json, write_text
    from sensact.report.tables import to_markdown

    out.mkdir(parents=True, exist_ok=True)
    write_json(out / f"{name}.json", res)
    write_text(out / f"{name}.md", to_markdown(tables))
    _print_tables(tables)


def _config(cls: type, config: Path | None, sets: list[str] | None, base: Any = None, **flags: Any) -> Any:
    """``base`` or defaults < ``--config`` YAML < ``--set`` < explicit flags."""
    import dataclasses

    from sensact.config import build_config

    cfg = build_config(cls, config, sets or [], base=base)
    flags = {k: v for k, v in flags.items() if v is not None}
    return dataclasses.replace(cfg, **flags) if flags else cfg


# ---- simulate -------------------------------------------------------------------------------------------


@simulate_app.command("track1d")
@_friendly
def simulate_track1d(
    out: Annotated[Path, typer.Option("--out", help="Log folder to write.")],
    seconds: Annotated[float | None, typer.Option(help="Length of the log (default 150).")] = None,
    seed: Annotated[int | None, typer.Option(help="Random seed (default 0).")] = None,
    set_: SetOpt = None,
    config: ConfigOpt = None,
) -> None:
    """Simulate the chapter-3 Aibo walking toward and away from a beacon (sec. 3.3)."""
    from sensact.io.logfolder import write_log_folder
    from sensact.sim.track1d import Track1DConfig, log_tables, simulate_track

    cfg = _config(Track1DConfig, config, set_, seconds=seconds, seed=seed)
    run = simulate_track(cfg)
    write_log_folder(out, **log_tables(run))
    n_obs = int((run.heights_px == run.heights_px).sum())
    console.print(
        f"wrote {out}: {len(run.times_s)} steps, {n_obs} observations, "
        f"distance {run.distance_mm.min():.0f}-{run.distance_mm.max():.0f} mm (seed {cfg.seed})"
    )


@simulate_app.command("field2d")
@_friendly
def simulate_field2d(
    out: Annotated[Path, typer.Option("--out", help="Log folder to write.")],
    seconds: Annotated[float | None, typer.Option(help="Length of the log (default 900).")] = None,
    seed: Annotated[int | None, typer.Option(help="Random seed (default 0).")] = None,
    setting: Annotated[
        str, typer.Option(help="simulation (0.05 s steps, sec. 4.4.2) or real_robot (30 Hz, sec. 4.4.1).")
    ] = "simulation",
    set_: SetOpt = None,
    config: ConfigOpt = None,
) -> None:
    """Simulate the chapter-4 Aibo walking among four beacons with 40 actions (secs. 4.4.1-4.4.2)."""
    from sensact.errors import ConfigError
    from sensact.io.logfolder import write_log_folder
    from sensact.sim.field2d import Field2DConfig, log_tables, simulate_field

    if setting not in ("simulation", "real_robot"):
        raise ConfigError(f"unknown setting {setting!r}.", field="--setting", fix="use simulation or real_robot.")
    cfg = _config(Field2DConfig, config, set_, base=Field2DConfig.preset(setting), seconds=seconds, seed=seed)
    run = simulate_field(cfg)
    write_log_folder(out, **log_tables(run))
    console.print(
        f"wrote {out}: {len(run.times_s)} steps of {cfg.dt_s:.4g} s, {run.obs_step.size} observations "
        f"({int(run.obs_false.sum())} false positives), 40 actions (seed {cfg.seed})"
    )


@simulate_app.command("car")
@_friendly
def simulate_car(
    out: Annotated[Path, typer.Option("--out", help="Log folder to write (velodyne.pcap, actions.csv, ...).")],
    seconds: Annotated[float | None, typer.Option(help="Length of the drive (default 200).")] = None,
    seed: Annotated[int | None, typer.Option(help="Random seed (default 0).")] = None,
    set_: SetOpt = None,
    config: ConfigOpt = None,
) -> None:
    """Simulate the chapter-5 car with a Velodyne HDL-64E driving through a town (secs. 2.5.2, 5.4)."""
    from sensact.experiments.car import simulate_car_log
    from sensact.sim.car import CarConfig, log_summary

    cfg = _config(CarConfig, config, set_, seconds=seconds, seed=seed)
    with _progress() as progress:
        run = simulate_car_log(cfg, out, progress)
    s = log_summary(run)
    console.print(
        f"wrote {out}: {s['seconds']:.0f} s drive, top speed {s['max_speed_m_s']:.2f} m/s, turned "
        f"{s['turned_deg']:.0f}°, {s['obstacles']} obstacles; velodyne.pcap holds "
        f"{int(cfg.seconds * cfg.firing_hz) // 6} HDL-64E packets (seed {cfg.seed})"
    )


# ---- learn ----------------------------------------------------------------------------------------------


@learn_app.command("bootstrap")
@_friendly
def learn_bootstrap_cmd(
    log: Annotated[Path, typer.Argument(help="A log folder, or a Turtlebot CSV file.")],
    a0: Annotated[str | None, typer.Option(help="Starting action model: linear, sign or constant.")] = None,
    sensor: Annotated[
        str | None, typer.Option(help="Observation column (default: the log's own; sonar1 for a Turtlebot CSV).")
    ] = None,
    out: Annotated[
        Path | None,
        typer.Option("--out", help="Write the learned models here (JSON) and the history beside it (.npz)."),
    ] = None,
    set_: SetOpt = None,
    config: ConfigOpt = None,
) -> None:
    """Learn S(o) and A(c) from each other with Algorithm 1 (sec. 3.2.3). Prints the polynomials, and
    the scaled errors when the log carries ground truth."""
    from sensact.errors import ConfigError
    from sensact.io.atomic import write_json, write_npz
    from sensact.io.logfolder import read_track_log
    from sensact.learn.bootstrap import BootstrapConfig, learn_bootstrap

    if a0 is not None and a0 not in ("linear", "sign", "constant"):
        raise ConfigError(f"unknown starting model {a0!r}.", field="--a0", fix="use linear, sign or constant.")
    data = read_track_log(log, sensor=sensor)
    base = None
    if data.meta.get("platform") == "turtlebot1d":
        from sensact.experiments.turtlebot import learner_for

        base = learner_for(data.observation_name)
        console.print(
            "Turtlebot log: starting from the turtlebot settings (docs/bootstrap.md); --config and --set override them."
        )
    cfg = _config(BootstrapConfig, config, set_, base=base, a0=a0)
    console.print(
        f"{data.source}: {len(data.times_s)} steps over {data.duration_s:.1f} s, "
        f"{data.n_observations} observations of {data.observation_name}"
    )
    with _progress() as progress:
        res = learn_bootstrap(
            data.times_s,
            data.commands,
            data.observations,
            cfg,
            units=(data.command_unit, data.observation_unit, "w"),
            progress=lambda d, n: progress("Algorithm 1", d, n),
        )
    console.print(
        f"status: [bold]{res.status}[/]"
        + (f" at {res.diverged_at_s:.1f} s" if res.diverged_at_s else "")
        + (f"; {res.n_gated} observations gated as outliers" if res.n_gated else "")
    )
    console.print("  " + res.sensor.describe("S"))
    console.print("  " + res.action.describe("A"))
    evaluation = _evaluate_log(data, res, cfg)
    if out is not None:
        payload = {**res.to_dict(), "log": data.source, "evaluation": evaluation}
        write_json(out, payload)
        assert res.history is not None
        write_npz(out.with_suffix(".history.npz"), **res.history.arrays())
        console.print(f"wrote {out} and {out.with_suffix('.history.npz')}")


@learn_app.command("em")
@_friendly
def learn_em_cmd(
    log: Annotated[Path, typer.Argument(help="A log folder (planar or a 1-D track), or a Turtlebot CSV file.")],
    out: Annotated[
        Path | None,
        typer.Option("--out", help="Write the learned model here (JSON) and the learning history beside it (.npz)."),
    ] = None,
    bins: Annotated[int, typer.Option(help="Actions to bin continuous 1-D commands into.")] = 21,
    set_: SetOpt = None,
    config: ConfigOpt = None,
) -> None:
    """Learn the action model, sensor functions f and noise sigmas by EM (ch. 4). Ctrl-C stops early and
    still writes the most likely model so far."""
    from sensact.io.atomic import write_json, write_npz
    from sensact.io.landmark_log import read_landmark_log
    from sensact.learn.em import EMConfig, fit_em, initial_model

    lf, turtlebot_truth = None, None
    if log.is_file() and log.suffix.lower() == ".csv":
        from sensact.experiments.turtlebot_em import turtlebot_em_config
        from sensact.io.turtlebot import read_turtlebot_landmark_log

        data, turtlebot_truth = read_turtlebot_landmark_log(log)
        cfg = _config(EMConfig, config, set_, base=turtlebot_em_config())
        console.print(
            "Turtlebot CSV: starting from the Turtlebot's EM settings (docs/em-real.md); --config and --set "
            "override them."
        )
    else:
        if log.is_file():
            from sensact.errors import LogFormatError

            raise LogFormatError(
                "EM reads a log folder or a Turtlebot CSV file.",
                file=log,
                fix="give a folder with meta.json, actions.csv and observations.csv (sensact convert mrclam "
                "writes one), or a .csv with the Turtlebot's columns.",
            )
        cfg = _config(EMConfig, config, set_)
        lf = read_landmark_log(log, command_bins=bins)
        data = lf.data
    console.print(
        f"{data.source}: {data.geometry} log, {data.n_steps} steps of {data.dt_s:.4g} s, "
        f"{data.n_observations} observations, "
        + (
            f"continuous commands ({', '.join(data.command_names)})"
            if data.is_continuous
            else f"{data.n_actions} actions"
        )
        + (f" ({lf.note})" if lf is not None and lf.note else "")
    )
    start = initial_model(data, cfg)
    if cfg.start_search_s > 0 and data.geometry == "planar":
        console.print(
            f"finding the start pose: a {cfg.start_search_grid_mm:g} mm grid scored on the first "
            f"{cfg.start_search_s:g} s, then EM from its {cfg.start_candidates} best, the better half kept every "
            f"{cfg.start_trial_iterations} iterations (no bar until one is left)"
        )
    with _progress() as progress:
        res = fit_em(
            data,
            start,
            cfg,
            progress=lambda it, ll, best, since: progress(
                f"EM: log-likelihood {ll:.1f} (best {best:.1f}, {since} since)", it + 1, cfg.max_iterations
            ),
        )
    m = res.model
    console.print(
        f"stopped: [bold]{res.stop_reason}[/] after {res.iterations} iterations ({res.seconds:.1f} s); "
        f"best log-likelihood {res.loglik_best:.1f} at iteration {res.best_iteration}"
        + (f"; {res.n_pruned} observations pruned" if res.n_pruned else "")
    )
    if res.start_search:
        x, y, th = res.start_search["prior_mean"]
        race = res.start_search.get("race")
        which = f" (candidate {race['winner']} of {len(race['rounds'][0])} won the race)" if race else ""
        console.print(f"start pose chosen: x {x:.0f} mm, y {y:.0f} mm, heading {th:.3f} rad{which}")
    for r in res.ridge or []:
        console.print(
            f"ridge search at iteration {r['iteration']}: path and f moved {r['shift_mm']:+.0f} mm forward, "
            f"log-likelihood {r['loglik_before']:.1f} -> {r['loglik_after']:.1f} ({r['e_steps']} E-steps)"
        )
    for r in res.delay_search or []:
        console.print(
            f"delay search at iteration {r['iteration']}: command delay {r['delay_from']} -> {r['delay_to']} steps, "
            f"log-likelihood {r['loglik_before']:.1f} -> {r['loglik_after']:.1f} ({r['e_steps']} E-steps)"
        )
    _print_em_model(m)
    evaluation = _evaluate_em(lf, m) if lf is not None else _evaluate_turtlebot_em(res, data, turtlebot_truth)
    if out is not None:
        write_json(
            out,
            {
                "model": m.to_dict(),
                "summary": res.summary(),
                "log": data.source,
                "dt_s": data.dt_s,
                "evaluation": evaluation,
            },
        )
        write_npz(
            out.with_suffix(".history.npz"),
            loglik=res.loglik_history,
            velocities=res.velocity_history,
            sigmas=res.sigma_history,
        )
        written = [out, out.with_suffix(".history.npz")]
        if res.posteriors is not None:
            from sensact.report.figures_fit import figure_em_fit

            written.append(figure_em_fit(res, data, out.with_suffix(".png"), f"EM on {Path(data.source).name}"))
        console.print("wrote " + ", ".join(str(p) for p in written))


@learn_app.command("car")
@_friendly
def learn_car_cmd(
    log: Annotated[Path, typer.Argument(help="A car log folder (velodyne.pcap, actions.csv, meta.json).")],
    out: Annotated[Path | None, typer.Option("--out", help="Write the learned models here (JSON).")] = None,
    calibration_yaml: Annotated[
        Path | None,
        typer.Option("--calibration-yaml", help="Also write the learned angles as a ROS velodyne calibration."),
    ] = None,
    set_: SetOpt = None,
    config: ConfigOpt = None,
) -> None:
    """Learn the lidar's laser angles, the scan-matching odometry and the car dynamics (Algorithm 3)."""
    import numpy as np

    from sensact.config import config_to_dict
    from sensact.experiments.car import learn_from_log
    from sensact.io.atomic import write_json
    from sensact.io.car_log import read_car_log
    from sensact.io.velodyne_calibration import write_calibration
    from sensact.learn.car_dynamics import CarLearningConfig
    from sensact.models.laser_intrinsics import LaserIntrinsics

    cfg = _config(CarLearningConfig, config, set_)
    data = read_car_log(log)
    console.print(
        f"{log}: {data.distance_m.shape[0]} firings of {data.distance_m.shape[1]} lasers "
        f"({data.distance_m.shape[0] / data.firing_hz:.1f} s), {len(data.actions)} action rows"
    )
    with _progress() as progress:
        res = learn_from_log(data, cfg, progress)
    m = res.model
    console.print(f"converged after {res.iterations} iterations; C = {np.degrees(res.offset_rad):.3f}°")
    console.print(f"  a = {m.C5:.4g} + {m.C6:.4g} g + {m.C7:.4g} v + {m.C8:.4g} v b   (eq. 5.3)")
    console.print(f"  omega = {m.C9:.4g} v + {m.C10:.4g} v s   (eq. 5.4)")
    evaluation = None
    if "truth" in data.meta and data.groundtruth is not None:
        from sensact.experiments.car import evaluate_run

        evaluation, _ = evaluate_run(data.meta["truth"], data.groundtruth, res, cfg.odometry.dt_s)
        console.print(
            f"vs truth: laser angles {evaluation['laser_angle_rms_deg']:.3f}° RMS; accel "
            f"{evaluation['accel_rms']:.3f} m/s² (from truth {evaluation['accel_rms_from_truth']:.3f}), forward "
            f"velocity {evaluation['fwd_vel_rms']:.3f} m/s ({evaluation['fwd_vel_rms_from_truth']:.3f}), angular "
            f"velocity {evaluation['ang_vel_rms']:.4f} rad/s ({evaluation['ang_vel_rms_from_truth']:.4f})"
        )
    if out is not None:
        write_json(
            out,
            {
                "laser_angles_deg": np.degrees(res.laser_angles_rad).tolist(),
                "offset_C_deg": float(np.degrees(res.offset_rad)),
                "car_dynamics": m.to_dict(),
                "iterations": res.iterations,
                "history": res.history,
                "seconds_by_stage": res.seconds_by_stage,
                "config": config_to_dict(cfg),
                "evaluation": evaluation,
            },
        )
        console.print(f"wrote {out}")
    if calibration_yaml is not None:
        # ROS's driver puts a point at azimuth (rotation - rot_correction) clockwise from forward, which is
        # eq. 2.35 with theta_b = 90°: rot_correction = theta_hat_l - 90° puts points in the car's frame
        write_calibration(calibration_yaml, LaserIntrinsics(data.vertical_rad, res.laser_angles_rad - np.pi / 2))
        console.print(f"wrote {calibration_yaml} (rot_correction = learned angle - 90°)")


def _print_em_model(m: Any) -> None:
    from sensact.models.action_table import ActionTable

    for ch in m.sensor.channels:
        console.print(f"  {ch.name}: " + ch.function.describe("f") + f", sigma = {ch.sigma:.4g}")
    sb = m.sensor.sigma_bearing_rad
    if sb:
        console.print(f"  bearing sigma_2 = {sb:.4g} rad")
    console.print("  Sigma_m (sd per step): " + "; ".join(", ".join(f"{x:.4g}" for x in row) for row in m.motion_sd))
    if m.turn_var is not None:
        console.print(f"  heading variance per step grows by {m.turn_var:.4g} rad^2 per rad/s of turning")
    a = m.action
    if isinstance(a, ActionTable):
        t = Table(title="learned velocity of each action", title_justify="left")
        for name in (*a.command_names, *a.velocity_names):
            t.add_column(name)
        for c, v in zip(a.commands, a.velocities, strict=True):
            t.add_row(*(f"{x:.3g}" for x in c), *(f"{x:.4g}" for x in v))
    else:
        from sensact.models.linear_action import feature_names

        t = Table(title=f"learned A(c) = Phi(c) beta ({a.basis}; delay {a.delay_steps} steps)", title_justify="left")
        t.add_column("feature")
        for name in a.velocity_names:
            t.add_column(name)
        for fname, row in zip(feature_names(a.basis, a.degree, a.command_names), a.coefficients, strict=True):
            t.add_row(fname, *(f"{x:.4g}" for x in row))
    console.print(t)


def _print_truth_score(sc: dict[str, Any]) -> None:
    from sensact.experiments.real import bar_checks
    from sensact.report.tables import shared_by_motion

    a, r, b = sc["action"], sc["range"], sc["bearing"]
    bars = bar_checks(sc)

    def mark(*keys: str) -> str:
        return "pass" if all(bars[k] for k in keys) else "[bold red]miss[/]"

    t = Table(title=f"against ground truth ({sc['windows_scored']} windows of {sc['window_s']:.2g} s)")
    for col in ("quantity", "learned", "From-Truth", "ratio", "bar"):
        t.add_column(col)
    la, fa = a["learned"], a["from_truth"]
    t.add_row(
        "translation RMS (mm/s)",
        f"{la['translation_rms_mm_s']:.1f}",
        f"{fa['translation_rms_mm_s']:.1f}",
        f"{a['ratio_translation']:.2f}",
        mark("action_translation_ratio", "action_translation_abs"),
    )
    t.add_row(
        "rotation RMS (rad/s)",
        f"{la['rotation_rms_rad_s']:.4f}",
        f"{fa['rotation_rms_rad_s']:.4f}",
        f"{a['ratio_rotation']:.2f}",
        mark("action_rotation_ratio"),
    )
    t.add_row("command delay (s)", f"{a['learned_delay_s']:.3f}", f"{a['from_truth_delay_s']:.3f}", "", "")
    t.add_row(
        "range residual RMS (mm)",
        f"{r['learned_residual_rms_mm']:.1f}",
        f"{r['from_truth_residual_rms_mm']:.1f}",
        f"f gap {r['learned_vs_from_truth_rms_mm']:.1f} mm",
        "",
    )
    t.add_row(
        "range sigma (mm)",
        f"{r['sigma_learned_mm']:.1f}",
        f"{r['sigma_truth_mm']:.1f}",
        f"{r['sigma_ratio']:.2f}",
        mark("range_sigma"),
    )
    t.add_row(
        "bearing sigma (rad)",
        f"{b['sigma_learned_rad']:.4f}",
        f"{b['sigma_truth_rad']:.4f}",
        f"{b['sigma_ratio']:.2f}",
        mark("bearing_sigma"),
    )
    console.print(t)
    console.print(
        "bar: an action RMS at most 1.5 times From-Truth's (translation at most 50 mm/s), a sigma within a"
        " factor of 1.5 of the truth's (docs/em-real.md)"
    )
    n = sc.get("truth_noise")
    if n:
        console.print(
            f"truth's noise: heading drift per {sc['window_s']:.2g} s "
            f"{n['heading_drift_rms_at_rest_rad']:.4f} rad at rest (Sigma_m: "
            f"{n['learned_heading_drift_at_rest_rad']:.4f}), "
            f"{n['heading_drift_rms_turning_rad']:.4f} rad turning at {n['turning_rad_s']:.2f} rad/s (Sigma_m: "
            f"{n['learned_heading_drift_turning_rad']:.4f}); "
            f"position missed per {sc['window_s']:.2g} s, sideways / forward "
            f"{n['translation_drift_rms_mm'][0]:.1f} / {n['translation_drift_rms_mm'][1]:.1f} mm (Sigma_m: "
            f"{n['learned_translation_drift_mm'][0]:.1f} / {n['learned_translation_drift_mm'][1]:.1f}); "
            f"bearing residuals of frames 1-5 windows apart correlate at {n['bearing_frame_correlation']:.2f}; "
            f"a frame's sightings share {n['bearing_frame_shared_fraction']:.0%} of their residual's variance"
            f"{shared_by_motion(n)}, "
            f"and vary about their frame's mean by {n['bearing_within_frame_sd_rad']:.4f} rad (docs/em-real.md, "
            "Known limits)"
        )
    m = sc.get("sensor_mount")
    if m:
        console.print(
            f"sensor pose on the robot, fitted to the truth: {m['forward_mm']:.0f} mm forward, "
            f"{m['lateral_mm']:.0f} mm to the right, yaw {m['yaw_rad']:+.4f} rad (counterclockwise); "
            f"at the truth's origin instead the bearing residual is {b['truth_origin_sigma_rad']:.4f} rad RMS "
            f"(mean {b['truth_origin_mean_rad']:+.4f}; learned sigma / it {b['truth_origin_sigma_ratio']:.2f})"
        )
    if "bars" in sc:
        console.print("bars: " + ", ".join(f"{k} {'pass' if v else 'FAIL'}" for k, v in sc["bars"].items()))


def _evaluate_em(lf: Any, model: Any) -> dict[str, Any] | None:
    """Errors against the truth a simulated log carries (never used for learning)."""
    import numpy as np

    gt = lf.groundtruth
    if gt is not None and lf.data.is_continuous and {"x_mm", "y_mm", "theta_rad"} <= set(gt):
        from sensact.evaluate.landmark_truth import score_against_truth
        from sensact.experiments.real import bar_checks

        poses = np.column_stack([gt["x_mm"], gt["y_mm"], gt["theta_rad"]])
        valid = gt["valid"] > 0.5 if "valid" in gt else np.ones(len(poses), dtype=bool)
        sc = score_against_truth(model, lf.data, poses, valid)
        sc["bars"] = bar_checks(sc)
        _print_truth_score(sc)
        return sc
    truth = lf.meta.get("truth")
    if not truth:
        return None

    if lf.data.geometry == "planar" and "velocities" in truth:
        from sensact.evaluate.em import score_planar
        from sensact.sim.track1d import TrackTruth

        s = truth["sensor"]
        height = TrackTruth(sensor_k_px_mm=s["k_px_mm"], sensor_d0_mm=s["d0_mm"], sensor_h0_px=s["h0_px"]).height_px
        sc = score_planar(
            model, np.asarray(truth["velocities"]), height, truth["sigma_height_px"], truth["sigma_bearing_rad"]
        )
        console.print(
            f"vs truth: v_x {sc['vx_rms_mm_s']:.1f} mm/s, v_y {sc['vy_rms_mm_s']:.1f} mm/s, "
            f"v_theta {sc['vtheta_rms_rad_s']:.3f} rad/s RMS; sigma_1 {sc['sigma1_error_pct']:.1f} % off, "
            f"sigma_2 {sc['sigma2_error_pct']:.1f} % off; f {sc['sensor_rms_px']:.2f} px RMS"
        )
        return sc
    if lf.data.geometry == "track" and "action" in truth:
        from sensact.evaluate.em import score_track
        from sensact.evaluate.track1d import DISTANCE_GRID_MM
        from sensact.sim.track1d import TrackTruth

        tt = TrackTruth.from_dict(truth)
        sc = score_track(model, tt.velocity_mm_s(lf.data.action_commands[:, 0]), tt.height_px, DISTANCE_GRID_MM)
        console.print(
            f"vs truth (optimal scale): sensor {sc['sensor_rms_px']:.2f} px ({sc['sensor_rms_pct']:.2f} %), "
            f"action {sc['action_rms_mm_s']:.1f} mm/s ({sc['action_rms_pct']:.2f} %), "
            f"scale ratio {sc['scale_ratio']:.3f}"
        )
        return sc
    return None


def _evaluate_turtlebot_em(res: Any, data: Any, truth_mm: Any) -> dict[str, Any] | None:
    """The Turtlebot's scaled gain and sensor errors against its ``range`` column, when it has one."""
    import numpy as np

    if truth_mm is None or np.isnan(truth_mm).all():
        console.print("no range column: nothing to score against (the model is learned from the readings alone).")
        return None
    if not np.isfinite(truth_mm).all():
        console.print(f"the range column has {int((~np.isfinite(truth_mm)).sum())} empty steps: not scored.")
        return None
    from sensact.experiments.turtlebot_em import score_turtlebot_em

    sc = score_turtlebot_em(res, data, truth_mm)
    console.print(
        f"vs range (optimal scale and offset): action gain {sc['gain_learned']:.4f} against "
        f"{sc['gain_true']:.4f} ({sc['gain_error_pct']:.2f} % off); command delay {sc['delay_s']:.2f} s"
    )
    for name, s in sc["sensors"].items():
        console.print(f"  {name}: {s['rms_pct_of_span']:.2f} % of its {s['span_mm']:.0f} mm span")
    return sc


def _evaluate_log(data: Any, res: Any, cfg: Any) -> dict[str, Any] | None:
    """Scaled errors against the log's ground truth, if it has any (never used for learning)."""
    if "truth" in data.meta:
        from sensact.evaluate.track1d import score_track_models
        from sensact.sim.track1d import TrackTruth

        sc = score_track_models(res.sensor, res.action, TrackTruth.from_dict(data.meta["truth"]))
        console.print(
            f"vs truth (measured grid of sec. 3.3.2): sensor RMS {sc.sensor_rms:.1f} mm "
            f"(best cubic {sc.sensor_best_rms:.1f}), action RMS {sc.action_rms:.1f} mm/s "
            f"(best quartic {sc.action_best_rms:.1f}), consistency {sc.consistency:.3f}"
        )
        return sc.to_dict()
    if data.true_position is not None:
        from sensact.experiments.turtlebot import evaluate_real

        run = evaluate_real(data, res, cfg)
        sc = run.score
        console.print(
            f"vs ground truth: sensor RMS {sc.sensor_rms:.4g} {data.position_unit} "
            f"(best {sc.sensor_best_rms:.4g}), action RMS {sc.action_rms:.4g} {data.position_unit}/s, "
            f"gain {run.learned_gain:.4f} (truth {run.true_gain:.4f}), consistency {sc.consistency:.3f}"
        )
        return {**sc.to_dict(), "learned_gain": run.learned_gain, "true_gain": run.true_gain}
    return None


# ---- convert and evaluate -------------------------------------------------------------------------------


MRCLAM_CONFIG_HEADER = """The EM settings behind docs/em-real.md's MRCLAM results
(sensact.experiments.real.mrclam_config()), as the fields that differ from EMConfig's defaults.
Edit them for your robot (docs/em-real.md, section 2) and pass this file with --config;
--set overrides single fields."""


@convert_app.command("mrclam")
@_friendly
def convert_mrclam(
    dataset: Annotated[Path, typer.Argument(help="An MRCLAM dataset folder, e.g. .../MRCLAM_Dataset6.")],
    robot: Annotated[int, typer.Option(help="Robot 1-5.")] = 1,
    out: Annotated[Path, typer.Option("--out", help="The log folder to write.")] = Path("mrclam_log"),
    dt: Annotated[float, typer.Option(help="Step (s); commands are held between their rows.")] = 1.0 / 30.0,
) -> None:
    """Write one MRCLAM robot as an EM log folder: commands resampled with a zero-order hold, landmark
    sightings only (range in mm and bearing), the landmark map, and Vicon in groundtruth.csv (for
    `sensact learn em` to score against; it is never learned from)."""
    from sensact.config import config_to_yaml
    from sensact.experiments.real import mrclam_config
    from sensact.io.atomic import write_text
    from sensact.io.landmark_log import write_landmark_log
    from sensact.io.mrclam import read_mrclam

    ml = read_mrclam(dataset, robot, dt_s=dt)
    console.print(ml.summary_line())
    write_landmark_log(
        out,
        ml.data,
        t0_s=0.0,
        groundtruth=ml.groundtruth,
        meta_extra={"source": {"dataset": str(dataset), "robot": robot, "t0_s": ml.t0_s, "rows": ml.summary}},
    )
    cfg = out / "em_config.yaml"
    write_text(cfg, config_to_yaml(mrclam_config(), MRCLAM_CONFIG_HEADER))
    console.print(f"wrote {out} and its EM settings {cfg}; learn with `sensact learn em {out} --config {cfg}`")


@evaluate_app.command("mrclam")
@_friendly
def evaluate_mrclam_cmd(
    dataset: Annotated[Path, typer.Argument(help="An MRCLAM dataset folder, e.g. .../MRCLAM_Dataset6.")],
    model: Annotated[Path, typer.Option("--model", help="A model.json written by `sensact learn em`.")],
    robot: Annotated[int, typer.Option(help="Robot 1-5.")] = 1,
    out: Annotated[Path | None, typer.Option("--out", help="Write the scores here (JSON).")] = None,
) -> None:
    """Score a learned continuous-command model against Vicon, next to From-Truth: the same model
    families fitted directly to the ground truth."""
    import json

    from sensact.errors import ModelFormatError
    from sensact.evaluate.landmark_truth import score_against_truth
    from sensact.experiments.real import bar_checks
    from sensact.io.atomic import write_json
    from sensact.io.mrclam import read_mrclam
    from sensact.models.em_model import EMModel

    if not model.is_file():
        raise ModelFormatError("file not found.", file=model, fix="give the model.json `sensact learn em` wrote.")
    doc = json.loads(model.read_text())
    m = EMModel.from_dict(doc.get("model", doc), source=str(model))
    ml = read_mrclam(dataset, robot, dt_s=float(doc.get("dt_s", 1.0 / 30.0)))
    sc = score_against_truth(m, ml.data, *ml.truth_poses())
    sc["bars"] = bar_checks(sc)
    _print_truth_score(sc)
    if out is not None:
        write_json(out, sc)
        console.print(f"wrote {out}")


# ---- reproduce ------------------------------------------------------------------------------------------

EXPERIMENTS = ("track1d", "turtlebot", "field2d", "em1d", "car", "real")


def _data_dir(data: Path | None) -> Path:
    from sensact.experiments.shared_data import data_root

    return data if data is not None else data_root()


@app.command()
@_friendly
def reproduce(
    experiment: Annotated[str | None, typer.Argument(help=f"One of {', '.join(EXPERIMENTS)}; default: all.")] = None,
    out: Annotated[Path, typer.Option("--out", help="Results folder.")] = Path("results"),
    trials: Annotated[
        int | None,
        typer.Option(help="Trials: per Table 3.1 row (default 15) or field2d seeds (default 5)."),
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
) -> None:
    """Run the thesis's experiments and write RESULTS/<experiment>.json, tables and figures."""
    from sensact.errors import ConfigError

    if experiment is not None and experiment not in EXPERIMENTS:
        raise ConfigError(
            f"unknown experiment {experiment!r}.",
            field="EXPERIMENT",
            fix=f"choose one of {', '.join(EXPERIMENTS)}, or none for all.",
        )
    todo = [experiment] if experiment else list(EXPERIMENTS)
    if "track1d" in todo:
        _reproduce_track1d(out, trials or 15, seed, set_, config)
    if "turtlebot" in todo:
        csv = _data_dir(data) / "turtlebot1d" / "training1.csv"
        if not csv.is_file():
            if experiment == "turtlebot":
                raise SensactError(
                    "Turtlebot data not found.",
                    file=csv,
                    fix="pass --data DIR (the folder holding turtlebot1d/) or set SENSACT_DATA.",
                )
            console.print(f"skipping turtlebot: {csv} not found (pass --data DIR to include it)")
        else:
            _reproduce_turtlebot(out, csv)
    if "field2d" in todo:
        _reproduce_field2d(out, trials or 5, seed, set_, config)
    if "em1d" in todo:
        _reproduce_em1d(out, seed, set_, config)
    if "car" in todo:
        _reproduce_car(out, seed, set_, config)
    if "real" in todo:
        _reproduce_real(out, _data_dir(data), experiment == "real", set_, config, truth_restart)


def _reproduce_real(
    out: Path, root: Path, required: bool, set_: list[str] | None, config: Path | None, truth_restart: bool = False
) -> None:
    """MRCLAM's EM settings are ``mrclam_config()``, changed by the EM fields of ``--config``/``--set``
    (e.g. ``--set motion_noise=turning``); the Turtlebot's are fixed. ``truth_restart``: see
    ``experiments.real.restart_from_truth``."""
    from sensact.errors import ConfigError
    from sensact.experiments.real import mrclam_config, run_real
    from sensact.learn.em import EMConfig
    from sensact.report import figures_real
    from sensact.report.tables import real_tables

    learner_f, other = _split_fields(set_, config, EMConfig)
    if required and other:
        raise ConfigError(
            f"{', '.join(sorted(other))} is not an EM setting.",
            field="--set/--config",
            fix="give fields of the EM config (docs/em-real.md), e.g. --set motion_noise=turning.",
        )
    cfg = _merged(EMConfig, mrclam_config(), learner_f)

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
        )
    for line in res["skipped"]:
        console.print(f"skipped {line}")
    _write_results(out, "real", res, real_tables(res))
    figures_real.write_all(art, res, out)


def _reproduce_car(out: Path, seed: int, set_: list[str] | None, config: Path | None) -> None:
    import numpy as np

    from sensact.experiments.car import CarExperiment, run_car
    from sensact.learn.car_dynamics import CarLearningConfig
    from sensact.report import figures_car
    from sensact.report.tables import car_tables
    from sensact.sim.car import CarConfig

    learner_f, sim_f = _split_fields(set_, config, CarLearningConfig)
    base = CarExperiment()
    exp = CarExperiment(
        simulator=_merged(CarConfig, base.simulator, {**sim_f, "seed": seed}),
        learner=_merged(CarLearningConfig, base.learner, learner_f),
    )
    with _progress() as progress:
        res, art = run_car(exp, out / "car_log", progress)
    _write_results(out, "car", res, car_tables(res))
    log, r = art["log"], art["result"]
    figures_car.figure_5_2(log, r.intrinsics.relative_rad, 40.0, 0.5, out / "fig5_2_scans.png")
    figures_car.figure_5_3(
        r.laser_angles_rad,
        np.asarray(log.meta["truth"]["laser_angles_rad"]),
        log.vertical_rad,
        out / "fig5_3_laser_angles.png",
    )
    K = len(r.actions) - 1
    pred = r.model.predict(r.actions[:K], r.speed_m_s[0], exp.learner.odometry.dt_s)
    v, w, a = art["truth"]
    t = r.interval_times_s[:K]
    figures_car.figure_5_4_5(t, (v[:K], w[:K], a[:K]), pred, out / "fig5_4_5_dynamics.png", (85.0, 110.0))
    ok = res["bars_cleared"]
    console.print(
        f"bars cleared: {', '.join(f'{k} {v}' for k, v in ok.items())}; wrote {out / 'car.json'}, "
        f"{out / 'car.md'}, figures and the log in {out / 'car_log'} ({res['seconds']:.1f} s)"
    )


def _split_fields(set_: list[str] | None, config: Path | None, learner_cls: type) -> tuple[dict, dict]:
    """--set / --config fields go to the learner or the simulator, whichever has the field."""
    from sensact.config import load_yaml_mapping, parse_overrides

    fields = {**(load_yaml_mapping(config) if config else {}), **parse_overrides(set_ or [])}
    learner = {k: v for k, v in fields.items() if k in learner_cls.__dataclass_fields__}
    return learner, {k: v for k, v in fields.items() if k not in learner}


def _merged(cls: type, base: Any, fields: dict[str, Any]) -> Any:
    """``base`` with the given fields replaced, validated like any config."""
    from sensact.config import config_from_dict, config_to_dict

    return config_from_dict(cls, {**config_to_dict(base), **fields}, source="--set/--config") if fields else base


def _reproduce_field2d(out: Path, trials: int, seed: int, set_: list[str] | None, config: Path | None) -> None:
    from sensact.config import config_from_dict
    from sensact.experiments.field2d import Field2DExperiment, run_field2d, velocity_rms_history
    from sensact.io.atomic import write_npz
    from sensact.learn.em import EMConfig
    from sensact.report import figures_em
    from sensact.report.tables import field2d_tables
    from sensact.sim.field2d import Field2DConfig

    base = Field2DExperiment()
    learner_f, sim_f = _split_fields(set_, config, EMConfig)
    exp = Field2DExperiment(
        trials=trials,
        seed=seed,
        simulator=config_from_dict(Field2DConfig, sim_f, source="--set/--config"),
        learner=_merged(EMConfig, base.learner, learner_f),
    )
    with _progress() as progress:
        res, art = run_field2d(exp, progress)
    _write_results(out, "field2d", res, field2d_tables(res))
    first = art["trials"][0]
    vr = velocity_rms_history(first)
    figures_em.figure_learning_curve(
        first, vr, out / "fig4_4_field2d_learning.png", f"simulation, seed {first.run.config.seed}", res["thesis"]
    )
    from sensact.learn.em.fit import starting_height

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
    o = res["ours"]
    console.print(
        f"bars (v_x <= 23.06, v_y <= 18.34 mm/s, v_theta <= 0.086 rad/s, sigmas within 5 %) cleared in every trial: "
        f"[bold]{o['clears_bars_every_trial']}[/]"
    )
    console.print(f"wrote {out / 'field2d.json'}, {out / 'field2d.md'} and figures in {out} ({res['seconds']:.1f} s)")


def _reproduce_em1d(out: Path, seed: int, set_: list[str] | None, config: Path | None) -> None:
    from sensact.experiments.em1d import EM1D_TRACK, EM1DExperiment, run_em1d
    from sensact.learn.em import EMConfig
    from sensact.report import figures_em
    from sensact.report.tables import em1d_tables
    from sensact.sim.track1d import Track1DConfig

    base = EM1DExperiment()
    learner_f, sim_f = _split_fields(set_, config, EMConfig)
    exp = EM1DExperiment(
        seed=seed,
        simulator=_merged(Track1DConfig, EM1D_TRACK, sim_f),
        learner=_merged(EMConfig, base.learner, learner_f),
    )
    with _progress() as progress:
        res, art = run_em1d(exp, progress)
    _write_results(out, "em1d", res, em1d_tables(res))
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
    console.print(
        f"relearned models beat the stale ones: [bold]{res['ours']['relearning_beats_stale']}[/]; "
        f"wrote {out / 'em1d.json'}, {out / 'em1d.md'} and figures in {out} ({res['seconds']:.1f} s)"
    )


def _reproduce_track1d(out: Path, trials: int, seed: int, set_: list[str] | None, config: Path | None) -> None:
    from sensact.config import config_from_dict, load_yaml_mapping, parse_overrides
    from sensact.experiments.track1d import Track1DExperiment, run_track1d
    from sensact.io.atomic import write_npz
    from sensact.learn.bootstrap import BootstrapConfig
    from sensact.report import figures1d
    from sensact.report.tables import track1d_tables
    from sensact.sim.track1d import Track1DConfig

    # --set / --config fields go to the learner or the simulator, whichever has the field
    fields = {**(load_yaml_mapping(config) if config else {}), **parse_overrides(set_ or [])}
    learner_fields = {k: v for k, v in fields.items() if k in BootstrapConfig.__dataclass_fields__}
    sim_fields = {k: v for k, v in fields.items() if k not in learner_fields}
    exp = Track1DExperiment(
        trials=trials,
        degree_trials=trials,
        seed=seed,
        learner=config_from_dict(BootstrapConfig, learner_fields, source="--set/--config"),
        simulator=config_from_dict(Track1DConfig, sim_fields, source="--set/--config"),
    )
    with _progress() as progress:
        res, art = run_track1d(exp, progress)
    _write_results(out, "track1d", res, track1d_tables(res))
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


def _reproduce_turtlebot(out: Path, csv: Path) -> None:
    from sensact.experiments.turtlebot import run_turtlebot
    from sensact.report.figures1d import figure_real
    from sensact.report.tables import turtlebot_tables

    res, runs = run_turtlebot(csv)
    _write_results(out, "turtlebot", res, turtlebot_tables(res))
    figure_real(runs, out / "turtlebot_models.png")
    console.print(f"wrote {out / 'turtlebot.json'} and {out / 'turtlebot_models.png'}")


def main() -> None:
    """Console-script entry point."""
    try:
        app()
    except SensactError as exc:  # raised outside a command, e.g. while parsing
        if _state["debug"]:
            raise
        err_console.print(f"error: {exc}")
        sys.exit(2)


if __name__ == "__main__":
    main()
