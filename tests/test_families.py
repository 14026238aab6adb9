"""Robot families as types (issue 91): a Geometry owns its state and motion, every action model speaks one
protocol, and records reach JSON through one writer with their keys in order."""

from __future__ import annotations

import json
import pickle
from dataclasses import dataclass

import numpy as np
import pytest

from sensact.core import pose_models as pm
from sensact.core.geometry import GEOMETRIES, PLANAR, TRACK, geometry_named
from sensact.learn.em.result import FunctionTurns, Unsettled
from sensact.learn.em.searches.ridge import RidgeSearch
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.action_table import ActionTable
from sensact.models.em_model import EMModel
from sensact.models.linear_action import LinearActionModel
from sensact.records import omit_when, to_json


def test_a_geometry_is_its_name_in_json_and_one_instance_across_processes():
    for g in (PLANAR, TRACK):
        assert geometry_named(g.name) is g and geometry_named(g) is g and GEOMETRIES[g.name] is g
        assert pickle.loads(pickle.dumps(g)) is g  # what Dask's workers get back
        assert g.n == len(g.state_names) == len(g.velocity_names) == len(g.thesis_motion_sd)
    with pytest.raises(ValueError, match="'planar', 'track'"):
        geometry_named("ackermann")
    log = LandmarkLog("track", 0.1, np.zeros(3, int), np.zeros((1, 1)), ("c",), [], [], [], [], np.zeros((1, 2)))
    assert log.geometry is TRACK and log.mode == pm.TRACK


def test_a_geometry_moves_a_pose_as_the_kernels_do_and_back():
    """Exact reduction: apply_displacement inverts relative_displacement on either state space, and the
    thesis's Sigma_m is (10 mm, 10 mm, 0.1 rad) per step (sec. 4.4.1)."""
    rng = np.random.default_rng(0)
    w1 = np.column_stack([rng.normal(0, 1000, 20), rng.normal(0, 1000, 20), rng.uniform(-3, 3, 20)])
    w2 = w1 + rng.normal(0, [50, 50, 0.2], (20, 3))
    d = PLANAR.relative_displacement(w1, w2)
    back = PLANAR.apply_displacement(w1, d)
    np.testing.assert_allclose(back[:, :2], w2[:, :2], atol=1e-9)
    np.testing.assert_allclose(np.angle(np.exp(1j * (back[:, 2] - w2[:, 2]))), 0.0, atol=1e-12)
    t1, t2 = w1[:, :1], w2[:, :1]
    np.testing.assert_allclose(TRACK.apply_displacement(t1, TRACK.relative_displacement(t1, t2)), t2, atol=1e-9)
    np.testing.assert_allclose(PLANAR.motion_variance(10.0, 0.1), np.square(PLANAR.thesis_motion_sd))
    np.testing.assert_allclose(TRACK.motion_variance(10.0, 0.1), np.square(TRACK.thesis_motion_sd))


def test_the_table_and_the_one_hot_linear_model_answer_the_protocol_alike():
    """A table is the linear model on a one-hot basis: the same velocities every step, the same M-step
    (eq. 4.18), and each names its parameters and form."""
    rng = np.random.default_rng(1)
    T, A, dt = 200, 3, 0.1
    actions = rng.integers(0, A, T)
    commands = np.eye(A)
    vel = rng.normal(size=(A, 3))
    table = ActionTable(commands, vel, ("a", "b", "c"), PLANAR.velocity_names)
    beta = np.vstack([np.zeros((1, 3)), vel])  # affine on one-hot commands: constant 0, one row per action
    linear = LinearActionModel("affine", 1, beta, ("a", "b", "c"), PLANAR.velocity_names)
    data = LandmarkLog(
        "planar",
        dt,
        actions,
        commands,
        ("a", "b", "c"),
        [],
        [],
        [],
        [],
        np.zeros((1, 2)),
        step_commands=commands[actions],
    )
    np.testing.assert_allclose(table.step_velocity(data), linear.step_velocity(data), atol=1e-12)
    disp = rng.normal(size=(T - 1, 3))
    var = np.ones_like(disp)
    t2, l2 = table.update(data, disp, var, 0), linear.update(data, disp, var, 0)
    means = np.array([disp[actions[:-1] == a].mean(axis=0) / dt for a in range(A)])  # eq. 4.18
    np.testing.assert_allclose(t2.parameters, means, atol=1e-12)
    np.testing.assert_allclose(l2.features(commands) @ l2.parameters, means, atol=1e-9)  # the same velocities
    assert table.with_parameters(vel * 2).parameters is not vel and table.noise_groups == A and linear.noise_groups == 1
    assert not table.can_delay and linear.can_delay and table.zero_mean == ()
    assert len(table.named_parameters()) == A * 3 and len(linear.named_parameters()) == (A + 1) * 3
    assert ("action.basis", "table") in table.form() and ("action.basis", "affine") in linear.form()
    model = EMModel("planar", table, _sensor(), np.zeros(3), np.eye(3), np.ones((A, 3)))
    assert model.per_action_noise and model.geometry is PLANAR
    with pytest.raises(ValueError, match="one row per action"):
        EMModel("planar", linear, _sensor(), np.zeros(3), np.eye(3), np.ones((A, 3)))


def _sensor():
    from sensact.models.landmark_sensor import LandmarkSensor
    from sensact.models.polynomial import Polynomial1D

    return LandmarkSensor.single(Polynomial1D((0.0, 1.0)), 10.0, 0.1)


def test_records_reach_json_through_one_writer_keys_in_order():
    r = RidgeSearch(12.5, -10.0, 7, 1, -9.0, iteration=40)
    assert list(to_json(r)) == [
        "iteration",
        "shift_mm",
        "loglik_before",
        "forward_passes",
        "expansions",
        "loglik_after",
    ]
    turns = FunctionTurns("range_mm", turns_at_mm=(np.float64(2000.0),), distances_mm=(1000.0, 3000.0))
    assert to_json([turns, Unsettled(best_iteration=3)])[0] == {
        "channel": "range_mm",
        "sign": "turns",
        "turns_at_mm": [2000.0],
        "distances_mm": [1000.0, 3000.0],
    }
    assert to_json(Unsettled(best_iteration=3))["sign"] == "unsettled"

    @dataclass(frozen=True)
    class WithOptional:
        a: int
        b: float | None = omit_when(None, default=None)
        c: np.ndarray | None = None

    assert to_json(WithOptional(1)) == {"a": 1, "c": None}
    assert json.dumps(to_json(WithOptional(1, 2.0, np.arange(2)))) == '{"a": 1, "b": 2.0, "c": [0, 1]}'
