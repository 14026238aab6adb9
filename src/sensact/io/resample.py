"""Putting a robot's timed records onto EM's fixed step (sec. 4.1's time steps t = 0..T).

Real logs are asynchronous: commands arrive when the controller sends them, a camera reads when it
has a frame, motion capture samples at its own rate. EM needs one step ``dt``. Commands are held from
their row until the next (a zero-order hold: what the motors were told), readings go to the nearest
step, and ground truth is interpolated. ``sensact.io.mrclam`` and ``sensact.io.timed_csv`` share these.
"""

from __future__ import annotations

import math

import numpy as np

from sensact.core.angles import wrap_angle
from sensact.errors import LogFormatError
from sensact.limits import steps_problem

# sensact's planar frame (sec. 2.5.1) has theta = 0 facing world +y with the robot's forward axis its +y;
# the usual robotics frame (ROS REP 103, MRCLAM) has theta = 0 facing +x and the robot driving along its
# +x. Positions and bearings are the same in both; a heading is this much more in sensact's.
HEADING_OFFSET_RAD = -0.5 * np.pi


def step_count(span_s: float, dt_s: float, source: str | None = None, field: str = "time") -> int:
    """The steps of ``dt_s`` on a span of ``span_s`` seconds, refused by name before anything is allocated
    when they are not finite or over ``limits.MAX_STEPS`` (a row's time in ms or ns, one bogus late row)."""
    n = span_s / dt_s + 1 if dt_s > 0 else math.inf
    problem = steps_problem(n, f"the commands' span of {span_s:.6g} s in steps of {dt_s:.6g} s")
    if problem is not None:
        raise LogFormatError(f"{problem}.", file=source, field=field, fix="check the times' column and unit.")
    return int(np.floor(n))


def held_on_grid(
    times: np.ndarray, values: np.ndarray, dt_s: float, source: str | None = None
) -> tuple[float, np.ndarray]:
    """``(t0, held)``: the grid starts at the first (sorted) command time and ends at the last; each
    step takes the last row issued at or before it. ``times`` must be sorted."""
    t0 = float(times[0])
    tol = clock_tolerance_s(times)
    T = step_count(times[-1] - t0 + tol, dt_s, source)
    if T < 2:  # one command, or a step as long as the log: nothing to learn a motion from
        raise LogFormatError(
            f"the commands span {times[-1] - t0:.4g} s in {times.size} row(s): fewer than two steps of {dt_s:.4g} s.",
            file=source,
            field="dt_s",
            fix="give a log with commands over many steps, and a step (--dt) far shorter than it.",
        )
    grid = t0 + np.arange(T) * dt_s
    held = np.searchsorted(times, grid + tol, side="right") - 1
    return t0, values[held]


def nearest_steps(times: np.ndarray, t0: float, dt_s: float, n_steps: int) -> tuple[np.ndarray, np.ndarray]:
    """Each time's nearest step (halfway between two: the later) and whether it lies on the grid
    (steps 0..n_steps-1)."""
    step = np.floor((times - t0 + clock_tolerance_s(times)) / dt_s + 0.5).astype(np.int64)
    return step, (step >= 0) & (step < n_steps)


def clock_tolerance_s(times: np.ndarray) -> float:
    """How far apart two times may be and still be the same instant. A log's clock often counts from
    an epoch (MRCLAM: 1.2e9 s, in ms), where a float carries 2.4e-7 s of rounding; a row logged on
    a step boundary, or halfway between two steps, would then fall on either side by the rounding,
    and the same log would put other rows on other steps depending on its clock's origin. Times
    within a few of the clock's rounding steps (or 1 ns) count as equal, and such ties go to the later step."""
    scale = float(np.max(np.abs(times))) if len(times) else 0.0
    return max(1e-9, 8.0 * float(np.spacing(scale)))


def pose_truth_on_grid(
    grid: np.ndarray,
    t: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    heading: np.ndarray,
    *,
    max_gap_s: float,
    position_scale: float = 1.0,
    heading_offset_rad: float = 0.0,
) -> dict[str, np.ndarray]:
    """Ground-truth poses linearly interpolated onto ``grid`` (the heading unwrapped first, then turned by
    ``heading_offset_rad`` into sensact's frame and wrapped), with ``valid`` 1 only where the two samples
    around a step are less than ``max_gap_s`` apart. Positions are multiplied by ``position_scale`` (to mm)
    after the interpolation. ``t`` must be sorted."""
    idx = np.clip(np.searchsorted(t, grid), 1, len(t) - 1)
    gap = t[idx] - t[idx - 1]
    valid = (grid >= t[0]) & (grid <= t[-1]) & (gap < max_gap_s)
    return {
        "x_mm": np.interp(grid, t, x) * position_scale,
        "y_mm": np.interp(grid, t, y) * position_scale,
        "theta_rad": wrap_angle(np.interp(grid, t, np.unwrap(heading)) + heading_offset_rad),
        "valid": valid.astype(float),
    }
