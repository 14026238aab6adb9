"""What one EM fit returns (typed results, docs/design.md): the most likely model, its history, why EM stopped and what
its searches, gates and restarts did."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Literal

import numpy as np

from sensact.core.pose_models import sensor_distance
from sensact.learn.em.config import EMConfig
from sensact.learn.em.estep import Posteriors
from sensact.learn.em.mount import MountFreedom
from sensact.learn.em.searches.delay import DelaySearch
from sensact.learn.em.searches.mount_search import MountSearch
from sensact.learn.em.searches.ridge import RidgeSearch
from sensact.learn.em.searches.start_race import StartSearch
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.em_model import EMModel
from sensact.records import JsonObject, to_json
from sensact.reprs import compact_repr


def smoothed_distances(model: EMModel, post: Posteriors, data: LandmarkLog) -> np.ndarray:
    """Each sighting the E-step used (``post.obs_used``): its distance from the sensor, at its mount on the
    smoothed path, to its landmark; on a track the state itself."""
    use = np.asarray(post.obs_used, dtype=bool)
    steps = data.obs_step[use]
    if data.geometry.has_heading:
        lm = data.landmarks_xy[data.obs_landmark[use]]
        return sensor_distance(post.mean_gamma[steps], lm, model.sensor.mount.as_array())
    return post.mean_gamma[steps, 0]


# the signs, without ground truth, that EM lost the robot (checks/lost_signs.py finds them)


@dataclass(frozen=True)
class FunctionTurns:
    """A channel's f turns over at ``turns_at_mm`` inside the ``distances_mm`` it was fitted on."""

    channel: str
    sign: Literal["turns"] = field(default="turns", init=False)
    turns_at_mm: tuple[float, ...] = ()
    distances_mm: tuple[float, float] = (0.0, 0.0)


@dataclass(frozen=True)
class FunctionBends:
    """A length-reading channel's f whose slope goes from ``slopes[0]`` to ``slopes[1]`` without turning."""

    channel: str
    sign: Literal["bends"] = field(default="bends", init=False)
    slopes: tuple[float, float] = (0.0, 0.0)
    distances_mm: tuple[float, float] = (0.0, 0.0)


@dataclass(frozen=True)
class Unsettled:
    """The iterations after the best fell far below it: EM did not settle (it names no channel)."""

    sign: Literal["unsettled"] = field(default="unsettled", init=False)
    best_iteration: int = 0
    iterations_after: int = 0
    mean_fall: float = 0.0
    per_sighting: float = 0.0


LostSign = FunctionTurns | FunctionBends | Unsettled


def mean_fall_after_best(loglik_history: np.ndarray, best_iteration: int) -> float | None:
    """How far, on average, the log-likelihoods of the iterations after the best fell below the best's;
    None when no iteration followed it (a fit stopped at ``max_iterations`` while climbing)."""
    history = np.asarray(loglik_history, dtype=float)
    after = history[best_iteration + 1 :]
    return float(np.mean(history[best_iteration] - after)) if after.size else None


def fall_per_sighting(loglik_history: np.ndarray, best_iteration: int, n_used: int) -> float | None:
    """``mean_fall_after_best`` per sighting used: what ``unsettled_fit`` holds against
    ``SearchSettings.lost_fall_per_sighting`` (None with no iteration after the best or no sighting)."""
    fall = mean_fall_after_best(loglik_history, best_iteration)
    return None if fall is None or n_used <= 0 else fall / n_used


@dataclass(frozen=True)
class RestartRun:
    """One run of ``restart_while_lost``: its channels' start sigmas, its likelihood on the sightings every
    run kept, its own best, how it ended, the signs that it lost the robot, and whether it was kept."""

    start_sigma: dict[str, float]
    loglik: float
    loglik_best: float
    iterations: int
    stop_reason: str
    f_turns: tuple[LostSign, ...]
    kept: bool


@dataclass(frozen=True)
class HeadingRace:
    winner: int
    headings_rad: tuple[float, ...]


@dataclass(frozen=True)
class StartMoved:
    """A range-only fit whose given start moved metres: the start, where EM put it, how far, the race of
    headings there, both runs' likelihoods and which was kept (``"first"`` or ``"again"``)."""

    given: tuple[float, ...]
    learned: tuple[float, ...]
    moved_mm: float
    heading_race: HeadingRace
    loglik: tuple[float, ...]
    kept: str


@dataclass(frozen=True, eq=False)
class EMResult:
    __repr__ = compact_repr  # a line, never the arrays
    model: EMModel  # the model with the highest likelihood
    loglik_history: np.ndarray  # log P(O | C, lambda_i) for every iteration i
    velocity_history: np.ndarray  # (iterations, A, n) the action table (or beta) of every lambda_i
    sigma_history: np.ndarray  # (iterations, C+1) each channel's sigma, then sigma_2, of every lambda_i
    best_iteration: int
    stop_reason: str  # "converged", "max_iterations", "diverged" or "interrupted"
    n_observations: int
    n_pruned: int
    seconds: float
    config: EMConfig
    posteriors: Posteriors | None = field(default=None, repr=False)  # of the best model
    motion_sd_history: np.ndarray | None = None  # (iterations, G, n) Sigma_m's standard deviations
    start_search: StartSearch | None = None  # what the start search tried and chose
    freed_at: int = -1  # the iteration after which Sigma_m, the terms and robust readings were freed (-1: never held)
    ridge: list[RidgeSearch] | None = None  # each ridge search: its iteration, shift, likelihoods (searches/ridge)
    delay_search: list[DelaySearch] | None = None  # each delay search: its iteration, delays, likelihoods
    restarts: list[RestartRun] | None = None  # each run while the fit looked lost (restart_while_lost)
    n_pruned_when_freed: int = 0  # of n_pruned, those the gate dropped again when the robust readings took over
    # a range-only fit that ended facing backward, reported turned by pi (searches/facing.py; the same likelihood)
    turned_to_face_forward: bool = False
    # a range-only fit whose given start moved metres: the start, where EM put it, both runs' likelihoods
    start_moved: StartMoved | None = None
    # which of the sensor mount's components the M-step learned, and why the rest were held (mount.py)
    mount: MountFreedom | None = None
    mount_search: list[MountSearch] | None = None  # each mount search (mount.search_mount)
    stages: tuple[tuple[str, int], ...] = ()  # each stage EM ran (loop.Stage) and the iteration it began at
    # the whole fit's passes over the log (estep.counting_passes): E-steps, and the searches' forward passes
    e_steps: int = 0
    forward_passes: int = 0
    accelerated: int = 0  # SQUAREM's steps beyond plain EM's that were kept (squarem.py)
    # the rule that ended the fit: "fixed_point" (every step below fixed_point.STOP_SD of its standard error),
    # "patience" (sec. 4.4.1's), "max_iterations", "diverged" or "interrupted"
    stopped_because: str = ""

    @property
    def iterations(self) -> int:
        return int(self.loglik_history.size)

    @property
    def n_used(self) -> int:
        """The sightings the best model's E-step used (after every prune)."""
        if self.posteriors is not None:
            return int(np.count_nonzero(self.posteriors.obs_used))
        return self.n_observations - self.n_pruned

    @property
    def loglik_best(self) -> float:
        return float(self.loglik_history[self.best_iteration])

    @property
    def pruned_fraction(self) -> float:
        """The share of the log's sightings that the gates dropped (sec. 4.4.1's, and prune_when_freed's)."""
        return (self.n_observations - self.n_used) / self.n_observations if self.n_observations else 0.0

    def summary(self) -> JsonObject:
        return {
            "iterations": self.iterations,
            "best_iteration": self.best_iteration,
            "stop_reason": self.stop_reason,
            "stopped_because": self.stopped_because or self.stop_reason,
            "loglik_start": float(self.loglik_history[0]),
            "loglik_best": self.loglik_best,
            "n_observations": self.n_observations,
            "n_used": self.n_used,
            "n_pruned": self.n_pruned,
            "n_pruned_when_freed": self.n_pruned_when_freed,
            "pruned_fraction": self.pruned_fraction,
            "sensor_mount": None if self.mount is None else self.mount.to_dict(),
            "mount_search": to_json(self.mount_search),
            # how far the likelihood fell on average after the best, per sighting used (checks/lost_signs.unsettled_fit)
            "fall_per_sighting": fall_per_sighting(self.loglik_history, self.best_iteration, self.n_used),
            "seconds": self.seconds,
            # E-steps run, the searches' and the start race's included; the likelihoods that need only the
            # forward pass (a quarter of an E-step's time: the start grid, the searches, SQUAREM's safeguard) apart
            "e_steps": self.e_steps,
            "forward_passes": self.forward_passes,
            "accelerated_steps": self.accelerated,
            "start_search": to_json(self.start_search),
            "freed_at": self.freed_at,
            "stages": [{"stage": name, "from_iteration": it} for name, it in self.stages],
            "ridge": to_json(self.ridge),
            "delay_search": to_json(self.delay_search),
            "restarts": to_json(self.restarts),
            **({"turned_to_face_forward": True} if self.turned_to_face_forward else {}),
            **({"start_moved": to_json(self.start_moved)} if self.start_moved else {}),
            "config": asdict(self.config),
        }
