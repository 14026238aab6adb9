"""Intervals in (`convert intervals`, then `learn em DIR`): what users of Censi et al.'s calibration tool or of
OdomLaserCalibraTool already computed, learned as the scan route learns after its own matching. Seeded
recovery of a known robot from intervals made by the model itself, the two file formats agreeing, and bad
files refused in one line."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from typer.testing import CliRunner

from sensact.cli import app
from sensact.core.pose_models import to_rep103
from sensact.io.intervals import COLUMNS, read_censi
from sensact.learn import wheel_lidar as wl
from sensact.logs.intervals_log import IntervalsLog

runner = CliRunner()
TRUE = np.array([33.2, 32.8, 162.0, -80.0, 15.0, 0.05, 0.0])  # PARAMETERS' order: mm, mm, mm, mm, mm, rad, s
KEYS = wl.PARAMETERS[:6]


def _run(args, code=0):
    res = runner.invoke(app, [str(a) for a in args])
    assert res.exit_code == code, res.output
    return res


def _intervals(seed: int, n: int = 300, turn: float = 1.5) -> IntervalsLog:
    """Intervals of a robot driving and turning both ways, its lidar's displacement from the true model (an arc
    an interval, as Censi et al. model it), with the scan matcher's noise (2 mm, 2 mrad)."""
    rng = np.random.default_rng(seed)
    T = rng.uniform(0.2, 0.6, n)
    v, w = rng.uniform(-0.1, 0.3, n), rng.uniform(-turn, turn, n)
    rl, rr, b = TRUE[:3]
    phi = np.column_stack([(v * 1000 - w * b / 2) / rl, (v * 1000 + w * b / 2) / rr])
    track, t, _ = wl.intervals_track(IntervalsLog("sim", T, phi, np.zeros((n, 3))))
    k = np.arange(n)
    sm = to_rep103(wl.predicted(TRUE, track, t, k, k + 1)) * [1e-3, 1e-3, 1] + rng.normal(0, 0.002, (n, 3))
    return IntervalsLog("sim", T, phi, sm)


def _censi_file(path, log: IntervalsLog):
    rows = [
        json.dumps({"T": T, "phi_l": p[0], "phi_r": p[1], "sm": list(s)})
        for T, p, s in zip(log.t_s.tolist(), log.phi_rad_s.tolist(), log.sm_m.tolist(), strict=True)
    ]
    path.write_text("\n".join(rows) + "\n")
    return path


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_known_robot_comes_back_within_its_error_bars(tmp_path, seed):
    log = _intervals(seed)
    _run(["convert", "intervals", _censi_file(tmp_path / "tuples.json", log), "--out", tmp_path / "run"])
    _run(["learn", "em", tmp_path / "run", "--out", tmp_path / "model.json"])
    doc = json.loads((tmp_path / "model.json").read_text())
    got = {**doc["drive"], **doc["lidar"]["mount"]}
    for key, want in zip(KEYS, TRUE, strict=False):
        assert 0 < got[f"{key}_sd"] and abs(got[key] - want) <= 3 * got[f"{key}_sd"], (key, got[key], want)
    assert doc["kind"] == "intervals" and doc["health"]["ok"]
    assert abs(doc["censi"]["axle_mm"] - TRUE[2]) < 2.0  # Censi et al.'s closed form, beside it
    xml = _run(["export", tmp_path / "model.json", "--format", "urdf", "--out", tmp_path / "m.urdf.xacro"])
    assert "wrote" in xml.output
    root = ET.parse(tmp_path / "m.urdf.xacro").getroot()
    radii = [float(p.get("value")) for p in root if p.get("name", "").startswith("wheel_radius")]
    assert radii and min(radii) > 0.005  # metres: radii, never gains


def test_the_csv_and_the_json_lines_are_one_log(tmp_path):
    log = _intervals(4, n=60)
    table = np.column_stack([log.t_s, log.phi_rad_s, log.sm_m])
    csv = tmp_path / "intervals.csv"
    csv.write_text(",".join(COLUMNS) + "\n" + "\n".join(",".join(map(repr, r)) for r in table.tolist()) + "\n")
    for src, out in ((csv, "a"), (_censi_file(tmp_path / "t.json", log), "b")):
        _run(["convert", "intervals", src, "--out", tmp_path / out])
        _run(["learn", "em", tmp_path / out, "--out", tmp_path / f"{out}.json", "--no-report"])
    a, b = (json.loads((tmp_path / f"{n}.json").read_text()) for n in "ab")
    assert a["drive"] == b["drive"] and a["lidar"] == b["lidar"]


def test_tuples_run_together_read_as_one_a_line(tmp_path):
    """The authors' whole-set files append each third's tuples to the last without a line break (their
    `l90.tuple`, line 1082): two objects on one line, and `#` comments, read as the same tuples."""
    log = _intervals(4, n=30)
    lines = _censi_file(tmp_path / "t.json", log).read_text().splitlines()
    joined = tmp_path / "joined.tuple"
    joined.write_text("# a comment\n" + "\n".join(lines[:10]) + "".join(lines[10:12]) + "\n" + "\n".join(lines[12:]))
    a, b = read_censi(tmp_path / "t.json"), read_censi(joined)
    assert np.array_equal(a.sm_m, b.sm_m) and np.array_equal(a.t_s, b.t_s) and len(b.t_s) == 30


def test_the_held_delay_leaves_the_scan_routes_fit_as_it_was():
    """`fit(hold_delay=True)` solves for six parameters; with the delay free it is the scan route's fit."""
    log = _intervals(5, n=120)
    track, t, m = wl.intervals_track(log)
    start = wl.closed_form(track, t, m)
    held = wl.fit(track, t, m, start, hold_delay=True)
    assert held.params[6] == start[6] and held.cov[6, 6] == 0.0 and np.all(held.sd[:6] > 0)


@pytest.mark.parametrize(
    "text, said",
    [
        ('{"T": 0.3, "phi_l": 1.0}\n', "is not a tuple"),
        ("not json\n", "line 1 is not a tuple"),
        ('{"T": 0.3, "phi_l": 1, "phi_r": 1, "sm": [0, 0, 0]}\n{"T": 0.3,\n', "line 2 is not a tuple"),
        ('{"T": -1, "phi_l": 1, "phi_r": 1, "sm": [0, 0, 0]}\n' * 12, "T_s is -1.0: not a length"),
        ('{"T": 0.3, "phi_l": 1, "phi_r": 1, "sm": [0, 0, 0]}\n' * 3, "only 3 intervals"),
        ('{"T": 0.3, "phi_l": 1e9, "phi_r": 1, "sm": [0, 0, 0]}\n' * 12, "phi_l_rad_s"),
    ],
)
def test_a_bad_file_is_refused_in_one_line(tmp_path, text, said):
    src = tmp_path / "bad.json"
    src.write_text(text)
    res = _run(["convert", "intervals", src, "--out", tmp_path / "out"], code=2)
    line = " ".join(res.output.split())
    assert said in line and "Fix:" in line and "Traceback" not in res.output
    assert not (tmp_path / "out").exists()


def test_intervals_that_never_turn_are_refused_naming_the_turns(tmp_path):
    log = _intervals(6, n=40, turn=0.0)
    flat = IntervalsLog("sim", log.t_s, log.phi_rad_s, log.sm_m * [1, 1, 0])
    _run(["convert", "intervals", _censi_file(tmp_path / "t.json", flat), "--out", tmp_path / "run"])
    res = _run(["learn", "em", tmp_path / "run"], code=2)
    assert "show only in turns" in " ".join(res.output.split())
    res = _run(["learn", "em", tmp_path / "run", "--preset", "thesis_aibo"], code=2)
    assert "--preset is for EM's landmark logs" in " ".join(res.output.split())
