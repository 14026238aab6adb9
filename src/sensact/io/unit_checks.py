"""Catching a column whose name gives the wrong unit, where the numbers show it: bearings in degrees
under a radians name, ranges or commanded speeds in millimetres under a metres name or the other way
round, a turn rate in degrees per second under a radians name, and a recorded heading that does not
point the way the recorded positions move.

A log's units are taken from its column names (``range_m`` is metres, ``bearing_rad`` radians); EM then
starts from a range function and noise in millimetres and radians, so a name that does not match its
numbers ruins the fit without an error. These checks turn the evident cases into one.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sensact.core.angles import wrap_angle
from sensact.errors import LogFormatError
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.wheel_drive import wheel_pair

DEGREES_SHARE = 0.1  # the share of bearings beyond a whole turn that makes them degrees
RANGE_TO_MAP = (1.0 / 300.0, 30.0)  # the median range over the map's extent; metres vs mm is x1000
SPEED_TO_MAP_PER_S = (1e-4, 3.0)  # the median commanded speed over that extent (MRCLAM's: about 0.01 a second)
# a commanded turn rate's 90th percentile beyond a whole turn a second is degrees per second; MRCLAM's is
# 0.40-0.41 rad/s on robots 1-5 (23 deg/s), the simulated drive's 0.4
TURN_RATE_MAX_RAD_S = 2.0 * np.pi
# a recorded 1-D path's lag-1 autocorrelation below this is not a path: a column shuffled, or another
# column's numbers (a path sampled four times per back-and-forth is at 0; shuffled values at 0 +- 1/sqrt(n))
MIN_PATH_AUTOCORRELATION = 0.3
MIN_PATH_ROWS = 20
PATH_TO_MAP = (1e-2, 1e2)  # the recorded path's extent over the map's (MRCLAM's 0.69-1.08; the simulated 0.56-0.72)


def refuse_degrees_as_radians(path: Path, bearing: np.ndarray, column: str, fix: str) -> None:
    """Bearings in radians never pass a whole turn; degrees from even a +-10 deg camera mostly do."""
    b = np.abs(bearing[np.isfinite(bearing)])
    beyond = float(np.mean(b > 2.0 * np.pi)) if b.size else 0.0
    if beyond > DEGREES_SHARE:
        raise LogFormatError(
            f"{100.0 * beyond:.0f} % of the bearings are beyond a whole turn (up to {b.max():.4g}): they are degrees.",
            file=path,
            field=column,
            fix=fix,
        )


NEGATIVE_SHARE = 0.05  # a range finder's readings this often below zero are not distances (a sign, an offset)


def refuse_negative_ranges(path: Path, values: np.ndarray, column: str) -> None:
    """A column named as a range is a distance (and one in pixels, a landmark's size in the image): a few
    readings below zero are noise about a near surface, more (or a median below zero) are another quantity, or
    a sign flipped."""
    what = "a height in pixels is not negative" if column.endswith("height_px") else "a range is a distance"
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size and (np.median(v) < 0.0 or np.mean(v < 0.0) > NEGATIVE_SHARE):
        raise LogFormatError(
            f"{np.mean(v < 0.0):.0%} of its readings are below zero (median {np.median(v):.4g}): {what}.",
            file=path,
            field=column,
            fix="write what the sensor read (no sign), an empty cell where it read nothing.",
        )


def refuse_scrambled_path(path: Path, x: np.ndarray, column: str) -> None:
    """A recorded distance (the truth a 1-D log is scored against) must move as a robot does, one row to the
    next; one whose rows are no nearer their neighbours than any other row would score the fit on noise."""
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    if x.size < MIN_PATH_ROWS or np.ptp(x) == 0.0:
        return
    d = x - x.mean()
    rho = float(np.dot(d[:-1], d[1:]) / np.dot(d, d))
    if rho < MIN_PATH_AUTOCORRELATION:
        raise LogFormatError(
            f"the recorded distance jumps from row to row (lag-1 autocorrelation {rho:.2f}, a path's is near 1): "
            "its rows are out of order, or it is another column.",
            file=path,
            field=column,
            fix="sort the recorded distance with its rows' times, or drop the column (it is only scored against).",
        )


def unit_doubts(data: LandmarkLog, truth_poses: tuple[np.ndarray, np.ndarray] | None = None) -> list[str]:
    """A sentence for each of the log's range and speed columns whose size disagrees with the map's by
    orders of magnitude, a turn rate in degrees per second, and recorded poses ``(poses, valid)`` whose
    path disagrees with the map's size; said before a fit, which such a column would ruin (the truth's
    would ruin its score)."""
    doubts = (
        range_unit_doubt(data),
        speed_unit_doubt(data),
        turn_unit_doubt(data),
        truth_unit_doubt(data, truth_poses),
    )
    return [d for d in doubts if d]


def refuse_map_off_the_ranges_scale(path: Path, xy_mm: np.ndarray, ranges_m: np.ndarray) -> None:
    """A map given beside readings whose unit is certain (a bag's, in metres by REP 103): a median range
    orders of magnitude off the map's extent makes the map's unit wrong, which ``range_unit_doubt`` can
    only doubt where the range's column name might be the wrong one."""
    xy = np.asarray(xy_mm, dtype=float).reshape(-1, 2)
    r = np.abs(np.asarray(ranges_m, dtype=float))
    r = r[np.isfinite(r)]
    span_m = float(np.hypot(*np.ptp(xy, axis=0))) / 1000.0 if len(xy) >= 2 else 0.0
    if span_m <= 0.0 or not r.size:
        return
    median_m = float(np.median(r))  # robust to the odd absurd range, which the table's own checks refuse
    ratio = median_m / span_m
    if not RANGE_TO_MAP[0] <= ratio <= RANGE_TO_MAP[1]:
        raise LogFormatError(
            f"the map spans {span_m:.4g} m, {1.0 / ratio:.3g} times the sightings' median range "
            f"({median_m:.3g} m, in metres as ROS gives it): the map is in another unit.",
            file=path,
            field="x_m, y_m",
            fix="write the map in metres (id,x_m,y_m), or name its columns x_mm,y_mm if they are millimetres.",
        )


def _map_span(data: LandmarkLog) -> float:
    """The map's extent (mm), its bounding box's diagonal: between its widest span and 1.42 times it,
    which serves checks of orders of magnitude at any number of landmarks. 0 with one landmark (a
    track's), which gives no size to compare with."""
    xy = data.landmarks_xy
    if len(xy) < 2:
        return 0.0
    return float(np.hypot(*np.ptp(xy, axis=0)))


def speed_unit_doubt(data: LandmarkLog) -> str | None:
    """A sentence when the commanded speeds (columns ending ``_mm_s``) would cross the map many times a
    second or hardly in hours: m/s under an ``_mm_s`` name or mm/s under an ``_m_s`` one (x1000)."""
    cols = [j for j, n in enumerate(data.command_names) if n.endswith("_mm_s")]
    span = _map_span(data)
    if data.step_commands is None or not cols or span <= 0.0:
        return None
    v = np.abs(data.step_commands[:, cols]).ravel()
    v = v[v > 0.0]
    if not v.size:
        return None
    ratio = float(np.median(v)) / span
    if SPEED_TO_MAP_PER_S[0] <= ratio <= SPEED_TO_MAP_PER_S[1]:
        return None
    names = ", ".join(data.command_names[j] for j in cols)
    return (
        f"the median commanded speed ({names}), {np.median(v):.4g} mm/s, crosses the map's extent "
        f"({span / 1000.0:.3g} m) {ratio:.3g} times a second: is its unit right? A column named v_m_s is read as "
        "metres per second (x1000 to mm/s), v_mm_s as millimetres per second"
    )


def truth_unit_doubt(data: LandmarkLog, truth_poses: tuple[np.ndarray, np.ndarray] | None) -> str | None:
    """A sentence when the recorded path's extent is orders of magnitude off the map's: its positions in
    millimetres under an ``_m`` name, or metres under an ``_mm`` one (x1000 either way)."""
    span = _map_span(data)
    if truth_poses is None or span <= 0.0:
        return None
    poses, valid = truth_poses
    xy = poses[np.asarray(valid, dtype=bool), :2]
    if len(xy) < 2:
        return None
    extent = float(np.hypot(*np.ptp(xy, axis=0)))
    ratio = extent / span
    if extent <= 0.0 or PATH_TO_MAP[0] <= ratio <= PATH_TO_MAP[1]:
        return None
    return (
        f"the recorded path spans {extent / 1000.0:.4g} m, {ratio:.3g} times the map's extent ({span / 1000.0:.3g} m): "
        "is its unit right? A truth column named x_m is read as metres (x1000 to mm), x_mm as millimetres"
    )


def turn_unit_doubt(data: LandmarkLog) -> str | None:
    """A sentence when a commanded turn rate (a column ending ``_rad_s``, not a wheel's, which may spin
    faster) turns more than a whole turn a second at its 90th percentile: degrees per second under a
    radians name. Its other side is not judged: a robot may turn slowly throughout."""
    wheels = wheel_pair(data.command_names) or ()
    cols = [j for j, n in enumerate(data.command_names) if n.endswith("_rad_s") and n not in wheels]
    if data.step_commands is None or not cols:
        return None
    for j in cols:
        w = np.abs(data.step_commands[:, j])
        w = w[w > 0.0]
        if w.size and (p90 := float(np.percentile(w, 90))) > TURN_RATE_MAX_RAD_S:
            name = data.command_names[j]
            return (
                f"the commanded turn rate {name} is {p90:.4g} rad/s at its 90th percentile, over a whole turn a "
                f"second: is it degrees per second? A column named {name[: -len('_rad_s')]}_deg_s is read as "
                "degrees per second (x pi/180)"
            )
    return None


def range_unit_doubt(data: LandmarkLog) -> str | None:
    """A sentence when ``range_mm``'s median is far from the map's size in either direction: the reading
    was in millimetres under an ``_m`` name (x1000) or in metres under an ``_mm`` or bare name. None when
    the sizes agree or the map has one landmark (no size)."""
    span = _map_span(data)
    if "range_mm" not in data.reading_names or span <= 0.0:
        return None
    r = data.obs_readings[:, data.reading_names.index("range_mm")]
    r = np.abs(r[np.isfinite(r)])
    if not r.size:
        return None
    ratio = float(np.median(r)) / span
    if RANGE_TO_MAP[0] <= ratio <= RANGE_TO_MAP[1]:
        return None
    return (
        f"the median range reading, {np.median(r):.4g} mm, is {ratio:.3g} times the map's extent "
        f"({span / 1000.0:.3g} m): is its unit right? A column named range_m is read as metres (x1000 to mm), "
        "range_mm as millimetres"
    )


# A recorded heading against the way the recorded positions move (a motion-capture body defined with
# other axes than the robot's, a compass heading, degrees under a radians name): a differential drive
# travels along its heading, forward or backward, so the chord of each second's move points along the
# heading at its middle. Measured (1-s moves of at least 30 mm): MRCLAM robots 1-5's Vicon agrees at
# 0.997-0.999 with a mean offset under 0.02 rad, the simulated drives at 0.999; a heading read in a
# wrong unit or sense agrees at most at 0.77, a robot that side-steps at 0.87 and the tests' robot that
# slips as it circles at 0.89, whichever way they are read. The moves' own directions spread (axial
# resultant 0.23-0.44 on MRCLAM, 0.65-0.78 on five simulated minutes); on a run that keeps one line
# (0.996 on a simulated minute) only the heading as written is judged.
HEADING_MOVE_S = 1.0
HEADING_MOVE_MM = 30.0
HEADING_AGREES = 0.95  # the moves' axial mean resultant length that makes a reading of the heading right
HEADING_OFFSET_RAD = 0.2  # a mean offset beyond this is named (the Vicon's: under 0.02)
HEADING_MIN_MOVES = 50
HEADING_ONE_WAY = 0.5  # the moves' resultant beyond which the robot mostly drives one way (3 in 4 moves)
HEADING_TRAVEL_SPREAD = 0.85  # the travel directions' axial resultant beyond which the moves keep one line
# other ways a heading column can be written, as the world angle each gives (before the convention's zero)
HEADING_READINGS = (
    ("in degrees", np.deg2rad, "{col} * pi/180 (name the column theta_deg)"),
    ("clockwise", np.negative, "-{col}"),
    ("clockwise in degrees (a compass heading?)", lambda h: -np.deg2rad(h), "-{col} * pi/180"),
)
# the same of a column the file names in degrees (theta_deg), whose values are already turned into radians
HEADING_READINGS_OF_DEGREES = (
    ("in radians", np.rad2deg, "{col} * 180/pi (or name the column theta_rad)"),
    ("clockwise", np.negative, "-{col}"),
    ("clockwise in radians", lambda h: -np.rad2deg(h), "-{col} * 180/pi"),
)


def _moves(t: np.ndarray, x: np.ndarray, y: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each ``HEADING_MOVE_S`` move of at least ``HEADING_MOVE_MM`` between valid rows: its first and last
    rows and the direction it travels."""
    j = np.searchsorted(t, t + HEADING_MOVE_S)
    i = np.flatnonzero(j < len(t))
    j = j[i]
    dx, dy = x[j] - x[i], y[j] - y[i]
    keep = valid[i] & valid[j] & (np.hypot(dx, dy) >= HEADING_MOVE_MM)
    return i[keep], j[keep], np.arctan2(dy[keep], dx[keep])


def _agreement(i: np.ndarray, j: np.ndarray, travel: np.ndarray, facing: np.ndarray) -> tuple[int, float, float]:
    """``(moves, agreement, offset)`` of the moves' travel against ``facing`` at each move's middle (a
    chord's direction is its mid-heading, on moves that turn less than 1 rad): the axial mean resultant,
    which counts driving backward as agreeing, and the mean offset, taken one-way when the robot mostly
    drives one way (so that it tells a heading pointing behind the robot) and axially otherwise."""
    turn = wrap_angle(facing[j] - facing[i])
    chord = np.abs(turn) < 1.0
    off = travel[chord] - (facing[i[chord]] + 0.5 * turn[chord])
    if off.size < HEADING_MIN_MOVES:
        return int(off.size), 0.0, 0.0
    z2, z1 = np.mean(np.exp(2j * off)), np.mean(np.exp(1j * off))
    offset = float(np.angle(z1)) if abs(z1) >= HEADING_ONE_WAY else float(np.angle(z2) / 2.0)
    return int(off.size), float(abs(z2)), offset


def truth_heading_doubt(
    t_s: np.ndarray,
    x_mm: np.ndarray,
    y_mm: np.ndarray,
    heading: np.ndarray,
    valid: np.ndarray | None = None,
    *,
    zero_rad: float,
    column: str,
    convention: str,
    in_degrees: bool = False,
) -> str | None:
    """A sentence when a recorded heading does not point the way the recorded positions move, but would
    read another way (degrees, clockwise, turned by a constant), with the column it should hold; None
    when it agrees, when too little moves, or when no reading agrees (a robot that side-steps).
    ``zero_rad``: the world angle the column's 0 faces (0 for ROS REP 103, pi/2 for sensact's frame);
    ``heading`` is in radians, and ``in_degrees`` says the file wrote it in degrees (so the fix is too)."""
    t = np.asarray(t_s, dtype=float)
    order = np.argsort(t, kind="stable")
    t, x, y, h = t[order], np.asarray(x_mm)[order], np.asarray(y_mm)[order], np.asarray(heading)[order]
    ok = np.ones(len(t), dtype=bool) if valid is None else np.asarray(valid, dtype=bool)[order]
    i, j, travel = _moves(t, x, y, ok)
    n, agree, offset = _agreement(i, j, travel, h + zero_rad)
    how, expression = "as written", "{col}"
    if agree >= HEADING_AGREES:
        if abs(offset) <= HEADING_OFFSET_RAD:
            return None
    elif travel.size and abs(np.mean(np.exp(2j * travel))) <= HEADING_TRAVEL_SPREAD:
        # another reading is told only where the moves go many ways: on a run that keeps one direction a
        # heading read in degrees is nearly constant and would agree too
        found = [
            (*_agreement(i, j, travel, reading(h) + zero_rad), how, expression)
            for how, reading, expression in (HEADING_READINGS_OF_DEGREES if in_degrees else HEADING_READINGS)
        ]
        n, agree, offset, how, expression = max(found, key=lambda f: f[1])
        if agree < HEADING_AGREES:
            return None
    else:
        return None
    turned = abs(offset) > HEADING_OFFSET_RAD
    by = f"{offset:+.3f} rad ({np.degrees(offset):+.0f} deg)"
    hint = ""
    if abs(abs(offset) - 0.5 * np.pi) < 0.1:
        hint = " (a quarter turn: its 0 faces another axis)"
    elif abs(offset) > np.pi - 0.1:
        hint = " (it points behind the robot, or the robot mostly reverses)"
    if how == "as written":
        said = f"is {by} off the way the robot moves{hint}"
    else:
        said = f"follows the way the robot moves only read {how}" + (f", turned by {by}{hint}" if turned else "")
    by_written = f"{abs(np.degrees(offset)):.1f}" if in_degrees else f"{abs(offset):.3f}"
    value = expression.format(col=column) + (f" {'+' if offset > 0 else '-'} {by_written}" if turned else "")
    return (
        f"the recorded heading ({column}) {said}, over {n} moves of {HEADING_MOVE_S:g} s; {column} is read as "
        f"{convention}, so the scores against this truth (From-Truth, the sensor's pose, the path) are off: "
        f"write {column} = {value}"
    )


def groundtruth_heading_doubt(poses: np.ndarray, valid: np.ndarray, dt_s: float) -> str | None:
    """``truth_heading_doubt`` of a log folder's recorded poses (``groundtruth.csv`` on the step grid, in
    sensact's frame: 0 facing +y), where a score or a path is read against them."""
    return truth_heading_doubt(
        np.arange(len(poses)) * dt_s,
        poses[:, 0],
        poses[:, 1],
        poses[:, 2],
        valid,
        zero_rad=0.5 * np.pi,
        column="theta_rad",
        convention="sensact's heading (radians, counterclockwise, 0 facing +y; `convert csv` turns a ROS REP 103 "
        "heading into it)",
    )
