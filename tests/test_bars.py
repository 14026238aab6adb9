"""The bars each experiment's JSON carries as ``scorecard``: each one at its edge, on made-up summaries."""

from __future__ import annotations

import copy
import json
import math

from sensact.evaluate.bars import at_most, checks_from_json, counts, not_scored, verdict_line, within_factor
from sensact.experiments import em1d, field2d, real, track1d, turtlebot_em
from sensact.experiments import velodyne_car as car


def test_a_bar_holds_at_its_edge_and_an_unmeasured_value_misses():
    assert at_most("k", "v_x RMS", 23.06, 23.06, "mm/s").cleared is True
    assert at_most("k", "v_x RMS", 23.0601, 23.06, "mm/s").cleared is False
    nan = at_most("k", "v_x RMS", math.nan, 23.06, "mm/s")
    assert nan.cleared is False and nan.ours == "not measured mm/s"
    assert at_most("k", "q", None, 1.0).cleared is False
    assert within_factor("k", "q", 1 / 1.5, 1.5).cleared is True and within_factor("k", "q", 1.5, 1.5).cleared is True
    assert within_factor("k", "q", 0.66, 1.5).cleared is False and within_factor("k", "q", 1.51, 1.5).cleared is False
    assert within_factor("k", "q", 0.56, 1.5).bar == "0.67 to 1.50"


def test_the_verdict_counts_scored_bars_and_names_each_miss():
    checks = [
        at_most("a", "v_x RMS", 17.7, 23.06, "mm/s"),
        within_factor("b", "robot1: bearing sigma / truth's", 0.56, 1.5),
        not_scored("c", "gain error", "≤ 5.00 %", "the log holds one command"),
    ]
    assert counts(checks) == (1, 2)
    assert verdict_line(checks) == (
        "bars: 1 of 2 cleared; missed: robot1: bearing sigma / truth's 0.56 (bar 0.67 to 1.50); "
        "1 not scored on this run"
    )
    assert verdict_line(checks[:1]) == "bars: 1 of 1 cleared"
    rows = json.loads(json.dumps([c.to_dict() for c in checks]))  # as the JSON holds them
    assert checks_from_json(rows) == checks


def _track1d_summary(converged: dict[str, tuple[int, int]]) -> dict:
    th = track1d.THESIS["rows"]
    rows = {
        name: {
            "sensor_rms_mm": th[name]["sensor_rms_mm"],
            "action_rms_mm_s": th[name]["action_rms_mm_s"],
            "consistency": 0.08,
            "converged": c,
            "trials": n,
        }
        for name, (c, n) in converged.items()
    }
    return {"rows": rows, "thesis": track1d.THESIS}


def test_table_3_1_bars_take_the_thesiss_share_of_converged_trials():
    at_bar = track1d.scorecard(_track1d_summary({"linear": (15, 15), "sign": (15, 15), "constant": (10, 15)}))
    assert len(at_bar) == 12 and all(c.cleared for c in at_bar)
    few = {c.key: c for c in track1d.scorecard(_track1d_summary({"linear": (2, 3), "constant": (2, 3)}))}
    assert few["linear.converged"].cleared is False and few["linear.converged"].ours == "2/3"
    assert few["constant.converged"].cleared is True  # 2 of 3 is the thesis's 10 of 15
    assert few["constant.converged"].bar == "≥ 10/15"
    worse = _track1d_summary({"sign": (15, 15)})
    worse["rows"]["sign"] |= {"sensor_rms_mm": 85.4, "consistency": 0.081}
    missed = [c.key for c in track1d.scorecard(worse) if not c.cleared]
    assert missed == ["sign.sensor_rms_mm", "sign.consistency"]


def test_field2d_bars_hold_on_the_mean_and_name_the_worst_seed():
    th = field2d.THESIS["simulation"]
    trials = [
        {"seed": 3, "vx_rms_mm_s": 17.0, "vy_rms_mm_s": 18.34, "vtheta_rms_rad_s": 0.02}
        | {"sigma1_error_pct": 1.0, "sigma2_error_pct": 5.5},
        {"seed": 4, "vx_rms_mm_s": 23.53, "vy_rms_mm_s": 10.0, "vtheta_rms_rad_s": 0.03}
        | {"sigma1_error_pct": 2.0, "sigma2_error_pct": 1.0},
    ]
    keys = ("vx_rms_mm_s", "vy_rms_mm_s", "vtheta_rms_rad_s", "sigma1_error_pct", "sigma2_error_pct")
    ours = {k: sum(t[k] for t in trials) / 2 for k in keys} | {"trials": 2}
    checks = {c.key: c for c in field2d.scorecard({"ours": ours, "thesis": th, "per_trial": trials})}
    assert len(checks) == 10 and all(checks[f"mean.{k}"].cleared for k in keys)
    assert checks["worst.vx_rms_mm_s"].quantity == "worst seed (4): v_x RMS" and not checks["worst.vx_rms_mm_s"].cleared
    assert checks["worst.vy_rms_mm_s"].cleared  # at the bar
    assert checks["worst.sigma2_error_pct"].quantity == "worst seed (3): sigma_2 error"
    assert not checks["worst.sigma2_error_pct"].cleared
    # the same misses as the per-seed lines
    missed = sorted(k.split(".")[1] for k, c in checks.items() if not c.cleared)
    assert (
        missed == ["sigma2_error_pct", "vx_rms_mm_s"] and len([m for t in trials for m in field2d.bar_misses(t)]) == 2
    )


def test_em1d_bars_take_the_scale_ratio_within_0_09_of_1():
    score = {"sensor_rms_pct": 2.52, "action_rms_pct": 2.8, "scale_ratio": 1.09, "relearning_beats_stale": True}
    score |= {
        "change_after_on_after": {"action_rms_mm_s": 7.1, "scale_ratio": 1.01},
        "change_before_on_after": {"action_rms_mm_s": 30.3, "scale_ratio": 1.15},
    }
    summary = {"ours": score, "thesis": em1d.THESIS}
    assert all(c.cleared for c in em1d.scorecard(summary))
    off = copy.deepcopy(summary)
    off["ours"] |= {"scale_ratio": 0.9099, "relearning_beats_stale": False}
    assert [c.key for c in em1d.scorecard(off) if not c.cleared] == ["scale_ratio", "relearning_beats_stale"]
    assert em1d.scorecard(summary)[3].ours == "7.1 against 30.3 mm/s, ratio 1.01 against 1.15"


def test_table_5_1_bars_need_both_the_thesiss_number_and_1_6_times_from_truth():
    th = car.THESIS
    summary = {"thesis": th, "laser_angle_rms_deg": 0.544}
    summary |= {"accel_rms": 0.17, "accel_rms_from_truth": 0.17, "fwd_vel_rms": 0.5, "fwd_vel_rms_from_truth": 0.3}
    summary |= {"ang_vel_rms": 0.013, "ang_vel_rms_from_truth": 0.0095}
    checks = {c.key: c for c in car.scorecard(summary)}
    assert len(checks) == 7 and checks["laser_angle_rms_deg"].cleared
    assert checks["fwd_vel_rms.thesis"].cleared and not checks["fwd_vel_rms.from_truth"].cleared  # 1.67 times
    assert checks["fwd_vel_rms.from_truth"].ours == "0.500 m/s (1.67 ×)"
    assert not checks["ang_vel_rms.thesis"].cleared and checks["ang_vel_rms.from_truth"].cleared


def _robot_score(bearing_ratio: float) -> dict:
    return {
        "action": {"ratio_translation": 1.04, "ratio_rotation": 1.5, "learned": {"translation_rms_mm_s": 50.0}},
        "range": {"sigma_ratio": 0.9},
        "bearing": {"sigma_ratio": bearing_ratio},
    }


def test_the_real_scorecard_holds_every_robots_bars_and_the_turtlebots():
    tb = {"score": {"gain_error_pct": None, "sensors": {"sonar1": {"rms_pct_of_span": 2.25}}}}
    tb["score"]["sensors"]["raw_ir2"] = {"rms_pct_of_span": math.nan}
    summary = {"mrclam": {"robot1": {"score": _robot_score(0.56)}, "robot2": {"score": _robot_score(1.0)}}}
    checks = real.scorecard(summary | {"turtlebot": tb})
    assert len(checks) == 12
    assert [c.key for c in checks if c.cleared is False] == ["robot1.bearing_sigma"]
    gain, sensor = checks[-2:]
    assert gain.cleared is None and "one command" in gain.ours  # a one-command log has no gain to score
    assert sensor.quantity == "Turtlebot: best sensor (sonar1), % of its span" and sensor.cleared
    # the per-robot marks `learn em` and `evaluate mrclam` print are the same bars
    assert real.bar_checks(_robot_score(0.56)) == {
        c.key.split(".")[1]: c.cleared for c in checks if c.key.startswith("robot1.")
    }
    tb["score"]["gain_error_pct"] = 5.01
    assert turtlebot_em.scorecard(tb)[0].cleared is False
