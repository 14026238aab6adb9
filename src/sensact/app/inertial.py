"""``sensact learn em`` on an outdoor robot's log (docs/inertial.md): wheel odometry, an IMU and GNSS. The
calibration, its health (a flag naming the manoeuvre a parameter needs), its JSON (``odometry.*``,
``imu.gyro.*``, ``imu.mount.*``, ``imu.time_offset_s``, ``gnss.*``, each with its ``_sd``), the bias's path in
an ``.npz`` beside it, its report page, and the next run's consistency (``evaluate log``)."""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sensact import __version__
from sensact.app.em import FitEvents
from sensact.app.opened import OpenedFolder
from sensact.app.save import Saved, save_model
from sensact.core import inertial_smoother as ks
from sensact.health import Health, HealthFlag
from sensact.io.inertial_folder import KIND
from sensact.learn.inertial import (
    MAX_ITERATIONS,
    InertialResult,
    MountFit,
    carries_gravity,
    gyro_follows_odometry,
    learn_inertial,
    tilt_sd,
)
from sensact.logs.inertial_log import InertialLog
from sensact.outputs import EM_MODEL, OUTPUT_KEY
from sensact.progress import Progress
from sensact.records import JsonObject

# what a parameter must be known to, or the log did not tell it (and what would)
GAIN_SD = 0.005  # forward gain and gyro scale (a share)
TURN_GAIN_SD = 0.01
LEVER_SD_MM = 100.0
YAW_SD_RAD = np.radians(2.0)
HEADING_SD_RAD = np.radians(10.0)
MIN_DISTANCE_M = 5.0
MIN_TURN_RAD = np.pi  # each way, for the gyro's scale
NPZ = "bias.npz"
NOISE_NAMES = {  # core.inertial_smoother's q, by the name model.json gives each
    ks.Q_ALONG: "along_mm2_per_mm",
    ks.Q_ALONG_T: "along_mm2_per_s_moving",
    ks.Q_ACROSS: "across_mm2_per_mm",
    ks.Q_TURN: "turn_rad2_per_rad",
    ks.Q_TURN_D: "turn_rad2_per_mm",
    ks.Q_TURN_T: "turn_rad2_per_s_moving",
    ks.Q_BIAS: "bias_walk_rad2_s3",
    ks.R_GYRO: "gyro_rad2_s",
    ks.R_GNSS: "gnss_mm2",
    ks.R_OUTLIER: "gnss_outlier_mm2",
    ks.OUTLIER_SHARE: "gnss_outlier_share",
}
MIN_GYRO_CORRELATION = 0.3  # a gyro on the robot follows its turns far closer (0.99 in a simulated Husky)


@dataclass(frozen=True, eq=False)
class OpenedInertialLog(OpenedFolder):
    """An outdoor robot's log folder, opened (``app.log_kinds``)."""

    data: InertialLog

    def describe(self) -> str:
        d = self.data
        gnss = f", {d.gnss_t.size} GNSS fixes" if d.has_gnss else ", no GNSS"
        return (
            f"{self.path}: {d.seconds:.1f} s of wheel odometry ({d.odom_t.size} rows), {d.imu_t.size} IMU readings"
            + gnss
        )


def open_inertial_log(path: Path) -> OpenedInertialLog:
    from sensact.io.inertial_folder import read_inertial_log

    return OpenedInertialLog(Path(path), read_inertial_log(path))


def _nest(flat: dict[str, Any]) -> JsonObject:
    out: JsonObject = {}
    for key, value in flat.items():
        node = out
        *parents, leaf = key.split(".")
        for p in parents:
            node = node.setdefault(p, {})
        node[leaf] = value
    return out


@dataclass(frozen=True, eq=False)
class InertialCalibration:
    log: InertialLog
    result: InertialResult
    health: Health
    seconds: float

    @property
    def interrupted(self) -> bool:
        return False  # seconds of EM: Ctrl-C ends the command

    def value(self, key: str) -> float | None:
        return self.result.estimates[key].value

    def to_json(self) -> JsonObject:
        res = self.result
        flat: dict[str, Any] = {}
        for key, e in res.estimates.items():
            flat[key] = e.value
            flat[f"{key}_sd"] = e.sd
        q = res.noise
        doc: JsonObject = {
            "sensact_version": __version__,
            OUTPUT_KEY: EM_MODEL,
            "kind": KIND,
            "log": self.log.source,
            **_nest(flat),
            "conventions": {
                "odometry.gain_*": "the true motion is the gain times what the odometry reports",
                "imu.mount": "base_link -> imu_link as tf gives it: URDF rpy, Rz(yaw) Ry(pitch) Rx(roll)",
                "imu.time_offset_s": "t_imu - t_odom for one instant (as Kalibr's timeshift_cam_imu)",
                "imu.gyro.bias_rad_s": f"the run's mean bias about base_link's z; its path in {NPZ}",
                "gnss.heading_offset_rad": "theta: a point p of the odometry frame lies at start + Rz(theta) p in "
                "east-north-up; navsat_transform's yaw_offset + magnetic_declination_radians must sum to it "
                "(only the sum is learned)",
                "gnss.covariance_ratio": "the reported sd over the learned sd",
            },
            "datum": None if self.log.datum is None else self.log.datum.to_dict(),
            "tf_static": {"imu": self.log.imu_mount.to_dict(), "gnss": self.log.gnss_mount.to_dict()},
            "topics": dict(self.log.topics),
            "imu_hz": self.log.imu_hz,
            "fit": {
                "iterations": res.iterations,
                "converged": res.converged,
                "loglik": list(res.loglik),
                "seconds": self.seconds,
                "distance_m": res.distance_m,
                "speed_m_s": res.distance_m / max(self.log.seconds, 1e-9),
                "turn_rate_rad_s": (res.turn_left_rad + res.turn_right_rad) / max(self.log.seconds, 1e-9),
                "turn_left_rad": res.turn_left_rad,
                "turn_right_rad": res.turn_right_rad,
                "gnss_fixes": int(res.gnss_t.size),
                # the E-step's noise (core.inertial_smoother's q), for `evaluate log` and the exports
                "noise": {name: float(q[i]) for i, name in NOISE_NAMES.items()},
            },
            "health": self.health.to_dict(),
        }
        ev = self.evaluation()
        if ev is not None:
            doc["evaluation"] = ev
        return doc

    def evaluation(self) -> JsonObject | None:
        """Each learned number against the simulator's truth: error, and error in sds."""
        truth = self.log.truth
        if not truth:
            return None
        out: JsonObject = {}
        est = self.result.estimates
        if est["imu.gyro.scale"].sd is None and "imu.gyro.scale" in truth and "odometry.gain_turn" in truth:
            # without GNSS only the product is told: the turn gain carries it and the scale is held at 1
            truth = {**truth, "odometry.gain_turn": truth["odometry.gain_turn"] * truth["imu.gyro.scale"]}
            truth = {k: v for k, v in truth.items() if k != "imu.gyro.scale"}
        for key, want in truth.items():
            e = self.result.estimates.get(key)
            if e is None or e.value is None or not isinstance(want, int | float):
                continue
            err = e.value - want
            if key.endswith("_rad"):
                err = float(np.angle(np.exp(1j * err)))
            out[key] = {"error": err, "error_sd": None if not e.sd else err / e.sd}
        return out


def health_of(res: InertialResult) -> Health:
    """A parameter the log cannot tell is flagged with the manoeuvre that would tell it."""
    est = res.estimates
    flags: list[HealthFlag | None] = []

    def sd(key: str) -> float:
        e = est[key]
        return float("inf") if e.sd is None or not np.isfinite(e.sd) else e.sd

    if not res.filter_ok:
        flags.append(
            HealthFlag(
                "filter_failed", "the path's Kalman filter lost positive definiteness: nothing here is to be trusted."
            )
        )
    if res.distance_m < MIN_DISTANCE_M and res.turn_left_rad + res.turn_right_rad < MIN_TURN_RAD:
        return Health.of(
            HealthFlag(
                "no_motion",
                f"the robot hardly moved ({res.distance_m:.3g} m, {res.turn_left_rad + res.turn_right_rad:.3g} rad): "
                "the gains, the gyro's scale, the IMU's yaw and the lever arm need it to drive and turn both ways.",
            )
        )
    if min(res.turn_left_rad, res.turn_right_rad) < MIN_TURN_RAD and (
        sd("imu.gyro.scale") > GAIN_SD or sd("odometry.gain_turn") > TURN_GAIN_SD
    ):
        flags.append(
            HealthFlag(
                "turns_one_way",
                f"the robot turned {res.turn_left_rad:.3g} rad left and {res.turn_right_rad:.3g} rad right: the gyro's "
                "scale and the turn gain need turning both ways (half a turn each way at least).",
            )
        )
    if sd("odometry.gain_turn") > TURN_GAIN_SD * abs(est["odometry.gain_turn"].value or 1):
        flags.append(
            HealthFlag(
                "turn_gain_not_observable",
                f"the turn gain is known only to {sd('odometry.gain_turn'):.3g}: turn more, both ways.",
            )
        )
    if res.has_gnss:
        if sd("odometry.gain_forward") > GAIN_SD:
            flags.append(
                HealthFlag(
                    "forward_gain_not_observable",
                    f"the forward gain is known only to {sd('odometry.gain_forward'):.3g}: drive further.",
                )
            )
        if sd("imu.gyro.scale") > GAIN_SD:
            flags.append(
                HealthFlag(
                    "gyro_scale_not_observable",
                    f"the gyro's scale is known only to {sd('imu.gyro.scale'):.3g}: turn whole turns both ways.",
                )
            )
        lever_sd = max(sd("gnss.lever_arm.forward_mm"), sd("gnss.lever_arm.left_mm"))
        if lever_sd > LEVER_SD_MM:
            flags.append(
                HealthFlag(
                    "lever_arm_not_observable",
                    f"the antenna's lever arm is known only to {lever_sd:.3g} mm: "
                    "it shows only when the robot turns; drive tight turns both ways.",
                )
            )
        if sd("gnss.heading_offset_rad") > HEADING_SD_RAD:
            flags.append(
                HealthFlag(
                    "heading_not_observable",
                    "the heading to east-north-up is not pinned down: drive straight for tens of metres early on.",
                )
            )
    # the yaw the robot's motion tells: what the accelerometer's bias adds through the URDF angles near a pitch
    # of 90 degrees (roll and yaw about nearly one axis) is no manoeuvre's to fix, and is in the sd, not a flag
    e = res.estimates
    tilt = tilt_sd(MountFit(*(float(e[f"imu.mount.{a}_rad"].value) for a in ("roll", "pitch", "yaw")), 0.0))[2]
    yaw_sd = float(np.sqrt(max(sd("imu.mount.yaw_rad") ** 2 - tilt**2, 0.0)))
    if yaw_sd > YAW_SD_RAD:
        flags.append(
            HealthFlag(
                "imu_yaw_not_observable",
                f"the IMU's yaw on the robot is known only to {np.degrees(yaw_sd):.3g} deg: it shows in the robot's "
                "accelerations; speed up, brake and turn while driving.",
            )
        )
    if not res.converged and res.filter_ok:
        flags.append(HealthFlag("not_converged", f"EM did not settle in {MAX_ITERATIONS} passes."))
    return Health.of(*flags)


def calibrate_inertial(log: InertialLog, progress: Progress | None = None) -> InertialCalibration:
    from sensact.errors import LogFormatError

    t0 = time.monotonic()
    overlap = min(log.odom_t[-1], log.imu_t[-1]) - max(log.odom_t[0], log.imu_t[0])
    if overlap < 10.0:
        raise LogFormatError(
            f"the odometry and the IMU share only {max(overlap, 0):.3g} s.",
            file=Path(log.source),
            fix="record both together, 60 s or more of driving and turning.",
        )
    follows = gyro_follows_odometry(log)
    if follows is not None and follows < MIN_GYRO_CORRELATION:
        raise LogFormatError(
            f"the IMU's gyro does not turn with the robot (correlation {follows:.2f} with the odometry's turn rate "
            "over the turns): a stuck gyro, or another IMU than the robot's.",
            file=Path(log.source),
            field="imu",
            fix="record the IMU on the robot's base (name it with convert bag's --imu).",
        )
    _refuse_gravity_free(log)
    res = learn_inertial(log, progress)
    return InertialCalibration(log, res, health_of(res), time.monotonic() - t0)


def _refuse_gravity_free(log: InertialLog) -> None:
    """The IMU's roll and pitch come from gravity: in its accelerations (REP 145) or, where a driver took it
    out, in the orientation it reports."""
    from sensact.errors import LogFormatError

    if carries_gravity(log):
        return
    q = log.imu_orientation_xyzw
    if q is not None and np.isfinite(q).all(axis=1).mean() > 0.5:
        return
    size = float(np.linalg.norm(np.nanmean(log.accel_m_s2, axis=0)))
    in_g = 0.8 < size < 1.2
    raise LogFormatError(
        f"the IMU's accelerations average {size:.3g}"
        + (" (gravity in g, not m/s^2)" if in_g else ", not gravity's 9.81 m/s^2 (the driver took gravity out)")
        + " and it reports no orientation: its roll and pitch on the robot cannot be told.",
        file=Path(log.source),
        field="imu",
        fix="record the IMU's raw accelerations in m/s^2 (REP 145), e.g. its driver's imu/data_raw"
        + (", or scale them by 9.80665." if in_g else ", or a topic that carries its orientation."),
    )


def calibrate_opened_inertial(
    log: OpenedInertialLog,
    preset: str | None = None,
    config: Any = None,
    *,
    sets: Any = (),
    start_from: Path | None = None,
    events: FitEvents | None = None,
) -> InertialCalibration:
    """The kind's learner (``app.log_kinds``): it takes no EM settings (the door refuses them)."""
    return calibrate_inertial(log.data, None if events is None else events.progress)


def save_inertial(cal: InertialCalibration, out: Path, report: bool = True) -> Saved:
    """model.json, the bias's path (``bias.npz`` beside it), and the report page with its figures."""
    from sensact.io.atomic import write_npz

    res = cal.result
    npz = write_npz(
        out.with_name(out.stem + "_" + NPZ),
        t_s=res.t_s[1:],
        bias_rad_s=res.bias_rad_s,
        bias_sd_rad_s=res.bias_sd_rad_s,
        path_enu_m=res.path_enu_m,
    )

    def page() -> tuple[Path, list[str]]:
        from sensact.report.inertial import write_inertial_report

        return write_inertial_report(cal, out)

    return save_model(out, cal.to_json(), page if report else None, (npz,))


CHI2_90 = {1: 2.705543454095404, 2: 4.605170185988091}  # scipy.stats.chi2.ppf(0.9, dof)
GATE_2 = 18.420680743952364  # chi2.ppf(0.9999, 2): a fix beyond it is not used (an outlier), though it counts


def _model_number(doc: JsonObject, key: str, default: float | None, model: Path) -> float:
    from sensact.errors import ModelFormatError

    node: object = doc
    for k in key.split("."):
        node = node.get(k) if isinstance(node, dict) else None
    if node is None and default is not None:
        return default
    if isinstance(node, bool) or not isinstance(node, int | float) or not np.isfinite(node):
        raise ModelFormatError(
            f"{key} is {node!r}, not a number.",
            file=model,
            field=key,
            fix="give a model `sensact learn em` wrote from an odometry-IMU-GNSS log.",
        )
    return float(node)


def _mixture_threshold(share: float, ratio: np.ndarray) -> np.ndarray:
    """The NIS (2 dof) that holds 90 % of the model's predictive mixture: inliers with probability 1 - share,
    outliers (their NIS scaled by ``ratio``) with ``share``: (1 - share) F(c) + share F(c ratio) = 0.9, F the
    chi-square CDF, 1 - exp(-x / 2); by bisection."""
    lo, hi = np.zeros_like(ratio), np.full_like(ratio, 1e4)
    for _ in range(60):
        c = 0.5 * (lo + hi)
        p = (1 - share) * (1 - np.exp(-c / 2)) + share * (1 - np.exp(-c * ratio / 2))
        lo, hi = np.where(p < 0.9, c, lo), np.where(p < 0.9, hi, c)
    return 0.5 * (lo + hi)


def evaluate_inertial(log: InertialLog, doc: JsonObject, model: Path) -> JsonObject:
    """The model's consistency on another run: the filter's one-step-ahead innovations with the model held,
    the share inside the model's 90 % interval per sensor (``consistency.gyro.coverage90``,
    ``consistency.gnss.coverage90``: 0.90 when its noise is honest) and their mean normalized square
    (``nis_mean``, 1 when honest). The robot's start (place, heading) and the gyro's turn-on bias are the new
    run's own, started broad."""
    from sensact.core.pose_models import rpy_matrix
    from sensact.errors import ModelFormatError
    from sensact.learn import inertial as li

    if doc.get("kind") != KIND:
        raise ModelFormatError(
            f"is a {doc.get('kind') or 'landmark EM'} model, not an odometry-IMU-GNSS one.",
            file=model,
            field="kind",
            fix="learn one with `sensact learn em` on an odometry-IMU-GNSS log.",
        )
    num = lambda key, default=None: _model_number(doc, key, default, model)  # noqa: E731
    R = rpy_matrix(num("imu.mount.roll_rad"), num("imu.mount.pitch_rad"), num("imu.mount.yaw_rad"))
    steps = li.make_steps(log, R[2], num("imu.time_offset_s"))
    has_gnss = steps.n_fixes >= li.MIN_FIXES and doc.get("gnss", {}).get("sigma_mm") is not None
    noise = doc.get("fit", {}).get("noise", {})
    q = np.zeros(ks.N_NOISE)
    for i, key in NOISE_NAMES.items():
        q[i] = _model_number(noise, key, 0.0, model)
    m0 = li._start(steps, has_gnss)
    m0[ks.GF] = num("odometry.gain_forward", 1.0)
    m0[ks.GT] = num("odometry.gain_turn")
    m0[ks.S] = num("imu.gyro.scale", 1.0)
    m0[ks.LF] = num("gnss.lever_arm.forward_mm", 0.0)
    m0[ks.LL] = num("gnss.lever_arm.left_mm", 0.0)
    m0[ks.B] = m0[ks.CB] = num("imu.gyro.bias_rad_s")
    P0 = li._prior(has_gnss)
    for i in li.PARAMETER_STATES:  # held: the model's
        P0[i, :] = 0.0
        P0[:, i] = 0.0
    out = li.run_filter(steps, q, m0, P0)
    nu_g, s_g, nu_n, s_n = out[6], out[7], out[8], out[9]

    def summary(nis: np.ndarray, dof: int) -> JsonObject:
        nis = nis[np.isfinite(nis)]
        return {
            "coverage90": float(np.mean(nis <= CHI2_90[dof])) if nis.size else None,
            "nis_mean": float(np.mean(nis) / dof) if nis.size else None,
            "n": int(nis.size),
        }

    cons: JsonObject = {"gyro": summary(nu_g**2 / s_g, 1)}
    if has_gnss:
        nis = np.array(
            [r @ np.linalg.solve(S, r) if np.isfinite(S).all() else np.nan for r, S in zip(nu_n, s_n, strict=True)]
        )
        share, out2 = q[ks.OUTLIER_SHARE], q[ks.R_OUTLIER]
        tr = np.trace(s_n, axis1=1, axis2=2)
        ratio = tr / (tr + 2 * max(out2 - q[ks.R_GNSS], 0.0))  # an outlier's NIS in the inliers' units shrinks by it
        c = _mixture_threshold(share, ratio)
        inside = nis <= c
        ok = np.isfinite(nis)
        cons["gnss"] = summary(nis, 2) | {"coverage90": float(np.mean(inside[ok])) if ok.any() else None}
    return {"log": log.source, "model": str(model), "consistency": cons, "filter_ok": bool(out[10])}


# what a run, not the robot, sets: the bias walks, and the odometry frame's heading is its first pose's
RUN_KEYS = ("imu.gyro.bias_rad_s", "gnss.heading_offset_rad")
AGREE_SD = 3.0


def halves_inertial(cal: InertialCalibration, progress: Progress | None = None) -> JsonObject:
    """`learn em --halves` on an odometry-IMU-GNSS log: each half of the log learned alone, every learned
    number compared in the two halves' combined sd (the robot's constants must agree within 3; the bias's mean
    and the heading offset belong to each run and are shown, not held to it), and the first half's model scored
    on the second half (``evaluate log``'s consistency): no ground truth needed."""
    log = cal.log
    t0, t1 = log.odom_t[0], log.odom_t[-1]
    mid = (t0 + t1) / 2
    parts = [
        calibrate_inertial(log.between(t0, mid, f"{log.source} (first half)"), progress),
        calibrate_inertial(log.between(mid, t1 + 1.0, f"{log.source} (second half)"), progress),
    ]
    differ: JsonObject = {}
    for key in cal.result.estimates:
        a, b = (p.result.estimates[key] for p in parts)
        if None in (a.value, b.value, a.sd, b.sd):
            continue
        d = b.value - a.value
        if key.endswith("_rad"):
            d = float(np.angle(np.exp(1j * d)))
        combined = float(np.hypot(a.sd, b.sd))
        differ[key] = d / combined if combined > 0 else None
    held = {k: z for k, z in differ.items() if k not in RUN_KEYS and z is not None}
    worst = max(held, key=lambda k: abs(held[k]), default=None)
    first_doc = parts[0].to_json()
    return {
        "cut_s": float(mid - t0),
        "first_half": _estimates_json(parts[0]),
        "second_half": _estimates_json(parts[1]),
        "differ_sd": differ,
        "run_keys": list(RUN_KEYS),
        "agree_within_3sd": bool(worst is None or abs(held[worst]) <= AGREE_SD),
        "worst": worst,
        "first_on_second": evaluate_inertial(parts[1].log, first_doc, Path(log.source)),
        "flags": [[f.code for f in p.health.flags] for p in parts],
    }


def _estimates_json(cal: InertialCalibration) -> JsonObject:
    return {k: {"value": e.value, "sd": e.sd} for k, e in cal.result.estimates.items()}
