"""`learn em --halves`: each half of a log learned on from the whole log's model, and the three compared
(learn/em/uses/split_halves.py, evaluate/halves.py): no ground truth, the log against itself."""

from __future__ import annotations

from dataclasses import replace

import pytest

from continuous_robot import TRUE_BETA, continuous_config, simulate_continuous
from sensact.errors import ConfigError
from sensact.evaluate.halves import compare_halves
from sensact.learn.em import fit_em
from sensact.learn.em.uses.split_halves import half_steps, learn_halves

FORWARD = (1, 1)  # TRUE_BETA's forward gain: the forward velocity per commanded v


def test_a_model_compared_with_itself_differs_by_nothing(continuous_fit):
    """Exact reduction: the whole log's model as both halves differs from itself by zero everywhere."""
    data, _, res = continuous_fit
    m = res.model
    cmp = compare_halves(m, m, m, res.posteriors, data)
    for k in ("first_vs_whole", "second_vs_whole", "first_vs_second"):
        assert all(v == 0.0 for v in cmp["velocity"][k].values())
        assert cmp["f"][k] == {"range_mm": 0.0}
    assert set(cmp["noise"]["halves_ratio"]) == set(cmp["noise"]["whole"]) and all(
        r == 1.0 for r in cmp["noise"]["halves_ratio"].values()
    )
    lo, hi = cmp["f"]["spans"]["range_mm"]
    assert 0.0 < lo < hi


def test_halves_tell_a_change_during_the_run_from_a_run_that_does_not_pin_a_parameter(continuous_fit):
    """Seeded: the robot of tests/continuous_robot.py circles at one turn command through its second half
    (1 step in 4500 is another), so that half cannot tell the turn gain from the turn constant, and its turn
    model differs from the first half's where the whole log commands other turns; when the forward gain
    drops from 0.9 to 0.75 at the middle, each half learns its own gain and the halves' translation
    differs several times more than in the unchanged run, while the turn stays as it was."""
    data, _, whole = continuous_fit
    assert half_steps(data.n_steps) == [(0, 4500), (4500, 9000)]
    same = learn_halves(whole.model, data, continuous_config())
    assert [h.data.n_steps for h in same] == [4500, 4500]
    assert sum(h.data.n_observations for h in same) == data.n_observations  # the halves split the sightings
    cmp_same = compare_halves(whole.model, same[0].result.model, same[1].result.model, whole.posteriors, data)
    assert cmp_same["velocity"]["first_vs_second"]["rotation_rad_s"] > 0.1  # measured 0.174 rad/s
    # the first half, which commands many turns, learns the true turn gain (0.8)
    assert same[0].result.model.action.coefficients[2, 2] == pytest.approx(TRUE_BETA[2, 2], abs=0.05)

    changed_beta = TRUE_BETA.copy()
    changed_beta[FORWARD] = 0.75
    changed, _ = simulate_continuous(1, beta_after=changed_beta)
    res = fit_em(changed, None, continuous_config())
    halves = learn_halves(res.model, changed, continuous_config())
    gains = [h.result.model.action.coefficients[FORWARD] for h in halves]
    assert gains[0] == pytest.approx(0.9, abs=0.04) and gains[1] == pytest.approx(0.75, abs=0.04), gains
    assert gains[1] < res.model.action.coefficients[FORWARD] < gains[0]  # the whole log's is between
    cmp = compare_halves(res.model, halves[0].result.model, halves[1].result.model, res.posteriors, changed)
    moved = cmp["velocity"]["first_vs_second"]["translation_mm_s"]
    assert moved > 3 * cmp_same["velocity"]["first_vs_second"]["translation_mm_s"]  # measured 26.7 against 5.6
    assert cmp["velocity"]["first_vs_second"]["rotation_rad_s"] == pytest.approx(
        cmp_same["velocity"]["first_vs_second"]["rotation_rad_s"], rel=0.2
    )


def test_a_half_without_a_sighting_is_refused_naming_it(continuous_fit):
    data, _, res = continuous_fit
    keep = data.obs_step < data.n_steps // 2  # the second half's sightings dropped
    blind = replace(
        data,
        obs_step=data.obs_step[keep],
        obs_landmark=data.obs_landmark[keep],
        obs_readings=data.obs_readings[keep],
        obs_bearing_rad=data.obs_bearing_rad[keep],
    )
    with pytest.raises(ConfigError, match=r"the second half \(steps 4500:9000\) has no sighting"):
        learn_halves(res.model, blind, continuous_config())
