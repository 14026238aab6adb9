"""Log folders for EM: round trips and one-line errors that name the file, the field and the fix."""

from __future__ import annotations

import json

import numpy as np
import pytest

from sensact.errors import LogFormatError
from sensact.io.landmark_folder import read_landmark_log
from sensact.io.logfolder import write_log_folder
from sensact.sim import field2d, track1d


@pytest.fixture(scope="module")
def field_log(tmp_path_factory):
    run = field2d.simulate_field(field2d.Field2DConfig(seconds=20.0, seed=2))
    folder = tmp_path_factory.mktemp("logs") / "field"
    write_log_folder(folder, **field2d.log_tables(run))
    return folder, run


def test_planar_round_trip(field_log):
    folder, run = field_log
    lf = read_landmark_log(folder)
    ref = field2d.to_landmark_log(run)
    for name in ("actions", "obs_step", "obs_landmark", "action_commands", "landmarks_xy"):
        np.testing.assert_array_equal(getattr(lf.data, name), getattr(ref, name), err_msg=name)
    np.testing.assert_allclose(lf.data.obs_height_px, ref.obs_height_px)
    np.testing.assert_allclose(lf.data.obs_bearing_rad, ref.obs_bearing_rad)
    assert lf.data.dt_s == pytest.approx(ref.dt_s)
    np.testing.assert_allclose(lf.groundtruth["x_mm"], run.poses[:, 0])


def test_track_round_trip_with_levels(tmp_path):
    cfg = track1d.Track1DConfig(seconds=30.0, seed=1, command_levels=21)
    run = track1d.simulate_track(cfg)
    write_log_folder(tmp_path / "t", **track1d.log_tables(run))
    lf = read_landmark_log(tmp_path / "t")
    ref = track1d.to_landmark_log(run)
    used = np.unique(ref.actions)
    # the folder knows only the levels that were used, one action each
    np.testing.assert_allclose(lf.data.action_commands[:, 0], cfg.levels_mm_s()[used])
    np.testing.assert_array_equal(used[lf.data.actions], ref.actions)
    np.testing.assert_allclose(lf.data.obs_height_px, ref.obs_height_px)


def test_continuous_track_commands_are_binned(tmp_path):
    run = track1d.simulate_track(track1d.Track1DConfig(seconds=300.0, seed=1))  # 100 distinct commands
    write_log_folder(tmp_path / "t", **track1d.log_tables(run))
    lf = read_landmark_log(tmp_path / "t", command_bins=9)
    assert lf.data.n_actions == 9 and "binned" in lf.note


def _copy(folder, tmp_path):
    import shutil

    dst = tmp_path / "copy"
    shutil.copytree(folder, dst)
    return dst


def test_bad_action_index(field_log, tmp_path):
    folder = _copy(field_log[0], tmp_path)
    lines = (folder / "actions.csv").read_text().splitlines()
    lines[3] = lines[3].split(",")[0] + ",57.0"
    (folder / "actions.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(LogFormatError, match=r"actions.csv: action_id: row 4: 57.0 is not an action index"):
        read_landmark_log(folder)


def test_off_grid_time_and_unknown_landmark(field_log, tmp_path):
    folder = _copy(field_log[0], tmp_path)
    lines = (folder / "observations.csv").read_text().splitlines()
    cells = lines[1].split(",")
    lines[1] = ",".join([str(float(cells[0]) + 0.013), *cells[1:]])
    (folder / "observations.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(LogFormatError, match=r"not on the 0\.05 s step grid.*Fix: resample"):
        read_landmark_log(folder)
    lines[1] = ",".join([cells[0], "9.0", *cells[2:]])
    (folder / "observations.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(LogFormatError, match=r"landmark id 9 is not in meta\.json's landmarks"):
        read_landmark_log(folder)


def test_bearings_in_degrees_are_refused_naming_the_column(field_log, tmp_path):
    folder = _copy(field_log[0], tmp_path)
    lines = (folder / "observations.csv").read_text().splitlines()
    col = lines[0].split(",").index("bearing_rad")
    rows = [line.split(",") for line in lines[1:]]
    for cells in rows:
        cells[col] = repr(float(np.degrees(float(cells[col]))))
    (folder / "observations.csv").write_text("\n".join([lines[0], *(",".join(c) for c in rows)]) + "\n")
    with pytest.raises(LogFormatError) as err:
        read_landmark_log(folder)
    assert err.value.field == "bearing_rad" and "degrees" in err.value.problem and "radians" in err.value.fix


def test_meta_without_landmarks(field_log, tmp_path):
    folder = _copy(field_log[0], tmp_path)
    meta = json.loads((folder / "meta.json").read_text())
    del meta["landmarks"]
    (folder / "meta.json").write_text(json.dumps(meta))
    with pytest.raises(LogFormatError, match=r"meta\.json: landmarks: a landmark log needs"):
        read_landmark_log(folder)


def test_landmarks_named_in_the_folder_read_as_numbered_ones_do(field_log, tmp_path):
    """Exact reduction: the field log with its landmarks renamed (``post 1``; one left a number, written
    ``2.0`` in the sightings) reads to the same sightings; the names are kept. A landmark without an id,
    an id given twice, or a sighting with an empty id is one line naming the file and field."""
    folder = _copy(field_log[0], tmp_path)
    meta = json.loads((folder / "meta.json").read_text())
    ids = [m["id"] for m in meta["landmarks"]]
    new = {i: (f"post {i}" if k != 2 else 2) for k, i in enumerate(ids)}
    for m in meta["landmarks"]:
        m["id"] = new[m["id"]]
        m.pop("name", None)
    (folder / "meta.json").write_text(json.dumps(meta))
    lines = (folder / "observations.csv").read_text().splitlines()
    col = lines[0].split(",").index("landmark_id")

    def renamed(line: str) -> str:
        cells = line.split(",")
        old = round(float(cells[col]))
        cells[col] = f"{float(new[old]):.1f}" if isinstance(new[old], int) else new[old]
        return ",".join(cells)

    (folder / "observations.csv").write_text("\n".join([lines[0], *map(renamed, lines[1:])]) + "\n")
    named, numbered = read_landmark_log(folder).data, read_landmark_log(field_log[0]).data
    for name in ("obs_step", "obs_landmark", "obs_readings", "landmarks_xy", "actions"):
        np.testing.assert_array_equal(getattr(named, name), getattr(numbered, name), err_msg=name)
    assert named.landmark_names == tuple(str(new[i]) for i in ids) and "post 0" in named.landmark_names
    blank = [x for x in lines if x.strip()][-1].split(",")  # the last sighting's time: the file stays in order
    blank[col] = ""
    (folder / "observations.csv").write_text("\n".join([lines[0], *map(renamed, lines[1:]), ",".join(blank)]) + "\n")
    with pytest.raises(LogFormatError, match=r"observations\.csv: landmark_id: row \d+ has no value"):
        read_landmark_log(folder)
    for first, problem in (("", "landmark 1 has no id"), ("post 1", "landmark id post 1 appears more than once")):
        meta["landmarks"][0]["id"] = first
        (folder / "meta.json").write_text(json.dumps(meta))
        with pytest.raises(LogFormatError, match=rf"meta\.json: landmarks\.id: {problem}"):
            read_landmark_log(folder)


def test_a_track_log_written_by_write_landmark_log_reads_back(tmp_path):
    """Exact reduction for a 1-D track (one landmark, id 0, written ``0.0`` in observations.csv)."""
    from sensact.io.landmark_folder import write_landmark_log

    run = track1d.simulate_track(track1d.Track1DConfig(seconds=30.0, seed=1, command_levels=21))
    data = track1d.to_landmark_log(run)
    write_landmark_log(tmp_path / "t", data)
    back = read_landmark_log(tmp_path / "t").data
    assert back.geometry.name == "track"
    for name in ("actions", "obs_step", "obs_landmark", "obs_readings", "action_commands"):
        np.testing.assert_array_equal(getattr(back, name), getattr(data, name), err_msg=name)
