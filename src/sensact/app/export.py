"""A learned model handed to a ROS stack (``sensact export``): SI units and REP 103 axes (x forward, y left,
z up; yaw 0 facing the map's +x, counterclockwise), whatever sensact's own frame (the thesis's: x right, y
forward, heading 0 facing +y, millimetres).

* ``robot-localization``: the process noise covariance from the learned Sigma_m, per second, in the 15-state
  order robot_localization uses, a command's twist covariance, and the action model's gains and offsets;
* ``tum``: the smoothed path (``timestamp x y z qx qy qz qw``) and the truth's, for evo;
* ``velodyne``: a car model's learned laser angles as a ROS velodyne calibration;
* ``urdf`` (and ``robot-localization``) of a wheels-and-lidar model: ``app/export_lidar2d.py``.
"""

from __future__ import annotations

import math
import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sensact.app.logs import model_step
from sensact.app.ros_params import RL_STATES, process_noise, refuse_non_finite
from sensact.errors import LogFormatError, ModelFormatError
from sensact.models.em_model import EMModel
from sensact.records import JsonObject
from sensact.report.frames import MM, REP_ORDER, VELOCITY_REP, si
from sensact.reprs import compact_repr

FORMATS = (
    "robot-localization",
    "tum",
    "velodyne",
    "landmarks",
    "urdf",
    "diff-drive-controller",
    "navsat-transform",
    "kalibr",
    "vesc",
)
LANDMARKS_HEADER = "id,x_m,y_m"  # the map file `convert csv --landmarks` reads
UNMEASURED_VAR = 1e6  # a twist's dimensions a planar robot does not measure (z, roll, pitch), as ROS drivers set


@dataclass(frozen=True)
class Exported:
    __repr__ = compact_repr  # a line, never the arrays
    written: tuple[Path, ...]
    notes: tuple[str, ...] = ()
    flags: tuple[str, ...] = ()  # the model's own health flags (codes): what was exported is as doubtful


def read_model_doc(path: Path) -> JsonObject:
    from sensact.io.jsonfile import read_json_object

    return read_json_object(path, ModelFormatError, "give a model.json written by `sensact learn em` or `learn car`.")


def read_em_doc(doc: JsonObject, source: Path) -> tuple[EMModel, float]:
    """A `learn em` model file's model and step (s), each checked."""
    from sensact.models.em_model import EMModel

    _refuse_missing_or_wild(doc.get("model"), source)
    model = EMModel.from_dict(doc.get("model"), source=str(source))
    return model, model_step(doc, source)


MAX_MOUNT_MM = 100_000.0  # a sensor 100 m from the robot's point is no mount


def _refuse_missing_or_wild(model: Any, source: Path) -> None:
    """What an export reads of a `learn em` model must be there and in range: ``motion_sd`` (its Sigma_m;
    a default would pass for a learned one) and the sensor's ``mount`` (within ``MAX_MOUNT_MM``, its yaw
    within a turn either way)."""
    if not isinstance(model, dict):
        return  # EMModel.from_dict says what is wrong with it
    fix = "learn it again with `sensact learn em`."
    if model.get("motion_sd") is None:
        raise ModelFormatError(
            "has no motion_sd, the Sigma_m an export writes.", file=source, field="model.motion_sd", fix=fix
        )
    sensor = model.get("sensor")
    mount = sensor.get("mount") if isinstance(sensor, dict) else None
    if not isinstance(mount, dict):
        raise ModelFormatError("has no sensor mount.", file=source, field="model.sensor.mount", fix=fix)
    limits = {"forward_mm": MAX_MOUNT_MM, "left_mm": MAX_MOUNT_MM, "yaw_rad": 2.0 * math.pi}
    for key, limit in limits.items():
        try:
            value = float(mount[key])
        except (KeyError, TypeError, ValueError):
            value = math.nan
        if not (math.isfinite(value) and abs(value) <= limit):
            raise ModelFormatError(
                f"sensor mount {key} is {mount.get(key)!r}, not a number within {limit:g}.",
                file=source,
                field=f"model.sensor.mount.{key}",
                fix=fix,
            )


def body_sigma_m(model: EMModel, source: Path) -> np.ndarray:
    """Sigma_m per step in REP 103's body axes (x forward, y left, yaw; m, rad)."""
    if not model.geometry.has_heading or model.per_action_noise:
        raise ModelFormatError(
            "robot_localization takes one planar Sigma_m; this model is a 1-D track's or has one per action.",
            file=source,
            field="model.motion_sd",
            fix="export a planar model learned on continuous commands (`learn em` on a 2-D log).",
        )
    sideways, forward, heading = model.motion_sd[0]
    # thesis axes (x right, y forward) to REP 103's (x forward, y left): a diagonal Sigma_m only swaps
    return np.diag([(forward * MM) ** 2, (sideways * MM) ** 2, heading**2])


def twist_covariance(sigma_step: np.ndarray, dt_s: float) -> np.ndarray:
    """The 6x6 covariance (vx, vy, vz, vroll, vpitch, vyaw) of a command (or wheel odometry) read as the
    robot's twist over one step: Sigma_m / dt^2, the velocity error that moves the pose as Sigma_m says."""
    per = np.diag(sigma_step) / dt_s**2
    return np.diag([per[0], per[1], UNMEASURED_VAR, UNMEASURED_VAR, UNMEASURED_VAR, per[2]])


def action_model_si(action: Any, dt_s: float) -> JsonObject:
    """The action model's coefficients in SI and REP 103 axes: each velocity (vx forward, vy left, vyaw) as a
    sum of coefficient times feature (1, a command, or a product of commands in their SI units)."""
    from sensact.models.linear_action import monomials

    if action.linear() is None:
        return {"table": action.to_dict(), "note": "an action table (discrete actions): no gains to convert"}
    scaled = [si(n) for n in action.command_names]
    outputs: dict[str, dict[str, float]] = {}
    for j, v in enumerate(action.velocity_names):
        name, out_scale = VELOCITY_REP[v]
        terms = {}
        for i, mono in enumerate(monomials(action.basis, len(action.command_names), action.degree)):
            in_scale = float(np.prod([scaled[k][1] for k in mono])) if mono else 1.0
            feature = "*".join(scaled[k][0] for k in mono) or "constant"
            terms[feature] = float(action.coefficients[i, j]) * out_scale / in_scale
        outputs[name] = terms
    return {
        "commands": [s[0] for s in scaled],
        "delay_s": action.delay_steps * dt_s,
        "velocities": {k: outputs[k] for k in REP_ORDER if k in outputs},
    }


def robot_localization_yaml(doc: JsonObject, source: Path) -> tuple[str, str]:
    """Two files' text: the node's ROS 2 parameter file (only what robot_localization reads, so that
    ``--params-file`` loads it), and sensact's own beside it (what ROS has no parameter for)."""
    import yaml

    model, dt = read_em_doc(doc, source)
    sigma = body_sigma_m(model, source)
    q = process_noise(sigma, dt)
    mount = model.sensor.mount.to_dict()
    sensact = {
        "source": str(source),
        "step_s": dt,
        "sigma_m_per_s_body": (sigma / dt).ravel().tolist(),  # x forward, y left, yaw: Sigma_m / dt, row-major
        **({} if model.turn_var is None else {"turn_variance_per_s": model.turn_var / dt}),
        "twist_covariance": twist_covariance(sigma, dt).ravel().tolist(),
        "action_model": action_model_si(model.action, dt),
        "sensor_mount": {
            "x_m": mount["forward_mm"] * MM,
            "y_m": mount["left_mm"] * MM,
            "yaw_rad": mount["yaw_rad"],
        },
    }
    refuse_non_finite(sensact | {"process_noise_covariance": q.ravel().tolist()}, source)
    rows = ",\n".join("      " + ", ".join(repr(v) for v in row) for row in q.tolist())
    node = f"ekf_filter_node:\n  ros__parameters:\n    two_d_mode: true\n    process_noise_covariance: [\n{rows}]\n"
    header = (
        f"# robot_localization parameters from {source.name}, learned by sensact (SI units, REP 103 axes).\n"
        "# process_noise_covariance: 15x15 per second, states "
        + ", ".join(RL_STATES)
        + ";\n# x, y and yaw from the learned Sigma_m (x and y averaged over headings, as robot_localization\n"
        "# applies them in the world frame), the rest robot_localization's defaults. Merge the node's\n"
        "# ros__parameters into your EKF's; sensact's other numbers (the twist covariance, the action model,\n"
        "# the sensor's mount) are in the .sensact.yaml file beside this one.\n"
    )
    extra = (
        f"# sensact's calibration from {source.name} beyond robot_localization's parameters (SI, REP 103), as\n"
        "# ROS 2 parameters too. sigma_m_per_s_body is 3x3 (x forward, y left, yaw) and twist_covariance 6x6\n"
        "# (vx vy vz vroll vpitch vyaw), row-major: the latter is a command's (or wheel odometry's) covariance\n"
        "# as a twist over one step, for its messages; action_model's velocities are sums of coefficient times\n"
        "# feature (constant, a command, or a product of commands).\n"
    )
    doc = {"sensact_calibration": {"ros__parameters": _ros_values(sensact)}}
    return header + node, extra + yaml.safe_dump(doc, sort_keys=False, default_flow_style=None, width=120)


def _ros_values(value: Any) -> Any:
    """What a ROS 2 parameter file holds: maps, scalars and flat lists (an action table's rows flattened
    row-major), no null."""
    if isinstance(value, dict):
        return {k: _ros_values(v) for k, v in value.items() if v is not None}
    if isinstance(value, list | tuple) and any(isinstance(v, list | tuple) for v in value):
        return [x for v in value for x in (_ros_values(v) if isinstance(v, list | tuple) else [v])]
    return value


def companion_path(out: Path) -> Path:
    """Where sensact's own numbers go beside a robot_localization file: rl.yaml -> rl.sensact.yaml."""
    return out.with_name(f"{out.stem}.sensact{out.suffix or '.yaml'}")


def _log_folder(doc: JsonObject, source: Path) -> Path | None:
    log = doc.get("log")
    if not isinstance(log, str):
        return None
    for candidate in (Path(log), source.parent / log):
        if (candidate / "meta.json").is_file():
            return candidate
    return None


def _t0_s(folder: Path | None) -> float:
    """The log's first step on the recording's own clock (a bag's: epoch seconds), 0 when unknown."""
    if folder is None:
        return 0.0
    from sensact.io.jsonfile import read_json_object

    meta = read_json_object(folder / "meta.json", LogFormatError, "give the log folder's own meta.json.")
    src = meta.get("source") if isinstance(meta.get("source"), dict) else {}
    tables = src.get("tables") if isinstance(src.get("tables"), dict) else {}
    t0 = src.get("t0_s", tables.get("t0_s", 0.0))
    if not isinstance(t0, int | float) or not math.isfinite(t0):
        raise LogFormatError(
            f"source.t0_s {t0!r} is not a time.",
            file=folder / "meta.json",
            field="source.t0_s",
            fix="convert the log again.",
        )
    return float(t0)


def tum_rows(t_s: np.ndarray, x_mm: np.ndarray, y_mm: np.ndarray, theta: np.ndarray) -> str:
    """TUM lines from poses in sensact's frame: metres, yaw = theta + pi/2 (REP 103: 0 faces +x)."""
    yaw = theta + 0.5 * np.pi
    qz, qw = np.sin(yaw / 2), np.cos(yaw / 2)
    return "".join(
        f"{t:.9f} {x * MM!r} {y * MM!r} 0.0 0.0 0.0 {z!r} {w!r}\n"
        for t, x, y, z, w in zip(t_s.tolist(), x_mm.tolist(), y_mm.tolist(), qz.tolist(), qw.tolist(), strict=True)
    )


def _read_path(npz: Path) -> tuple[np.ndarray, np.ndarray]:
    """A planar path's times (s) and poses (x_mm, y_mm, theta_rad), checked: finite, as many times as poses,
    times rising."""
    again = "learn it again with `sensact learn em` (or `localize`)."
    try:
        with np.load(npz, allow_pickle=False) as z:
            names = tuple(str(s) for s in z["state"])
            t, mean = np.asarray(z["time_s"], dtype=np.float64), np.asarray(z["mean"], dtype=np.float64)
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
        raise ModelFormatError(f"not a path sensact wrote ({type(exc).__name__}).", file=npz, fix=again) from None
    if names != ("x_mm", "y_mm", "theta_rad"):
        raise ModelFormatError(
            "a 1-D track's path has no pose to write as TUM.", file=npz, fix="export a planar model's path."
        )
    if t.ndim != 1 or mean.shape != (t.size, 3) or not t.size:
        raise ModelFormatError(f"{t.shape} times for poses of shape {mean.shape}.", file=npz, field="mean", fix=again)
    if not (np.isfinite(t).all() and np.isfinite(mean).all()):
        raise ModelFormatError("the path holds a number that is not finite.", file=npz, field="mean", fix=again)
    if np.any(np.diff(t) <= 0):
        raise ModelFormatError("the path's times do not rise.", file=npz, field="time_s", fix=again)
    return t, mean


def export_tum(doc: JsonObject, source: Path, out: Path, truth_out: Path | None) -> Exported:
    from sensact.io.atomic import write_text

    read_em_doc(doc, source)  # the path is exported only beside a model that reads as one
    npz = source.with_suffix(".path.npz")
    if not npz.is_file():
        raise ModelFormatError(
            f"no smoothed path beside it ({npz.name}).", file=source, fix="learn it again with `sensact learn em`."
        )
    t, mean = _read_path(npz)
    folder = _log_folder(doc, source)
    t0 = _t0_s(folder)
    write_text(out, tum_rows(t0 + t, mean[:, 0], mean[:, 1], mean[:, 2]))
    written, notes = [out], []
    gt = None if folder is None else folder / "groundtruth.csv"
    if gt is not None and gt.is_file():
        from sensact.io.csvtable import read_numeric_csv

        g = read_numeric_csv(gt)
        if {"x_mm", "y_mm", "theta_rad"} <= set(g):
            ok = np.isfinite(g["x_mm"]) & np.isfinite(g["theta_rad"]) & (g.get("valid", np.ones_like(g["x_mm"])) > 0)
            dest = truth_out or out.with_name(f"{out.stem}_truth{out.suffix}")
            write_text(dest, tum_rows(t0 + g["t_s"][ok], g["x_mm"][ok], g["y_mm"][ok], g["theta_rad"][ok]))
            written.append(dest)
        else:
            notes.append("the log's truth has no heading: no truth trajectory written")
    else:
        notes.append("the log folder (or its truth) was not found beside the model: no truth trajectory written")
    return Exported(tuple(written), tuple(notes))


def velodyne_yaml(doc: JsonObject, source: Path) -> str:
    cal = doc.get("velodyne_calibration")
    if not isinstance(cal, dict):
        raise ModelFormatError(
            "not a car model with learned laser angles.",
            file=source,
            field="velodyne_calibration",
            fix="give a model.json written by `sensact learn car` (learn it again if it predates the export).",
        )
    from sensact.io.velodyne_calibration import calibration_from_dict, calibration_yaml

    return calibration_yaml(calibration_from_dict(cal, source))  # checked as a calibration file is


def landmarks_csv(doc: JsonObject, source: Path) -> tuple[str, int]:
    """A learned map (model.json's ``map``) as the file ``--landmarks`` reads: ``id,x_m,y_m`` in the map's
    frame (REP 103 axes), one row per placed landmark; and how many were left out (not placed)."""
    marks = (doc.get("map") or {}).get("landmarks") if isinstance(doc.get("map"), dict) else None
    if not isinstance(marks, list):
        raise ModelFormatError(
            "no learned landmark map in this model.",
            file=source,
            field="map.landmarks",
            fix="export a model `sensact learn em` learned on a log without (or with a partial) --landmarks map.",
        )
    rows, left = [LANDMARKS_HEADER], 0
    for i, m in enumerate(marks):
        x, y = (m.get("x_mm"), m.get("y_mm")) if isinstance(m, dict) else (None, None)
        if x is None or y is None:
            left += 1
            continue
        try:
            xm, ym = float(x) * MM, float(y) * MM
        except (TypeError, ValueError):
            xm = ym = math.nan
        if not (math.isfinite(xm) and math.isfinite(ym) and m.get("id") is not None):
            raise ModelFormatError(
                f"landmark {i + 1} of the map has no id or no finite position.",
                file=source,
                field="map.landmarks",
                fix="learn the model again with `sensact learn em`.",
            )
        rows.append(f"{m['id']},{xm:.6f},{ym:.6f}")
    return "\n".join(rows) + "\n", left


def default_out(model: Path, fmt: str) -> Path:
    """Where an export goes without --out: beside the model, named by it and the format."""
    suffix = {
        "tum": ".tum",
        "robot-localization": ".robot_localization.yaml",
        "velodyne": ".velodyne.yaml",
        "landmarks": ".landmarks.csv",
        "urdf": ".urdf.xacro",
        "diff-drive-controller": ".diff_drive_controller.yaml",
        "navsat-transform": ".navsat_transform.yaml",
        "kalibr": ".imu.yaml",
        "vesc": ".vesc.yaml",
    }
    return model.with_suffix(suffix.get(fmt, f".{fmt}"))


def is_export(path: Path) -> bool:
    """Whether ``path`` is a file sensact exported (any format): its header names sensact, or it is a TUM
    trajectory (rows of eight numbers)."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return False
    first = text.split("\n", 1)[0]
    if first.startswith(("#", "<!--")) and "sensact" in first:
        return True
    if first.strip() == LANDMARKS_HEADER and path.name.endswith(".landmarks.csv"):  # a map export, by its own name
        return True
    rows = [ln.split() for ln in text.splitlines() if ln.strip()]
    try:
        return bool(rows) and all(len(r) == 8 and all(math.isfinite(float(v)) for v in r) for r in rows)
    except ValueError:
        return False


def refuse_to_replace(paths: list[Path | None], model: Path, force: bool) -> None:
    """An export replaces an earlier export, never the model it reads nor a file of the user's (``force``
    overrides the latter); no two of its outputs share a path."""
    from sensact.errors import ConfigError

    given = [p for p in paths if p is not None]
    for p in given:
        if p.exists() and p.resolve() == model.resolve():
            raise ConfigError(f"{p} is the model being exported.", field="--out", fix="give the export its own path.")
        if p.is_file() and not force and not is_export(p):
            raise ConfigError(
                f"{p} exists and is not a sensact export; writing here would replace it.",
                field="--out",
                fix="give a new path, or pass --force to replace it.",
            )
    if len({p.resolve() for p in given}) < len(given):
        raise ConfigError(
            f"two of the export's files would be {given[-1]}.", field="--truth-out", fix="give each its own path."
        )


def export_model(model: Path, fmt: str, out: Path, truth_out: Path | None = None, *, force: bool = False) -> Exported:
    """``model`` in ``fmt`` at ``out`` (and, for tum, the truth's trajectory beside it)."""
    from sensact.errors import ConfigError

    if fmt not in FORMATS:
        raise ConfigError(f"no export format {fmt!r}.", field="--format", fix=f"one of {', '.join(FORMATS)}")
    beside = {
        "tum": truth_out or out.with_name(f"{out.stem}_truth{out.suffix}"),
        "robot-localization": companion_path(out),
    }
    refuse_to_replace([out, beside.get(fmt)], model, force)
    doc = read_model_doc(model)
    from sensact.app.logs import refuse_newer

    refuse_newer(doc, model)
    writers = _writers(doc)
    if fmt not in writers:
        raise ConfigError(
            f"--format {fmt} does not apply to {_what(doc)}.",
            field="--format",
            fix=f"one of {', '.join(writers)} for this model.",
        )
    from dataclasses import replace

    from sensact.health import learned_flag_codes

    return replace(writers[fmt](doc, model, out, truth_out), flags=learned_flag_codes(doc))


def _what(doc: JsonObject) -> str:
    """A model file's family in a user's words, for a refusal."""
    from sensact.io.car_folder import KIND as CAR_KIND
    from sensact.io.inertial_folder import KIND as INERTIAL_KIND
    from sensact.io.lidar2d_folder import KIND as LIDAR2D_KIND

    words = {
        LIDAR2D_KIND: "a wheels-and-2-D-lidar model",
        INERTIAL_KIND: "a wheels, IMU and GNSS model",
        CAR_KIND: "a car model",
    }
    return words.get(str(doc.get("kind")), "this model")


# a format's writer: (model.json, its path, --out, --truth-out) -> what it wrote
Writer = Callable[[JsonObject, Path, Path, "Path | None"], "Exported"]


def _text(render: Callable[[JsonObject, Path], str]) -> Writer:
    """A writer of one file from ``render(doc, source) -> text``."""

    def write(doc: JsonObject, source: Path, out: Path, truth_out: Path | None) -> Exported:
        from sensact.io.atomic import write_text

        write_text(out, render(doc, source))
        return Exported((out,))

    return write


def _with_companion(render: Callable[[JsonObject, Path], tuple[str, str]]) -> Writer:
    """A writer of the node's parameter file and sensact's own beside it, from ``render -> (node, extra)``."""

    def write(doc: JsonObject, source: Path, out: Path, truth_out: Path | None) -> Exported:
        from sensact.io.atomic import write_text

        node, extra = render(doc, source)
        write_text(out, node)
        write_text(companion_path(out), extra)
        return Exported((out, companion_path(out)))

    return write


def _landmarks(doc: JsonObject, source: Path, out: Path, truth_out: Path | None) -> Exported:
    from sensact.io.atomic import write_text

    text, left = landmarks_csv(doc, source)
    write_text(out, text)
    note = f"{left} landmarks were not placed (seen too rarely or from too narrow a baseline) and are left out"
    return Exported((out,), (note,) if left else ())


def _writers(doc: JsonObject) -> dict[str, Writer]:
    """The formats a model file exports to, by what it is: its ``kind`` (a wheels-and-lidar model's
    ``lidar2d``), else a model `learn em` or `learn car` wrote."""
    from sensact.app import export_car, export_inertial, export_lidar2d
    from sensact.io.car_folder import KIND as CAR_KIND
    from sensact.io.inertial_folder import KIND as INERTIAL_KIND
    from sensact.io.intervals import KIND as INTERVALS_KIND
    from sensact.io.lidar2d_folder import KIND as LIDAR2D_KIND

    by_kind = {
        LIDAR2D_KIND: {
            "urdf": _text(export_lidar2d.urdf_snippet),
            "robot-localization": _with_companion(export_lidar2d.robot_localization),
        },
        INTERVALS_KIND: {"urdf": _text(export_lidar2d.urdf_snippet)},
        CAR_KIND: {"vesc": _text(export_car.vesc_yaml), "urdf": _text(export_car.urdf_snippet)},
        INERTIAL_KIND: {
            "diff-drive-controller": _text(export_inertial.diff_drive_controller),
            "robot-localization": _text(export_inertial.robot_localization_ekf),
            "navsat-transform": _text(export_inertial.navsat_transform),
            "urdf": _text(export_inertial.urdf_joints),
            "kalibr": _text(export_inertial.kalibr_imu),
        },
    }
    return by_kind.get(doc.get("kind"), EM_WRITERS)


EM_WRITERS: dict[str, Writer] = {
    "robot-localization": _with_companion(robot_localization_yaml),
    "tum": export_tum,
    "velodyne": _text(velodyne_yaml),
    "landmarks": _landmarks,
}
