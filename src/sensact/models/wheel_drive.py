"""A learned action model on a differential drive's wheel speeds, read as the drive's own numbers (beyond
the thesis, whose Aibo had no wheels).

A robot driven wheel by wheel logs ``left_mm_s, right_mm_s``; its affine action model has one
coefficient per wheel for each velocity, which says little at a glance. A differential drive whose
wheels move ``g_l`` and ``g_r`` times their commanded speeds on an axle (track) of ``B`` has

    forward speed  v = (g_l left + g_r right) / 2,
    turn rate      omega = (g_r right - g_l left) / B,

so the turn coefficients give the wheels' ratio ``g_r / g_l = -b_right / b_left`` and, with the forward
gain ``g = (g_l + g_r) / 2``, the axle ``B = 2 g / (b_right - b_left)``: the two numbers a wheel-odometry
calibration (UMBmark's E_d and E_b) reports. A ratio other than 1 is what curves the robot when it
drives straight: ``(b_left + b_right)`` rad/s per mm/s of the wheels' mean.
"""

from __future__ import annotations

from typing import Any

from sensact.models.em_model import PLANAR_VELOCITY_NAMES
from sensact.models.linear_action import LinearActionModel

WHEEL_COMMAND_NAMES = ("left_mm_s", "right_mm_s")


def as_differential_drive(action: Any) -> dict[str, float | None] | None:
    """The drive's numbers of an affine model on ``WHEEL_COMMAND_NAMES`` (None for any other model):
    ``forward_gain`` (mm/s per mm/s of the wheels' mean), ``axle_mm``, ``wheel_ratio`` (right over left),
    ``curvature_rad_per_mm`` (turn rate per mm/s of the wheels' mean), and the constants
    ``forward_bias_mm_s`` and ``turn_bias_rad_s``; the axle and ratio are None where the turn
    coefficients cannot give them (a turn that does not follow the wheels' difference), and the ratio
    where ``inputs`` held the turn rate to that difference."""
    if not (
        isinstance(action, LinearActionModel)
        and action.basis == "affine"
        and action.command_names == WHEEL_COMMAND_NAMES
        and action.velocity_names == PLANAR_VELOCITY_NAMES
    ):
        return None
    beta = action.coefficients  # rows (1, left, right); columns sideways, forward, turn
    gain = float(beta[1, 1] + beta[2, 1])
    b_left, b_right = float(beta[1, 2]), float(beta[2, 2])
    return {
        "forward_gain": gain,
        "forward_bias_mm_s": float(beta[0, 1]),
        "axle_mm": 2.0 * gain / (b_right - b_left) if b_right != b_left else None,
        # a turn held to the wheels' difference (a range-only robot's action_inputs) has them alike by fiat
        "wheel_ratio": -b_right / b_left if b_left != 0 and 2 not in action.combined_inputs else None,
        "curvature_rad_per_mm": b_left + b_right,
        "turn_bias_rad_s": float(beta[0, 2]),
    }
