"""`sensact monitor`: the change test (core/changepoint.py) and the filter's scores it reads
(learn/em/uses/change_detect.py), by the ladder: exact reductions, Monte Carlo references, seeded recovery of sec.
4.4.3's slowdown, and a real robot with its own model."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from conftest import assert_written
from sensact.cli import app
from sensact.core.changepoint import (
    binned,
    confirm_quantile,
    cusum_crossings,
    cusum_threshold,
    long_run_scale,
    persistence,
)

runner = CliRunner()
MRCLAM = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "mrclam" / "MRCLAM_Dataset6"


# ---------------------------------------------------------------- the change test alone


def test_bins_are_weighted_standardized_sums():
    rng = np.random.default_rng(0)
    t = np.sort(rng.uniform(0, 10, 200))
    u, w = rng.normal(size=200), rng.uniform(0, 2, 200)
    t[t >= 7.0] += 1.0  # no score in [7, 8)
    b = binned(u, w, t, 1.0, 11.0)
    for j in range(11):
        k = np.floor(t) == j
        if not k.any():
            assert np.isnan(b[j])
        else:
            assert b[j] == pytest.approx(np.sum(w[k] * u[k]) / np.sqrt(np.sum(w[k] ** 2)), rel=1e-12)
    assert np.isnan(b[7]) and np.isfinite(b[8])


def test_the_threshold_gives_siegmunds_run_length():
    """Monte Carlo reference: a one-sided CUSUM on N(0, 1) with the h for an average run length of 2000
    steps (tests=1, n_bins=10, false_alarm=0.01) runs about that long before its first false alarm."""
    k = 0.5
    h = cusum_threshold(10, 1, 0.01, k)
    rng = np.random.default_rng(1)
    runs = 400
    s = np.zeros(runs)
    length = np.zeros(runs)
    alive = np.ones(runs, dtype=bool)
    for step in range(1, 40_000):
        s[alive] = np.maximum(0.0, s[alive] + rng.normal(size=alive.sum()) - k)
        hit = alive & (s > h)
        length[hit] = step
        alive &= ~hit
        if not alive.any():
            break
    assert not alive.any()
    assert np.mean(length) == pytest.approx(2000, rel=0.15)


def test_the_long_run_scale_reads_correlation_and_ignores_a_step():
    rng = np.random.default_rng(2)
    white = rng.normal(size=3000)
    assert long_run_scale(white, 30) == pytest.approx(1.0, abs=0.15)
    rho = 0.8
    ar = np.zeros(3000)
    for i in range(1, 3000):
        ar[i] = rho * ar[i - 1] + np.sqrt(1 - rho**2) * rng.normal()
    assert long_run_scale(ar, 30) == pytest.approx(np.sqrt((1 + rho) / (1 - rho)), rel=0.2)
    stepped = white.copy()
    stepped[1500:] += 3.0  # one step moves a single batch difference: the robust spread does not see it
    assert long_run_scale(stepped, 30) == pytest.approx(long_run_scale(white, 30), abs=0.1)
    assert long_run_scale(white[:60], 30) == 1.0  # too few batches to tell


def test_a_step_is_a_change_and_a_burst_an_episode():
    rng = np.random.default_rng(3)
    h, k = cusum_threshold(900, 2, 0.01, 0.5), 0.5
    confirm = confirm_quantile(2, 0.01)
    noise = rng.normal(size=900)
    step = noise.copy()
    step[500:] += 1.5
    found = cusum_crossings(step, h, k, confirm, 30)
    assert found[-1].confirmed and 480 <= found[-1].start <= 505 and 500 < found[-1].alarm < 530
    assert found[-1].sign == 1
    burst = noise.copy()
    burst[300:320] += 2.5  # 20 bins of misfit, then the model holds again
    episodes = cusum_crossings(burst, h, k, confirm, 30)
    assert episodes and not any(c.confirmed for c in episodes)
    assert cusum_crossings(noise, h, k, confirm, 30) == []
    # a log the model misfits alike throughout has not changed once 30 bins came before; from the start
    # (nothing before it) the model's own zero is the reference
    offset = noise + 0.8
    late = cusum_crossings(offset[300:], h, k, confirm, 30)
    assert late and late[-1].confirmed and late[-1].start < 30
    assert persistence(offset, 400, 1, 30) < confirm < persistence(offset, 400, 1, 10_000)


# ---------------------------------------------------------------- the filter's scores


def test_innovations_and_their_sensitivity_are_the_whitened_observations_exactly():
    """Exact reduction: on a linear-Gaussian track the standardized innovations are L^-1 (y - E y), L the
    Cholesky factor of Cov y, and their derivative in a gain on the velocity is -L^-1 dE[y]/dg."""
    from sensact.learn.em.estep import innovations
    from test_estep import SM, _linear_track

    data, model, y, mu, S, H, b, _ = _linear_track()
    inn = innovations(model.replace(motion_sd=np.array([[SM]])), data)
    assert inn.ok
    L = np.linalg.cholesky(H @ S @ H.T + 1.5**2 * np.eye(y.size))
    np.testing.assert_allclose(inn.z[:, 0], np.linalg.solve(L, y - (H @ mu + b)), atol=1e-9)
    assert np.all(np.isnan(inn.z[:, 1]))  # a track reads no bearing
    dmu = mu - mu[0]  # mu = 2000 - cumulative displacement, linear in the gain
    np.testing.assert_allclose(inn.sensitivity[:, 0, 0], -np.linalg.solve(L, H @ dmu), atol=1e-9)


# ---------------------------------------------------------------- sec. 4.4.3


@pytest.fixture(scope="module")
def slowdown():
    """Sec. 4.4.3's run (em1d's track, the robot at 3/4 from 8 minutes), seed 0, the same run without the
    change, and the model learned on the first 8 minutes as the thesis learns its "before" model."""
    from sensact.experiments.em1d import EM1D_TRACK, EM1DExperiment
    from sensact.learn.em import fit_em, initial_model
    from sensact.sim.track1d import simulate_track, to_landmark_log

    sim = dataclasses.replace(EM1D_TRACK, seed=0)
    changed = to_landmark_log(simulate_track(sim))
    steady = to_landmark_log(simulate_track(dataclasses.replace(sim, change_at_s=None)))
    before = changed.slice_steps(0, round(480.0 / sim.dt_s))
    learner = EM1DExperiment().learner
    return sim, changed, steady, fit_em(before, initial_model(before, learner), learner).model, learner


@pytest.mark.slow  # 45 s with its fixture (an 8-minute fit): `python -m pytest -m slow`
def test_monitor_flags_sec_4_4_3s_slowdown_within_30_s_and_nothing_without_it(slowdown):
    from sensact.learn.em.uses.change_detect import monitor_placed

    sim, changed, steady, model, learner = slowdown
    _, res = monitor_placed(model, changed, learner)
    stream, event = res.change
    assert stream.model == "action" and stream.name == "action:v_mm_s"
    assert 480.0 < event.alarm_s <= 510.0 and 470.0 <= event.change_s <= 500.0
    assert event.direction == 1  # the robot moves less than the model says
    assert res.change_step() == round(event.change_s / sim.dt_s)
    _, quiet = monitor_placed(model, steady, learner)
    assert quiet.change is None
    assert {s.name for s in quiet.streams} == {"sensor:height_px", "action:v_mm_s"}


@pytest.mark.slow
def test_cli_monitor_writes_the_change_and_relearns_from_it(slowdown, tmp_path):
    from sensact.evaluate.em import score_track
    from sensact.evaluate.track1d import DISTANCE_GRID_MM
    from sensact.experiments.em1d import true_velocities
    from sensact.io.landmark_folder import write_landmark_log

    sim, changed, _, model, learner = slowdown
    log = write_landmark_log(tmp_path / "log", changed)
    model_json = tmp_path / "before.json"
    summary = {"config": json.loads(json.dumps(dataclasses.asdict(learner)))}
    model_json.write_text(json.dumps({"model": model.to_dict(), "dt_s": changed.dt_s, "summary": summary}))
    out, relearned = tmp_path / "m" / "monitor.json", tmp_path / "r" / "model.json"
    args = ["monitor", str(log), "--model", str(model_json), "--out", str(out), "--relearn", str(relearned)]
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    doc = json.loads(out.read_text())
    assert doc["changed"] is True and doc["change"]["model"] == "action"
    assert doc["change"]["stream"] == "action:v_mm_s"
    assert doc["change"]["delay_s"] == pytest.approx(doc["change"]["alarm_s"] - doc["change"]["change_s"])
    assert doc["change"]["alarm_s"] - 480.0 <= 30.0
    assert [s["name"] for s in doc["streams"]] == ["sensor:height_px", "action:v_mm_s"]
    assert out.with_suffix(".png").stat().st_size > 20_000
    # relearned from the change on: the slowed robot's velocities, far better than the stale model's
    from sensact.models.em_model import EMModel

    new = EMModel.from_dict(json.loads(relearned.read_text())["model"])
    truth, height = true_velocities(sim, True), sim.truth().height_px
    fresh = score_track(new, truth, height, DISTANCE_GRID_MM)["action_rms_mm_s"]
    stale = score_track(model, truth, height, DISTANCE_GRID_MM)["action_rms_mm_s"]
    assert fresh < 0.5 * stale, (fresh, stale)
    # bad input is one line
    res = runner.invoke(app, ["monitor", str(log), "--model", str(model_json), "--false-alarm", "2"])
    assert res.exit_code == 2 and "false_alarm must be between 0 and 1" in res.output


def test_the_simulated_drive_wears_from_change_at_s():
    """``DiffDriveConfig.change_at_s``: the same run until then; after it, the robot covers 3/4 of the
    ground per commanded millimetre that it covered before."""
    from sensact.sim.diffdrive import DiffDriveConfig, simulate_diffdrive

    cfg = DiffDriveConfig(seed=3, seconds=300.0, forward_sd_mm=0.0, sideways_sd_mm=0.0, forward_bias_mm_s=0.0)
    steady, worn = simulate_diffdrive(cfg), simulate_diffdrive(dataclasses.replace(cfg, change_at_s=150.0))
    k = round(150.0 / cfg.dt_s)
    np.testing.assert_array_equal(worn.poses[: k + 1], steady.poses[: k + 1])
    assert not np.array_equal(worn.poses, steady.poses)

    def per_commanded_mm(run, a, b):
        moved = np.hypot(*np.diff(run.poses[a:b, :2], axis=0).T).sum()
        return moved / (np.abs(run.commands[a : b - 1, 0]).sum() * cfg.dt_s)

    before = per_commanded_mm(worn, 60, k)
    after = per_commanded_mm(worn, k + 60, len(worn.poses))
    assert after / before == pytest.approx(0.75, abs=0.03)


def test_a_planar_robot_learned_on_one_run_is_flagged_when_its_motors_wear_on_another():
    """Off the thesis's track: a simulated differential drive in MRCLAM's conditions, learned on one 300 s
    run; on another run its motors give 3/4 of every velocity from 150 s (``change_at_s``): the action
    model is named within 30 s; the same run without the change raises no alarm."""
    from sensact.learn.em import fit_em
    from sensact.learn.em.uses.change_detect import monitor_placed
    from sensact.presets import simulator_settings
    from sensact.sim.diffdrive import DiffDriveConfig, simulate_diffdrive

    learned_on = DiffDriveConfig(seed=0, seconds=300.0)
    settings = simulator_settings(learned_on)
    model = fit_em(simulate_diffdrive(learned_on).log("learned on"), None, settings).model
    other = DiffDriveConfig(seed=1000, seconds=300.0)
    worn = simulate_diffdrive(dataclasses.replace(other, change_at_s=150.0)).log("worn")
    _, res = monitor_placed(model, worn, settings)
    stream, event = res.change
    assert stream.model == "action" and 150.0 < event.alarm_s <= 180.0 and 140.0 <= event.change_s <= 165.0
    assert [s.name for s in res.streams] == [
        "sensor:range_mm",
        "sensor:bearing",
        "action:v_y_mm_s",
        "action:v_theta_rad_s",
    ]
    _, quiet = monitor_placed(model, simulate_diffdrive(other).log("steady"), settings)
    assert quiet.change is None


def test_a_tracks_commands_go_onto_the_models_actions_on_another_log(tmp_path):
    """A model learned on one 1-D log of continuous commands runs on the next (`monitor`, `localize`): that
    log's commands go into the model's own bins, not into equal bins over their own span."""
    from sensact.app.logs import open_landmark_log, read_model_and_log
    from sensact.learn.em import EMConfig, initial_model

    for name, seed in (("a", 0), ("b", 1)):
        res = runner.invoke(
            app, ["simulate", "track1d", "--out", str(tmp_path / name), "--seconds", "240", "--seed", str(seed)]
        )
        assert res.exit_code == 0, res.output
    a, b = open_landmark_log(tmp_path / "a"), open_landmark_log(tmp_path / "b")
    assert not np.array_equal(a.data.action_commands, b.data.action_commands)  # each log's own span
    model = initial_model(a.data, EMConfig())
    (tmp_path / "m.json").write_text(json.dumps({"model": model.to_dict(), "dt_s": a.data.dt_s}))
    _, _, opened = read_model_and_log(tmp_path / "b", tmp_path / "m.json", 21, use="run")
    levels = a.data.action_commands[:, 0]
    np.testing.assert_array_equal(opened.data.action_commands[:, 0], levels)
    from sensact.io.logfolder import read_track_log

    c = read_track_log(tmp_path / "b").commands
    np.testing.assert_array_equal(opened.data.actions, np.argmin(np.abs(c[:, None] - levels[None, :]), axis=1))
    res = runner.invoke(app, ["monitor", str(tmp_path / "b"), "--model", str(tmp_path / "m.json")])
    assert res.exit_code == 0, res.output


@pytest.mark.slow
@pytest.mark.realdata
@pytest.mark.skipif(not MRCLAM.is_dir(), reason=f"MRCLAM data not found at {MRCLAM}")
def test_a_mrclam_robot_with_its_own_model_raises_no_alarm(tmp_path):
    """The user's route: `convert mrclam`, `learn em`, `monitor` on the same log: no change (episodes of
    misfit may come and go)."""
    log, model, out = tmp_path / "r1", tmp_path / "m" / "model.json", tmp_path / "mon.json"
    assert runner.invoke(app, ["convert", "mrclam", str(MRCLAM), "--robot", "1", "--out", str(log)]).exit_code == 0
    assert runner.invoke(app, ["learn", "em", str(log), "--out", str(model), "--no-report"]).exit_code == 0
    res = runner.invoke(app, ["monitor", str(log), "--model", str(model), "--out", str(out)])
    assert_written(res)
    doc = json.loads(out.read_text())
    assert doc["changed"] is False and doc["change"] is None
    names = [s["name"] for s in doc["streams"]]
    assert names == ["sensor:range_mm", "sensor:bearing", "action:v_y_mm_s", "action:v_theta_rad_s"]
