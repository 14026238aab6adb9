"""The motion and observation geometry of ch. 4: Jacobians against finite differences, and inverses."""

from __future__ import annotations

import numpy as np
import pytest

from sensact.core.pose_models import (
    PLANAR,
    TRACK,
    apply_displacement,
    arc_poses,
    chords_of,
    displacement,
    from_rep103,
    landmark_bearing,
    landmark_distance,
    observe_bearing,
    observe_height,
    predict,
    relative_displacement,
    sensor_poses,
    to_rep103,
)

COEF = np.array([14.0, -6.0, 2.0, -0.5])
CENTER, SCALE = 2500.0, 900.0


def _num_jac(f, x, eps=1e-6):
    y0 = np.atleast_1d(f(x))
    J = np.zeros((y0.size, x.size))
    for j in range(x.size):
        d = np.zeros_like(x)
        d[j] = eps * max(1.0, abs(x[j]))
        J[:, j] = (np.atleast_1d(f(x + d)) - np.atleast_1d(f(x - d))) / (2 * d[j])
    return J


def test_predict_jacobian_and_inverse():
    rng = np.random.default_rng(0)
    for _ in range(5):
        w = np.array([*rng.uniform(-2000, 2000, 2), rng.uniform(-np.pi, np.pi)])
        u = np.array([*rng.uniform(-30, 30, 2), rng.uniform(-0.1, 0.1)])
        out, F = np.zeros(3), np.zeros((3, 3))
        predict(PLANAR, w, u, out, F)

        def g(x, u=u):
            o = np.zeros(3)
            predict(PLANAR, x, u, o, np.zeros((3, 3)))
            return o

        np.testing.assert_allclose(F, _num_jac(g, w), atol=1e-6)
        np.testing.assert_allclose(apply_displacement(w, u)[0], out)
        np.testing.assert_allclose(relative_displacement(w, out)[0], u, atol=1e-9)


def test_displacement_jacobian():
    rng = np.random.default_rng(1)
    w1 = np.array([100.0, -300.0, 0.7])
    w2 = w1 + np.array([25.0, -10.0, 0.05])
    D, G = np.zeros(3), np.zeros((3, 6))
    displacement(PLANAR, w1, w2, D, G)

    def d(x):
        o = np.zeros(3)
        displacement(PLANAR, x[:3], x[3:], o, np.zeros((3, 6)))
        return o

    np.testing.assert_allclose(G, _num_jac(d, np.r_[w1, w2]), atol=1e-6)
    np.testing.assert_allclose(D, relative_displacement(w1, w2)[0])
    # the track: D is the distance walked toward the beacon
    D1, G1 = np.zeros(1), np.zeros((1, 2))
    displacement(TRACK, np.array([2000.0]), np.array([1990.0]), D1, G1)
    assert D1[0] == pytest.approx(10.0) and list(G1[0]) == [1.0, -1.0]
    assert rng is not None


@pytest.mark.parametrize("mount", [(0.0, 0.0, 0.0), (220.0, 40.0, np.deg2rad(2.0)), (-90.0, -35.0, -0.3)])
def test_observation_jacobians_and_convention(mount):
    """Readings are predicted from the sensor's pose (at ``mount`` on the robot): the compiled forms
    agree with the vectorized ones at the sensor's pose, and their gradients in the robot's pose with
    finite differences."""
    mount = np.array(mount)
    w = np.array([300.0, -200.0, 0.4])
    lx, ly = 1350.0, 1950.0
    H = np.zeros(3)
    at = sensor_poses(w, mount)
    r = landmark_distance(at, np.array([lx, ly]))[0]
    u = (r - CENTER) / SCALE
    for gain in (0.0, -0.03):  # a bearing term adds gain * d to the reading
        h = observe_height(PLANAR, w, lx, ly, COEF, CENTER, SCALE, gain, mount, H)
        Hn = _num_jac(
            lambda x, g=gain: observe_height(PLANAR, x, lx, ly, COEF, CENTER, SCALE, g, mount, np.zeros(3)), w
        )
        np.testing.assert_allclose(H, Hn[0], rtol=1e-6, atol=1e-9)
        assert h == pytest.approx(np.polyval(COEF[::-1], u) + gain * r)
    b = observe_bearing(w, lx, ly, mount, H)
    Hn = _num_jac(lambda x: observe_bearing(x, lx, ly, mount, np.zeros(3)), w)
    np.testing.assert_allclose(H, Hn[0], rtol=1e-6, atol=1e-12)
    assert b == pytest.approx(landmark_bearing(at, np.array([lx, ly]))[0])
    # theta = 0 faces +y: a landmark straight ahead has bearing 0, one to the left +pi/2
    assert landmark_bearing(np.zeros(3), np.array([0.0, 1000.0]))[0] == pytest.approx(0.0)
    assert landmark_bearing(np.zeros(3), np.array([-1000.0, 0.0]))[0] == pytest.approx(np.pi / 2)


def test_sensor_poses_convention():
    """A sensor 100 mm forward and 20 mm left on a robot facing world +y (theta = 0) sits at x -20, y 100;
    turned a quarter counterclockwise (facing -x) at x -100, y -20; a zero mount is the pose itself."""
    mount = np.array([100.0, 20.0, 0.1])
    np.testing.assert_allclose(sensor_poses(np.zeros(3), mount)[0], [-20.0, 100.0, 0.1], atol=1e-12)
    np.testing.assert_allclose(sensor_poses(np.array([0, 0, np.pi / 2]), mount)[0], [-100.0, -20.0, np.pi / 2 + 0.1])
    w = np.array([[1.0, 2.0, 3.0]])
    assert sensor_poses(w, np.zeros(3)) is not None and np.array_equal(sensor_poses(w, np.zeros(3)), w)


def test_apply_and_relative_displacement_invert_each_other():
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(50, 3)) * (1000, 1000, 2), rng.normal(size=(50, 3)) * (1000, 1000, 2)
    back = apply_displacement(a, relative_displacement(a, b))
    np.testing.assert_allclose(back[:, :2], b[:, :2], atol=1e-9)
    np.testing.assert_allclose(np.cos(back[:, 2] - b[:, 2]), 1.0)  # the same heading, wrapped


def test_rep103_is_a_swap_and_a_sign():
    """REP 103's forward is sensact's +y, its left sensact's -x; a yaw is the same in both, and the round
    trip is exact."""
    np.testing.assert_array_equal(from_rep103([[100.0, 20.0, 0.3]]), [[-20.0, 100.0, 0.3]])
    np.testing.assert_array_equal(from_rep103([1.0, 2.0]), [-2.0, 1.0])
    v = np.random.default_rng(1).normal(size=(20, 3))
    np.testing.assert_array_equal(to_rep103(from_rep103(v)), v)


def test_arcs_integrate_and_their_chords_come_back():
    """A constant turn rate drives a circle exactly; the chords read back from the poses are each arc's
    chord, and the turns its turns."""
    rng = np.random.default_rng(2)
    ds, dth = rng.uniform(0, 30, 400), rng.uniform(-0.2, 0.2, 400)
    poses = arc_poses(ds, dth)
    steps = np.column_stack([-ds * np.sinc(dth / (2 * np.pi)) * np.sin(dth / 2), ds * np.sinc(dth / (2 * np.pi))
                             * np.cos(dth / 2), dth])  # fmt: skip
    np.testing.assert_allclose(relative_displacement(poses[:-1], poses[1:]), steps, atol=1e-9)
    chord, turn = chords_of(poses)
    np.testing.assert_allclose(chord, ds * np.sinc(dth / (2 * np.pi)), rtol=1e-9)
    np.testing.assert_allclose(turn, dth, atol=1e-12)
    circle = arc_poses(np.full(100, 10.0), np.full(100, 0.01))[-1]  # radius 1000 mm, centre at (-1000, 0)
    np.testing.assert_allclose(np.hypot(circle[0] + 1000.0, circle[1]), 1000.0, rtol=1e-12)
