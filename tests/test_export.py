"""``sensact export``: each format checked against an independent reading of the same model (the YAML
parsed and its matrices rebuilt from the model's own numbers, the action model evaluated both ways, the
TUM files read by evo and scored as sensact scores the path)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from sensact.cli import app
from sensact.models.em_model import EMModel

runner = CliRunner()


def _ok(args):
    res = runner.invoke(app, [str(a) for a in args])
    assert res.exit_code == 0, res.output
    return res


@pytest.fixture(scope="module")
def learned(tmp_path_factory):
    """A simulated differential drive (two minutes, its camera 150 mm ahead) learned by `learn em`."""
    root = tmp_path_factory.mktemp("export")
    _ok(
        [
            "simulate",
            "diffdrive",
            "--out",
            root / "log",
            "--seconds",
            "120",
            "--seed",
            "2",
            "--set",
            "mounted_at=[150,0,0]",
        ]
    )
    _ok(["learn", "em", root / "log", "--out", root / "model.json"])
    return root, json.loads((root / "model.json").read_text())


def _ros2_parameters(doc) -> list[str]:
    """What a ROS 2 `--params-file` parser refuses in ``doc``: a top-level key without exactly
    `ros__parameters`, or a leaf that is not a scalar or a flat list of one scalar type (nested lists, nulls)."""
    bad = [k for k, node in doc.items() if not (isinstance(node, dict) and set(node) == {"ros__parameters"})]

    def leaves(node, name):
        if isinstance(node, dict):
            for k, v in node.items():
                leaves(v, f"{name}.{k}")
        elif isinstance(node, list):
            kinds = {type(v) for v in node}
            if not (len(kinds) <= 1 and kinds <= {bool, int, float, str}):
                bad.append(name)
        elif not isinstance(node, bool | int | float | str):
            bad.append(name)

    for k, node in doc.items():
        leaves(node.get("ros__parameters") if isinstance(node, dict) else None, k)
    return bad


def test_robot_localization_yaml_is_sigma_m_in_si_per_second(learned, tmp_path):
    root, doc = learned
    _ok(["export", root / "model.json", "--format", "robot-localization", "--out", tmp_path / "rl.yaml"])
    params = yaml.safe_load((tmp_path / "rl.yaml").read_text())
    # a ROS 2 parameter file, as `--params-file` parses it: every top-level key a node's ros__parameters
    assert _ros2_parameters(params) == [] and list(params) == ["ekf_filter_node"]
    q = np.array(params["ekf_filter_node"]["ros__parameters"]["process_noise_covariance"]).reshape(15, 15)
    beside = yaml.safe_load((tmp_path / "rl.sensact.yaml").read_text())  # sensact's numbers, beside it
    assert _ros2_parameters(beside) == []  # a ROS 2 parameter file too
    params["sensact"] = beside["sensact_calibration"]["ros__parameters"]
    assert np.array_equal(q, q.T) and np.linalg.eigvalsh(q).min() > 0  # symmetric positive-definite
    dt = doc["dt_s"]
    side, fwd, head = doc["model"]["motion_sd"][0]  # sensact's robot frame: x right, y forward (mm, per step)
    body = np.array(params["sensact"]["sigma_m_per_s_body"]).reshape(3, 3)
    np.testing.assert_allclose(body, np.diag([(fwd / 1000) ** 2, (side / 1000) ** 2, head**2]) / dt, rtol=1e-12)
    # world x, y: the body covariance averaged over headings (a rotated covariance's mean is trace/2 * I)
    headings = np.linspace(0, 2 * np.pi, 3600, endpoint=False)
    rot = np.stack([[np.cos(headings), -np.sin(headings)], [np.sin(headings), np.cos(headings)]]).transpose(2, 0, 1)
    mean_world = np.mean(rot @ body[:2, :2] @ rot.transpose(0, 2, 1), axis=0)
    np.testing.assert_allclose(q[:2, :2], mean_world, rtol=1e-9, atol=1e-18)
    assert q[5, 5] == pytest.approx(head**2 / dt, rel=1e-12)
    twist = np.array(params["sensact"]["twist_covariance"]).reshape(6, 6)
    assert twist[0, 0] == pytest.approx((fwd / 1000) ** 2 / dt**2) and twist[5, 5] == pytest.approx(head**2 / dt**2)
    mount = params["sensact"]["sensor_mount"]
    assert mount["x_m"] == pytest.approx(doc["model"]["sensor"]["mount"]["forward_mm"] / 1000)
    assert 0.10 < mount["x_m"] < 0.20  # the camera sits 150 mm ahead


def test_exported_action_model_predicts_what_the_model_predicts(learned, tmp_path):
    """Commands in SI through the exported gains give the velocities sensact's own model gives, turned
    into REP 103's axes (forward = sensact's y, left = -x)."""
    root, doc = learned
    _ok(["export", root / "model.json", "--format", "robot-localization", "--out", tmp_path / "rl.yaml"])
    act = yaml.safe_load((tmp_path / "rl.sensact.yaml").read_text())["sensact_calibration"]["ros__parameters"]
    act = act["action_model"]
    assert act["commands"] == ["v_m_s", "omega_rad_s"]
    model = EMModel.from_dict(doc["model"])
    rng = np.random.default_rng(0)
    for v, w in rng.uniform([-0.3, -1.0], [0.3, 1.0], size=(20, 2)):
        vx, vy, vth = (model.action.features(np.array([[v * 1000, w]])) @ model.action.coefficients)[0]
        values = {"constant": 1.0, "v_m_s": v, "omega_rad_s": w, "v_m_s*omega_rad_s": v * w}
        si = {k: sum(c * values[f] for f, c in terms.items()) for k, terms in act["velocities"].items()}
        assert si["vx_m_s"] == pytest.approx(vy / 1000, abs=1e-12)
        assert si["vy_m_s"] == pytest.approx(-vx / 1000, abs=1e-12)
        assert si["vyaw_rad_s"] == pytest.approx(vth, abs=1e-12)
    assert act["delay_s"] == pytest.approx(model.action.delay_steps * doc["dt_s"])


def test_tum_trajectories_read_by_evo_score_as_sensact_scores_the_path(learned, tmp_path):
    evo = pytest.importorskip("evo.core.metrics", reason="evo reads the TUM files independently")
    from evo.core import sync
    from evo.tools import file_interface

    root, doc = learned
    path, truth = tmp_path / "path.tum", tmp_path / "truth.tum"
    _ok(["export", root / "model.json", "--format", "tum", "--out", path, "--truth-out", truth])
    est = file_interface.read_tum_trajectory_file(str(path))
    ref = file_interface.read_tum_trajectory_file(str(truth))
    with np.load(root / "model.path.npz") as z:
        mean = z["mean"]
    np.testing.assert_allclose(est.positions_xyz[:, :2] * 1000, mean[:, :2], atol=1e-9)
    yaw = np.array([2 * math.atan2(q[3], q[0]) for q in est.orientations_quat_wxyz])  # a yaw-only quaternion
    np.testing.assert_allclose(np.angle(np.exp(1j * (yaw - mean[:, 2] - np.pi / 2))), 0, atol=1e-9)
    ref, est = sync.associate_trajectories(ref, est, max_diff=1e-4)
    ape = evo.APE(evo.PoseRelation.translation_part)
    ape.process_data((ref, est))
    median_mm = 1000 * ape.get_statistic(evo.StatisticsType.median)
    assert median_mm == pytest.approx(doc["evaluation"]["path"]["median_raw_mm"], rel=0.02)


def test_export_refuses_a_format_it_does_not_know_and_a_model_without_its_parts(learned, tmp_path):
    root, _ = learned
    res = runner.invoke(app, ["export", str(root / "model.json"), "--format", "xml", "--out", str(tmp_path / "x")])
    assert res.exit_code == 2 and "no export format 'xml'" in res.output
    res = runner.invoke(app, ["export", str(root / "model.json"), "--format", "urdf", "--out", str(tmp_path / "x")])
    assert res.exit_code == 2 and "--format urdf does not apply to this model" in res.output
    res = runner.invoke(app, ["export", str(root / "model.json"), "--format", "velodyne", "--out", str(tmp_path / "x")])
    assert res.exit_code == 2 and "not a car model with learned laser angles" in " ".join(res.output.split())


def test_export_without_out_writes_beside_the_model(learned):
    root, _ = learned
    _ok(["export", root / "model.json", "--format", "tum"])
    rows = np.loadtxt(root / "model.tum")
    truth = np.loadtxt(root / "model_truth.tum")
    assert rows.shape[1] == 8 == truth.shape[1] and np.all(np.diff(rows[:, 0]) > 0)
    np.testing.assert_allclose(np.linalg.norm(rows[:, 4:], axis=1), 1.0, atol=1e-12)  # unit quaternions


# what ROS's velodyne driver (velodyne_pointcloud/src/lib/calibration.cc) reads of each laser without checking
# that it is there, and of the file
DRIVER_LASER_KEYS = {
    "laser_id",
    "rot_correction",
    "vert_correction",
    "dist_correction",
    "dist_correction_x",
    "dist_correction_y",
    "vert_offset_correction",
    "horiz_offset_correction",
    "min_intensity",
    "focal_distance",
    "focal_slope",
}


@pytest.mark.parametrize("factory", [False, True])
def test_the_velodyne_export_holds_every_key_the_ros_driver_reads(tmp_path, factory):
    """With or without a factory calibration: num_lasers and every laser's keys as the driver reads them,
    the learned angles as given, and a factory calibration's own corrections kept."""
    n = 16
    lasers = [{"laser_id": i, "rot_correction": 0.001 * i, "vert_correction": -0.2 + 0.02 * i} for i in range(n)]
    if factory:
        for entry in lasers:
            entry.update(dist_correction=1.2, dist_correction_x=1.1, dist_correction_y=1.3, focal_slope=0.5)
    (tmp_path / "car.json").write_text(json.dumps({"velodyne_calibration": {"num_lasers": n, "lasers": lasers}}))
    _ok(["export", tmp_path / "car.json", "--format", "velodyne", "--out", tmp_path / "v.yaml"])
    text = (tmp_path / "v.yaml").read_text()
    doc = yaml.safe_load(text)
    assert doc["num_lasers"] == n == len(doc["lasers"])
    for i, entry in enumerate(doc["lasers"]):
        assert DRIVER_LASER_KEYS <= set(entry), DRIVER_LASER_KEYS - set(entry)
        assert all(isinstance(v, int | float) for v in entry.values())
        assert entry["laser_id"] == i and entry["rot_correction"] == lasers[i]["rot_correction"]
        assert entry["dist_correction"] == (1.2 if factory else 0.0)
    said = " ".join(ln for ln in text.splitlines() if ln.startswith("#"))
    assert "written by sensact" in said and "vert_offset_correction" in said and ("dist_correction," in said) != factory


def test_the_report_shows_error_bars_in_the_frame_and_units_of_the_exports(learned):
    """Each action coefficient the report's error-bar table shows (REP 103, SI) is the one the
    robot_localization export writes; lengths are metres."""
    from sensact.app.export import action_model_si
    from sensact.app.report import si_parameter
    from sensact.learn.em.uses.error_bars import model_parameters

    _, doc = learned
    model = EMModel.from_dict(doc["model"])
    exported = action_model_si(model.action, doc["dt_s"])["velocities"]
    shown = {}
    for name, (family, value) in model_parameters(model, (1000.0,)).items():
        label, k = si_parameter(name)
        shown[label] = value * k
        if family == "action":
            velocity, feature = label.removeprefix("action.").rstrip("]").split("[")
            assert shown[label] == pytest.approx(exported[velocity][feature], rel=1e-12, abs=1e-15)
    assert shown["mount.forward_m"] == pytest.approx(doc["model"]["sensor"]["mount"]["forward_mm"] / 1000)
    assert "f.range_m(1 m)" in shown or "f.height_px(1 m)" in shown


@pytest.mark.parametrize(
    "change,field",
    [
        (lambda m: m.pop("motion_sd"), "model.motion_sd"),
        (lambda m: m["sensor"].pop("mount"), "model.sensor.mount"),
        (lambda m: m["sensor"]["mount"].__setitem__("yaw_rad", 1e9), "model.sensor.mount.yaw_rad"),
        (lambda m: m["sensor"]["mount"].__setitem__("forward_mm", "ahead"), "model.sensor.mount.forward_mm"),
    ],
)
def test_an_export_refuses_a_model_missing_or_wild_in_what_it_writes(learned, tmp_path, change, field):
    """Issue 95: a model with no Sigma_m, no mount, or a mount's yaw of 1e9 rad is one line (exit 2), not an
    export of a default or of nonsense."""
    doc = json.loads(json.dumps(learned[1]))
    change(doc["model"])
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(doc))
    res = runner.invoke(app, ["export", str(bad), "--format", "robot-localization", "--out", str(tmp_path / "rl.yaml")])
    assert res.exit_code == 2 and f"error: {bad}: {field}:" in res.output.replace("\n", ""), res.output
    assert not (tmp_path / "rl.yaml").exists()


@pytest.mark.parametrize("fmt", ["robot-localization", "tum"])
def test_a_flagged_models_export_is_written_with_one_warning_and_exit_3(learned, tmp_path, fmt):
    """A model flagged when it was learned is exported as asked, but not as a success: one warning line names
    its flags and the command exits 3; the same model unflagged exits 0."""
    root, doc = learned
    flagged = tmp_path / "flagged.json"
    flags = [{"code": "not_converged", "message": "EM did not settle."}, {"code": "sigma_collapsed", "message": "x"}]
    flagged.write_text(json.dumps(doc | {"health": {"ok": False, "flags": flags}}))
    for beside in root.glob("model.*.npz"):  # the path and the like, as learn em wrote them
        (tmp_path / beside.name.replace("model.", "flagged.", 1)).write_bytes(beside.read_bytes())
    res = runner.invoke(app, ["export", str(flagged), "--format", fmt, "--out", str(tmp_path / "f.out")])
    assert res.exit_code == 3, res.output
    assert (tmp_path / "f.out").exists()
    warnings = [ln for ln in res.output.splitlines() if ln.startswith("warning:")]
    assert len(warnings) == 1 and "not_converged, sigma_collapsed" in " ".join(res.output.split())
    _ok(["export", root / "model.json", "--format", fmt, "--out", tmp_path / "ok.out"])
