"""A learned model on wheel speeds read as a differential drive's numbers (models/wheel_drive.py)."""

from __future__ import annotations

import numpy as np
import pytest

from sensact.cli.scores import describe_differential_drive
from sensact.models.em_model import PLANAR_VELOCITY_NAMES
from sensact.models.linear_action import LinearActionModel
from sensact.models.wheel_drive import WHEEL_COMMAND_NAMES, as_differential_drive
from sensact.sim.diffdrive import DiffDriveConfig, from_wheel_coefficients


def wheel_model(beta: np.ndarray, inputs: tuple[str, ...] = ()) -> LinearActionModel:
    return LinearActionModel("affine", 1, beta, WHEEL_COMMAND_NAMES, PLANAR_VELOCITY_NAMES, 0, (), inputs)


def test_a_physical_drive_reads_back_its_wheel_gains_and_axle():
    """Exact reduction: wheels moving 0.93 and 0.97 times their commands on a 250-mm axle give a forward
    gain of their mean, that axle, their ratio, and the curvature (g_r - g_l) / B of driving straight."""
    g_l, g_r, axle = 0.93, 0.97, 250.0
    beta = np.array([[0.0, 2.0, 0.003], [0.0, g_l / 2, -g_l / axle], [0.0, g_r / 2, g_r / axle]])
    drive = as_differential_drive(wheel_model(beta))
    assert drive.forward_gain == pytest.approx(0.95, rel=1e-12)
    assert drive.axle_mm == pytest.approx(axle, rel=1e-12)
    assert drive.wheel_ratio == pytest.approx(g_r / g_l, rel=1e-12)
    assert drive.curvature_rad_per_unit == pytest.approx((g_r - g_l) / axle, rel=1e-12)
    assert drive.forward_bias_mm_s == 2.0 and drive.turn_bias_rad_s == 0.003
    text = describe_differential_drive(drive)
    assert "axle of 250 mm" in text and f"right wheel {g_r / g_l:.4g} times the left" in text


def test_the_simulated_drive_on_wheel_speeds_turns_as_its_axle_over_the_turn_gain():
    """Independent reference (sim.diffdrive.from_wheel_coefficients): the simulated (v, omega) model on
    a 235-mm axle's wheel speeds has the forward gain 0.95 and turns as on an axle of 235 x 0.95 / 0.92,
    its wheels alike; held to the wheels' difference, the ratio is not reported (it is 1 by fiat)."""
    sim = DiffDriveConfig(wheel_axle_mm=235.0)
    beta_vw = sim.action_coefficients()
    beta_w = np.linalg.solve(from_wheel_coefficients(np.eye(3), 235.0), beta_vw)  # T beta_w = beta_vw
    drive = as_differential_drive(wheel_model(beta_w))
    assert drive.forward_gain == pytest.approx(sim.forward_gain, rel=1e-12)
    assert drive.axle_mm == pytest.approx(235.0 * sim.forward_gain / sim.turn_gain, rel=1e-12)
    assert drive.wheel_ratio == pytest.approx(1.0, rel=1e-12) and abs(drive.curvature_rad_per_unit) < 1e-15
    held = as_differential_drive(wheel_model(beta_w, ("v_theta_rad_s:(right_mm_s-left_mm_s)",)))
    assert held.wheel_ratio is None and held.axle_mm == pytest.approx(drive.axle_mm, rel=1e-12)
    assert "right wheel" not in describe_differential_drive(held)
    no_turn = beta_w.copy()
    no_turn[1:, 2] = 0.0
    assert as_differential_drive(wheel_model(no_turn)).axle_mm is None
    on_vw = LinearActionModel("affine", 1, beta_vw, ("v_mm_s", "omega_rad_s"), PLANAR_VELOCITY_NAMES)
    assert as_differential_drive(on_vw) is None


@pytest.mark.slow
def test_em_on_wheel_speeds_reads_back_a_wheel_mismatch():
    """Seeded recovery: a simulated drive that turns 0.0003 rad/s per mm/s of forward command (the curve of
    a wheel mismatch), logged by its wheel speeds on a 235-mm axle and learned with the settings `simulate
    diffdrive` writes (the camera pins the curve), reads back the curve within 10 %, the wheels' ratio
    within 0.01 and the axle within 2 %."""
    from sensact.learn.em import fit_em
    from sensact.presets import simulator_settings
    from sensact.sim.diffdrive import simulate_diffdrive

    sim = DiffDriveConfig(seed=1, seconds=600, wheel_axle_mm=235.0, straight_turn_rad_per_mm=0.0003)
    res = fit_em(simulate_diffdrive(sim).log(), None, simulator_settings(sim))
    drive = as_differential_drive(res.model.action)
    per_difference = sim.turn_gain / 235.0  # rad/s per mm/s of (right - left)
    half = 0.5 * sim.straight_turn_rad_per_mm
    assert drive.curvature_rad_per_unit == pytest.approx(sim.straight_turn_rad_per_mm, rel=0.1)
    assert drive.wheel_ratio == pytest.approx((per_difference + half) / (per_difference - half), abs=0.01)
    assert drive.axle_mm == pytest.approx(235.0 * sim.forward_gain / sim.turn_gain, rel=0.02)
    assert drive.forward_gain == pytest.approx(sim.forward_gain, rel=0.02)


def test_wheels_in_any_one_unit_are_a_differential_drive():
    """Invariants: two commands ``left_<unit>``, ``right_<unit>`` in either order are a wheel pair and get
    the differential drive's settings in that unit; other commands are not."""
    from sensact.cli.convert import config_header
    from sensact.models.wheel_drive import wheel_pair
    from sensact.presets import planar_config, range_only_config

    assert wheel_pair(("left_rad_s", "right_rad_s")) == ("left_rad_s", "right_rad_s")
    assert wheel_pair(("right_ticks_s", "left_ticks_s")) == ("left_ticks_s", "right_ticks_s")
    for names in (
        ("left_mm_s", "right_rad_s"),
        ("left_", "right_"),
        ("v_mm_s", "omega_rad_s"),
        ("left_a", "b", "right_a"),
    ):
        assert wheel_pair(names) is None, names
    names = ("left_rad_s", "right_rad_s")
    assert planar_config(names).action.inputs == ("v_y_mm_s:(left_rad_s+right_rad_s)",)
    assert planar_config(names).action.zero_mean == ("v_x_mm_s",)  # a differential drive: no side-steps
    assert range_only_config(names, (0.0, 0.0, 0.0)).action.inputs[-1] == "v_theta_rad_s:(right_rad_s-left_rad_s)"
    assert "(left_rad_s+right_rad_s)" in config_header(names) and "not a differential drive" not in config_header(names)


def test_wheel_turning_rates_learn_what_wheel_speeds_learn_and_read_as_the_wheels_radius():
    """Exact reduction: the same drive logged as its wheels' turning rates (rad/s, a 35-mm radius) has the
    same EM likelihood at every iteration as on their speeds (mm/s); its coefficients are 35 times those,
    so its forward gain reads as the wheels' radius in mm, with the same axle, ratio and curve."""
    from dataclasses import replace

    from sensact.learn.em import fit_em
    from sensact.presets import planar_config
    from sensact.sim.diffdrive import simulate_diffdrive

    radius = 35.0
    sim = DiffDriveConfig(seed=2, seconds=60, wheel_axle_mm=235.0, straight_turn_rad_per_mm=0.0002)
    log_mm = simulate_diffdrive(sim).log()
    log_rad = replace(log_mm, command_names=("left_rad_s", "right_rad_s"), step_commands=log_mm.step_commands / radius)
    fits = [
        fit_em(log, None, planar_config(log.command_names).replace(max_iterations=6, start_candidates=2))
        for log in (log_mm, log_rad)
    ]
    np.testing.assert_allclose(fits[1].loglik_history, fits[0].loglik_history, rtol=1e-9)
    mm, rad = (as_differential_drive(f.model.action) for f in fits)
    assert rad.unit == "rad_s" and mm.unit == "mm_s"
    assert rad.forward_gain == pytest.approx(radius * mm.forward_gain, rel=1e-6)
    for key in ("axle_mm", "wheel_ratio", "forward_bias_mm_s", "turn_bias_rad_s"):
        assert getattr(rad, key) == pytest.approx(getattr(mm, key), rel=1e-6), key
    text = [describe_differential_drive(d) for d in (mm, rad)]
    assert "mm/s per rad_s of the wheels' mean (their mean radius, mm)" in text[1]
    assert text[0].split("rad per metre")[0][-8:] == text[1].split("rad per metre")[0][-8:]  # the same curve
