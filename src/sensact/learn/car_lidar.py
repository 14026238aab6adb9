"""A car-like robot's VESC numbers, wheelbase, delays and its 2-D lidar's mount, learned together from the
VESC's ERPM, the servo's commands and scan matching, with no ground truth and no map (docs/ackermann.md).

The car moves by the kinematic bicycle at its rear axle (the thesis's chapter 5 learns a car's motion from
scan matching; here its steering as well): its speed is the motor's ERPM through the speed gain and offset,
``v = (ERPM - offset) / gain``, and its curvature the servo's position through the steering gain and offset and
the wheelbase, ``kappa = tan((servo - offset) / gain) / L``. Over an interval between two scans the lidar's
displacement predicted from them, ``l^-1 (+) o (+) l`` for the lidar's mount ``l``, is matched against the scan
matcher's, and everything is fitted by maximum likelihood as the wheels-and-lidar route fits a differential
drive (``wheel_lidar.fit_intervals``: the residual's variance per axis growing with distance and turn, outliers
beyond 4 sd set aside, error bars from the curvature).

At small angles the curvature is ``(servo - offset) / (gain * L)``: only the product of the steering gain and the
wheelbase shows, and the two part only through the tangent's bend on tight turns. So the fit's parameters are
that product ``P = gain * L`` (in servo units times metres per radian) and ``u = 1 / gain^2``, with which
``kappa = g tan(x / g) / P`` (``x = servo - offset``) is smooth through ``u = 0``; the gain is
``sign(P) / sqrt(u)`` and the wheelbase ``|P| sqrt(u)`` where ``u`` is known to be positive; where it is not,
the app flags the wheelbase as not identified and ``P`` is the answer.

The speed's delay is the VESC's clock behind the lidar's (its reports stamped late); the steering's, how long
the wheels take to follow a servo command.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sensact.core.angles import wrap_angle
from sensact.core.pose_models import (
    apply_displacement,
    arc_poses,
    from_rep103,
    relative_displacement,
    sensor_poses,
    to_rep103,
)
from sensact.errors import LogFormatError
from sensact.learn.scan_match2d import scan_xy
from sensact.learn.wheel_lidar import (
    Matches,
    RangeNoise,
    WheelLidarFit,
    fit_intervals,
    keyframes_of,
    match_pairs,
    range_noise,
)
from sensact.logs.car_log import CarLog
from sensact.progress import Progress
from sensact.records import JsonObject

PARAMETERS = (
    "speed_to_erpm_gain",  # ERPM per m/s
    "speed_to_erpm_offset",  # ERPM
    "servo_per_curvature",  # P = steering gain x wheelbase, servo units x m / rad
    "steering_angle_to_servo_offset",  # servo units
    "inverse_gain_squared",  # u = 1 / steering gain^2
    "forward_mm",
    "left_mm",
    "yaw_rad",
    "steering_delay_s",
    "speed_delay_s",
)
KEYFRAME_MM, KEYFRAME_RAD = 400.0, 0.35
# each round deskews the scans by the last round's fit and matches every n-th keyframe pair: a scan bent by a
# wrong motion (above all a wrong steering delay) is matched as bent, and the fit follows it, so the rounds
# go on until the deskew is the fit's own; the early ones, which only bring it near, match a sample
ROUNDS = (4, 2, 1)
PROBE_EVERY = 32  # the first look at the motion: every 32nd pair of consecutive scans
NOISE_SCANS = 600  # the range noise is the lidar's: this many scans, spread over the log, tell it
# the scan matcher's surfaces are drawn through each beam's neighbours: beams closer than this are thinned, so
# that a range's noise does not turn a surface's normal (and the matcher is quicker)
BEAM_SPACING_RAD = math.radians(0.7)
# a surface's end that an edge nearer the lidar hides slides along it as the lidar moves: beams this close to a
# jump in range are not matched (matched as fixed places, they stretched the matches by 0.1-0.25 % along the
# travel in the simulated corridors, a bias the speed gain and the wheelbase inherit)
EDGE_RAD = math.radians(1.5)
MIN_SPEED_M_S = 0.3  # slower, a curvature from a turn over a distance is noise
MIN_TURN_RAD = 1.0  # the steering shows only in turns
# what a log must pin down for an answer: the mount (mm, rad), the speed gain and wheelbase (share of themselves)
MOUNT_SD_MM, MOUNT_SD_RAD, GAIN_SD_SHARE, WHEELBASE_SD_SHARE = 10.0 / 3, math.radians(0.5) / 3, 0.01 / 3, 0.02 / 3


# --- the car's motion ---
def bend(x: np.ndarray, u: float) -> np.ndarray:
    """``g tan(x / g)`` with ``u = 1 / g^2``: ``tan(x sqrt(u)) / sqrt(u)``, smooth through ``u = 0`` (where it is
    ``x``) and ``tanh``'s for ``u < 0``."""
    z = u * x * x
    series = x * (1 + z / 3 + 2 * z * z / 15)
    r = math.sqrt(abs(u))
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        exact = np.tan(x * r) / r if u > 0 else np.tanh(x * r) / max(r, 1e-300)
    return np.where(np.abs(z) < 1e-4, series, exact)


@dataclass(frozen=True, eq=False)
class CarDrive:
    """The VESC's ERPM and the servo's commands, each on its own clock (the lidar's)."""

    erpm_t: np.ndarray
    erpm: np.ndarray
    servo_t: np.ndarray
    servo: np.ndarray

    def held_mean(self, values: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """``values`` (one per servo command, each held until the next, as the servo's pulse is) averaged over
        ``[a, b]``: the exact integral of that step function, which a shift in time moves smoothly."""
        held = np.concatenate([[0.0], np.cumsum(values[:-1] * np.diff(self.servo_t))])

        def integral(t: np.ndarray) -> np.ndarray:  # beyond the ends, the first and last commands held
            inside = np.interp(t, self.servo_t, held)
            return (
                inside
                + np.minimum(t - self.servo_t[0], 0) * values[0]
                + np.maximum(t - self.servo_t[-1], 0) * values[-1]
            )

        return (integral(b) - integral(a)) / (b - a)

    def track(self, params: np.ndarray, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The rear axle's poses (sensact's axes, mm) on a grid of times (the lidar's clock) that holds the VESC's
        reports and ``times``: the speed linear between reports, the curvature each servo command gives, held
        until the next, ``steering_delay_s`` later. A pose at one of ``times`` is then the integral up to that
        very time, which a delay moves smoothly (interpolated between reports, the fit would stick where the
        reports' and the scans' clocks line up)."""
        k_v, o_v, p, o_s, u, *_, d_s, d_v = params
        t_e = self.erpm_t - d_v
        # the servo's commands as they reach the wheels are on the grid too: its curvature is then one within
        # each step, whose arc is exact (a command that changed mid-step bent a deskewed scan by up to 10 mm)
        grid = np.concatenate([t_e, times, self.servo_t + d_s])
        grid.sort(kind="stable")  # three sorted runs: merged, not sorted afresh
        grid = grid[np.concatenate([[True], np.diff(grid) > 0])]
        v = np.interp(grid, t_e, (self.erpm - o_v) / k_v * 1000.0)  # mm/s
        ds = (v[:-1] + v[1:]) / 2 * np.diff(grid)
        # each command's curvature, held: a step that spans a command's change has the mean of the two curvatures
        kappa = self.held_mean(bend(self.servo - o_s, u), grid[:-1] - d_s, grid[1:] - d_s) / (p * 1000.0)  # 1/mm
        return arc_poses(ds, ds * kappa), grid


def along_arcs(grid: np.ndarray, poses: np.ndarray, times: np.ndarray) -> np.ndarray:
    """The poses at ``times`` between the ``grid``'s, each step driven as the arc it is (its turn in proportion to
    its time): on a chord, a lidar ahead of the axle in a tight turn would move 1 % less sideways through a sweep
    than it does, and a scan deskewed so is bent into its matches' turns (0.06 % more turn in every tight corner,
    which moved the wheelbase 0.25 %)."""
    k = np.clip(np.searchsorted(grid, times, side="right") - 1, 0, grid.size - 2)
    phi = np.clip((times - grid[k]) / (grid[k + 1] - grid[k]), 0.0, 1.0)
    step = relative_displacement(poses[k], poses[k + 1])  # (chord in the step's start frame, turn)
    dth = step[:, 2]
    ds = np.hypot(step[:, 0], step[:, 1]) / np.maximum(np.sinc(dth / (2 * np.pi)), 1e-9)
    part = np.column_stack([np.zeros(times.size), phi * ds, phi * dth])
    chord = part[:, 1] * np.sinc(part[:, 2] / (2 * np.pi))
    mid = part[:, 2] / 2
    sign = np.sign(step[:, 1]) + (step[:, 1] == 0)  # reversing: the arc runs backward
    local = np.column_stack([-sign * chord * np.sin(mid), sign * chord * np.cos(mid), part[:, 2]])
    return apply_displacement(poses[k], local)


def poses_at(drive: CarDrive, params: np.ndarray, times: np.ndarray) -> np.ndarray:
    poses, grid = drive.track(params, times)
    return poses[np.searchsorted(grid, times)]


def predicted(params: np.ndarray, drive: CarDrive, scan_t: np.ndarray, i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """The lidar's displacement from scan ``i`` to ``j`` the VESC predicts: ``l^-1 (+) o (+) l``."""
    mount = params[5:8]
    at = poses_at(drive, params, scan_t)
    lidar = sensor_poses(np.zeros(3), mount)
    return relative_displacement(lidar, sensor_poses(relative_displacement(at[i], at[j]), mount))


def interval_size(params: np.ndarray, drive: CarDrive, scan_t: np.ndarray, m: Matches) -> tuple[np.ndarray, np.ndarray]:
    at = poses_at(drive, params, scan_t)
    o = relative_displacement(at[m.i], at[m.j])
    return np.hypot(o[:, 0], o[:, 1]), np.abs(o[:, 2])


def fit(drive: CarDrive, scan_t: np.ndarray, m: Matches, start: np.ndarray, rounds: int = 5) -> WheelLidarFit:
    """The maximum-likelihood VESC numbers, wheelbase, mount and delays on the matched intervals, from ``start``."""
    k_v, _, p, _, u, *_ = start
    g = 1 / math.sqrt(u) if u > 0 else abs(p) / 0.3
    scale = np.array(
        [abs(k_v) / 100, abs(k_v) / 100, abs(p) / 100, abs(g) * 0.003, 1 / g**2 / 5, 10.0, 10.0, 0.01, 0.01, 0.01]
    )

    def predict(params: np.ndarray, rows: np.ndarray | slice) -> np.ndarray:
        return predicted(params, drive, scan_t, m.i[rows], m.j[rows])

    def size(params: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return interval_size(params, drive, scan_t, m)

    return fit_intervals(predict, size, m, start, scale, len(PARAMETERS), rounds)


# --- the scans ---
def deskewed(log: CarLog, drive: CarDrive, params: np.ndarray | None, which: np.ndarray) -> dict[int, np.ndarray]:
    """Scans ``which``'s points in the lidar's frame (REP 103) at their stamps, each beam moved to where the lidar
    was at the stamp by the car's motion (``params``; None: as taken); NaN where no return."""
    every = thinning(log)
    edge = max(1, round(EDGE_RAD / (abs(log.scan.angle_increment_rad) * every)))
    angles = log.scan.angles(log.beams)[::every]
    beam_dt = log.scan.time_increment_s * np.arange(log.beams)[::every]
    if params is not None:
        mount = params[5:8]
        poses, t = drive.track(params, log.scan_t)
    out = {}
    for k in which.tolist():
        r = log.ranges_mm[k, ::every]
        xy = scan_xy(r, angles)
        ok = np.isfinite(xy[:, 0]) & ~shadow_edges(r, edge)
        if params is not None and log.scan.time_increment_s > 0:
            at = along_arcs(t, poses, log.scan_t[k] + beam_dt)
            sensor = sensor_poses(at, mount)
            rel = relative_displacement(sensor[0], sensor)
            xy = to_rep103(apply_displacement(rel, from_rep103(np.column_stack([xy, np.zeros(len(xy))]))))[:, :2]
        out[k] = np.where(ok[:, None], xy, np.nan)
    return out


def shadow_edges(r: np.ndarray, width: int) -> np.ndarray:
    """Beams within ``width`` of a jump in range (or of no return): the ends of a surface that an edge nearer the
    lidar hides. They are no fixed place in the world (they slide along the hidden wall as the lidar moves), and
    matched as if they were, they pull a match along the car's travel."""
    with np.errstate(invalid="ignore"):
        jump = ~(np.abs(np.diff(r)) <= 0.05 * np.fmin(r[1:], r[:-1]) + 50.0)
    edge = np.zeros(r.size, dtype=bool)
    for k in np.flatnonzero(jump):
        edge[max(0, k - width + 1) : k + width + 1] = True
    return edge


def thinning(log: CarLog) -> int:
    """Every how many beams the scan matcher takes."""
    return max(1, round(BEAM_SPACING_RAD / abs(log.scan.angle_increment_rad)))


def _points_list(log: CarLog, points: dict[int, np.ndarray]) -> list[np.ndarray]:
    """``match_pairs``' list, the scans not matched left empty."""
    empty = np.zeros((0, 2))
    return [points.get(k, empty) for k in range(log.scan_t.size)]


def keyframes(
    drive: CarDrive, params: np.ndarray, scan_t: np.ndarray, usable: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Pairs of usable scans ``KEYFRAME_MM`` or ``KEYFRAME_RAD`` apart by the car's motion, each from the last."""
    return keyframes_of(poses_at(drive, params, scan_t), usable, KEYFRAME_MM, KEYFRAME_RAD)


def _too_few_matched(log: CarLog, m: Matches, what: str) -> None:
    raise LogFormatError(
        f"only {len(m.i)} of {m.tried} {what} could be matched: the scans do not see enough of the same walls.",
        file=log.source,
        field="scans.csv",
        fix="record on a track with walls within the lidar's range, at its full rate.",
    )


# --- the first look: no guess ---
@dataclass(frozen=True)
class FirstLook:
    """What a sample of consecutive scans, matched from standing still, says of the car before any fit."""

    params: np.ndarray  # PARAMETERS' order
    turned_rad: float
    servo_spread: float  # the servo's commands' spread while moving
    notes: tuple[str, ...]


def first_look(log: CarLog, drive: CarDrive, progress: Progress | None) -> FirstLook:
    """Every ``PROBE_EVERY``th pair of consecutive scans matched from no motion (25 ms at 40 Hz is a few cm):
    the lidar's speed against the ERPM gives the speed gain and offset, its turn rate over its speed against the
    servo the steering offset and ``P``, its direction of travel the mount's yaw. The mount's position starts
    where /tf_static says, or at 0."""
    n = log.scan_t.size
    i = np.arange(0, n - 1, max(1, min(PROBE_EVERY, n // 300)))  # a short log's every pair
    points = deskewed(log, drive, None, np.unique(np.concatenate([i, i + 1])))
    m = match_pairs(
        _points_list(log, points),
        abs(log.scan.angle_increment_rad) * thinning(log),
        i,
        i + 1,
        None,
        progress,
        "a first look",
    )
    if len(m.i) < 20:
        _too_few_matched(log, m, "consecutive scans")
    dt = log.scan_t[m.j] - log.scan_t[m.i]
    mid = (log.scan_t[m.i] + log.scan_t[m.j]) / 2
    speed = np.hypot(m.s[:, 0], m.s[:, 1]) / dt / 1000  # m/s of the lidar
    rate = wrap_angle(m.s[:, 2]) / dt
    erpm = np.interp(mid, drive.erpm_t, drive.erpm)
    servo = np.interp(mid, drive.servo_t, drive.servo)
    moving = speed > MIN_SPEED_M_S
    if moving.sum() < 10:
        raise LogFormatError(
            f"the car hardly moved: {int(moving.sum())} of {len(m.i)} sampled scan pairs move faster than "
            f"{MIN_SPEED_M_S} m/s.",
            file=log.source,
            field="vesc.csv",
            fix="record the car driving laps for a few minutes.",
        )
    a = np.column_stack([speed, np.ones(len(speed))])
    (k_v, o_v), *_ = np.linalg.lstsq(a[moving], erpm[moving], rcond=None)  # ERPM = k v + o
    spread = float(np.std(servo[moving]))
    turned = float(np.abs(wrap_angle(m.s[:, 2])).sum() * (n - 1) / len(i))
    if spread < 1e-6:
        raise LogFormatError(
            f"the servo's command never moves ({float(servo[moving][0]):.6g} throughout): the steering cannot be "
            "learned.",
            file=log.source,
            field="servo",
            fix="record /sensors/servo_position_command while the car steers (both ways).",
        )
    if turned < MIN_TURN_RAD:
        raise LogFormatError(
            f"the car never steered: it turned {turned:.2g} rad in all, and the steering shows only in turns.",
            file=log.source,
            field="servo",
            fix="record the car driving curves (tight ones, both ways) as well as straight.",
        )
    curv = rate[moving] / speed[moving]  # 1/m of the car (the mount's offset aside)
    (c1, c0), *_ = np.linalg.lstsq(np.column_stack([servo[moving], np.ones(moving.sum())]), curv, rcond=None)
    p = 1 / c1  # kappa = (servo - o) / P
    o_s = -c0 * p
    # the lidar's direction of travel in its own frame, the car driving forward: the mount's yaw
    heading = np.arctan2(m.s[moving, 1], m.s[moving, 0])  # sensact's axes: +y is ahead
    straight = np.abs(rate[moving]) < 0.2
    yaw = -float(np.median(wrap_angle(heading[straight] - np.pi / 2))) if straight.sum() >= 5 else 0.0
    mount = log.urdf.mount
    fwd, left = (mount.forward_mm, mount.left_mm) if mount is not None else (0.0, 0.0)
    notes = () if mount is not None else ("/tf_static gave no lidar mount: the fit started it at the rear axle",)
    # u starts at a steering gain of P / 0.33 m (a 1/10-scale car's wheelbase): its sign and size are P's
    g = abs(p) / 0.33
    params = np.array([k_v, o_v, p, o_s, 1 / g**2, fwd, left, yaw, 0.0, 0.0])
    return FirstLook(params, turned, spread, notes)


@dataclass(frozen=True)
class CarLidarResult:
    fit: WheelLidarFit
    first: FirstLook
    range: RangeNoise
    drive: CarDrive
    rounds: tuple[int, ...]


def learn_car_lidar(log: CarLog, progress: Progress | None = None, rounds: tuple[int, ...] = ROUNDS) -> CarLidarResult:
    """The whole calibration from no guess: a first look at a sample of consecutive scans, then keyframes matched
    from the car's predicted motion and deskewed by it, and the maximum-likelihood fit; a round for each of
    ``rounds`` (every how many keyframe pairs it matches), each deskewing by the last one's fit."""
    log = log.from_its_start()
    drive = CarDrive(log.erpm_t, log.erpm, log.servo_t, log.servo)
    first = first_look(log, drive, progress)
    params = first.params
    inc = abs(log.scan.angle_increment_rad) * thinning(log)
    usable = np.isfinite(log.ranges_mm).sum(axis=1) >= 40
    result = None
    for r, every in enumerate(rounds):
        ki, kj = keyframes(drive, params, log.scan_t, usable)
        step = max(1, min(every, len(ki) // 100))  # a short log's sample: a hundred pairs at least
        ki, kj = ki[::step], kj[::step]
        points = deskewed(log, drive, params, np.unique(np.concatenate([ki, kj])))
        m = match_pairs(
            _points_list(log, points),
            inc,
            ki,
            kj,
            predicted(params, drive, log.scan_t, ki, kj),
            progress,
            f"matching keyframes, round {r + 1}",
        )
        if len(m.i) < 20:
            _too_few_matched(log, m, "keyframe pairs")
        result = fit(drive, log.scan_t, m, params)
        params = result.params
    every = max(1, log.scan_t.size // NOISE_SCANS)
    rn = range_noise(log.ranges_mm[::every], log.scan.angles(log.beams))
    return CarLidarResult(result, first, rn, drive, rounds)


# --- the yaml's numbers from the fit ---
def old_straight_ahead(log: CarLog) -> tuple[float, float] | None:
    """The yaml the log was driven with, ``(servo gain, servo offset)``: the servo's commands against /drive's
    steering angles (the VESC driver maps one onto the other by it); None without /drive."""
    if log.drive_t.size < 10:
        return None
    angle = np.interp(log.servo_t, log.drive_t, log.drive[:, 1])
    if np.std(angle) < 1e-6:
        return None
    (g, o), *_ = np.linalg.lstsq(np.column_stack([angle, np.ones(angle.size)]), log.servo, rcond=None)
    return float(g), float(o)


def yaml_before(log: CarLog) -> JsonObject:
    """The yaml the log was driven with, as far as the log tells it: the servo's gain and offset from /drive's
    angles (``old_straight_ahead``), the speed's from /odom's speed against the ERPM, and the wheelbase from
    /odom's turn rate (vesc_to_odom's ``v tan(angle) / wheelbase``); None where the log lacks what tells it."""
    steer = old_straight_ahead(log)
    out: JsonObject = {
        "speed_to_erpm_gain": None,
        "speed_to_erpm_offset": None,
        "steering_angle_to_servo_gain": None if steer is None else steer[0],
        "steering_angle_to_servo_offset": None if steer is None else steer[1],
        "wheelbase_mm": None,
    }
    if log.odom_t.size < 10 or not np.std(log.odom[:, 0]) > 1e-6:
        return out
    v, w = log.odom[:, 0], log.odom[:, 1]
    erpm = np.interp(log.odom_t, log.erpm_t, log.erpm)
    (k, o), *_ = np.linalg.lstsq(np.column_stack([v, np.ones(v.size)]), erpm, rcond=None)
    out["speed_to_erpm_gain"], out["speed_to_erpm_offset"] = float(k), float(o)
    if steer is not None:  # vesc_to_odom turns by the last servo command it was told of
        last = np.clip(np.searchsorted(log.servo_t, log.odom_t, side="right") - 1, 0, log.servo_t.size - 1)
        x = v * np.tan((log.servo[last] - steer[1]) / steer[0])
        turning = np.abs(w) > 0.05
        if turning.sum() >= 10 and np.sum(x[turning] * w[turning]) > 0:
            out["wheelbase_mm"] = float(np.sum(x[turning] ** 2) / np.sum(x[turning] * w[turning]) * 1000)
    return out


@dataclass(frozen=True)
class Steering:
    """The steering gain and wheelbase from ``P`` and ``u`` with their sds (delta method); NaN where ``u`` is not
    known to be positive."""

    gain: float
    gain_sd: float
    wheelbase_m: float
    wheelbase_m_sd: float
    product: float  # P
    product_sd: float


def steering(params: np.ndarray, cov: np.ndarray) -> Steering:
    p, u = params[2], params[4]
    c = cov[np.ix_([2, 4], [2, 4])]
    p_sd = math.sqrt(max(c[0, 0], 0.0))
    if not u > 0:
        return Steering(math.nan, math.inf, math.nan, math.inf, float(p), p_sd)
    g = math.copysign(1 / math.sqrt(u), p)
    grad_g = np.array([0.0, -0.5 * g / u])
    length = abs(p) * math.sqrt(u)
    grad_l = np.array([math.copysign(math.sqrt(u), p), 0.5 * abs(p) / math.sqrt(u)])
    return Steering(
        float(g),
        float(math.sqrt(max(grad_g @ c @ grad_g, 0.0))),
        float(length),
        float(math.sqrt(max(grad_l @ c @ grad_l, 0.0))),
        float(p),
        p_sd,
    )
