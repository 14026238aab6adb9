"""No surveyed map needed (issue 92): EM learns the landmarks' positions with the models.

Oracles: exact reductions (a full map is today's fit, bit for bit: no learned map in the model; the
rigid alignment recovers a known rotation and translation exactly; a map merged from rotated copies is
the first), an independent reference (the landmark M-step on the true poses finds the true positions),
seeded recovery (a simulated robot among landmarks unknown to the learner: the map, the path and the
models), invariants (the log folder and model round trips, the export read back by --landmarks), and
errors in one line (range-only anchors with unknown positions, a half-given position).
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from conftest import write_csv
from sensact.app.shared_map import _map_step, merge_maps
from sensact.cli import app
from sensact.errors import ConfigError, LogFormatError
from sensact.evaluate.map_truth import map_scores, rigid_alignment, similarity_alignment
from sensact.io.landmark_folder import read_landmark_log, write_landmark_log
from sensact.io.timed_csv import MIN_SIGHTINGS_TO_LEARN, read_landmarks, read_timed_csv
from sensact.learn.em import fit_em, initial_model
from sensact.learn.em.landmark_step import landmark_update, normal_equations
from sensact.models.em_model import EMModel
from sensact.models.landmark_map import LandmarkMap
from sensact.models.landmark_sensor import SampledSightings
from sensact.presets import planar_config
from sensact.sim.diffdrive import DiffDriveConfig, simulate_diffdrive

runner = CliRunner()


def _rot(a: float) -> np.ndarray:
    return np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])


def test_rigid_alignment_recovers_a_known_rotation_and_translation_exactly():
    rng = np.random.default_rng(0)
    survey = rng.uniform(-4000, 4000, (12, 2))
    learned = (survey - [300.0, -50.0]) @ _rot(0.7)  # survey = R(0.7) learned + t
    learned[3] = np.nan  # not placed: skipped
    fit = rigid_alignment(learned, survey)
    assert fit.rotation_rad == pytest.approx(0.7, abs=1e-12)
    np.testing.assert_allclose(fit.points(learned[~np.isnan(learned).any(axis=1)]), np.delete(survey, 3, 0), atol=1e-9)
    scores, _ = map_scores(learned, survey, np.full(12, 30))
    assert scores["rms_mm"] == pytest.approx(0.0, abs=1e-9)
    assert (scores["landmarks_placed"], scores["landmarks_total"], scores["seen_enough_not_placed"]) == (11, 12, 1)
    poses = np.array([[0.0, 0.0, 0.1], [100.0, 0.0, -3.0]])
    moved = fit.poses(poses)
    np.testing.assert_allclose(moved[:, 2] - poses[:, 2], 0.7)
    assert rigid_alignment(learned[:1], survey[:1]) is None


def test_a_scaled_map_is_not_aligned_away():
    """The scores align rigidly, without scale: a map 3 % too large shows its error."""
    survey = np.array([[0.0, 0.0], [4000.0, 0.0], [4000.0, 9000.0], [0.0, 9000.0]])
    scores, _ = map_scores(survey * 1.03, survey, np.full(4, 100))
    assert scores["rms_mm"] > 100.0
    # ... and the scale is said beside it: the map's size over the survey's, its shape exact once taken out
    assert scores["scale"] == pytest.approx(1.03, rel=1e-12) and scores["similarity_rms_mm"] < 1e-9


def test_similarity_alignment_recovers_a_known_rotation_translation_and_scale_exactly():
    rng = np.random.default_rng(1)
    survey = rng.uniform(-4000, 4000, (9, 2))
    learned = (survey - [300.0, -50.0]) @ _rot(-1.1) / 0.96  # survey = 0.96 R(-1.1) learned + t
    fit = similarity_alignment(learned, survey)
    assert fit.rotation_rad == pytest.approx(-1.1, abs=1e-12) and fit.scale == pytest.approx(0.96, rel=1e-12)
    np.testing.assert_allclose(fit.points(learned), survey, atol=1e-9)
    poses = fit.poses(np.array([[0.0, 0.0, 0.2]]))
    assert poses[0, 2] == pytest.approx(0.2 - 1.1) and similarity_alignment(learned[:1], survey[:1]) is None


def test_the_landmark_m_step_on_the_true_poses_finds_the_true_positions():
    run = simulate_diffdrive(DiffDriveConfig(seconds=120, seed=3, range_gain=1.0, range_offset_mm=0.0, misread_rate=0))
    data = run.log()
    model = initial_model(data, planar_config(data.command_names))
    ch = model.sensor.channels[0]
    f = type(ch.function)(coef=(0.0, 1.0) + (0.0,) * (ch.function.degree - 1), center=0.0, scale=1.0)
    from dataclasses import replace

    sensor = replace(model.sensor, channels=(replace(ch, function=f, sigma=40.0, bearing_terms=(0.0, 0.08)),))
    sensor = replace(sensor, sigma_bearing_rad=0.006)
    poses = run.poses[data.obs_step][None]  # one "sample": the truth
    weights = np.ones((data.n_observations, 2))
    start = data.landmarks_xy + 250.0
    seen = np.bincount(data.obs_landmark, minlength=len(start)) >= 5
    sightings = SampledSightings(poses, data.obs_landmark, data.obs_readings, weights, data.obs_bearing_rad)
    xy, sd = landmark_update(sightings, sensor, start, seen)
    err = np.hypot(*(xy[seen] - data.landmarks_xy[seen]).T)
    assert np.all(err < 5 * np.nanmax(sd[seen], axis=1) + 10.0) and np.median(err) < 40.0
    info, grad = normal_equations(sightings, sensor, xy)
    step = np.linalg.solve(info[seen], grad[seen][:, :, None])[:, :, 0]
    assert np.abs(step).max() < 1.0  # mm: the update's fixed point is where Q's gradient vanishes


def test_a_full_map_learns_no_map_and_the_model_round_trips_a_learned_one():
    data = simulate_diffdrive(DiffDriveConfig(seconds=30, seed=1)).log()
    assert initial_model(data, planar_config(data.command_names)).landmarks is None
    assert "landmarks" not in initial_model(data, planar_config(data.command_names)).to_dict()
    hidden = data.with_landmarks(np.full_like(data.landmarks_xy, np.nan))
    model = initial_model(hidden, planar_config(data.command_names))
    learned = model.landmarks
    assert learned is not None and not learned.held.any() and learned.scale == "range"
    np.testing.assert_allclose(model.prior_mean, [0.0, 0.0, -np.pi / 2])  # the start faces REP 103's +x
    back = EMModel.from_dict(json.loads(json.dumps(model.to_dict())))
    np.testing.assert_array_equal(back.landmarks.xy, learned.xy)
    np.testing.assert_array_equal(back.landmarks.placed, learned.placed)
    assert "the robot's start" in learned.frame and "range readings" in learned.frame


def test_a_log_folder_keeps_unknown_positions_as_null_and_the_survey_for_scoring(tmp_path):
    data = simulate_diffdrive(DiffDriveConfig(seconds=30, seed=1)).log()
    hidden = data.with_landmarks(np.where(np.arange(len(data.landmarks_xy))[:, None] < 3, data.landmarks_xy, np.nan))
    write_landmark_log(tmp_path / "log", hidden, survey_xy=data.landmarks_xy)
    meta = json.loads((tmp_path / "log" / "meta.json").read_text())
    assert meta["landmarks"][5]["x_mm"] is None and meta["landmarks"][0]["x_mm"] is not None
    lf = read_landmark_log(tmp_path / "log")
    np.testing.assert_array_equal(lf.data.map_given, np.arange(len(data.landmarks_xy)) < 3)
    np.testing.assert_allclose(lf.survey_xy, data.landmarks_xy)
    meta["landmarks"][1]["y_mm"] = None  # half a position
    (tmp_path / "log" / "meta.json").write_text(json.dumps(meta))
    with pytest.raises(LogFormatError, match="not finite") as err:
        read_landmark_log(tmp_path / "log")
    assert "null for both" in err.value.fix


def test_range_only_anchors_with_unknown_positions_are_refused_in_one_line():
    data = simulate_diffdrive(DiffDriveConfig(seconds=30, seed=2, sensor="radio")).log()
    hidden = data.with_landmarks(np.full_like(data.landmarks_xy, np.nan))
    from sensact.presets import range_only_config

    with pytest.raises(ConfigError, match="ranges alone") as err:
        initial_model(hidden, range_only_config(data.command_names, (0.0, 0.0, 0.0)))
    assert err.value.field == "landmarks" and "\n" not in str(err.value)


def test_convert_csv_without_a_map_learns_every_landmark_and_a_partial_map_holds_its_own(tmp_path):
    """A full map drops unlisted ids as before (other robots); --learn-unlisted learns those seen often."""
    write_csv(tmp_path / "c.csv", {"t_s": [0.0, 1.0, 2.0, 3.0], "v_m_s": [0.1] * 4, "omega_rad_s": [0.0] * 4})
    n = MIN_SIGHTINGS_TO_LEARN
    rows = ["t_s,landmark_id,range_m,bearing_rad"]
    rows += [f"{0.1 * (i % 25):.2f},tagA,2.0,0.1" for i in range(n)]
    rows += [f"{0.1 * (i % 25):.2f},7,3.0,-0.1" for i in range(n)]
    rows += ["1.0,99,1.0,0.0"]  # seen once: a false detection
    (tmp_path / "s.csv").write_text("\n".join(rows) + "\n")
    free = read_timed_csv(tmp_path / "c.csv", tmp_path / "s.csv", None)
    assert free.data.landmark_names == ("7", "99", "tagA") and not free.data.map_given.any()
    (tmp_path / "l.csv").write_text("id,x_m,y_m\ntagA,1,2\n")
    listed = read_timed_csv(tmp_path / "c.csv", tmp_path / "s.csv", tmp_path / "l.csv")
    assert listed.data.landmark_names == ("tagA",) and listed.summary["dropped_unknown_landmark"] == n + 1
    partial = read_timed_csv(tmp_path / "c.csv", tmp_path / "s.csv", tmp_path / "l.csv", learn_unlisted=True)
    assert partial.data.landmark_names == ("tagA", "7")  # 99 seen once: dropped and counted
    np.testing.assert_array_equal(partial.data.map_given, [True, False])
    np.testing.assert_allclose(partial.data.landmarks_xy[0], [1000.0, 2000.0])
    assert partial.summary["dropped_unknown_landmark"] == 1 and partial.summary["learned_landmarks"] == 1


def test_merged_maps_of_rotated_copies_are_the_first_and_a_step_without_gradient_moves_nothing():
    rng = np.random.default_rng(1)
    truth = rng.uniform(-3000, 3000, (8, 2))

    def doc(xy, first=0):
        marks = [
            {"id": f"L{first + j}", "x_mm": x, "y_mm": y, "sd_x_mm": 20.0, "sd_y_mm": 20.0}
            for j, (x, y) in enumerate(xy)
        ]
        return {"map": {"landmarks": marks}}

    docs = [doc(truth), doc((truth - [500.0, 100.0]) @ _rot(1.1)), doc(truth[2:] @ _rot(-0.4) + 40.0, first=2)]
    shared, fits = merge_maps(docs)
    assert shared.names == tuple(f"L{j}" for j in range(8))
    np.testing.assert_allclose(shared.xy, truth, atol=1e-6)
    assert all(f is not None for f in fits)

    class Fit:
        map_names = shared.names
        map_info = np.tile(np.eye(2), (8, 1, 1))
        map_grad = np.zeros((8, 2))

    np.testing.assert_allclose(_map_step(shared, [Fit(), Fit()]).xy, shared.xy)
    np.testing.assert_array_equal(_map_step(shared, []).xy, shared.xy)  # no sightings: nothing moves


def test_a_learned_map_reads_back_through_landmarks_and_export(tmp_path):
    learned = LandmarkMap(
        np.array([[1000.0, -500.0], [2.0, 3.0], [7.0, 7.0]]),
        np.array([True, False, False]),
        np.array([[np.nan, np.nan], [10.0, 12.0], [900.0, 900.0]]),
        "range",
        np.array([True, True, False]),
    )
    doc = {"map": learned.to_dict(("a", "b", "c"), np.array([50, 40, 3]))}
    marks = doc["map"]["landmarks"]
    assert [m["placed"] for m in marks] == [True, True, False] and marks[2]["x_mm"] is None
    assert set(marks[1]) >= {"id", "x_mm", "y_mm", "sd_x_mm", "sd_y_mm"}
    (tmp_path / "m.json").write_text(json.dumps(doc))
    res = runner.invoke(app, ["export", str(tmp_path / "m.json"), "--format", "landmarks"])
    assert res.exit_code == 0, res.output
    out = tmp_path / "m.landmarks.csv"
    assert out.read_text().splitlines()[0] == "id,x_m,y_m"
    xy, ids = read_landmarks(out)
    assert list(ids) == ["a", "b"]
    np.testing.assert_allclose(xy, [[1000.0, -500.0], [2.0, 3.0]], atol=1e-3)
    again = runner.invoke(app, ["export", str(tmp_path / "m.json"), "--format", "landmarks"])
    assert again.exit_code == 0, again.output  # its own export is replaced
    (tmp_path / "bare.json").write_text("{}")
    res = runner.invoke(
        app, ["export", str(tmp_path / "bare.json"), "--format", "landmarks", "--out", str(tmp_path / "x.csv")]
    )
    assert res.exit_code == 2 and "map.landmarks" in res.output


def test_em_learns_an_unsurveyed_map_with_the_models_on_a_simulated_robot(tmp_path):
    """Seeded recovery through the route a user takes (`simulate diffdrive --no-map`, `learn em`): the map
    within 100 mm after the rigid alignment (a metric range sensor), every landmark seen 20 times placed,
    the path and the models scored as with a survey; the map exported and read back as --landmarks."""
    sim = tmp_path / "sim"
    args = ["simulate", "diffdrive", "--no-map", "--seconds", "300", "--seed", "1", "--set", "range_gain=1.0"]
    res = runner.invoke(app, [*args, "--out", str(sim)])
    assert res.exit_code == 0, res.output
    assert json.loads((sim / "meta.json").read_text())["landmarks"][0]["x_mm"] is None
    res = runner.invoke(app, ["learn", "em", str(sim), "--out", str(sim / "model.json")])
    assert res.exit_code == 0, res.output
    doc = json.loads((sim / "model.json").read_text())
    marks, ev = doc["map"]["landmarks"], doc["evaluation"]
    assert len(marks) == 14 and "the robot's start" in doc["map"]["frame"]
    assert all(set(m) >= {"id", "x_mm", "y_mm", "sd_x_mm", "sd_y_mm"} for m in marks)
    assert ev["map"]["rms_mm"] < 100.0 and ev["map"]["seen_enough_not_placed"] == 0
    assert ev["map"]["landmarks_total"] == 14 and ev["map"]["landmarks_placed"] >= 13
    assert ev["path"]["median_mm"] < 150.0
    assert ev["path"]["similarity"]["median_mm"] <= ev["path"]["median_mm"] * 1.05
    assert abs(ev["map"]["scale"] - 1.0) < 0.03 and ev["map"]["similarity_rms_mm"] <= ev["map"]["rms_mm"]
    assert ev["action"]["ratio_translation"] < 1.5 and ev["action"]["ratio_rotation"] < 1.5
    assert 1 / 1.5 < ev["range"]["sigma_ratio"] < 1.5
    assert (sim / "model_map.png").is_file()
    res = runner.invoke(
        app, ["export", str(sim / "model.json"), "--format", "landmarks", "--out", str(tmp_path / "m.csv")]
    )
    assert res.exit_code == 0, res.output
    xy, ids = read_landmarks(tmp_path / "m.csv")
    placed = [m for m in marks if m["placed"]]
    assert list(ids) == [m["id"] for m in placed]
    np.testing.assert_allclose(xy, [[m["x_mm"], m["y_mm"]] for m in placed], atol=1e-3)


def test_convert_mrclam_no_map_keeps_the_survey_for_scoring_only(tmp_path):
    from conftest import DATA, require

    folder = require(DATA / "mrclam" / "MRCLAM_Dataset6")
    out = tmp_path / "mr1"
    res = runner.invoke(app, ["convert", "mrclam", str(folder), "--robot", "1", "--no-map", "--out", str(out)])
    assert res.exit_code == 0, res.output
    lf = read_landmark_log(out)
    assert not lf.data.map_given.any() and len(lf.data.landmarks_xy) == 15
    from sensact.io.mrclam import read_mrclam

    np.testing.assert_allclose(lf.survey_xy, read_mrclam(folder, 1).data.landmarks_xy)


@pytest.mark.slow  # 36 s (`python -m pytest -m slow`)
def test_range_only_anchors_are_learned_when_three_or_more_are_given():
    """Seeded recovery: four of fourteen radio anchors hidden; the others fix the path, which places them."""
    from sensact.presets import range_only_config

    run = simulate_diffdrive(DiffDriveConfig(seconds=150, seed=1, sensor="radio"))
    data = run.log()
    hide = np.isin(np.arange(len(data.landmarks_xy)), [1, 5, 8, 12])
    log = data.with_landmarks(np.where(hide[:, None], np.nan, data.landmarks_xy))
    res = fit_em(log, None, range_only_config(data.command_names, (0.0, 0.0, 0.0)))
    learned = res.model.landmarks
    assert learned.scale == "map" and learned.held.sum() == 10 and learned.placed[hide].all()
    assert np.hypot(*(learned.xy[hide] - data.landmarks_xy[hide]).T).max() < 100.0
    np.testing.assert_array_equal(learned.xy[~hide], data.landmarks_xy[~hide])  # held
    assert np.median(np.hypot(*(res.posteriors.mean_gamma[:, :2] - run.poses[:, :2]).T)) < 50.0


@pytest.mark.slow
def test_fleet_learns_one_shared_map_from_two_robots_in_one_room(tmp_path):
    """Two simulated robots among the same unsurveyed landmarks: OUT/map.json holds one map (scored against
    the survey), each robot's model carries it, and the models learned alone stay beside them."""
    logs = []
    for seed in (1, 2):
        out = tmp_path / f"r{seed}"
        args = ["simulate", "diffdrive", "--no-map", "--seconds", "200", "--seed", str(seed), "--set", "range_gain=1.0"]
        res = runner.invoke(app, [*args, "--out", str(out)])
        assert res.exit_code == 0, res.output
        logs.append(str(out))
    fleet = tmp_path / "fleet"
    res = runner.invoke(
        app, ["fleet", "learn", *logs, "--workers", "1", "--shared-map", "--no-report", "--out", str(fleet)]
    )
    assert res.exit_code in (0, 3), res.output
    doc = json.loads((fleet / "map.json").read_text())
    assert len(doc["map"]["landmarks"]) == 14 and "r1" in doc["map"]["frame"]
    assert doc["evaluation"]["map"]["rms_mm"] < 100.0
    for name in ("r1", "r2"):
        shared = json.loads((fleet / name / "model.json").read_text())
        alone = json.loads((fleet / "alone" / name / "model.json").read_text())
        assert shared["map"]["landmarks"] and alone["map"]["landmarks"]
        assert shared["evaluation"]["path"]["median_mm"] < 1.5 * alone["evaluation"]["path"]["median_mm"] + 20.0


def test_a_malformed_survey_or_learned_map_is_one_line(tmp_path):
    data = simulate_diffdrive(DiffDriveConfig(seconds=20, seed=1)).log()
    write_landmark_log(tmp_path / "log", data.with_landmarks(np.full_like(data.landmarks_xy, np.nan)))
    meta = json.loads((tmp_path / "log" / "meta.json").read_text())
    meta["survey"] = [{"id": 99, "x_mm": 0.0, "y_mm": 0.0}]
    (tmp_path / "log" / "meta.json").write_text(json.dumps(meta))
    with pytest.raises(LogFormatError, match="survey is malformed") as err:
        read_landmark_log(tmp_path / "log")
    assert err.value.field == "survey"
    (tmp_path / "m.json").write_text(json.dumps({"map": {"landmarks": [{"id": "a", "x_mm": "far", "y_mm": 1.0}]}}))
    res = runner.invoke(app, ["export", str(tmp_path / "m.json"), "--format", "landmarks"])
    assert res.exit_code == 2 and "map.landmarks" in res.output
