"""Catching a column whose name gives the wrong unit, where the numbers show it: bearings in degrees
under a radians name, ranges in millimetres under a metres name or the other way round.

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
RANGE_TO_MAP = (1.0 / 300.0, 30.0)  # the median range over the map's widest span; metres vs mm is x1000


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


def range_unit_doubt(data: LandmarkLog) -> str | None:
    """A sentence when ``range_mm``'s median is far from the map's size in either direction: the reading
    was in millimetres under an ``_m`` name (x1000) or in metres under an ``_mm`` or bare name. None when
    the sizes agree or the map has one landmark (no size)."""
    if "range_mm" not in data.reading_names or len(data.landmarks_xy) < 2:
        return None
    r = data.obs_readings[:, data.reading_names.index("range_mm")]
    r = np.abs(r[np.isfinite(r)])
    xy = data.landmarks_xy
    span = float(np.max(np.linalg.norm(xy[:, None, :] - xy[None, :, :], axis=-1)))
    if not r.size or span <= 0.0:
        return None
    ratio = float(np.median(r)) / span
    if RANGE_TO_MAP[0] <= ratio <= RANGE_TO_MAP[1]:
        return None
    return (
        f"the median range reading, {np.median(r):.4g} mm, is {ratio:.3g} times the map's widest span "
        f"({span / 1000.0:.3g} m): is its unit right? A column named range_m is read as metres (x1000 to mm), "
        "range_mm as millimetres"
    )
