"""A learned model scored against the truth its log carries (never used for learning): recorded poses
(groundtruth.csv, as `convert mrclam` writes from Vicon), the true model a simulated log's meta.json
carries, or a 1-D robot's recorded distance (a Turtlebot CSV's range column, a track folder's
distance_mm). The scores are the JSON the model file keeps as ``evaluation``; their key names are fixed."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from sensact.app.logs import OpenedLandmarkLog
from sensact.errors import LogFormatError
from sensact.io.landmark_folder import LandmarkLogFile
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.em_model import EMModel
from sensact.records import JsonObject
from sensact.reprs import compact_repr

# what a fit was scored against (``Scores.against``)
RECORDED_POSES = "recorded poses"
SIMULATED_MODEL = "the simulated model"


@dataclass(frozen=True)
class Scores:
    """A fit's errors against its log's truth."""

    __repr__ = compact_repr  # a line, never the arrays

    against: str  # RECORDED_POSES, SIMULATED_MODEL, or the 1-D log's recorded distance (logs.RANGE_COLUMN, ...)
    evaluation: JsonObject  # the model JSON's ``evaluation``: its keys are what checks and reports read

    @property
    def bars(self) -> dict[str, bool]:
        """Each bar the fit is held to (``evaluate.bars``), cleared or not; empty where none applies."""
        return dict(self.evaluation.get("bars") or {})


@dataclass(frozen=True)
class Unscored:
    """Why a fit on a log with truth was not scored."""

    reason: str


def score_model(
    log: OpenedLandmarkLog,
    model: EMModel,
    *,
    learned_here: bool = False,
    path: np.ndarray | None = None,
    fit: Any = None,
) -> Scores | Unscored | None:
    """``model`` against ``log``'s truth; None when it carries none. A 1-D robot's recorded distance scores
    it (``_on_distance``); else the first of ``SCORERS`` that applies to the truth the log folder carries.
    ``learned_here``: the model was just learned on this log, so recorded poses too broken up to score leave it
    ``Unscored`` (saying why) instead of failing. ``path``: EM's smoothed poses, scored against the recorded
    poses as ``path``. ``fit``: what placed the model on a 1-D log (an ``EMResult`` or a ``Localized``), for
    its recorded distance, or on a learned map, which sightings it used."""
    if log.recorded_distance_mm is not None or log.folder is None:
        return _on_distance(log, fit)
    for scorer in SCORERS:
        scores = scorer(log, model, learned_here, path, fit)
        if scores is not None:
            return scores
    return None


def _on_recorded_poses(
    log: OpenedLandmarkLog, model: EMModel, learned_here: bool, path: np.ndarray | None, fit: Any
) -> Scores | Unscored | None:
    """Against recorded poses (``evaluate/landmark_truth.py``; a learned map against the log's survey first,
    and a simulated differential drive's true models beside them)."""
    lf = log.folder
    recorded = lf.truth_poses()
    data, mapped = lf.data, None
    similar = None
    if model.landmarks is not None:  # a learned map: scored against the survey, the path in its frame
        view = in_truth_frame(lf, model, path, fit)
        data, mapped, path, similar = view.data, view.mapped, view.path, view.similar_path
    if recorded is None or not data.is_continuous or not data.map_given.all():
        return None  # not scored against them: a simulator's truth may score it
    from sensact.evaluate.bars import bar_checks
    from sensact.evaluate.landmark_truth import path_offset, score_against_truth

    try:
        sc = score_against_truth(model, data, *recorded)
    except LogFormatError as exc:
        if not learned_here:
            raise
        return Unscored(f"not scored against the recorded poses: {exc}")
    if mapped is not None:
        sc["map"] = mapped
    if path is not None:
        sc["path"] = path_offset(np.asarray(path), *recorded)
        if similar is not None:  # a learned map's path, its size taken out as well (docs/map.md)
            sc["path"]["similarity"] = {"median_mm": path_offset(similar, *recorded)["median_mm"]}
    sc["bars"] = bar_checks(sc)
    simulated = lf.meta.get("truth") or {}
    if "action_coefficients" in simulated:  # a simulated differential drive's true models
        from sensact.evaluate.simulated_robot import score_against_simulated

        sc["simulated"] = score_against_simulated(model, simulated, lf.data.dt_s)
    return Scores(RECORDED_POSES, sc)


def _on_simulated_planar(
    log: OpenedLandmarkLog, model: EMModel, learned_here: bool, path: np.ndarray | None, fit: Any
) -> Scores | None:
    """Against the true velocities and sensor a simulated planar log's meta.json carries (sec. 4.4.2)."""
    truth = log.folder.meta.get("truth") or {}
    if not (log.folder.data.geometry.has_heading and "velocities" in truth):
        return None
    from sensact.evaluate.em import score_planar
    from sensact.sim.track1d import TrackTruth

    s = truth["sensor"]
    height = TrackTruth(sensor_k_px_mm=s["k_px_mm"], sensor_d0_mm=s["d0_mm"], sensor_h0_px=s["h0_px"]).height_px
    sc = score_planar(
        model, np.asarray(truth["velocities"]), height, truth["sigma_height_px"], truth["sigma_bearing_rad"]
    )
    return Scores(SIMULATED_MODEL, sc)


def _on_simulated_track(
    log: OpenedLandmarkLog, model: EMModel, learned_here: bool, path: np.ndarray | None, fit: Any
) -> Scores | Unscored | None:
    """Against the true models a simulated track's meta.json carries (sec. 4.4.3)."""
    lf = log.folder
    truth = lf.meta.get("truth") or {}
    if not (lf.data.geometry.state_is_range and "action" in truth):
        return None
    from sensact.evaluate.em import score_track
    from sensact.evaluate.track1d import DISTANCE_GRID_MM
    from sensact.sim.track1d import TrackTruth

    try:  # scoring only: a truth block that is not the simulator's numbers leaves the fit unscored, not failed
        tt = TrackTruth.from_dict(truth)
    except (TypeError, ValueError, KeyError, AttributeError) as exc:
        return Unscored(f"meta.json's truth is not a simulated track's models ({type(exc).__name__}): not scored.")
    sc = score_track(model, tt.velocity_mm_s(lf.data.action_commands[:, 0]), tt.height_px, DISTANCE_GRID_MM)
    return Scores(SIMULATED_MODEL, sc)


# the scorers of a log folder's truth, in the order tried: recorded poses first, then a simulator's models
SCORERS: tuple[Callable[..., Scores | Unscored | None], ...] = (
    _on_recorded_poses,
    _on_simulated_planar,
    _on_simulated_track,
)


@dataclass(frozen=True, eq=False)
class TruthFrame:
    """A fit on a learned map, seen in its log's truth's frame (``in_truth_frame``)."""

    data: LandmarkLog  # the log on the surveyed map (the learned map, aligned, where the survey lacks one)
    mapped: JsonObject | None  # evaluation.map; None without a survey
    path: np.ndarray | None  # EM's smoothed path, aligned; None when nothing aligns the frames
    similar_path: np.ndarray | None = None  # the path after the alignment with the scale free as well


def in_truth_frame(lf: LandmarkLogFile, model: EMModel, path: np.ndarray | None, fit: Any = None) -> TruthFrame:
    """A learned map against the log's survey (``evaluate/map_truth.py``): the log on the survey (each
    landmark the survey lacks where the learned map, aligned, puts it), ``evaluation.map``, and the path
    in the survey's frame. Without a survey the frames are aligned by the path against the recorded poses
    instead, and the map is not scored."""
    return TruthFrame(*_on_survey(lf, model, path, fit))


def _on_survey(lf: LandmarkLogFile, model: EMModel, path: np.ndarray | None, fit: Any) -> tuple[Any, ...]:
    from sensact.evaluate.map_truth import map_scores, rigid_alignment, similarity_alignment

    learned, survey, mapped = model.landmarks, lf.survey_xy, None
    if survey is None:
        recorded = lf.truth_poses()
        alignment = similar = None
        if recorded is not None and path is not None:
            poses, valid = recorded
            alignment = rigid_alignment(np.asarray(path)[valid, :2], poses[valid, :2])
            similar = similarity_alignment(np.asarray(path)[valid, :2], poses[valid, :2])
        survey = np.full_like(learned.xy, np.nan)
    else:
        from sensact.learn.em.landmark_step import sightings_per_landmark

        used = getattr(getattr(fit, "posteriors", None), "obs_used", None)
        mapped, alignment = map_scores(learned.placed_xy(), survey, sightings_per_landmark(lf.data, used))
        similar = similarity_alignment(learned.placed_xy(), survey)
    if alignment is None:
        return lf.data.with_landmarks(learned.xy), mapped, None, None
    filled = np.where(np.isfinite(survey), survey, alignment.points(learned.xy))
    if path is None:
        return lf.data.with_landmarks(filled), mapped, None, None
    return (
        lf.data.with_landmarks(filled),
        mapped,
        alignment.poses(np.asarray(path)),
        None if similar is None else similar.poses(np.asarray(path)),
    )


def _on_distance(log: OpenedLandmarkLog, fit: Any) -> Scores | Unscored | None:
    """The Turtlebot's scaled gain and sensor errors against its range column, or a track folder's recorded
    distance; None without either."""
    from sensact.evaluate.turtlebot_em import NO_RANGE_COLUMN, range_column_problem, score_turtlebot_em

    problem = range_column_problem(log.recorded_distance_mm)
    if problem == NO_RANGE_COLUMN:
        return None
    if problem:
        return Unscored(f"{problem}: not scored.")
    return Scores(log.scored_against, score_turtlebot_em(fit, log.data, log.recorded_distance_mm))
