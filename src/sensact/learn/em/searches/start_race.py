"""Where the robot starts, when nobody says (beyond the thesis, whose robots started at a known pose).

A real log begins wherever the robot happened to be. With a landmark map and bearings, the EKF can
only lock on from a start near the truth, so the start is chosen in two rounds:

1. ``start_candidates`` scores a grid of starting positions over the mapped area (``search_grid``, laid
   in the map's own frame so that it turns with the map) by
   ``log P(O | C, lambda)`` of the first ``start_search_s`` seconds under the starting model, the E-step's own
   likelihood (its forward pass). At each position the heading is the one that makes the first bearing
   exact, so only positions need a grid. The best few, each at least a few grid cells from the others,
   go on. A window's likelihood alone cannot choose among them: under the starting model the robot does
   not move, and a robot that drives toward the landmarks it sees changes their bearings hardly at all.
2. ``race_starts`` runs EM from each candidate on the whole log, in rounds of
   ``start_trial_iterations`` held iterations (Sigma_m and the bearing terms fixed, Gaussian readings,
   no pruning, so every candidate is scored on the same observations by the same likelihood), and
   keeps the better half after each round. A start that lost the robot stays thousands of log-units
   below one that found it, so the rounds are decisive; the winner's EM goes on where it stopped.
   A trial whose best model is the one it started from would repeat itself exactly in the next
   round (the M-step's samples are seeded), so it is not run again: its score stands.
   A round's trials are independent and each seeds its own samples, so they run in threads, one
   per core (the E-step's compiled passes release the GIL): the same race, sooner.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from contextvars import copy_context
from dataclasses import dataclass
from typing import Any

import numpy as np

from sensact.core.angles import wrap_angle
from sensact.errors import ConfigError
from sensact.learn.em.config import EMConfig
from sensact.learn.em.estep import log_likelihood
from sensact.limits import thread_budget
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.em_model import EMModel
from sensact.records import omit_when

MIN_OBSERVATIONS = 10  # the window grows until it holds this many sightings
DISTINCT_CELLS = 2.5  # candidates closer than this many grid cells are one candidate
MAX_GRID_CELLS = 1_000_000  # a 500 mm grid over a 500 m room; more is a map in the wrong unit


@dataclass(frozen=True)
class StartCandidate:
    prior_mean: tuple[float, ...]  # x mm, y mm, heading rad
    window_loglik: float  # the forward likelihood of the first seconds from it


@dataclass(frozen=True)
class Race:
    """A race of starts: each round's likelihood by candidate (its index as a string), the winner, and the
    held iterations it ran."""

    rounds: tuple[dict[str, float], ...]
    winner: int
    winner_iterations: int


@dataclass(frozen=True)
class StartSearch:
    """What the start search tried and chose: the grid, its window, the distinct best candidates, their race
    (with more than one) and the start EM took."""

    grid_points: int
    window_steps: int
    first_sighting_step: int
    candidates: tuple[StartCandidate, ...]
    race: Race | None = omit_when(None, default=None)
    prior_mean: tuple[float, ...] = ()


def start_candidates(data: LandmarkLog, model: EMModel, config: EMConfig) -> tuple[list[EMModel], StartSearch]:
    """Up to ``config.search.start_candidates`` models with distinct ``pi(w_0)``, best window likelihood first."""
    first = np.flatnonzero(np.isfinite(data.obs_bearing_rad))
    if not data.geometry.has_heading or first.size == 0 or len(data.landmarks_xy) == 0:
        raise ValueError("the start search needs a planar log with bearings to mapped landmarks")
    window = search_window(data, config.search.start_s)
    k0 = first[0]
    lm = data.landmarks_xy
    g = config.search.start_grid_mm
    target = lm[data.obs_landmark[k0]]
    points = search_grid(lm, target, g)
    cov = np.diag([g**2, g**2, 0.3**2])
    # the starting f is a guess, so the search trusts the bearings alone: the readings get a spread
    # that makes them uninformative; Gaussian bearings, so that no candidate can discount the sightings
    # that contradict it
    chans = model.sensor.channels
    vague = model.sensor.gaussian().with_fits(
        [(c.function, 1e9, c.bearing_terms) for c in chans], model.sensor.sigma_bearing_rad
    )
    scorer = model.replace(sensor=vague)
    scored: list[tuple[float, np.ndarray]] = []
    for x, y in points:
        d = target - (x, y)
        # the heading that puts the first sighting's landmark at its measured bearing (sec. 2.5.1:
        # theta = 0 faces +y, bearings counterclockwise from forward); the robot's heading is
        # held by the starting model (no motion) until that sighting
        theta = float(wrap_angle(np.arctan2(d[1], d[0]) - 0.5 * np.pi - data.obs_bearing_rad[k0]))
        prior_mean = np.array([x, y, theta])
        ll = log_likelihood(scorer.replace(prior_mean=prior_mean, prior_cov=cov), window)
        if np.isfinite(ll):
            scored.append((ll, prior_mean))
    if not scored:
        raise ConfigError(
            "no start candidate gave a finite likelihood.",
            file=data.source,
            field="search.start_s",
            fix="set search.start_s: null and give thesis.start_prior_mean (x mm, y mm, heading rad) and "
            "start_prior_sd.",
        )
    scored.sort(key=lambda s: -s[0])
    chosen: list[tuple[float, np.ndarray]] = []
    for ll, mean in scored:
        if all(np.hypot(*(mean[:2] - m[:2])) >= DISTINCT_CELLS * g for _, m in chosen):
            chosen.append((ll, mean))
        if len(chosen) == config.search.start_candidates:
            break
    info = StartSearch(
        len(scored),
        window.n_steps,
        int(data.obs_step[k0]),
        tuple(StartCandidate(tuple(m.tolist()), float(ll)) for ll, m in chosen),
    )
    return [model.replace(prior_mean=m, prior_cov=cov) for _, m in chosen], info


def search_window(data: LandmarkLog, seconds: float) -> LandmarkLog:
    """The log's first ``seconds``, longer when they hold fewer than ``MIN_OBSERVATIONS`` sightings."""
    stop = round(seconds / data.dt_s) + 1
    stop = max(stop, int(data.obs_step[min(MIN_OBSERVATIONS, data.n_observations) - 1]) + 2)
    return data.slice_steps(0, min(stop, data.n_steps))


def search_grid(landmarks_xy: np.ndarray, target_xy: np.ndarray, cell_mm: float) -> np.ndarray:
    """The start search's positions (n x 2): square cells of ``cell_mm`` over the mapped area and
    four cells around it, in a frame the map itself sets, so that moving and turning the map and its
    log together moves and turns the grid with them (an axis-aligned grid would score other
    positions in a turned map, and EM would start elsewhere). The frame: its origin at the first
    sighting's landmark, its first axis towards the landmarks' centroid (towards the farthest
    landmark when the centroid is that landmark; the map's x-axis when it is the only one). Points
    sit at cell centres, half a cell off the landmark in each axis, and the four within a cell of it
    are left out: a start on the landmark has no bearing to it."""
    rel = landmarks_xy - target_xy
    toward = rel.mean(axis=0)
    if np.hypot(*toward) < 1e-6 * cell_mm:
        far = np.hypot(rel[:, 0], rel[:, 1])
        toward = rel[int(np.argmax(far))] if far.max() > 1e-6 * cell_mm else np.array([1.0, 0.0])
    u = toward / np.hypot(*toward)
    axes = np.array([u, [-u[1], u[0]]])  # rows: the grid's axes, counterclockwise, so a rotation
    local = rel @ axes.T
    lo = np.floor(local.min(axis=0) / cell_mm - 4.5)
    hi = np.ceil(local.max(axis=0) / cell_mm + 4.5)
    cells = float(np.prod(hi - lo))
    if cells > MAX_GRID_CELLS:  # before allocating: a map in mm read as metres asks for billions
        extent = float(np.max(local.max(axis=0) - local.min(axis=0))) / 1000.0
        raise ConfigError(
            f"the start search's grid would be {cells:.3g} cells of {cell_mm:g} mm over a map {extent:.4g} m across, "
            f"over the limit of {MAX_GRID_CELLS:,}: is the map's unit right?",
            field="search.start_grid_mm",
            fix="give the landmarks in metres (x_m, y_m) or mm (x_mm, y_mm) as named, or a coarser start_grid_mm.",
        )
    i, j = np.meshgrid(np.arange(lo[0], hi[0]) + 0.5, np.arange(lo[1], hi[1]) + 0.5, indexing="ij")
    cells = np.column_stack([i.ravel(), j.ravel()])
    cells = cells[np.hypot(cells[:, 0], cells[:, 1]) >= 1.0]
    return target_xy + (cells * cell_mm) @ axes


# (data, starting model, iterations) -> an EMResult: EM's held stage alone for that many iterations,
# ungated and without a stop (loop.held_trial), passed in to keep the modules one-way
RunTrial = Callable[[LandmarkLog, EMModel, int], Any]
# (trials done, trials the race holds at most) -> None; a stalled trial is done without running
OnTrial = Callable[[int, int], None]


def race_trials(n_candidates: int) -> int:
    """How many trials a race of ``n_candidates`` holds at most: a round for each field, halved until two
    are left (``race_starts``); fewer when every start loses the robot at once."""
    total, field = n_candidates, n_candidates
    while field > 2:
        field = math.ceil(field / 2)
        total += field
    return total


def race_starts(
    data: LandmarkLog,
    candidates: list[EMModel],
    config: EMConfig,
    run: RunTrial,
    workers: int | None = None,
    on_trial: OnTrial | None = None,
) -> tuple[EMModel, Race]:
    """The candidate whose held EM reaches the highest whole-log likelihood, as its model after the
    race, and the race: each round's scores, the winner and its iterations. The field is halved every
    ``start_trial_iterations`` until two are left, and the better of those wins. ``workers`` threads
    run a round's trials (by default ``limits.thread_budget()``: the cores, or a Dask worker's allocation);
    ``on_trial`` hears of each trial as it is done, in the order of the field."""
    trial = config.search.start_trial_iterations  # of the held, Gaussian, ungated stage: one likelihood for every start
    alive = list(range(len(candidates)))
    models = list(candidates)
    spent = [0] * len(candidates)
    rounds: list[dict[str, float]] = []
    stalled: dict[int, float] = {}  # candidates whose last trial found nothing better than its start
    planned, done = race_trials(len(candidates)), 0
    with ThreadPoolExecutor(max_workers=max(min(len(candidates), workers or thread_budget()), 1)) as pool:
        while True:
            to_run = [i for i in alive if i not in stalled]
            # the trial is deterministic (seeded), so a stalled one would repeat itself from the same model
            if len(to_run) < len(alive):
                done += len(alive) - len(to_run)
                if on_trial is not None:
                    on_trial(done, planned)
            results = {}
            # each trial in a copy of this context: a fit's pass count (estep.counting_passes) sees its threads
            contexts = [copy_context() for _ in to_run]
            trials = pool.map(lambda i, ctx: ctx.run(run, data, models[i], trial), to_run, contexts)
            for i, res in zip(to_run, trials, strict=True):
                results[i] = res
                done += 1
                if on_trial is not None:
                    on_trial(done, planned)
            scores = {}
            for i in alive:
                if i in stalled:
                    scores[i] = stalled[i]
                    spent[i] += trial
                    continue
                res = results[i]
                scores[i] = res.loglik_best if res.iterations else -math.inf
                if res.model is models[i] and res.iterations == trial:
                    stalled[i] = scores[i]
                models[i] = res.model
                spent[i] += res.iterations
            rounds.append({str(i): float(s) for i, s in scores.items()})
            ranked = sorted(alive, key=lambda i: -scores[i])
            if len(ranked) <= 2 or scores[ranked[0]] == -math.inf:
                break
            alive = ranked[: math.ceil(len(ranked) / 2)]
    winner = ranked[0]
    return models[winner], Race(tuple(rounds), winner, spent[winner])
