"""The application layer (``sensact.app``) and the presets it reads: `learn em DIR` is
``calibrate(open_log(DIR))``, the presets ship as YAML inside the package, and a settings file naming
its preset reads back to the settings it was written from."""

from __future__ import annotations

import inspect
import json
from types import SimpleNamespace

import numpy as np
import pytest
from typer.testing import CliRunner

from conftest import assert_written
from sensact.app import Calibration, Scores, calibrate, open_log, read_settings_file, save_calibration
from sensact.app.settings import resolve_settings
from sensact.cli import app
from sensact.errors import ConfigError, LogFormatError
from sensact.learn.em import EMConfig, fit_em
from sensact.learn.em.loop import em_loop
from sensact.learn.em.mount import MountFreedom
from sensact.learn.em.stage import HELD, plan_stages
from sensact.presets import PRESETS, for_log, load_preset, planar_config, preset_yaml, range_only_config, settings_yaml

runner = CliRunner()


@pytest.fixture(scope="module")
def diffdrive_log(tmp_path_factory):
    out = tmp_path_factory.mktemp("app") / "dd"
    res = runner.invoke(app, ["simulate", "diffdrive", "--out", str(out), "--seconds", "60"])
    assert res.exit_code == 0, res.output
    return out


def test_every_preset_ships_as_yaml_and_loads():
    """Each preset is package data, loads to a valid EMConfig and documents itself (comments)."""
    for name in PRESETS:
        text = preset_yaml(name)
        assert text.lstrip().startswith("#")
        assert isinstance(load_preset(name), EMConfig)
    assert load_preset("aibo_field") == EMConfig()  # the thesis's constants are the defaults
    with pytest.raises(ConfigError, match="no preset"):
        load_preset("mars_rover")


def test_planar_presets_follow_the_commands():
    """A differential drive on wheel speeds gets the forward speed on their sum; a range-only one the turn
    rate on their difference; a side-stepper every velocity free."""
    assert planar_config(("v_mm_s", "omega_rad_s")) == load_preset("differential_drive_camera")
    wheels = planar_config(("left_mm_s", "right_mm_s"))
    assert wheels.action.inputs == ("v_y_mm_s:(left_mm_s+right_mm_s)",)
    assert planar_config(("v_mm_s", "v_left_mm_s", "omega_rad_s")).action.zero_mean == ()
    ro = range_only_config(("left_mm_s", "right_mm_s"), (1.0, 2.0, 3.0))
    assert ro.action.inputs == ("v_y_mm_s:(left_mm_s+right_mm_s)", "v_theta_rad_s:(right_mm_s-left_mm_s)")
    assert ro.thesis.start_prior_mean == (1.0, 2.0, 3.0) and all(c.bearing_degree == 0 for c in ro.channels)
    assert range_only_config(("v_mm_s", "omega_rad_s"), (0.0, 0.0, 0.0)) == load_preset("range_only_anchors")


def test_settings_file_names_its_preset_and_reads_back(diffdrive_log, tmp_path):
    """The file `simulate`/`convert` write names its preset and lists only what differs from it; read back,
    it is the settings it was written from, also with fields changed."""
    text = (diffdrive_log / "em_config.yaml").read_text()
    lines = [ln for ln in text.splitlines() if not ln.startswith("#")]
    assert lines == ["preset: differential_drive_camera"]
    data = open_log(diffdrive_log).data
    assert read_settings_file(diffdrive_log / "em_config.yaml") == planar_config(data.command_names)
    changed = planar_config(data.command_names).replace(motion_sd_mm=2.0, turn_restarts=0)
    path = tmp_path / "mine.yaml"
    path.write_text(settings_yaml("differential_drive_camera", changed, data))
    assert read_settings_file(path, open_log(diffdrive_log)) == changed


def test_settings_precedence(diffdrive_log, tmp_path):
    """--preset replaces the folder's file; --config's own preset line rebases; --set is last."""
    log = open_log(diffdrive_log)
    beside = resolve_settings(log)
    assert beside.preset == "differential_drive_camera" and beside.base == str(diffdrive_log / "em_config.yaml")
    aibo = resolve_settings(log, preset="aibo_field", sets=["patience=7"])
    assert aibo.config == EMConfig.of(patience=7) and aibo.preset == "aibo_field"
    cfg = tmp_path / "c.yaml"
    cfg.write_text("preset: range_only_anchors\nmotion_sd_mm: 4.0\n")
    ro = resolve_settings(log, preset="aibo_field", config=cfg, sets=["turn_restarts=1"])
    assert (
        ro.preset == "range_only_anchors"
        and ro.config.thesis.motion_sd_mm == 4.0
        and ro.config.search.turn_restarts == 1
    )
    assert ro.config.channels == load_preset("range_only_anchors").channels
    with pytest.raises(ConfigError, match="for a 1-D robot"):
        for_log("track_1d", log.data)


def test_calibrate_is_learn_em(diffdrive_log, tmp_path):
    """``calibrate(open_log(DIR))`` gives what `sensact learn em DIR` writes: the same model and scores, with
    typed diagnostics; the fit itself is ``fit_em`` with the folder's settings."""
    sets = ["max_iterations=20", "start_search_s=null", "turn_restarts=0"]
    cal = calibrate(open_log(diffdrive_log), sets=sets)
    assert isinstance(cal, Calibration) and isinstance(cal.scores, Scores)
    assert cal.settings.preset == "differential_drive_camera"
    assert 0.0 <= cal.diagnostics.pruned_fraction < 0.2 and set(cal.diagnostics.residual_lag1_autocorrelation)
    assert set(cal.scores.bars) >= {"range_sigma", "path_median", "bearing_sigma"}
    direct = fit_em(cal.log.data, None, cal.config)
    np.testing.assert_array_equal(direct.model.action.coefficients, cal.model.action.coefficients)
    out = tmp_path / "m.json"
    flags = [arg for s in sets for arg in ("--set", s)]
    res = runner.invoke(app, ["learn", "em", str(diffdrive_log), "--out", str(out), *flags])
    assert_written(res)
    doc = json.loads(out.read_text())
    mine = cal.to_json()
    assert doc["model"] == json.loads(json.dumps(mine["model"]))
    assert doc["evaluation"]["path"]["median_mm"] == pytest.approx(mine["evaluation"]["path"]["median_mm"])
    assert doc["summary"]["preset"] == "differential_drive_camera" and doc["pruned_fraction"] == mine["pruned_fraction"]
    saved = save_calibration(cal, tmp_path / "again.json")
    assert {p.name for p in saved.written} >= {"again.json", "again.history.npz", "again.path.npz", "again.png"}


def test_open_log_says_what_a_path_is(tmp_path):
    with pytest.raises(LogFormatError):
        open_log(tmp_path / "nothing.txt").data  # noqa: B018
    (tmp_path / "nothing.txt").write_text("x")
    with pytest.raises(LogFormatError, match=r"not a log sensact reads.*a Turtlebot CSV.*a landmark log folder"):
        open_log(tmp_path / "nothing.txt")


def test_learn_em_with_a_preset(diffdrive_log, tmp_path):
    """`learn em LOG --preset NAME` runs on the preset, not the folder's file."""
    out = tmp_path / "m.json"
    args = ["learn", "em", str(diffdrive_log), "--preset", "range_only_anchors", "--out", str(out)]
    res = runner.invoke(app, [*args, "--set", "max_iterations=3"])
    assert_written(res)
    doc = json.loads(out.read_text())
    assert doc["summary"]["preset"] == "range_only_anchors"
    assert doc["summary"]["config"]["channels"][0]["bearing_degree"] == 0


def test_stages_are_declared():
    """The held stage holds Sigma_m, the bearing terms, the mount and the robust readings until refine_from
    (a start race's iterations count); nothing to hold, or a learned start: the free stage alone."""
    cfg = load_preset("differential_drive_camera")
    robust = SimpleNamespace(sensor=SimpleNamespace(is_robust=True, channels=()))
    plain = SimpleNamespace(sensor=SimpleNamespace(is_robust=False, channels=()))
    learned, held_mount = MountFreedom((True, True, True), "learned"), MountFreedom((False,) * 3, "held")
    held, free = plan_stages(cfg, robust, learned, spent=30)
    assert held == HELD.with_end(cfg.search.refine_from - 30) and not held.robust and held.mount == (False,) * 3
    assert free.robust and free.motion_noise and free.bearing_terms and free.mount == (True,) * 3
    assert [s.name for s in plan_stages(EMConfig(), plain, held_mount)] == ["free"]
    assert [s.name for s in plan_stages(cfg.replace(warm_start=True), robust, learned)] == ["free"]
    assert [s.name for s in plan_stages(cfg.replace(refine_from=0), robust, learned)] == ["free"]


def test_the_loop_reads_as_the_thesis():
    """DESIGN.md, 10: fit_em and its loop each fit in under 40 lines."""
    for f in (fit_em, em_loop):
        assert len(inspect.getsource(f).splitlines()) < 40, f.__name__
