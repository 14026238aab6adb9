"""io.timed_csv and `sensact convert csv`: a robot's own asynchronous CSV files as an EM log folder.

Oracles: an exact reduction (a simulated log written as timed files, off the step grid and shuffled,
converts back to the same log), an independent reference on real data (MRCLAM's files written as
timed CSVs give what io.mrclam reads), and errors that name the file, the column and the fix.
"""

from __future__ import annotations

import re

import numpy as np
import pytest
from typer.testing import CliRunner

from conftest import DATA, require, write_csv
from sensact.app import read_settings_file
from sensact.cli import app
from sensact.errors import LogFormatError
from sensact.io.csvtable import read_numeric_csv
from sensact.io.landmark_folder import read_landmark_log, truth_poses_of
from sensact.io.timed_csv import in_sensact_units, read_timed_csv
from sensact.io.unit_checks import unit_doubts
from sensact.sim.diffdrive import DiffDriveConfig, simulate_diffdrive

runner = CliRunner()
T0 = 1234.5  # the files' own clock


def _as_timed_files(run, folder):
    """A simulated run written as a robot would log it: commands only when they change, sightings off the
    grid and out of order, three sightings to drop, the map with ids of its own, truth heading from +x."""
    d, dt = run.log(), run.config.dt_s
    rng = np.random.default_rng(0)
    grid = T0 + np.arange(d.n_steps) * dt
    sent = np.flatnonzero(np.r_[True, np.any(np.diff(d.step_commands, axis=0) != 0, axis=1)])
    order = rng.permutation(sent)
    write_csv(
        folder / "commands.csv",
        {"t_s": grid[order], "v_mm_s": d.step_commands[order, 0], "omega_rad_s": d.step_commands[order, 1]},
    )
    ids = 100.0 + 3.0 * np.arange(len(d.landmarks_xy))
    t_obs = grid[d.obs_step] + rng.uniform(-0.4, 0.4, d.obs_step.size) * dt
    extra_t = [grid[5], grid[-1] + 10.0, grid[7]]  # a landmark not on the map, after the run, nothing read
    extra_id = [7.0, ids[0], ids[1]]
    extra_r = [1000.0, 1000.0, np.nan]
    perm = rng.permutation(d.obs_step.size + 3)
    write_csv(
        folder / "sightings.csv",
        {
            "t_s": np.r_[t_obs, extra_t][perm],
            "landmark_id": np.r_[ids[d.obs_landmark], extra_id][perm],
            "range_mm": np.r_[d.obs_readings[:, 0], extra_r][perm],
            "bearing_rad": np.r_[d.obs_bearing_rad, 0.1, 0.1, np.nan][perm],
        },
    )
    write_csv(folder / "landmarks.csv", {"id": ids, "x_mm": d.landmarks_xy[:, 0], "y_mm": d.landmarks_xy[:, 1]})
    write_csv(
        folder / "truth.csv",
        {"t_s": grid, "x_mm": run.poses[:, 0], "y_mm": run.poses[:, 1], "theta_rad": run.poses[:, 2] + 0.5 * np.pi},
    )
    return run, folder


@pytest.fixture(scope="module")
def timed(tmp_path_factory):
    """A minute's run as timed files (``_as_timed_files``); it drives one way nearly throughout."""
    return _as_timed_files(simulate_diffdrive(DiffDriveConfig(seconds=60.0, seed=5)), tmp_path_factory.mktemp("timed"))


@pytest.fixture(scope="module")
def wandering(tmp_path_factory):
    """Five minutes of the same robot as timed files: it drives back and forth, turning many ways (its
    moves' directions have an axial resultant of 0.65, where a heading read another way cannot agree)."""
    return _as_timed_files(
        simulate_diffdrive(DiffDriveConfig(seconds=300.0, seed=5)), tmp_path_factory.mktemp("wander")
    )


def _same_sightings(a, b):
    """The same sightings on the same steps; a step's order is the files' times, which the jitter shuffles."""
    ia = np.lexsort((a.obs_landmark, a.obs_step))
    ib = np.lexsort((b.obs_landmark, b.obs_step))
    for k in ("obs_step", "obs_landmark", "obs_readings", "obs_bearing_rad"):
        np.testing.assert_array_equal(getattr(a, k)[ia], getattr(b, k)[ib])


def test_unit_suffixes_become_millimetres_and_radians():
    x = np.array([1.5, -2.0])
    for name, new, factor in [
        ("range_m", "range_mm", 1000.0),
        ("v_m_s", "v_mm_s", 1000.0),
        ("sonar_cm", "sonar_mm", 10.0),
        ("v_cmd_cm_s", "v_cmd_mm_s", 10.0),
        ("bearing_deg", "bearing_rad", np.pi / 180),
        ("omega_deg_s", "omega_rad_s", np.pi / 180),
    ]:
        got_name, got = in_sensact_units(name, x)
        assert got_name == new
        np.testing.assert_array_equal(got, x * factor)
    for name, factor in [("t_ms", 1e-3), ("t_us", 1e-6), ("t_ns", 1e-9)]:
        got_name, got = in_sensact_units(name, x)
        assert got_name == "t_s"
        np.testing.assert_array_equal(got, x * factor)
    for name in ("range_mm", "v_mm_s", "ir_volts", "bearing_rad", "height_px", "echo_ms", "t_s"):
        assert in_sensact_units(name, x)[0] == name and in_sensact_units(name, x)[1] is x


def test_a_simulated_log_written_off_the_grid_converts_back_exactly(timed):
    run, folder = timed
    f = {k: folder / f"{k}.csv" for k in ("commands", "sightings", "landmarks", "truth")}
    tl = read_timed_csv(f["commands"], f["sightings"], f["landmarks"], f["truth"], dt_s=run.config.dt_s)
    d, ref = tl.data, run.log()
    assert tl.t0_s == T0 and d.n_steps == ref.n_steps and d.command_names == ("v_mm_s", "omega_rad_s")
    np.testing.assert_array_equal(d.step_commands, ref.step_commands)
    np.testing.assert_array_equal(d.landmarks_xy, ref.landmarks_xy)
    assert np.all(np.diff(d.obs_step) >= 0)
    _same_sightings(d, ref)
    gt = tl.groundtruth
    np.testing.assert_allclose(gt["x_mm"], run.poses[:, 0], atol=1e-9)
    heading_err = np.angle(np.exp(1j * (gt["theta_rad"] - run.poses[:, 2])))
    assert np.max(np.abs(heading_err)) < 1e-9 and np.all(gt["valid"] == 1)
    s = tl.summary
    assert (s["kept"], s["dropped_unknown_landmark"], s["dropped_outside_time"], s["dropped_nothing_read"]) == (
        ref.obs_step.size,
        1,
        1,
        1,
    )
    assert s["unknown_landmark_ids"] == ["7"] and s["command_rows"] < d.n_steps
    assert d.landmark_names[:2] == ("100", "103")  # the map's own ids name the landmarks
    assert s["dropped_after_commands"] == 1  # the one 10 s after the run, with how to keep such sightings
    assert "1 after the last command row: a row at the log's end holds the last command to it" in tl.summary_line()
    assert f"kept {ref.obs_step.size} of {ref.obs_step.size + 3} sightings" in tl.summary_line()


def test_landmarks_named_by_words_convert_as_numbered_ones_do(timed, tmp_path):
    """The same files with every other landmark's id written as a name, the rest as whole numbers on the
    map (``106``) while the sightings say ``106.0``, give the same log, the map's ids kept as its names."""
    _, folder = timed
    lm = read_numeric_csv(folder / "landmarks.csv")
    names = {f"{v:g}": f"post {j}" if j % 2 else f"{v:g}" for j, v in enumerate(lm["id"])}
    header, *rows = (folder / "landmarks.csv").read_text().splitlines()
    named = [header] + [",".join([names[f"{float(r.split(',')[0]):g}"], *r.split(",")[1:]]) for r in rows]
    (tmp_path / "landmarks.csv").write_text("\n".join(named) + "\n")
    header, *rows = (folder / "sightings.csv").read_text().splitlines()
    col = header.split(",").index("landmark_id")

    def rename(row):
        cells = row.split(",")
        key = f"{float(cells[col]):g}"
        if key in names and not names[key][0].isdigit():  # the others, and the one not on the map, stay 106.0
            cells[col] = names[key]
        return ",".join(cells)

    (tmp_path / "sightings.csv").write_text("\n".join([header, *map(rename, rows)]) + "\n")
    by_number = read_timed_csv(folder / "commands.csv", folder / "sightings.csv", folder / "landmarks.csv")
    by_name = read_timed_csv(folder / "commands.csv", tmp_path / "sightings.csv", tmp_path / "landmarks.csv")
    _same_sightings(by_name.data, by_number.data)
    assert by_name.data.landmark_names == tuple(names[n] for n in by_number.data.landmark_names)
    assert by_name.summary["unknown_landmark_ids"] == ["7"]
    out = tmp_path / "named"
    res = runner.invoke(
        app,
        [
            "convert",
            "csv",
            f"--commands={folder / 'commands.csv'}",
            f"--sightings={tmp_path / 'sightings.csv'}",
            f"--landmarks={tmp_path / 'landmarks.csv'}",
            "--out",
            str(out),
        ],
    )
    assert res.exit_code == 0, res.output
    assert read_landmark_log(out).data.landmark_names == by_name.data.landmark_names


def test_times_in_nanoseconds_convert_as_seconds_do(timed, tmp_path):
    """A ROS bag's stamps: every file's t_s written as whole nanoseconds under t_ns gives the same log."""
    _, folder = timed
    for name in ("commands", "sightings", "landmarks", "truth"):
        table = read_numeric_csv(folder / f"{name}.csv")
        if "t_s" in table:
            table = {("t_ns" if k == "t_s" else k): (np.round(v * 1e9) if k == "t_s" else v) for k, v in table.items()}
        write_csv(tmp_path / f"{name}.csv", table)
    files = ("commands", "sightings", "landmarks", "truth")
    # one step for both: the commands' median interval read in whole nanoseconds differs in its 10th digit
    seconds = read_timed_csv(*(folder / f"{n}.csv" for n in files), dt_s=1.0 / 30.0)
    nanoseconds = read_timed_csv(*(tmp_path / f"{n}.csv" for n in files), dt_s=1.0 / 30.0)
    assert "t_ns" in (tmp_path / "commands.csv").read_text().splitlines()[0]
    assert nanoseconds.t0_s == pytest.approx(seconds.t0_s, abs=1e-9)
    np.testing.assert_array_equal(nanoseconds.data.step_commands, seconds.data.step_commands)
    _same_sightings(nanoseconds.data, seconds.data)
    np.testing.assert_allclose(nanoseconds.groundtruth["x_mm"], seconds.groundtruth["x_mm"], atol=1e-3)
    (tmp_path / "c.csv").write_text("time,v_m_s\n0,0.1\n1,0.1\n")
    with pytest.raises(LogFormatError, match="t_ms, t_us or t_ns"):
        read_timed_csv(tmp_path / "c.csv", tmp_path / "sightings.csv", tmp_path / "landmarks.csv")


def test_files_as_a_spreadsheet_exports_them_convert_as_plain_csv_does(timed, tmp_path):
    """Excel's "CSV UTF-8" (a byte-order mark, CRLF lines), its export where the decimal mark is a comma
    (semicolons between cells) and tab-separated text each give the plain files' log, cell for cell."""
    _, folder = timed
    files = ("commands", "sightings", "landmarks", "truth")
    plain = read_timed_csv(*(folder / f"{n}.csv" for n in files))
    exports = {
        "utf8_bom": lambda text: ("\ufeff" + text.replace("\n", "\r\n"), "utf-8"),
        "decimal_comma": lambda text: ("\ufeff" + text.replace(",", ";").replace(".", ","), "utf-8"),
        "tabs": lambda text: (text.replace(",", "\t"), "utf-8"),
    }
    for kind, export in exports.items():
        sub = tmp_path / kind
        sub.mkdir()
        for n in files:
            text, encoding = export((folder / f"{n}.csv").read_text())
            (sub / f"{n}.csv").write_bytes(text.encode(encoding))
        got = read_timed_csv(*(sub / f"{n}.csv" for n in files))
        assert got.t0_s == plain.t0_s, kind
        np.testing.assert_array_equal(got.data.step_commands, plain.data.step_commands, err_msg=kind)
        _same_sightings(got.data, plain.data)
        np.testing.assert_array_equal(got.groundtruth["x_mm"], plain.groundtruth["x_mm"], err_msg=kind)
    assert (tmp_path / "decimal_comma" / "commands.csv").read_text(encoding="utf-8-sig").startswith("t_s;")
    # a decimal comma in a comma-separated file splits its number: the error says so
    (tmp_path / "c.csv").write_text("t_s,v_m_s,omega_rad_s\n0,0,1,0.2\n")
    with pytest.raises(LogFormatError, match="decimal comma"):
        read_numeric_csv(tmp_path / "c.csv")


def test_a_rostopic_export_is_told_what_to_rename(tmp_path):
    """ROS 1's `rostopic echo -p` writes %time (ns) and field.* columns; the error names the renames."""
    (tmp_path / "c.csv").write_text("%time,field.linear.x,field.angular.z\n1600000000000000000,0.1,0.0\n")
    write_csv(tmp_path / "s.csv", {"t_s": [0.5], "landmark_id": [1], "range_m": [1.0]})
    write_csv(tmp_path / "l.csv", {"id": [1], "x_m": [2.0], "y_m": [0.0]})
    with pytest.raises(LogFormatError) as err:
        read_timed_csv(tmp_path / "c.csv", tmp_path / "s.csv", tmp_path / "l.csv")
    assert err.value.field == "t_s" and "rename %time to t_ns" in err.value.fix
    assert "field.linear.x is v_m_s" in err.value.fix
    with pytest.raises(LogFormatError) as err:  # a file that is not ROS's gets no ROS hint
        read_timed_csv(tmp_path / "s.csv", tmp_path / "s.csv", tmp_path / "l.csv", dt_s=0.1)
    assert "rostopic" not in err.value.fix


def test_a_column_whose_name_gives_the_wrong_unit_is_caught(timed, tmp_path):
    """Degrees under bearing_rad are refused; millimetres under range_m (x1000) or metres under range_mm
    (/1000), and mm/s under v_m_s, are warned about against the map's size; the simulated run's own units
    raise none."""
    _, folder = timed
    files = ("commands", "sightings", "landmarks")
    plain = read_timed_csv(*(folder / f"{n}.csv" for n in files))
    assert unit_doubts(plain.data) == []
    sight = read_numeric_csv(folder / "sightings.csv")
    for n in ("commands", "landmarks"):
        (tmp_path / f"{n}.csv").write_text((folder / f"{n}.csv").read_text())
    as_degrees = sight | {"bearing_rad": np.degrees(sight["bearing_rad"])}
    write_csv(tmp_path / "sightings.csv", as_degrees)
    with pytest.raises(LogFormatError) as err:
        read_timed_csv(*(tmp_path / f"{n}.csv" for n in files))
    assert err.value.field == "bearing_rad" and "bearing_deg" in err.value.fix
    median = float(np.nanmedian(plain.data.obs_readings[:, 0]))
    xy = plain.data.landmarks_xy
    span = float(np.hypot(xy[:, 0].max() - xy[:, 0].min(), xy[:, 1].max() - xy[:, 1].min()))
    for name, scale, times in (("range_m", 1.0, 1000.0), ("range_mm", 1e-3, 1e-3)):
        wrong = {k: v for k, v in sight.items() if k != "range_mm"} | {name: sight["range_mm"] * scale}
        write_csv(tmp_path / "sightings.csv", wrong)
        doubts = unit_doubts(read_timed_csv(*(tmp_path / f"{n}.csv" for n in files)).data)
        assert len(doubts) == 1 and "range_m is read as metres" in doubts[0], (name, doubts)
        doubt = doubts[0]
        ratio = float(re.search(r"is ([0-9.e+-]+) times the map", doubt).group(1))
        assert ratio == pytest.approx(times * median / span, rel=0.01), doubt
    cmd = read_numeric_csv(folder / "commands.csv")  # v in mm/s, named as if in m/s: x1000
    write_csv(tmp_path / "commands.csv", {"t_s": cmd["t_s"], "v_m_s": cmd["v_mm_s"], "omega_rad_s": cmd["omega_rad_s"]})
    res = runner.invoke(
        app,
        ["convert", "csv", *[f"--{n}={tmp_path / f'{n}.csv'}" for n in files], "--out", str(tmp_path / "o")],
    )
    flat = " ".join(res.output.split())
    assert res.exit_code == 0 and flat.count("is its unit right") == 2, res.output
    assert "the median range reading" in flat and "the median commanded speed (v_mm_s)" in flat
    assert "v_m_s is read as metres per second" in flat


@pytest.mark.parametrize(
    ("name", "written", "said"),
    [
        ("theta_rad", lambda h: h - 0.5 * np.pi, "is +1.571 rad (+90 deg) off the way the robot moves (a quarter turn"),
        ("theta_rad", lambda h: h + 0.5, "is -0.500 rad (-29 deg) off"),  # a motion-capture body's axes set apart
        ("theta_rad", lambda h: np.degrees(np.angle(np.exp(1j * h))), "only read in degrees,"),
        ("theta_rad", lambda h: -h, "only read clockwise,"),
        (
            "theta_rad",
            lambda h: (90.0 - np.degrees(h)) % 360.0,
            "only read clockwise in degrees (a compass heading?), turned by +1.571",
        ),
        # a column named in degrees: the fix is written in the file's degrees
        ("theta_deg", lambda h: np.degrees(h) - 90.0, "is +1.571 rad (+90 deg) off the way the robot moves"),
        ("theta_deg", lambda h: (90.0 - np.degrees(h)) % 360.0, "only read clockwise, turned by +1.571"),
        ("theta_deg", lambda h: h, "only read in radians,"),
    ],
    ids=["from +y", "turned", "degrees", "clockwise", "compass", "deg from +y", "deg compass", "deg holding rad"],
)
def test_a_truth_heading_read_another_way_is_named_with_the_column_that_fixes_it(
    wandering, tmp_path, name, written, said
):
    """A recorded heading that points off the way the recorded positions move is warned about, with the
    reading under which it agrees; the column the warning says to write, in the file's own column and
    unit, agrees (an exact check of the fix), and the simulated run's own heading (ROS REP 103) raises
    nothing."""
    _, folder = wandering
    files = [folder / f"{n}.csv" for n in ("commands", "sightings", "landmarks")]
    assert read_timed_csv(*files, folder / "truth.csv").truth_doubt is None
    truth = read_numeric_csv(folder / "truth.csv")
    rest = {k: v for k, v in truth.items() if k != "theta_rad"}
    column = written(truth["theta_rad"])
    write_csv(tmp_path / "truth.csv", rest | {name: column})
    doubt = read_timed_csv(*files, tmp_path / "truth.csv").truth_doubt
    assert doubt is not None and said in doubt, doubt
    unit = "degrees" if name == "theta_deg" else "radians"
    assert f"{name} is read as {unit}, counterclockwise, 0 facing +x" in doubt
    fix = re.split(r" \((or )?name the column", doubt.split(f"write {name} = ")[1])[0]
    fixed = eval(fix.replace(name, "column"), {"column": column, "pi": np.pi})  # the fix as it reads
    write_csv(tmp_path / "truth.csv", rest | {name: fixed})
    assert read_timed_csv(*files, tmp_path / "truth.csv").truth_doubt is None, fix


def test_a_truth_heading_is_judged_only_where_the_moves_show_it(timed, wandering, tmp_path):
    """No warning for a heading that no reading makes follow the moves (a robot that side-steps, a noisy
    compass), for a robot that never moves 30 mm in a second, or for another reading on a run that keeps
    one direction (a heading in degrees would be nearly constant there and agree); a heading turned on
    such a run is still named, as written."""
    _, folder = wandering
    files = [folder / f"{n}.csv" for n in ("commands", "sightings", "landmarks")]
    truth = read_numeric_csv(folder / "truth.csv")
    wander = np.cumsum(np.random.default_rng(1).normal(0.0, 0.2, truth["t_s"].size))
    write_csv(tmp_path / "truth.csv", truth | {"theta_rad": wander})
    assert read_timed_csv(*files, tmp_path / "truth.csv").truth_doubt is None
    still = truth | {"x_mm": truth["x_mm"] * 1e-3, "y_mm": truth["y_mm"] * 1e-3, "theta_rad": truth["theta_rad"] + 1.0}
    write_csv(tmp_path / "truth.csv", still)
    assert read_timed_csv(*files, tmp_path / "truth.csv").truth_doubt is None
    _, straight = timed
    files = [straight / f"{n}.csv" for n in ("commands", "sightings", "landmarks")]
    truth = read_numeric_csv(straight / "truth.csv")
    write_csv(tmp_path / "truth.csv", truth | {"theta_rad": np.degrees(truth["theta_rad"])})
    assert read_timed_csv(*files, tmp_path / "truth.csv").truth_doubt is None
    write_csv(tmp_path / "truth.csv", truth | {"theta_rad": truth["theta_rad"] - 0.5 * np.pi})
    assert "+1.571 rad (+90 deg) off" in read_timed_csv(*files, tmp_path / "truth.csv").truth_doubt


def test_convert_csv_warns_of_a_truth_heading_from_another_axis(wandering, tmp_path):
    """`convert csv` warns of a heading measured from +y and still writes the folder (the truth is for
    scoring only); the right heading raises nothing."""
    _, folder = wandering
    args = [f"--{n}={folder / f'{n}.csv'}" for n in ("commands", "sightings", "landmarks")]
    truth = read_numeric_csv(folder / "truth.csv")
    write_csv(tmp_path / "from_y.csv", truth | {"theta_rad": truth["theta_rad"] - 0.5 * np.pi})
    for name, out, warned in (("from_y.csv", "y", True), (folder / "truth.csv", "x", False)):
        res = runner.invoke(app, ["convert", "csv", *args, f"--truth={tmp_path / name}", "--out", str(tmp_path / out)])
        flat = " ".join(res.output.split())
        assert res.exit_code == 0 and ("theta_rad = theta_rad + 1.571" in flat) == warned, res.output


def test_a_truth_path_in_another_unit_is_warned_about(timed, tmp_path):
    """Recorded positions in millimetres under x_m, y_m (x1000) span a thousand times what they did
    against the map; the run's own truth raises nothing."""
    _, folder = timed
    files = [folder / f"{n}.csv" for n in ("commands", "sightings", "landmarks")]
    plain = read_timed_csv(*files, folder / "truth.csv")
    assert unit_doubts(plain.data, truth_poses_of(plain.groundtruth)) == []
    truth = read_numeric_csv(folder / "truth.csv")
    write_csv(
        tmp_path / "t.csv",
        {"t_s": truth["t_s"], "x_m": truth["x_mm"], "y_m": truth["y_mm"], "theta_rad": truth["theta_rad"]},
    )
    wrong = read_timed_csv(*files, tmp_path / "t.csv")
    (doubt,) = unit_doubts(wrong.data, truth_poses_of(wrong.groundtruth))
    poses, valid = truth_poses_of(plain.groundtruth)
    span = np.hypot(*np.ptp(plain.data.landmarks_xy, axis=0))
    ratio = float(re.search(r"([0-9.e+-]+) times the map's extent", doubt).group(1))
    assert ratio == pytest.approx(1000.0 * np.hypot(*np.ptp(poses[valid, :2], axis=0)) / span, rel=0.005)
    assert "A truth column named x_m is read as metres" in doubt


def test_a_landmark_named_twice_or_a_sighting_without_its_landmark_is_refused(tmp_path):
    write_csv(tmp_path / "c.csv", {"t_s": [0.0, 1.0, 2.0], "v_m_s": [0.1, 0.1, 0.1]})
    write_csv(tmp_path / "s.csv", {"t_s": [0.5], "range_m": [1.0]})
    (tmp_path / "l.csv").write_text("id,x_m,y_m\npost_A,0,0\n4.0,1,0\n4,2,0\n")
    with pytest.raises(LogFormatError, match="landmark id 4 appears more than once") as err:
        read_timed_csv(tmp_path / "c.csv", tmp_path / "s.csv", tmp_path / "l.csv")
    assert err.value.field == "id" and err.value.file == str(tmp_path / "l.csv")
    (tmp_path / "l.csv").write_text("id,x_m,y_m\n1234567,0,0\n1234568,1,0\n1234567.5,2,0\n")
    (tmp_path / "s.csv").write_text("t_s,landmark_id,range_m\n0.5,1234568.0,1.0\n0.7,1234567.5,2.0\n")
    big = read_timed_csv(tmp_path / "c.csv", tmp_path / "s.csv", tmp_path / "l.csv")  # ids past %g's six digits
    assert big.data.landmark_names == ("1234567", "1234568", "1234567.5")
    np.testing.assert_array_equal(big.data.obs_landmark, [1, 2])
    (tmp_path / "l.csv").write_text("id,x_m,y_m\npost_A,0,0\n")
    (tmp_path / "s.csv").write_text("t_s,landmark_id,range_m\n0.5,post_A,1.0\n0.7,,1.0\n")
    with pytest.raises(LogFormatError, match="row 3 has no value") as err:
        read_timed_csv(tmp_path / "c.csv", tmp_path / "s.csv", tmp_path / "l.csv")
    assert err.value.field == "landmark_id"


def test_convert_csv_writes_a_log_folder_learn_em_reads_with_mrclams_settings(timed, tmp_path):
    _, folder = timed
    sim = tmp_path / "sim"
    res = runner.invoke(app, ["simulate", "diffdrive", "--out", str(sim), "--seconds", "60", "--seed", "5"])
    assert res.exit_code == 0, res.output
    out = tmp_path / "converted"
    args = [f"--{k}={folder / f'{k}.csv'}" for k in ("commands", "sightings", "landmarks", "truth")]
    res = runner.invoke(app, ["convert", "csv", *args, "--out", str(out)])
    assert res.exit_code == 0, res.output
    flat = " ".join(res.output.split())
    assert "dropped 1 naming landmarks not on the map (ids 7)" in flat
    assert f"sensact learn em {out}`" in flat
    a, b = read_landmark_log(out), read_landmark_log(sim)
    np.testing.assert_array_equal(a.data.step_commands, b.data.step_commands)
    np.testing.assert_array_equal(a.data.landmarks_xy, b.data.landmarks_xy)
    _same_sightings(a.data, b.data)
    pa, va = a.truth_poses()
    pb, _ = b.truth_poses()
    assert va.all() and np.max(np.abs(np.angle(np.exp(1j * (pa[:, 2] - pb[:, 2]))))) < 1e-9
    assert (out / "em_config.yaml").read_text() == (sim / "em_config.yaml").read_text()
    assert a.meta["source"]["rows"]["kept"] == b.data.obs_step.size
    assert f"drew {out / 'overview.png'}" in flat and (out / "overview.png").stat().st_size > 20_000


def test_wheel_speeds_in_metres_convert_to_what_simulate_diffdrive_logs_with_the_same_settings(timed, tmp_path):
    """A robot driven wheel by wheel, logged in m/s, converts to the wheel-speed log of the same simulated
    drive (`simulate diffdrive --set wheel_axle_mm=...`) and gets the same em_config.yaml: MRCLAM's
    settings with the forward speed from the wheels' sum, as MRCLAM's is from v."""
    _, folder = timed
    axle = 235.0
    c = read_numeric_csv(folder / "commands.csv")
    half = 0.5 * axle * c["omega_rad_s"]
    write_csv(
        tmp_path / "wheels.csv",
        {"t_s": c["t_s"], "left_m_s": (c["v_mm_s"] - half) / 1000, "right_m_s": (c["v_mm_s"] + half) / 1000},
    )
    sim, out = tmp_path / "sim", tmp_path / "converted"
    res = runner.invoke(
        app,
        [
            "simulate",
            "diffdrive",
            "--out",
            str(sim),
            "--seconds",
            "60",
            "--seed",
            "5",
            "--set",
            f"wheel_axle_mm={axle}",
        ],
    )
    assert res.exit_code == 0, res.output
    args = [f"--{k}={folder / f'{k}.csv'}" for k in ("sightings", "landmarks")]
    res = runner.invoke(app, ["convert", "csv", f"--commands={tmp_path / 'wheels.csv'}", *args, "--out", str(out)])
    assert res.exit_code == 0, res.output
    assert f"sensact learn em {out}`" in " ".join(res.output.split())
    a, b = read_landmark_log(out).data, read_landmark_log(sim).data
    assert a.command_names == b.command_names == ("left_mm_s", "right_mm_s")
    np.testing.assert_allclose(a.step_commands, b.step_commands, rtol=0, atol=1e-9)
    assert (out / "em_config.yaml").read_text() == (sim / "em_config.yaml").read_text()
    # the preset put on the wheel speeds: the forward speed on their sum
    assert read_settings_file(out / "em_config.yaml").action.inputs == ("v_y_mm_s:(left_mm_s+right_mm_s)",)


def test_a_legged_robots_commands_convert_with_the_sideways_velocity_free(timed, tmp_path):
    """Commands that are not a differential drive's, as a legged robot's (v, v_left, omega) in m/s, get the
    settings `simulate diffdrive --set sidestep_mm_s=...` writes for the same commands: MRCLAM's, with every
    velocity affine in every command, and the converted commands are the simulated log's."""
    _, folder = timed
    sim, out = tmp_path / "sim", tmp_path / "converted"
    args = ["--seconds", "60", "--seed", "5", "--set", "sidestep_mm_s=60"]
    res = runner.invoke(app, ["simulate", "diffdrive", "--out", str(sim), *args])
    assert res.exit_code == 0, res.output
    d = read_landmark_log(sim).data
    grid = T0 + np.arange(d.n_steps) * d.dt_s
    v, left, w = d.step_commands.T
    write_csv(tmp_path / "legs.csv", {"t_s": grid, "v_m_s": v / 1000, "v_left_m_s": left / 1000, "omega_rad_s": w})
    more = [f"--{k}={folder / f'{k}.csv'}" for k in ("sightings", "landmarks")]
    res = runner.invoke(app, ["convert", "csv", f"--commands={tmp_path / 'legs.csv'}", *more, "--out", str(out)])
    assert res.exit_code == 0, res.output
    flat = " ".join(res.output.split())
    assert "a robot that can side-step on commands v_mm_s, v_left_mm_s, omega_rad_s" in flat
    a = read_landmark_log(out).data
    assert a.command_names == d.command_names
    np.testing.assert_allclose(a.step_commands, d.step_commands, rtol=1e-12, atol=1e-9)
    assert (out / "em_config.yaml").read_text() == (sim / "em_config.yaml").read_text()


def test_other_readings_get_no_config_and_are_told_how_to_choose(tmp_path):
    write_csv(tmp_path / "c.csv", {"t_s": [0.0, 1.0, 2.0], "left_wheel": [1.0, 2.0, 3.0], "right_wheel": [1, 1, 1]})
    write_csv(
        tmp_path / "s.csv",
        {"t_s": [0.5, 1.5], "landmark_id": [1, 1], "sonar_m": [0.5, np.nan], "bearing_deg": [10.0, 20.0]},
    )
    write_csv(tmp_path / "l.csv", {"id": [1], "x_m": [2.0], "y_m": [0.0]})
    out = tmp_path / "o"
    res = runner.invoke(
        app,
        [
            "convert",
            "csv",
            "--commands",
            str(tmp_path / "c.csv"),
            "--sightings",
            str(tmp_path / "s.csv"),
            "--landmarks",
            str(tmp_path / "l.csv"),
            "--out",
            str(out),
            "--dt",
            "0.5",
        ],
    )
    assert res.exit_code == 0, res.output
    assert "docs/em-real.md, section 2" in " ".join(res.output.split()) and not (out / "em_config.yaml").exists()
    assert (out / "overview.png").stat().st_size > 10_000  # drawn without a truth path too
    d = read_landmark_log(out).data
    assert d.command_names == ("left_wheel", "right_wheel") and d.reading_names == ("sonar_mm",)
    np.testing.assert_array_equal(d.step_commands[:, 0], [1.0, 1.0, 2.0, 2.0, 3.0])
    np.testing.assert_array_equal(d.obs_step, [1, 3])
    np.testing.assert_array_equal(d.obs_readings[:, 0], [500.0, np.nan])
    np.testing.assert_allclose(d.obs_bearing_rad, np.radians([10.0, 20.0]))
    np.testing.assert_array_equal(d.landmarks_xy, [[2000.0, 0.0]])


@pytest.mark.parametrize(
    ("name", "columns", "field", "words"),
    [
        ("commands", {"time": [0.0, 1.0], "v_m_s": [0.1, 0.2]}, "t_s", "missing column t_s"),
        ("commands", {"t_s": [0.0, 1.0], "v_m_s": [0.1, np.nan]}, "v_mm_s", "row 3 has no value"),
        ("commands", {"t_s": [0.0, 1.0]}, None, "no command columns"),
        ("commands", {"t_s": [0.0, 0.01], "v_m_s": [0.1, 0.2]}, "t_s", "less than one step"),
        ("commands", {"t_s": [1.7e12, 1.7e12 + 1e3], "v_m_s": [0.1, 0.2]}, "t_s", "most likely ms"),
        ("truth", {"t_s": [1.7e18, 1.7e18 + 1e9], "x_m": [0, 1], "y_m": [0, 0], "theta_rad": [0, 0]}, "t_s", "ns"),
        ("commands", {"t_s": [0.0, 6e5], "v_m_s": [0.1, 0.2]}, "t_s", "beyond what EM learns from in an hour"),
        ("landmarks", {"id": [1, 1], "x_m": [0, 1], "y_m": [0, 1]}, "id", "appears more than once"),
        ("landmarks", {"id": [1], "x": [0], "y": [0]}, "x_mm", "missing column x_mm"),
        (
            "sightings",
            {"t_s": [0.5], "landmark_id": [1], "range_m": [1.0], "range_mm": [1000.0]},
            "range_mm",
            "two columns mean range_mm",
        ),
        ("sightings", {"t_s": [0.5], "landmark_id": [1], "bearing_rad": [0.1]}, None, "no reading columns"),
        ("sightings", {"t_s": [0.5], "landmark_id": [9], "range_m": [1.0]}, None, "none of the 1 sightings"),
        ("truth", {"t_s": [0.5], "x_m": [0], "y_m": [0], "theta_rad": [0]}, "t_s", "one row cannot"),
    ],
)
def test_bad_files_are_named_with_the_column_and_the_fix(tmp_path, name, columns, field, words):
    files = {
        "commands": {"t_s": [0.0, 1.0], "v_m_s": [0.1, 0.2]},
        "sightings": {"t_s": [0.5], "landmark_id": [1], "range_m": [1.0]},
        "landmarks": {"id": [1], "x_m": [2.0], "y_m": [0.0]},
        "truth": {"t_s": [0.0, 1.0], "x_m": [0, 1], "y_m": [0, 0], "theta_rad": [0, 0]},
    } | {name: columns}
    paths = {k: write_csv(tmp_path / f"{k}.csv", v) for k, v in files.items()}
    with pytest.raises(LogFormatError) as err:
        read_timed_csv(paths["commands"], paths["sightings"], paths["landmarks"], paths["truth"], dt_s=0.1)
    e = err.value
    assert words in e.problem and e.fix
    assert e.file == str(paths[name]) and e.field == field
    res = runner.invoke(
        app, ["convert", "csv", *[f"--{k}={p}" for k, p in paths.items()], "--out", str(tmp_path / "o"), "--dt", "0.1"]
    )
    assert res.exit_code != 0 and words in " ".join(res.output.split()) and "Traceback" not in res.output


def test_mrclams_files_as_timed_csv_read_as_io_mrclam_reads_them(tmp_path):
    """An independent reference: MRCLAM robot 1 written as a robot's own files (metres, the usual
    heading frame, other robots' barcodes as ids the map lacks) converts to what read_mrclam gives."""
    from sensact.io.mrclam import read_mrclam

    folder = require(DATA / "mrclam" / "MRCLAM_Dataset6")
    load = lambda n: np.loadtxt(folder / n, comments="#")  # noqa: E731
    odo, meas, gt = load("Robot1_Odometry.dat"), load("Robot1_Measurement.dat"), load("Robot1_Groundtruth.dat")
    barcodes, marks = load("Barcodes.dat"), load("Landmark_Groundtruth.dat")
    subject = {b: s for s, b in barcodes}
    write_csv(tmp_path / "c.csv", {"t_s": odo[:, 0], "v_m_s": odo[:, 1], "omega_rad_s": odo[:, 2]})
    write_csv(
        tmp_path / "s.csv",
        {
            "t_s": meas[:, 0],
            "landmark_id": [subject.get(b, -1) for b in meas[:, 1]],
            "range_m": meas[:, 2],
            "bearing_rad": meas[:, 3],
        },
    )
    write_csv(tmp_path / "l.csv", {"id": marks[:, 0], "x_m": marks[:, 1], "y_m": marks[:, 2]})
    write_csv(tmp_path / "t.csv", {"t_s": gt[:, 0], "x_m": gt[:, 1], "y_m": gt[:, 2], "theta_rad": gt[:, 3]})
    tl = read_timed_csv(*(tmp_path / f"{n}.csv" for n in "cslt"), dt_s=1.0 / 30.0)  # convert mrclam's step
    ml = read_mrclam(folder, 1)
    a, b = tl.data, ml.data
    assert tl.t0_s == ml.t0_s and a.n_steps == b.n_steps
    for k in ("step_commands", "obs_step", "obs_landmark", "obs_readings", "obs_bearing_rad", "landmarks_xy"):
        np.testing.assert_array_equal(getattr(a, k), getattr(b, k))
    for k in ("x_mm", "y_mm", "theta_rad"):
        np.testing.assert_allclose(tl.groundtruth[k], ml.groundtruth[k], atol=1e-9)
    np.testing.assert_array_equal(tl.groundtruth["valid"], ml.groundtruth["valid"])
    s, m = tl.summary, ml.summary
    assert s["kept"] == m["kept"] and s["dropped_unknown_landmark"] == m["dropped_robot"] + m["dropped_unknown_barcode"]
    # real units and Vicon's heading raise no doubt; the same files in degrees do
    assert unit_doubts(a) == [] and tl.truth_doubt is None
    write_csv(tmp_path / "c.csv", {"t_s": odo[:, 0], "v_m_s": odo[:, 1], "omega_rad_s": np.degrees(odo[:, 2])})
    write_csv(
        tmp_path / "t.csv", {"t_s": gt[:, 0], "x_m": gt[:, 1], "y_m": gt[:, 2], "theta_rad": np.degrees(gt[:, 3])}
    )
    deg = read_timed_csv(tmp_path / "c.csv", tmp_path / "s.csv", tmp_path / "l.csv", tmp_path / "t.csv")
    (turn,) = unit_doubts(deg.data)
    assert "omega_rad_s is 22.8 rad/s at its 90th percentile" in turn and "omega_deg_s" in turn, turn
    assert "only read in degrees," in deg.truth_doubt and deg.truth_doubt.endswith("(name the column theta_deg)")


def test_a_log_without_bearings_gets_no_camera_settings_and_learn_em_names_what_needs_them(timed, tmp_path):
    """A range-only log gets MRCLAM's settings without the bearings, with the start pose to set; a file
    already there (the start pose the user set in it) is left; the camera's settings are refused in one line."""
    from sensact.presets import range_only_config

    _, folder = timed
    sight = read_numeric_csv(folder / "sightings.csv")
    write_csv(tmp_path / "s.csv", {k: v for k, v in sight.items() if k != "bearing_rad"})
    out = tmp_path / "o"
    args = ["--commands", str(folder / "commands.csv"), "--landmarks", str(folder / "landmarks.csv")]
    res = runner.invoke(app, ["convert", "csv", *args, "--sightings", str(tmp_path / "s.csv"), "--out", str(out)])
    assert res.exit_code == 0, res.output
    assert "set start_prior_mean in" in " ".join(res.output.split())
    written = read_settings_file(out / "em_config.yaml")
    assert written == range_only_config(("v_mm_s", "omega_rad_s"), (0.0, 0.0, 0.0))
    assert (
        written.search.start_s is None
        and written.channels[0].bearing_degree == 0
        and not written.robust.prune_when_freed
    )
    text = (out / "em_config.yaml").read_text()
    assert "start_prior_mean: [0.0, 0.0, 0.0]" in text and "bearing_robust" not in text  # shown, though a default
    (out / "em_config.yaml").write_text("motion_sd_mm: 2.0\n")  # a file of the user's, or an earlier run's
    res = runner.invoke(app, ["convert", "csv", *args, "--sightings", str(tmp_path / "s.csv"), "--out", str(out)])
    assert res.exit_code == 0 and "was there before and is left as it was" in " ".join(res.output.split())
    assert (out / "em_config.yaml").read_text() == "motion_sd_mm: 2.0\n"
    (out / "em_config.yaml").unlink()
    sim = tmp_path / "sim"
    assert runner.invoke(app, ["simulate", "diffdrive", "--out", str(sim), "--seconds", "20"]).exit_code == 0
    cfg = ["--config", str(sim / "em_config.yaml")]
    res = runner.invoke(app, ["learn", "em", str(out), *cfg])
    flat = " ".join(res.output.split())
    assert res.exit_code == 2 and "channels[0].bearing_degree" in flat and "Traceback" not in res.output
    no_terms = "channels=[{name: range_mm, degree: 3, start_intercept: 500, start_slope: 0.6, start_sigma: 1000}]"
    res = runner.invoke(app, ["learn", "em", str(out), *cfg, "--set", no_terms])
    flat = " ".join(res.output.split())
    assert res.exit_code == 2 and "search.start_s" in flat and "start_prior_mean" in flat
    # the library refuses the same, so a script calling fit_em gets the line and not a failure deep in EM
    from sensact.errors import ConfigError
    from sensact.learn.em import fit_em
    from sensact.presets import mrclam_config

    with pytest.raises(ConfigError, match=r"channels\[0\]\.bearing_degree: .* Fix: set bearing_degree: 0"):
        fit_em(read_landmark_log(out).data, config=mrclam_config())


def test_the_clocks_origin_moves_no_row_to_another_step():
    """Invariant: a log timed from an epoch (MRCLAM: 1.2e9 s, in ms) puts every command and reading on
    the step it takes when timed from 0. Ties are common at 30 Hz with ms times: a command on a step
    boundary holds from that step, a reading halfway between two steps goes to the later one."""
    from sensact.io.resample import held_on_grid, nearest_steps

    rng = np.random.default_rng(0)
    dt = 1 / 30
    # ms times, a fifth of them on a step boundary (every 0.1 s is 3 steps) or halfway (odd 0.05 s)
    rel_cmd = np.unique(np.concatenate([np.round(rng.uniform(0, 60, 800), 3), np.arange(0, 60, 0.1).round(3)]))
    rel_obs = np.unique(np.concatenate([np.round(rng.uniform(0, 60, 300), 3), np.arange(0.05, 60, 0.1).round(3)]))
    values = rng.normal(size=(rel_cmd.size, 2))
    for origin in (1248444187.156, 1.7e9 + 0.001, 12345.678):
        # as a file gives them: the decimal text's nearest float
        epoch_cmd = np.array([float(f"{origin + r:.3f}") for r in rel_cmd])
        epoch_obs = np.array([float(f"{origin + r:.3f}") for r in rel_obs])
        t0_rel, held_rel = held_on_grid(rel_cmd, values, dt)
        t0_epoch, held_epoch = held_on_grid(epoch_cmd, values, dt)
        np.testing.assert_array_equal(held_epoch, held_rel)
        steps_rel, _ = nearest_steps(rel_obs, t0_rel, dt, len(held_rel))
        steps_epoch, _ = nearest_steps(epoch_obs, t0_epoch, dt, len(held_epoch))
        np.testing.assert_array_equal(steps_epoch, steps_rel)
    # the ties: 0.1 s is step 3 exactly, so the command logged then holds from step 3; 0.05 s is 1.5 steps
    times = np.array([0.0, 0.1, 0.2])
    _, held = held_on_grid(times, np.array([[1.0], [2.0], [3.0]]), dt)
    assert held[:, 0].tolist() == [1.0, 1.0, 1.0, 2.0, 2.0, 2.0, 3.0]
    assert nearest_steps(np.array([0.05, 0.15]), 0.0, dt, 7)[0].tolist() == [2, 5]


def test_the_step_defaults_to_the_commands_median_interval(timed, tmp_path):
    """Without --dt the grid steps at the commands' median interval (the controller's rate), whatever it
    is: the same files with every command row's time stretched threefold step at three times the run's
    step; commands all at one time have no rate and are refused by name."""
    run, folder = timed
    files = ("commands", "sightings", "landmarks")
    plain = read_timed_csv(*(folder / f"{n}.csv" for n in files))
    assert plain.data.dt_s == pytest.approx(run.config.dt_s)
    table = read_numeric_csv(folder / "commands.csv")
    write_csv(tmp_path / "commands.csv", {**table, "t_s": T0 + 3.0 * (table["t_s"] - T0)})
    slow = read_timed_csv(tmp_path / "commands.csv", folder / "sightings.csv", folder / "landmarks.csv")
    assert slow.data.dt_s == pytest.approx(3.0 * run.config.dt_s)
    write_csv(tmp_path / "same.csv", {**table, "t_s": np.full(table["t_s"].size, T0)})
    with pytest.raises(LogFormatError, match=r"same time|repeat an earlier row"):  # a repeated row is refused first
        read_timed_csv(tmp_path / "same.csv", folder / "sightings.csv", folder / "landmarks.csv")
