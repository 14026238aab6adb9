"""io: the log folder round trip, atomic writes, and errors that name the file, the field and the fix."""

from __future__ import annotations

import json

import numpy as np
import pytest

from sensact.errors import LogFormatError, ModelFormatError
from sensact.io.atomic import write_json, write_npz
from sensact.io.logfolder import read_track_log, write_log_folder
from sensact.learn.bootstrap import learn_bootstrap
from sensact.models.polynomial import Polynomial1D
from sensact.sim.track1d import Track1DConfig, log_tables, simulate_track


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    run = simulate_track(Track1DConfig(seconds=40.0, seed=3, observation_dropout=0.2))
    path = write_log_folder(tmp_path_factory.mktemp("log") / "run", **log_tables(run))
    return run, path


def test_round_trip_is_exact(folder):
    run, path = folder
    log = read_track_log(path)
    np.testing.assert_array_equal(log.times_s, run.times_s)
    np.testing.assert_array_equal(log.commands, run.commands_mm_s)
    np.testing.assert_array_equal(np.isnan(log.observations), np.isnan(run.heights_px))
    np.testing.assert_array_equal(
        log.observations[~np.isnan(log.observations)], run.heights_px[~np.isnan(run.heights_px)]
    )
    np.testing.assert_array_equal(log.true_position, run.distance_mm)
    assert log.meta["truth"] == run.truth.to_dict()
    a = learn_bootstrap(log.times_s, log.commands, log.observations)
    b = learn_bootstrap(run.times_s, run.commands_mm_s, run.heights_px)
    assert a.sensor.coef == b.sensor.coef


def test_observations_between_action_rows_get_the_held_command(tmp_path):
    meta = {"platform": "x", "action": {"column": "c"}, "sensor": {"column": "o"}}
    write_log_folder(
        tmp_path,
        meta=meta,
        actions={"t_s": np.array([0.0, 1.0]), "c": np.array([5.0, -5.0])},
        observations={"t_s": np.array([0.5, 1.5]), "o": np.array([10.0, 11.0])},
    )
    log = read_track_log(tmp_path)
    np.testing.assert_array_equal(log.times_s, [0.0, 0.5, 1.0, 1.5])
    np.testing.assert_array_equal(log.commands, [5.0, 5.0, -5.0, -5.0])
    np.testing.assert_array_equal(log.observations, [np.nan, 10.0, np.nan, 11.0])


def test_bad_cell_names_file_row_and_column(folder, tmp_path):
    _, path = folder
    bad = tmp_path / "bad"
    bad.mkdir()
    for name in ("meta.json", "actions.csv", "observations.csv"):
        (bad / name).write_text((path / name).read_text())
    lines = (bad / "actions.csv").read_text().splitlines()
    lines[5] = lines[5].split(",")[0] + ",fast"
    (bad / "actions.csv").write_text("\n".join(lines))
    with pytest.raises(LogFormatError) as exc:
        read_track_log(bad)
    msg = str(exc.value)
    assert "actions.csv" in msg and "row 6" in msg and "command_mm_s" in msg and "Fix:" in msg
    assert "\n" not in msg


def test_a_hand_written_folder_saved_by_a_spreadsheet_or_an_editor_with_a_bom_reads_the_same(folder, tmp_path):
    """meta.json and the CSVs each saved with a UTF-8 byte-order mark (and CRLF lines) read as written."""
    _, path = folder
    for name in ("meta.json", "actions.csv", "observations.csv", "groundtruth.csv"):
        text = (path / name).read_text()
        (tmp_path / name).write_bytes(b"\xef\xbb\xbf" + text.replace("\n", "\r\n").encode())
    a, b = read_track_log(path), read_track_log(tmp_path)
    assert b.meta == a.meta
    np.testing.assert_array_equal(b.commands, a.commands)
    np.testing.assert_array_equal(b.observations, a.observations)
    np.testing.assert_array_equal(b.true_position, a.true_position)


def test_missing_column_and_missing_meta(folder, tmp_path):
    _, path = folder
    with pytest.raises(LogFormatError, match="missing column"):
        read_track_log(path, sensor="range_m")
    with pytest.raises(LogFormatError, match=r"meta\.json not found"):
        read_track_log(tmp_path)
    (tmp_path / "meta.json").write_text("{}")
    with pytest.raises(LogFormatError, match="format"):
        read_track_log(tmp_path)


def test_atomic_writes_leave_no_temporary_files(tmp_path):
    write_json(tmp_path / "r.json", {"x": float("nan"), "y": np.float64(2.5), "a": np.arange(3)})
    assert json.loads((tmp_path / "r.json").read_text()) == {"x": None, "y": 2.5, "a": [0, 1, 2]}
    write_npz(tmp_path / "a.npz", w=np.ones(3))
    with np.load(tmp_path / "a.npz", allow_pickle=False) as z:
        np.testing.assert_array_equal(z["w"], np.ones(3))
    with pytest.raises(TypeError):
        write_npz(tmp_path / "b.npz", w=np.array([object()]))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.npz", "r.json"]
    # a written file has the mode any new file gets (mkstemp's own is private, 0600), the same as open()'s
    (tmp_path / "plain.txt").write_text("x")
    plain = (tmp_path / "plain.txt").stat().st_mode & 0o777
    assert (tmp_path / "r.json").stat().st_mode & 0o777 == plain
    assert (tmp_path / "a.npz").stat().st_mode & 0o777 == plain


def test_polynomial_json_round_trip_and_power_form():
    p = Polynomial1D((1.0, -2.0, 0.5), center=20.0, scale=10.0, input_name="o")
    q = Polynomial1D.from_dict(json.loads(json.dumps(p.to_dict())))
    assert q == p
    x = np.linspace(5, 35, 7)
    np.testing.assert_allclose(np.polyval(p.power_coefficients()[::-1], x), p(x), rtol=1e-10)
    assert p.describe("S").startswith("S(o) = ")
    with pytest.raises(ModelFormatError, match="kind"):
        Polynomial1D.from_dict({"coef": [1]})
    with pytest.raises(ModelFormatError, match="coef"):
        Polynomial1D.from_dict({"kind": "polynomial1d", "coef": []})
