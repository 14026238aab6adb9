"""ROS velodyne calibration YAML (the format of ``64e_utexas.yaml``): read it into ``LaserIntrinsics``
and write learned angles back as ``rot_correction`` so that the standard driver can use them."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from sensact.config import safe_yaml
from sensact.errors import LogFormatError
from sensact.io.atomic import write_text
from sensact.models.laser_intrinsics import LaserIntrinsics
from sensact.records import JsonObject


def read_calibration(path: str | Path) -> LaserIntrinsics:
    """A ROS velodyne calibration (YAML), or an Ouster OS-1's metadata JSON (which YAML reads too)."""
    path = Path(path)
    if not path.is_file():
        raise LogFormatError("calibration file not found.", file=path, fix="check the path.")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise LogFormatError("not text (UnicodeDecodeError).", file=path, fix="give the calibration file.") from None
    kind = "JSON" if text.lstrip().startswith("{") else "YAML"
    try:
        # an OS-1 writes its metadata as JSON indented with tabs, which YAML does not allow
        data = json.loads(text) if kind == "JSON" else safe_yaml(text, path, LogFormatError)
    except (yaml.YAMLError, ValueError, RecursionError) as exc:
        problem = f"not valid {kind} ({exc.__class__.__name__})."
        raise LogFormatError(problem, file=path, fix="repair the file.") from None
    if isinstance(data, dict) and "beam_altitude_angles" in data:
        return _ouster_intrinsics(data, path)
    return calibration_from_dict(data, path)


def _ouster_intrinsics(data: JsonObject, path: Path) -> LaserIntrinsics:
    """An OS-1 puts beam i at ``theta_encoder - 2 pi beam_azimuth_angles[i] / 360`` (counterclockwise) and
    elevation ``beam_altitude_angles[i]``, degrees (its user manual): theta_l is minus the azimuth."""
    try:
        alt = np.asarray(data["beam_altitude_angles"], dtype=float).reshape(-1)
        az = np.asarray(data.get("beam_azimuth_angles", np.zeros(alt.size)), dtype=float).reshape(-1)
        if alt.size == 0 or az.shape != alt.shape or not (np.all(np.isfinite(alt)) and np.all(np.isfinite(az))):
            raise ValueError
    except (TypeError, ValueError):
        raise LogFormatError(
            "beam_altitude_angles and beam_azimuth_angles are not two equal lists of numbers.",
            file=path,
            field="beam_altitude_angles",
            fix="give the metadata JSON the OS-1 itself wrote (one altitude and one azimuth per beam, degrees).",
        ) from None
    _refuse_angles_out_of_range(path, np.radians(alt), -np.radians(az), "beam_altitude_angles", "beam_azimuth_angles")
    return LaserIntrinsics(np.radians(alt), -np.radians(az), 0.001)


def _refuse_angles_out_of_range(
    path: Path, vertical: np.ndarray, horizontal: np.ndarray, v_field: str, h_field: str
) -> None:
    """A laser points within a quarter turn of the horizon and its azimuth offset within a half turn: a
    file outside that is in another unit (degrees where radians are read, or the reverse)."""
    for field, values, limit in ((v_field, vertical, math.pi / 2), (h_field, horizontal, math.pi)):
        worst = float(np.max(np.abs(values))) if values.size else 0.0
        if worst > limit:
            raise LogFormatError(
                f"a laser's {field} is {worst:.4g} rad, beyond {limit:.4g} rad: the angles are in another unit.",
                file=path,
                field=field,
                fix="a ROS velodyne calibration gives radians, an Ouster's metadata degrees: check which this is.",
            )


def ouster_metadata(intrinsics: LaserIntrinsics) -> JsonObject:
    """The angles as an OS-1's metadata JSON holds them (degrees; see ``_ouster_intrinsics``)."""
    return {
        "beam_altitude_angles": np.degrees(intrinsics.vertical_rad).tolist(),
        "beam_azimuth_angles": (-np.degrees(intrinsics.horizontal_rad)).tolist(),
    }


def calibration_from_dict(data: Any, path: str | Path) -> LaserIntrinsics:
    """A calibration file's content (or a car model's ``velodyne_calibration``), checked; ``path`` names it."""
    path = Path(path)
    lasers = data.get("lasers") if isinstance(data, dict) else None
    if not isinstance(lasers, list) or not lasers:
        raise LogFormatError(
            "no 'lasers' list.", file=path, field="lasers", fix="give a ROS velodyne calibration file."
        )
    rows: dict[int, JsonObject] = {}
    for i, entry in enumerate(lasers):
        try:
            lid = int(entry["laser_id"])
            if not (math.isfinite(float(entry["rot_correction"])) and math.isfinite(float(entry["vert_correction"]))):
                raise ValueError
        except (KeyError, TypeError, ValueError, OverflowError):
            raise LogFormatError(
                f"laser entry {i} lacks a numeric laser_id, rot_correction or vert_correction.",
                file=path,
                field=f"lasers[{i}]",
                fix="every laser needs laser_id, rot_correction and vert_correction (radians).",
            ) from None
        rows[lid] = dict(entry)
    try:
        n = int(data.get("num_lasers", len(rows)))
    except (TypeError, ValueError, OverflowError):
        n = -1
    if n != len(rows) or sorted(rows) != list(range(n)):  # n is checked before a list of n is made
        raise LogFormatError(
            f"num_lasers is {data.get('num_lasers', len(rows))!r} and the file lists {len(rows)} lasers, ids "
            f"{min(rows)} to {max(rows)}.",
            file=path,
            field="laser_id",
            fix="number the lasers 0 to num_lasers-1, one entry each.",
        )
    ordered = [rows[i] for i in range(n)]
    resolution = data.get("distance_resolution", 0.002)
    if not isinstance(resolution, int | float) or not (math.isfinite(resolution) and resolution > 0):
        raise LogFormatError(
            f"distance_resolution {resolution!r} is not a length.",
            file=path,
            field="distance_resolution",
            fix="give the unit's range step in metres (0.002 for an HDL-64E).",
        )
    vertical = np.array([float(r["vert_correction"]) for r in ordered])
    horizontal = np.array([float(r["rot_correction"]) for r in ordered])
    _refuse_angles_out_of_range(path, vertical, horizontal, "vert_correction", "rot_correction")
    return LaserIntrinsics(
        vertical,
        horizontal,
        float(data.get("distance_resolution", 0.002)),
        tuple({k: v for k, v in r.items() if k not in ("rot_correction", "vert_correction")} for r in ordered),
    )


# what ROS's velodyne driver (velodyne_pointcloud's calibration.cc) reads of every laser besides the two angles
# sec. 5.1 learns, and the value that means "no correction" (a unit's nominal geometry) where no factory
# calibration gave one
DRIVER_DEFAULTS: dict[str, float | int | bool] = {
    "dist_correction": 0.0,
    "dist_correction_x": 0.0,
    "dist_correction_y": 0.0,
    "focal_distance": 0.0,
    "focal_slope": 0.0,
    "horiz_offset_correction": 0.0,
    "max_intensity": 255,
    "min_intensity": 0,
    "two_pt_correction_available": False,
    "vert_offset_correction": 0.0,
}


def calibration_yaml(intrinsics: LaserIntrinsics) -> str:
    """The ROS driver's calibration file: every key its ``calibration.cc`` reads for each laser, the learned
    angles as ``rot_correction``/``vert_correction``, the rest the factory calibration's where one was given,
    else the nominal geometry's (no correction), said in a comment at the top."""
    lasers, filled = [], set()
    for i in range(intrinsics.n_lasers):
        entry = dict(intrinsics.extra[i]) if intrinsics.extra else {}
        filled |= set(DRIVER_DEFAULTS) - set(entry)
        entry = {**DRIVER_DEFAULTS, **entry}
        entry["laser_id"] = i
        entry["rot_correction"] = float(intrinsics.horizontal_rad[i])
        entry["vert_correction"] = float(intrinsics.vertical_rad[i])
        lasers.append(dict(sorted(entry.items())))
    doc = {
        "distance_resolution": intrinsics.distance_resolution_m,
        "lasers": lasers,
        "num_lasers": intrinsics.n_lasers,
    }
    note = "# a ROS velodyne calibration (velodyne_pointcloud), written by sensact\n"
    if filled:
        note += (
            f"# {', '.join(sorted(filled))}: not learned and not in a factory calibration, so the unit's nominal\n"
            "# geometry (no correction); rot_correction and vert_correction are the angles sensact uses.\n"
        )
    return note + yaml.safe_dump(doc, sort_keys=False, default_flow_style=False)


def write_calibration(path: str | Path, intrinsics: LaserIntrinsics) -> Path:
    """Write a ROS velodyne calibration YAML, atomically."""
    return write_text(path, calibration_yaml(intrinsics))
