"""The learned parameters as one vector (``LearnedSpace``): the space ``uses/information.py`` takes the
likelihood's curvature in, and ``fixed_point.py`` measures EM's steps in."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from sensact.learn.em.estep import log_likelihood, sighting_logliks
from sensact.learn.em.squarem import Coordinates
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.em_model import EMModel

HELD_BLOCKS = ("prior.log_diag", "prior.low")  # the start's covariance, at its floor


@dataclass(frozen=True, eq=False)
class LearnedSpace:
    """The model's learned parameters as one vector ``p`` about ``model`` (``Coordinates``'s layout, the
    action model by its free coefficients, the held entries left out); ``labels`` names each entry's
    block."""

    coords: Coordinates
    base: np.ndarray  # the model's whole coordinate vector
    free: np.ndarray  # (len(base),) bool: the entries ``p`` holds (the action block replaced by beta)
    labels: tuple[str, ...]  # each entry of ``p``: its block's name
    n_beta: int
    data: LandmarkLog
    # the log-likelihood a point is scored by (None: the forward pass's on every sighting, eq. 4.14)
    score: Callable[[EMModel], float] | None = None

    @classmethod
    def about(
        cls,
        model: EMModel,
        data: LandmarkLog,
        mount_free: tuple[bool, bool, bool] | None,
        score: Callable[[EMModel], float] | None = None,
    ) -> LearnedSpace:
        beta = np.asarray(model.action.parameters, dtype=float).ravel()
        moving = beta != 0.0  # a coefficient the action model holds is exactly zero (zero_mean, inputs)
        coords = Coordinates.about(model, data, moving)
        free, labels = [], [f"action.{k}" for k in np.flatnonzero(moving)]
        for name, part in coords.blocks(model):
            keep = np.full(part.size, name not in HELD_BLOCKS and name != "action")
            if name == "mount":
                keep[:] = (False, False, False) if mount_free is None else mount_free
            free.append(keep if name != "action" else np.zeros(part.size, dtype=bool))
            labels += [name] * int(keep.sum())
        return cls(coords, coords.vector(model), np.concatenate(free), tuple(labels), int(moving.sum()), data, score)

    @property
    def p0(self) -> np.ndarray:
        return np.concatenate([self.beta(self.coords.template), self.base[self.free]])

    def beta(self, model: EMModel) -> np.ndarray:
        return np.asarray(model.action.parameters, dtype=float).ravel()[self.coords.moving]

    def p_of(self, model: EMModel) -> np.ndarray:
        """``model``'s entries of ``p`` (a model of the template's shape: the same channels, blocks and map)."""
        return np.concatenate([self.beta(model), self.coords.vector(model)[self.free]])

    def model(self, p: np.ndarray) -> EMModel:
        x = self.base.copy()
        x[self.free] = p[self.n_beta :]
        x[: self.coords.velocity_map.shape[0]] = self.coords.velocity_map @ p[: self.n_beta]
        return self.coords.model(x)

    def contributions(self, p: np.ndarray) -> np.ndarray | None:
        """Each sighting's share of the likelihood at ``p`` (every sighting read; None where no model or the
        filter fails)."""
        try:
            return sighting_logliks(self.model(p), self.data)
        except ValueError:
            return None

    def loglik(self, p: np.ndarray) -> float:
        try:
            model = self.model(p)
            return log_likelihood(model, self.data) if self.score is None else self.score(model)
        except ValueError:  # no valid model there
            return -math.inf
