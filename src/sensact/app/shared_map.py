"""`fleet learn --shared-map`: one landmark map from every robot's log, with each robot's own models (docs/map.md).

Robots in one room see the same landmarks, so the map couples their fits; everything else (each robot's
path, action model, sensor and mount) is its own. The work splits as EM's steps do:

1. **Alone, a job per log** (``learn_log``): each robot learns its models and a map of its own, in its own
   frame (its start). These models are kept (OUT/alone/NAME/model.json) to compare against.
2. **The maps merged, on the client** (``merge_maps``): each robot's placed landmarks laid on the first
   robot's by the best rigid alignment on the landmarks both placed (no scale: each map's scale is its
   range sensor's), then averaged by their inverse variances; repeated until the alignments settle. The
   first log's robot's start fixes the shared frame.
3. **On the shared map, a job per log** (``learn_on_map``): each robot learns its models again with the
   shared map held, as on a survey (its start found by the start search), and returns the landmark
   M-step's information and gradient at the shared map from its posteriors (``mstep.map_normal_equations``).
4. **The map's M-step, on the client**: the logs' information and gradients summed per landmark, one
   Gauss-Newton step (``landmarks.py``): the map every robot's sightings support together, with its sds.

Only small arrays cross the cluster (an L x 2 x 2 information per log), never a path or a log.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sensact.app.fleet import Learned, LearnOptions, calibrate_and_save
from sensact.evaluate.map_truth import RigidAlignment, rigid_alignment
from sensact.learn.em.landmark_step import gauss_newton_step, position_sd
from sensact.models.landmark_map import LandmarkMap
from sensact.records import JsonObject

MERGE_ROUNDS = 10
SAMPLES = 50  # pose samples per sighting for the map's normal equations (as the M-step's)


@dataclass(frozen=True)
class SharedMap:
    """Landmarks by name, in the first log's frame (mm), with their sds (NaN: not placed)."""

    names: tuple[str, ...]
    xy: np.ndarray  # (L, 2)
    sd: np.ndarray  # (L, 2)

    def on_log(self, names: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
        """(xy, sd) for a log's landmarks by its names, NaN where the shared map has no placed position."""
        row = {n: j for j, n in enumerate(self.names)}
        xy = np.full((len(names), 2), np.nan)
        sd = np.full((len(names), 2), np.nan)
        for i, n in enumerate(names):
            if n in row:
                xy[i], sd[i] = self.xy[row[n]], self.sd[row[n]]
        return xy, sd

    def to_json(self, frame: str, evaluation: JsonObject | None = None) -> JsonObject:
        """OUT/map.json: ``{"map": {"landmarks": [...], "frame": ...}}``, as model.json's ``map``."""
        held = np.zeros(len(self.names), dtype=bool)
        placed = np.isfinite(self.xy).all(axis=1)
        doc = LandmarkMap(np.nan_to_num(self.xy), held, self.sd, "range", placed).to_dict(self.names)
        return {"map": doc | {"frame": frame}, "evaluation": evaluation}


def _placed(doc: JsonObject) -> tuple[list[str], np.ndarray, np.ndarray]:
    """A model.json's placed landmarks: names, positions and sds (mm)."""
    marks = [m for m in (doc.get("map") or {}).get("landmarks", []) if m.get("x_mm") is not None]
    xy = np.array([[m["x_mm"], m["y_mm"]] for m in marks], dtype=float).reshape(-1, 2)
    sd = np.array([[m.get("sd_x_mm") or np.nan, m.get("sd_y_mm") or np.nan] for m in marks], dtype=float)
    return [str(m["id"]) for m in marks], xy, sd.reshape(-1, 2)


def merge_maps(docs: Sequence[JsonObject]) -> tuple[SharedMap, list[RigidAlignment | None]]:
    """Each log's learned map (model.json) laid on the first's and averaged by inverse variance (step 2);
    and each log's alignment onto the shared frame (None for a map sharing fewer than two landmarks)."""
    maps = [_placed(d) for d in docs]
    names = list(dict.fromkeys(n for m in maps for n in m[0]))
    row = {n: j for j, n in enumerate(names)}
    on_shared = []
    for ns, xy, sd in maps:
        full, var = np.full((len(names), 2), np.nan), np.full(len(names), np.nan)
        idx = [row[n] for n in ns]
        full[idx] = xy
        var[idx] = np.nansum(np.nan_to_num(sd, nan=100.0) ** 2, axis=1)  # an sd not given counts as 100 mm
        on_shared.append((full, np.maximum(var, 1.0)))
    merged = on_shared[0][0].copy()
    fits: list[RigidAlignment | None] = [RigidAlignment(0.0, np.zeros(2))] + [None] * (len(docs) - 1)
    for _ in range(MERGE_ROUNDS):
        num, den = np.zeros((len(names), 2)), np.zeros(len(names))
        for k, (full, var) in enumerate(on_shared):
            fit = fits[k] if k == 0 else rigid_alignment(full, merged)
            fits[k] = fit
            if fit is None:
                continue
            ok = np.isfinite(full).all(axis=1)
            num[ok] += fit.points(full[ok]) / var[ok, None]
            den[ok] += 1.0 / var[ok]
        new = np.where(den[:, None] > 0, num / np.maximum(den, 1e-300)[:, None], np.nan)
        moved = np.nanmax(np.abs(new - merged)) if np.isfinite(merged).any() else np.inf
        merged = new
        if moved < 0.01:  # mm
            break
    # each weight is 1 / (sd_x^2 + sd_y^2): one coordinate's variance is half the merged one's inverse
    sd = np.where(den > 0, np.sqrt(0.5 / np.maximum(den, 1e-300)), np.nan)
    return SharedMap(tuple(names), merged, np.column_stack([sd, sd])), fits


@dataclass(frozen=True)
class OnSharedMap(Learned):
    """A log learned on the shared map (step 3), with its part of the map's M-step."""

    map_names: tuple[str, ...] = ()
    map_info: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 2)))
    map_grad: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))


def learn_on_map(
    log: Path, out: Path, options: LearnOptions, shared: SharedMap, *, progress: Any = None
) -> OnSharedMap:
    """``log`` learned with ``shared`` held as its map (step 3), written at ``out`` as `learn em` writes a
    model (its ``map`` the shared one, scored against the log's survey), and the landmark M-step's
    information and gradient at the shared map from this fit."""
    from dataclasses import replace

    from sensact.app.log_kinds import landmark_log
    from sensact.learn.em.mstep import map_normal_equations

    opened = landmark_log(log, "fleet learn --shared-map")
    names = opened.data.landmark_names or tuple(str(j) for j in range(len(opened.data.landmarks_xy)))
    xy, sd = shared.on_log(names)
    given = np.isfinite(xy).all(axis=1)
    on_map = replace(opened, data=opened.data.with_landmarks(np.where(given[:, None], xy, opened.data.landmarks_xy)))

    def attach(cal: Any) -> Any:
        """The shared map as the model's (learned, not held: scored against the survey like any learned map)."""
        model = cal.result.model
        if model.landmarks is None:
            learned = LandmarkMap(on_map.data.landmarks_xy, np.zeros(len(xy), dtype=bool), sd, "range", given)
            cal = replace(cal, result=replace(cal.result, model=model.replace(landmarks=learned)))
        return cal

    cal, learned = calibrate_and_save(on_map, out, options, progress=progress, finish=attach)
    post = cal.result.posteriors
    if post is None:
        L = len(names)
        info, grad = np.zeros((L, 2, 2)), np.zeros((L, 2))
    else:
        info, grad = map_normal_equations(post, on_map.data, cal.model.sensor, SAMPLES, np.random.default_rng(0))
    base = {k: getattr(learned, k) for k in Learned.__dataclass_fields__}
    return OnSharedMap(**base, map_names=tuple(names), map_info=info, map_grad=grad)


def learn_fleet_shared_map(
    engine: Any, logs: Sequence[Path], out: Path, options: LearnOptions, events: Any = None
) -> Any:
    """Steps 1-4 on ``engine``: each log's models on one shared map, written as OUT/NAME/model.json, the
    map as OUT/map.json, the models learned alone under OUT/alone/. A ``FleetRun`` of step 3's outcomes
    (cross-scores are not taken: each model carries the shared map)."""
    import time
    from dataclasses import replace

    from sensact.app.fleet import FleetRun, fleet_names, learn_fleet, log_name
    from sensact.app.log_kinds import landmark_log
    from sensact.engine import Failed, Job
    from sensact.errors import ModelFormatError
    from sensact.io.atomic import write_json
    from sensact.io.jsonfile import read_json_object

    t0 = time.perf_counter()
    names = fleet_names(logs, log_name)
    alone = learn_fleet(engine, logs, out / "alone", replace(options, report=False), cross_scores=False, events=events)
    kept = [(p, g, o) for p, g, o in zip(logs, names, alone.outcomes, strict=True) if not isinstance(o, Failed)]
    docs = [read_json_object(Path(o.model), ModelFormatError, "learn the fleet again") for _, _, o in kept]
    with_map = [(k, d) for k, d in zip(kept, docs, strict=True) if isinstance(d.get("map"), dict)]
    if not with_map:
        return alone
    merged, _ = merge_maps([d for _, d in with_map])
    jobs = [Job(learn_on_map, (p, out / g / "model.json", options, merged), g) for (p, g, _), _ in with_map]
    outcomes = engine.run(jobs, isolate=True, on_progress=getattr(events, "learning", None))
    final = _map_step(merged, [o for o in outcomes if not isinstance(o, Failed)])
    first = landmark_log(with_map[0][0][0], "fleet learn --shared-map")
    evaluation = _against_survey(final, first)
    frame = (
        f"frame: the start of {with_map[0][0][1]}'s robot (the origin, facing +x in REP 103), the first log's; "
        "scale: each robot's range readings (in mm)"
    )
    write_json(out / "map.json", final.to_json(frame, evaluation))
    done = {g: o for ((_, g, _), _), o in zip(with_map, outcomes, strict=True)}
    every = tuple(done.get(g, o) for g, o in zip(names, alone.outcomes, strict=True))
    return FleetRun(
        tuple(logs),
        tuple(names),
        every,
        None,
        "cross-scores are not taken with --shared-map (each model carries the shared map)",
        engine.where,
        engine.workers,
        time.perf_counter() - t0,
    )


def _map_step(shared: SharedMap, fits: Sequence[OnSharedMap]) -> SharedMap:
    """Step 4: the logs' information and gradients summed per landmark, and one Gauss-Newton step."""
    row = {n: j for j, n in enumerate(shared.names)}
    L = len(shared.names)
    info, grad = np.zeros((L, 2, 2)), np.zeros((L, 2))
    for f in fits:
        for i, n in enumerate(f.map_names):
            if n in row:
                info[row[n]] += f.map_info[i]
                grad[row[n]] += f.map_grad[i]
    free = np.isfinite(shared.xy).all(axis=1)
    step, ok = gauss_newton_step(info, grad, free)
    xy = np.where(ok[:, None], shared.xy + step, shared.xy)
    sd = np.where(ok[:, None], position_sd(info, free), shared.sd)
    return SharedMap(shared.names, xy, sd)


def _against_survey(shared: SharedMap, opened: Any) -> JsonObject | None:
    """``evaluation.map`` of the shared map against the first log's survey, when it has one."""
    from sensact.evaluate.map_truth import map_scores

    folder = opened.folder
    survey = None if folder is None else folder.survey_xy
    if survey is None:
        return None
    names = opened.data.landmark_names or tuple(str(j) for j in range(len(survey)))
    xy, _ = shared.on_log(names)
    # the shared map's sightings are every log's: each surveyed landmark it did not place counts as seen enough
    scores, _ = map_scores(xy, survey, np.full(len(names), np.iinfo(np.int64).max))
    return {"map": scores}
