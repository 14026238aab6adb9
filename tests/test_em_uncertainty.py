"""`--uncertainty B`: logs drawn from a learned model read as the model says (learn/em/uses/draw_log.py), the
bootstrap's standard errors and intervals (learn/em/uses/error_bars.py), and the model JSON's ``uncertainty``."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from conftest import assert_written
from sensact.cli import app
from sensact.core.angles import wrap_angle
from sensact.core.pose_models import landmark_bearing, landmark_distance, relative_displacement, sensor_poses
from sensact.learn.em.actions import step_motion_var
from sensact.learn.em.uses.draw_log import simulate_from_model
from sensact.learn.em.uses.error_bars import Parameter, Uncertainty, Z, coverage, model_parameters, summarize

runner = CliRunner()


def test_a_log_drawn_from_a_model_reads_as_the_model_says(continuous_fit):
    """The drawn path's steps about A(c) dt, over Sigma_m, and each reading about f at the drawn path, over
    its sigma, are standard normal; the log's commands, sighting times, landmarks and gaps are kept."""
    data, _, res = continuous_fit
    model = res.model
    drawn, path = simulate_from_model(model, data, seed=5)
    v = model.action.step_velocity(data)[:-1] * data.dt_s
    sd = np.sqrt(step_motion_var(model, data))[:-1]
    z = (relative_displacement(path[:-1], path[1:]) - v) / sd
    assert np.all(np.abs(z.mean(axis=0)) < 0.05)
    assert np.allclose(z.std(axis=0), 1.0, atol=0.03)  # 9000 steps: the sd's own error is under 1 %
    at = sensor_poses(path[drawn.obs_step], model.sensor.mount.as_array())
    lm = drawn.landmarks_xy[drawn.obs_landmark]
    ch = model.sensor.channels[0]
    z_range = (drawn.obs_readings[:, 0] - ch.predict(landmark_distance(at, lm), drawn.obs_bearing_rad)) / ch.sigma
    z_bearing = wrap_angle(drawn.obs_bearing_rad - landmark_bearing(at, lm)) / model.sensor.sigma_bearing_rad
    for zz in (z_range, z_bearing):  # 1500 sightings
        assert abs(zz.mean()) < 0.1 and abs(zz.std() - 1.0) < 0.06
    for name in ("obs_step", "obs_landmark", "step_commands", "landmarks_xy"):
        assert np.array_equal(getattr(drawn, name), getattr(data, name))
    again, _ = simulate_from_model(model, data, seed=5)
    other, _ = simulate_from_model(model, data, seed=6)
    assert np.array_equal(again.obs_readings, drawn.obs_readings)
    assert not np.array_equal(other.obs_readings, drawn.obs_readings)


def test_a_gap_in_the_log_stays_a_gap(continuous_fit):
    data, _, res = continuous_fit
    from dataclasses import replace

    gappy = replace(
        data, obs_bearing_rad=np.where(np.arange(data.n_observations) % 3 == 0, np.nan, data.obs_bearing_rad)
    )
    drawn, _ = simulate_from_model(res.model, gappy, seed=1)
    assert np.array_equal(np.isnan(drawn.obs_bearing_rad), np.isnan(gappy.obs_bearing_rad))
    assert np.isfinite(drawn.obs_readings).all()


def test_every_learned_parameter_is_named_once_by_family(continuous_fit):
    _, _, res = continuous_fit
    params = model_parameters(res.model, (1000.0, 2000.0))
    families = {family for family, _ in params.values()}
    assert families == {"action", "f", "sigma", "Sigma_m", "mount"}
    assert params["f.range_mm(1000 mm)"][1] == pytest.approx(
        res.model.sensor.channels[0].function(np.array([1000.0]))[0]
    )
    assert params["sigma.range_mm"] == ("sigma", res.model.sensor.channels[0].sigma)
    beta = res.model.action.coefficients
    assert params["action.v_theta_rad_s[omega_rad_s]"] == ("action", beta[2, 2])


def test_standard_errors_and_intervals_are_the_replicates(continuous_fit):
    """The standard error is the replicates' sd; the interval is the value less their bias, +- z_0.95 SE;
    a parameter every replicate gives alike is held; a failed replicate is counted, not used."""
    _, _, res = continuous_fit
    model = res.model
    f_at = (1000.0,)
    base = {name: value for name, (_, value) in model_parameters(model, f_at).items()}
    shifts = np.array([-0.3, 0.1, 0.5, 0.9])
    held = "action.v_x_mm_s[1]"
    draws = [{k: (v if k == held else v + s) for k, v in base.items()} for s in shifts]
    unc = summarize(model, [*draws, "EM diverged on replicate 9"], f_at, seed=7)
    assert (unc.replicates, unc.used, unc.failed) == (5, 4, ("EM diverged on replicate 9",))
    p = unc.by_name()["sigma.range_mm"]
    se, bias = float(np.std(shifts, ddof=1)), float(shifts.mean())
    assert p.se == pytest.approx(se) and p.bias == pytest.approx(bias)
    assert p.interval == pytest.approx((p.value - bias - Z * se, p.value - bias + Z * se))
    assert unc.by_name()[held].held and unc.by_name()[held].interval is None
    doc = unc.to_dict()
    assert doc["level"] == 0.9 and doc["parameters"]["sigma.range_mm"]["se"] == pytest.approx(se)


def test_coverage_counts_each_familys_intervals_that_hold_the_truth():
    unc = Uncertainty(
        3,
        3,
        0,
        (),
        (
            Parameter("a", "action", 1.0, 0.1, (0.8, 1.2), 0.0),
            Parameter("b", "action", 2.0, 0.1, (1.8, 2.2), 0.0),
            Parameter("s", "sigma", 5.0, None, None, None),
        ),
    )
    got = coverage([(unc, {"a": 1.1, "b": 3.0, "s": 5.0})])
    assert got["action"] == {"covered": 1, "intervals": 2, "share": 0.5}
    assert got["sigma"]["intervals"] == 0


@pytest.mark.slow
def test_learn_em_writes_the_error_bars_into_the_model(tmp_path):
    log, out = tmp_path / "log", tmp_path / "m" / "model.json"
    assert runner.invoke(app, ["simulate", "diffdrive", "--out", str(log), "--seconds", "30"]).exit_code == 0
    res = runner.invoke(app, ["learn", "em", str(log), "--out", str(out), "--uncertainty", "3"])
    assert_written(res)
    doc = json.loads(out.read_text())
    unc = doc["uncertainty"]
    assert unc["method"] == "parametric bootstrap" and (unc["replicates"], unc["used"]) == (3, 3)
    params = unc["parameters"]
    assert {p["family"] for p in params.values()} == {"action", "f", "sigma", "Sigma_m", "mount"}
    free = [p for p in params.values() if not p["held"]]
    assert free and all(p["se"] > 0 and p["interval"][0] < p["interval"][1] for p in free)
    assert params["sigma.range_mm"]["value"] == doc["model"]["sensor"]["channels"][0]["sigma"]
    assert "Error bars" in (out.parent / "report.html").read_text()
    one = runner.invoke(app, ["learn", "em", str(log), "--uncertainty", "1"])
    assert one.exit_code == 2 and "at least 2 replicates" in one.output
