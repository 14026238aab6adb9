"""The sensor protocol (``models/sensor_model.py``) and its first implementation, the landmark sensor of
eq. 4.19: its parameters read back, what it predicts from a pose, what the compiled E-step reads of it, and
its M-step's exact reduction (noiseless readings at known poses give f back)."""

from __future__ import annotations

import numpy as np
import pytest

from sensact.core.ekf_smoother import LANDMARK, STUDENT_T_JOINT
from sensact.core.geometry import PLANAR
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.landmark_sensor import (
    MIN_SIGMA,
    LandmarkSensor,
    ReadingChannel,
    SampledSightings,
    SensorMount,
)
from sensact.models.polynomial import Polynomial1D
from sensact.models.sensor_model import SensorModel


def _sensor(mount: SensorMount | None = None) -> LandmarkSensor:
    f = Polynomial1D((1000.0, 800.0, -20.0), center=1000.0, scale=800.0)  # a range reading near d, slightly bent
    ir = Polynomial1D((2.0, -0.5), center=1000.0, scale=800.0)
    chans = (
        ReadingChannel("range_mm", f, 25.0, robust="student_t", robust_param=4.0, bearing_terms=(0.01, -0.002)),
        ReadingChannel("ir_v", ir, 0.05, valid_min=200.0, valid_max=1500.0),
    )
    return LandmarkSensor(chans, 0.01, "student_t", 4.0, joint_student_t=True, mount=mount or SensorMount())


def _log(poses: np.ndarray, landmark_xy: np.ndarray, readings: np.ndarray, bearings: np.ndarray) -> LandmarkLog:
    K = len(poses)
    return LandmarkLog(
        "planar",
        0.1,
        np.zeros(K, dtype=int),
        np.zeros((1, 2)),
        ("v_mm_s", "omega_rad_s"),
        np.arange(K),
        np.arange(K) % len(landmark_xy),
        readings,
        bearings,
        landmark_xy,
        reading_names=("range_mm", "ir_v"),
    )


def test_the_landmark_sensor_is_a_sensor_model():
    sensor = _sensor()
    assert isinstance(sensor, SensorModel) and sensor.kind == LANDMARK
    assert sensor.noise_groups == ("range_mm", "ir_v", "bearing_rad")
    assert sensor.sigmas == (25.0, 0.05, 0.01)
    assert np.isnan(LandmarkSensor.single(Polynomial1D((1.0, 2.0)), 3.0).sigmas[-1])  # a 1-D sensor reads no bearing


def test_parameters_read_back_and_name_every_learned_number():
    sensor = _sensor(SensorMount(120.0, -15.0, 0.03))
    p = sensor.parameters
    assert p.size == (3 + 2 + 1) + (2 + 0 + 1) + 1 + 3
    assert sensor.with_parameters(p) == sensor
    moved = sensor.with_parameters(p + 1.0)
    assert moved.channels[0].function.coef == (1001.0, 801.0, -19.0)
    assert moved.channels[0].bearing_terms == (1.01, 0.998) and moved.channels[1].sigma == 1.05
    assert moved.sigma_bearing_rad == pytest.approx(1.01) and moved.mount == SensorMount(121.0, -14.0, 1.03)
    named = sensor.named_parameters()
    assert list(named) == [
        "f.range_mm[0]", "f.range_mm[1]", "f.range_mm[2]", "f.range_mm.bearing_term1", "f.range_mm.bearing_term2",
        "sigma.range_mm", "f.ir_v[0]", "f.ir_v[1]", "sigma.ir_v", "sigma.bearing_rad",
        "mount.forward_mm", "mount.left_mm", "mount.yaw_rad",
    ]  # fmt: skip
    at = sensor.named_parameters(f_at=(1000.0,))
    assert at["f.range_mm(1000 mm)"] == pytest.approx(1000.0) and at["f.ir_v(1000 mm)"] == pytest.approx(2.0)


def test_predict_reads_from_the_sensor_at_its_mount():
    """The thesis's frame: a robot at the origin facing +y; a landmark 1 m ahead is at bearing 0, one to its
    left at +pi/2; a sensor 100 mm ahead of the robot's point sees the first at 900 mm."""
    f = Polynomial1D((0.0, 1.0))  # reads the distance itself
    sensor = LandmarkSensor((ReadingChannel("range_mm", f, 10.0),), 0.01, mount=SensorMount(100.0, 0.0, 0.0))
    lm = np.array([[0.0, 1000.0], [-1000.0, 0.0]])
    data = LandmarkLog(
        "planar", 0.1, [0, 0], np.zeros((1, 2)), ("v_mm_s", "omega_rad_s"), [0, 1], [0, 1], [0.0, 0.0], [0.0, 0.0], lm
    )
    pred = sensor.predict(np.zeros((2, 3)), data, np.arange(2))
    np.testing.assert_allclose(pred[:, 0], [900.0, np.hypot(1000.0, 100.0)])
    np.testing.assert_allclose(pred[:, 1], [0.0, np.pi / 2 + np.arctan2(100.0, 1000.0)])


def test_kernel_inputs_are_what_the_passes_read():
    sensor = _sensor(SensorMount(50.0, 10.0, 0.1))
    lm = np.array([[0.0, 1000.0], [500.0, 500.0]])
    readings = np.array([[1000.0, 1.0], [np.nan, 1.5], [900.0, np.nan]])
    data = _log(np.zeros((3, 3)), lm, readings, np.array([0.1, np.nan, -0.2]))
    sight, inputs = sensor.kernel_inputs(data)
    assert inputs.kind == LANDMARK
    np.testing.assert_array_equal(inputs.reading_var, [25.0**2, 0.05**2])
    assert inputs.var_bearing == pytest.approx(1e-4)
    np.testing.assert_array_equal(inputs.robust_kind, [STUDENT_T_JOINT, 0, STUDENT_T_JOINT])
    np.testing.assert_array_equal(inputs.mount, [50.0, 10.0, 0.1])
    # a reading whose bearing is missing cannot carry its channel's bearing terms: it counts as missing
    assert np.isnan(sight.readings[1, 0]) and sight.gain[2, 0] == pytest.approx(-0.2 * 0.01 - 0.04 * 0.002)
    np.testing.assert_array_equal(inputs.coefs[1], [2.0, -0.5, 0.0])


def test_update_gives_f_back_from_noiseless_readings_at_known_poses():
    """Eqs. 4.25 and 4.27 reduce exactly: one sample per sighting at the true pose, readings f(d) with no
    noise and weight 1 give f back, and a sigma at the M-step's floor."""
    rng = np.random.default_rng(3)
    true = Polynomial1D((900.0, 700.0, 30.0, -5.0), center=1200.0, scale=500.0)
    sensor = LandmarkSensor((ReadingChannel("range_mm", Polynomial1D((0.0, 1.0, 0.0, 0.0)), 50.0),), None)
    K = 200
    poses = np.column_stack([rng.uniform(-500, 500, K), rng.uniform(-500, 500, K), rng.uniform(-3, 3, K)])
    lm = np.array([[0.0, 1500.0], [1400.0, 0.0]])
    which = np.arange(K) % 2
    dist = np.hypot(*(lm[which] - poses[:, :2]).T)
    seen = SampledSightings(poses[None], which, true(dist)[:, None], np.ones((K, 2)), np.full(K, np.nan))
    learned = sensor.update(seen, lm, PLANAR)
    d = np.linspace(dist.min(), dist.max(), 7)
    np.testing.assert_allclose(learned.channels[0].function(d), true(d), rtol=1e-9)
    assert learned.channels[0].sigma == pytest.approx(MIN_SIGMA, abs=1e-6)
    assert learned.sigma_bearing_rad is None
