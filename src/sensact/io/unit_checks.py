"""Catching a column whose name gives the wrong unit, where the numbers show it: bearings in degrees
under a radians name, ranges or commanded speeds in millimetres under a metres name or the other way
round.

A log's units are taken from its column names (``range_m`` is metres, ``bearing_rad`` radians); EM then
starts from a range function and noise in millimetres and radians, so a name that does not match its
numbers ruins the fit without an error. These checks turn the evident cases into one.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sensact.errors import LogFormatError
from sensact.logs.landmark_log import LandmarkLog

DEGREES_SHARE = 0.1  # the share of bearings beyond a whole turn that makes them degrees
RANGE_TO_MAP = (1.0 / 300.0, 30.0)  # the median range over the map's extent; metres vs mm is x1000
SPEED_TO_MAP_PER_S = (1e-4, 3.0)  # the median commanded speed over that extent (MRCLAM's: about 0.01 a second)


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


def unit_doubts(data: LandmarkLog) -> list[str]:
    """A sentence for each of the log's range and speed columns whose size disagrees with the map's by
    orders of magnitude; said before a fit, which such a column would ruin."""
    return [d for d in (range_unit_doubt(data), speed_unit_doubt(data)) if d]


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
