"""A model learned on a simulated differential drive or side-stepping robot (``sensact simulate
diffdrive``) against the model the simulator really used (meta.json's ``truth``), beside the
recorded-pose scores that real logs get (``evaluate.landmark_truth``): the truth's residual sigma is
what a real log's bars compare with, the simulated sigma is what a perfect learner would find."""

from __future__ import annotations

import numpy as np

from sensact.models.em_model import EMModel
from sensact.records import JsonObject
from sensact.sim.diffdrive import COMMAND_NAMES, from_wheel_coefficients


def score_against_simulated(model: EMModel, truth: JsonObject, dt_s: float) -> JsonObject:
    """Learned against true: the affine action's gains and biases (and the sideways gain of a robot that
    side-steps), the command delay (which the lag lengthens: a first-order lag of time constant tau
    delays a step by tau), Sigma_m's per-step sds, the range channel's sigma and bearing terms, the
    bearing sigma (when the model reads bearings), the sensor's mount; each sigma also as a ratio."""
    linear = model.action.linear()
    if linear is None or linear.basis != "affine":
        raise ValueError("a simulated differential drive is scored with the affine action basis (em_config.yaml)")
    beta, true_beta = linear.coefficients, np.asarray(truth["action_coefficients"])
    if truth.get("wheel_axle_mm", 0.0) > 0:  # learned on the wheel speeds: the gains are on (v, omega)
        beta = from_wheel_coefficients(beta, truth["wheel_axle_mm"])
    if beta.shape != true_beta.shape:
        raise ValueError(
            f"the model has {beta.shape[0] - 1} commands and the simulated robot {true_beta.shape[0] - 1}: "
            "learn it on the simulated log's own commands"
        )
    # the coefficient rows: the constant, then the controller's commands (logs written before they were named
    # in the truth are differential drives)
    rows = ["1", *truth.get("command_names", COMMAND_NAMES)]
    turn = rows.index("omega_rad_s")
    ch = model.sensor.channels[0]
    sigma_b = model.sensor.sigma_bearing_rad
    bearing = {}
    if sigma_b is not None and truth.get("bearing_sigma_rad") is not None:
        bearing = {
            "bearing_sigma_rad": [float(sigma_b), float(truth["bearing_sigma_rad"])],
            "bearing_sigma_ratio": float(sigma_b / truth["bearing_sigma_rad"]),
        }
    sideways = {}
    if "v_left_mm_s" in rows:  # sideways is v_x, to the right (sec. 2.5.1), so a step to the left is -v_x
        k = rows.index("v_left_mm_s")
        sideways = {"sideways_gain": [-float(beta[k, 0]), -float(true_beta[k, 0])]}
    return {
        "forward_gain": [float(beta[1, 1]), float(true_beta[1, 1])],
        "forward_bias_mm_s": [float(beta[0, 1]), float(true_beta[0, 1])],
        "turn_gain": [float(beta[turn, 2]), float(true_beta[turn, 2])],
        "turn_bias_rad_s": [float(beta[0, 2]), float(true_beta[0, 2])],
        **sideways,
        "delay_steps": [int(model.action.delay_steps), int(truth["delay_steps"])],
        "delay_with_lag_steps": float(truth["delay_steps"] + truth["lag_s"] / dt_s),
        "motion_sd_per_step": [np.asarray(model.motion_sd).reshape(-1, 3)[0].tolist(), truth["motion_sd_per_step"]],
        "range_bearing_terms": [list(ch.bearing_terms), truth["range_bearing_terms"]],
        "range_sigma_mm": [float(ch.sigma), float(truth["range_sigma_mm"])],
        "range_sigma_ratio": float(ch.sigma / truth["range_sigma_mm"]),
        **bearing,
        # learned and true (forward mm, left mm, yaw rad); a log written before mounts: the axle's middle
        "sensor_mount": [
            model.sensor.mount.to_dict(),
            truth.get("sensor_mount") or {"forward_mm": 0.0, "left_mm": 0.0, "yaw_rad": 0.0},
        ],
    }
