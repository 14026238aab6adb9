"""``sensact learn car``: chapter 5's laser angles, scan-matching odometry and car dynamics (Algorithm 3)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from sensact.app.settings import layered_config
from sensact.cli.base import (
    ConfigOpt,
    ForceOpt,
    SetOpt,
    check_out_file,
    console,
    finish,
    friendly,
    learn_app,
    progress_bar,
    write_result,
)
from sensact.outputs import CAR_MODEL
from sensact.records import JsonObject


def _learn(data: Any, cfg: Any, simulated: bool) -> tuple[Any, dict | None, list, JsonObject | None]:
    """Algorithm 3 on the log, or only its laser angles when it has no actions; what was learned is
    printed, and scored when the log is ``simulated``: ``(result, car dynamics or None, history,
    evaluation)``."""
    import numpy as np

    from sensact.app.velodyne_car import learn_angles_from_log, learn_from_log

    evaluation = None
    if data.actions is None:
        # secs. 5.1-5.2 need only the scans: a lidar remounted on a car without logged controls
        with progress_bar() as progress:
            res = learn_angles_from_log(data, cfg, progress)
        console.print(f"laser angles from the scans alone; C = {np.degrees(res.offset_rad):.3f}°")
        if simulated:
            from sensact.evaluate.velodyne_car import laser_angle_error

            evaluation = laser_angle_error(res.laser_angles_rad, np.asarray(data.meta["truth"]["laser_angles_rad"]))
            console.print(f"vs truth: laser angles {evaluation['laser_angle_rms_deg']:.3f}° RMS")
        model: dict | None = None
        history: list = []
    else:
        with progress_bar() as progress:
            res = learn_from_log(data, cfg, progress)
        m = res.model
        ended = "converged after" if res.converged else "max_iterations reached, not converged, after"
        console.print(f"{ended} {res.iterations} iterations; C = {np.degrees(res.offset_rad):.3f}°")
        console.print(f"  a = {m.C5:.4g} + {m.C6:.4g} g + {m.C7:.4g} v + {m.C8:.4g} v b   (eq. 5.3)")
        console.print(f"  omega = {m.C9:.4g} v + {m.C10:.4g} v s   (eq. 5.4)")
        if simulated:
            from sensact.app.velodyne_car import evaluate_run

            evaluation, _ = evaluate_run(data.meta["truth"], data.groundtruth, res, cfg.odometry.dt_s)
            console.print(
                f"vs truth: laser angles {evaluation['laser_angle_rms_deg']:.3f}° RMS; accel "
                f"{evaluation['accel_rms']:.3f} m/s² (from truth {evaluation['accel_rms_from_truth']:.3f}), forward "
                f"velocity {evaluation['fwd_vel_rms']:.3f} m/s ({evaluation['fwd_vel_rms_from_truth']:.3f}), angular "
                f"velocity {evaluation['ang_vel_rms']:.4f} rad/s ({evaluation['ang_vel_rms_from_truth']:.4f})"
            )
        model, history = m.to_dict(), res.history
    return res, model, history, evaluation


def _angle_reference(data: Any, res: Any, simulated: bool) -> tuple[tuple[Any, str] | None, JsonObject | None]:
    """What the figure draws the learned angles against (the factory's, turned by the mount, or a
    ``simulated`` log's truth), and the comparison with the factory calibration, printed."""
    import numpy as np

    reference, comparison = None, None
    if data.factory is not None:
        from sensact.evaluate.velodyne_car import factory_comparison

        comparison = factory_comparison(res.laser_angles_rad, data.factory.horizontal_rad)
        console.print(
            f"vs the factory calibration's horizontal angles (never used to learn): {comparison['rms_deg']:.3f}° RMS, "
            f"largest {comparison['max_deg']:.3f}°, with the unit turned θ_b = {comparison['mount_yaw_deg']:.2f}° "
            "on the car (90° when its forward axis is the car's)"
        )
        shift = np.radians(comparison["mount_yaw_deg"])
        reference = (data.factory.horizontal_rad + shift, f"factory + θ_b ({comparison['mount_yaw_deg']:.2f}°)")
    elif simulated:
        reference = (np.asarray(data.meta["truth"]["laser_angles_rad"]), "true θ_l + θ_b")
    return reference, comparison


def _ros_calibration(data: Any, res: Any) -> Any:
    """The learned angles as a ROS velodyne calibration (``LaserIntrinsics``), the factory's other fields kept."""
    import numpy as np

    from sensact.models.laser_intrinsics import LaserIntrinsics

    # ROS's driver puts a point at azimuth (rotation - rot_correction) clockwise from forward, which is
    # eq. 2.35 with theta_b = 90°: rot_correction = theta_hat_l - 90° puts points in the car's frame
    factory = data.factory
    return LaserIntrinsics(
        data.vertical_rad,
        res.laser_angles_rad - np.pi / 2,
        *((factory.distance_resolution_m, factory.extra) if factory is not None else ()),
    )


def _calibration_doc(data: Any, res: Any) -> tuple[str, JsonObject]:
    """The learned angles as the unit's own calibration format: a ROS velodyne calibration, or an OS-1's
    metadata fields (``beam_azimuth_angles`` = 90° - learned angle, the same mount convention)."""
    import yaml

    from sensact.io.velodyne_calibration import calibration_yaml, ouster_metadata

    cal = _ros_calibration(data, res)
    if data.model == "OS-1":
        return "ouster_metadata", ouster_metadata(cal)
    return "velodyne_calibration", yaml.safe_load(calibration_yaml(cal))


def _write_ros_calibration(path: Path, data: Any, res: Any) -> None:
    from sensact.io.atomic import write_json
    from sensact.io.velodyne_calibration import write_calibration

    if data.model == "OS-1":
        write_json(path, _calibration_doc(data, res)[1])
        console.print(f"wrote {path} (beam_azimuth_angles = 90° - learned angle, the OS-1's metadata fields)")
        return
    write_calibration(path, _ros_calibration(data, res))
    console.print(f"wrote {path} (rot_correction = learned angle - 90°)")


def best_matcher() -> str:
    """KISS-ICP where the kiss extra is installed (on a simulated 30-s drive its path is 13x closer to the truth
    than Algorithm 2's at a 20th of the CPU: docs/car.md, difference 6), else the thesis's Algorithm 2."""
    import importlib.util

    return "kiss_icp" if importlib.util.find_spec("kiss_icp") is not None else "algorithm2"


@learn_app.command("car")
@friendly
def learn_car_cmd(
    log: Annotated[Path, typer.Argument(help="A car log folder (velodyne.pcap, actions.csv, meta.json).")],
    out: Annotated[
        Path | None,
        typer.Option("--out", help="Write the learned models here (JSON) and a figure of the drive beside it (.png)."),
    ] = None,
    calibration_yaml: Annotated[
        Path | None,
        typer.Option(
            "--calibration-yaml",
            help="Also write the learned angles as a ROS velodyne calibration (an OS-1: its metadata JSON's angles).",
        ),
    ] = None,
    factory_calibration: Annotated[
        Path | None,
        typer.Option(
            "--factory-calibration",
            help="The unit's ROS velodyne calibration (YAML) or an OS-1's metadata JSON: its vertical angles are "
            "used (sec. 2.5.2), its horizontal ones never; --calibration-yaml then keeps its other fields.",
        ),
    ] = None,
    set_: SetOpt = None,
    config: ConfigOpt = None,
    report: Annotated[
        bool, typer.Option("--report/--no-report", help="Write OUT.report.html beside it (needs --out).")
    ] = True,
    force: ForceOpt = False,
) -> None:
    """Learn the lidar's laser angles, the scan-matching odometry and the car dynamics (Algorithm 3)."""
    check_out_file(out, kind=CAR_MODEL, force=force)
    import numpy as np

    from sensact.config import config_to_dict
    from sensact.io.velodyne_car_folder import read_car_log
    from sensact.learn.velodyne_car_dynamics import CarLearningConfig

    matcher = best_matcher()
    cfg = layered_config(CarLearningConfig, config, set_, base=CarLearningConfig(matcher=matcher))
    if cfg.matcher == matcher == "kiss_icp":
        console.print("scan matcher: KISS-ICP (the kiss extra; --set matcher=algorithm2 for the thesis's)")
    elif cfg.matcher == "algorithm2":
        console.print(
            "scan matcher: the thesis's Algorithm 2"
            + (
                ""
                if matcher == "kiss_icp"
                else " (pip install 'sensact[kiss]' for KISS-ICP, 13x closer to the truth: docs/car.md)"
            )
        )
    data = read_car_log(log, calibration=factory_calibration)
    rows = f"{len(data.actions)} action rows" if data.actions is not None else "no actions"
    console.print(
        f"{log}: {data.model}, {data.distance_m.shape[0]} firings of {data.distance_m.shape[1]} lasers "
        f"({data.distance_m.shape[0] / data.firing_hz:.1f} s), {rows}"
    )
    for note in data.notes:
        console.print(f"  {note}")
    for warning in data.warnings:
        console.print(f"[yellow]warning[/]: {warning}")
    simulated = "truth" in data.meta and data.groundtruth is not None  # scored against what it was made with
    res, model, history, evaluation = _learn(data, cfg, simulated)
    reference, comparison = _angle_reference(data, res, simulated)
    from sensact.learn.velodyne_car_dynamics import car_health

    odometry = getattr(res, "odometry", None)
    health = car_health(
        getattr(res, "model", None) if data.actions is not None else None,
        res.laser_angles_rad,
        None if odometry is None else odometry.motion,
        float(np.max(data.distance_m, initial=0.0)),
    )
    if out is not None:
        write_result(
            out,
            {
                "laser_angles_deg": np.degrees(res.laser_angles_rad).tolist(),
                "offset_C_deg": float(np.degrees(res.offset_rad)),
                "car_dynamics": model,
                "iterations": len(history),
                "converged": bool(getattr(res, "converged", True)),
                "history": history,
                "seconds_by_stage": res.seconds_by_stage,
                "config": config_to_dict(cfg),
                "factory_comparison": comparison,
                "evaluation": evaluation,
                # what `sensact export --format velodyne` writes (an OS-1: its metadata's angle fields)
                "lidar_model": data.model,
                **dict([_calibration_doc(data, res)]),
                "health": health.to_dict(),
            },
            CAR_MODEL,
        )
        from sensact.report.figures_velodyne_car import figure_car_fit

        png = figure_car_fit(
            res, data, out.with_suffix(".png"), f"Algorithm 3 on {log.name}", reference, cfg.odometry.dt_s
        )
        written = [out, png]
        if report:
            from sensact.app.report import simple_report

            numbers = {
                "firings": data.distance_m.shape[0],
                "lasers": data.distance_m.shape[1],
                "iterations": len(history),
                "offset C (deg)": float(np.degrees(res.offset_rad)),
            }
            numbers |= {f"vs the factory: {k}": v for k, v in (comparison or {}).items() if not isinstance(v, list)}
            numbers |= {f"vs truth: {k}": v for k, v in (evaluation or {}).items() if not isinstance(v, dict | list)}
            lead = f"Chapter 5's Algorithm 3 on {log}; the models are {out.name}."
            figures = [(png, "the laser angles, the scan-matching odometry and the car dynamics")]
            page = simple_report(out, f"sensact calibration: {log.name}", lead, numbers, list(data.warnings), figures)
            written.append(page)
        console.print("wrote " + ", ".join(str(p) for p in written))
    if calibration_yaml is not None:
        _write_ros_calibration(calibration_yaml, data, res)
    finish(health)
