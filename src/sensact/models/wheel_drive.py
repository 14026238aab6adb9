"""A learned action model on a differential drive's wheel speeds, read as the drive's own numbers (beyond
the thesis, whose Aibo had no wheels).

A robot driven wheel by wheel logs ``left_mm_s, right_mm_s``, or its wheels' turning rates
``left_rad_s, right_rad_s``, or any other unit the two share (``wheel_pair``); its affine action model
has one coefficient per wheel for each velocity, which says little at a glance. A differential drive whose
wheels move ``g_l`` and ``g_r`` times their commanded speeds on an axle (track) of ``B`` has

    forward speed  v = (g_l left + g_r right) / 2,
    turn rate      omega = (g_r right - g_l left) / B,

so the turn coefficients give the wheels' ratio ``g_r / g_l = -b_right / b_left`` and, with the forward
gain ``g = (g_l + g_r) / 2``, the axle ``B = 2 g / (b_right - b_left)``: the two numbers a wheel-odometry
calibration (UMBmark's E_d and E_b) reports. A ratio other than 1 is what curves the robot when it
drives straight: ``(b_left + b_right)`` rad/s per unit of the wheels' mean. On wheel turning rates
(rad/s) the forward gain is the wheels' mean radius in mm.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from sensact.models.em_model import PLANAR_VELOCITY_NAMES

WHEEL_COMMAND_NAMES = ("left_mm_s", "right_mm_s")


def wheel_pair(command_names: tuple[str, ...]) -> tuple[str, str] | None:
    """``(left, right)`` when the commands are a differential drive's two wheels in one unit,
    ``left_<unit>`` and ``right_<unit>`` in either order (``left_mm_s``, ``left_rad_s``, ...); None otherwise."""
    names = tuple(command_names)
    left = [n for n in names if n.startswith("left_")]
    right = [n for n in names if n.startswith("right_")]
    if len(names) == 2 and len(left) == len(right) == 1 and left[0][5:] and left[0][5:] == right[0][6:]:
        return left[0], right[0]
    return None


@dataclass(frozen=True)
class DifferentialDrive:
    """An affine action model on a wheel pair read as a differential drive (``as_differential_drive``)."""

    unit: str  # the wheel commands' unit: mm_s, rad_s, ...
    forward_gain: float  # mm/s per unit of the wheels' mean
    forward_bias_mm_s: float
    axle_mm: float | None  # None: the turn does not follow the wheels' difference
    wheel_ratio: float | None  # right over left; None where inputs held the turn to the difference
    curvature_rad_per_unit: float  # turn rate per unit of the wheels' mean
    turn_bias_rad_s: float


def as_differential_drive(action: Any) -> DifferentialDrive | None:
    """The drive's numbers of an affine model on a ``wheel_pair`` (None for any other model):
    ``forward_gain`` (mm/s per ``unit`` of the wheels' mean), ``axle_mm``, ``wheel_ratio`` (right over
    left), ``curvature_rad_per_unit`` (turn rate per ``unit`` of the wheels' mean), the constants
    ``forward_bias_mm_s`` and ``turn_bias_rad_s``, and the commands' ``unit``; the axle and ratio are
    None where the turn coefficients cannot give them (a turn that does not follow the wheels'
    difference), and the ratio where ``inputs`` held the turn rate to that difference."""
    pair = wheel_pair(getattr(action, "command_names", ()))
    action = action.linear()
    if not (
        pair is not None
        and action is not None
        and action.basis == "affine"
        and action.velocity_names == PLANAR_VELOCITY_NAMES
    ):
        return None
    i_left, i_right = (1 + action.command_names.index(n) for n in pair)  # rows (1, *commands)
    beta = action.coefficients  # columns sideways, forward, turn
    gain = float(beta[i_left, 1] + beta[i_right, 1])
    b_left, b_right = float(beta[i_left, 2]), float(beta[i_right, 2])
    return DifferentialDrive(
        unit=pair[0][5:],
        forward_gain=gain,
        forward_bias_mm_s=float(beta[0, 1]),
        axle_mm=2.0 * gain / (b_right - b_left) if b_right != b_left else None,
        # a turn held to the wheels' difference (a range-only robot's action_inputs) has them alike by fiat
        wheel_ratio=-b_right / b_left if b_left != 0 and 2 not in action.combined_inputs else None,
        curvature_rad_per_unit=b_left + b_right,
        turn_bias_rad_s=float(beta[0, 2]),
    )
