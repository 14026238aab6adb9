"""A learned landmark map scored against a survey (docs/map.md; evaluation only, never learned from).

The learned map and path share one rigid frame, which the robot's start fixes; the survey has its own.
``rigid_alignment`` finds the rotation and translation (no scale: the scale must come out right) that
best lay the placed learned positions on the surveyed ones (least squares, Kabsch/Umeyama without the
scale), and ``map_scores`` reports the RMS distance after it; the path is scored after the same
alignment. ``similarity_alignment`` frees the scale too: the map's ``scale`` against the survey, its RMS
and the path's median after it say how much of the error is the map's size alone."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sensact.records import JsonObject

SEEN_ENOUGH = 20  # sightings: a landmark seen this often must be placed (docs/map.md's bar)


@dataclass(frozen=True)
class RigidAlignment:
    rotation_rad: float  # counterclockwise
    translation_mm: np.ndarray  # (2,)

    @property
    def matrix(self) -> np.ndarray:
        c, s = np.cos(self.rotation_rad), np.sin(self.rotation_rad)
        return np.array([[c, -s], [s, c]])

    def points(self, xy: np.ndarray) -> np.ndarray:
        return np.asarray(xy, dtype=float) @ self.matrix.T + self.translation_mm

    def poses(self, poses: np.ndarray) -> np.ndarray:
        """(T, 3) poses in the learned frame -> the survey's (a rotation turns every heading alike)."""
        out = np.array(poses, dtype=float, copy=True)
        out[:, :2] = self.points(out[:, :2])
        out[:, 2] += self.rotation_rad
        return out


@dataclass(frozen=True)
class SimilarityAlignment(RigidAlignment):
    """A rigid alignment that also scales: ``surveyed = scale R learned + t``."""

    scale: float = 1.0

    @property
    def matrix(self) -> np.ndarray:
        return self.scale * super().matrix


def similarity_alignment(learned: np.ndarray, surveyed: np.ndarray) -> SimilarityAlignment | None:
    """``rigid_alignment`` with the scale free as well (Umeyama 1991): what the learned map's shape is
    worth apart from its size, and that size against the survey's; None as ``rigid_alignment``."""
    fit = rigid_alignment(learned, surveyed)
    if fit is None:
        return None
    ok = np.isfinite(learned).all(axis=1) & np.isfinite(surveyed).all(axis=1)
    a, b = learned[ok], surveyed[ok]
    ca, cb = a.mean(axis=0), b.mean(axis=0)
    turned = (a - ca) @ fit.matrix.T
    spread = float(np.sum(turned**2))
    if not spread > 0:
        return None
    scale = float(np.sum(turned * (b - cb)) / spread)  # the least-squares scale once turned
    return SimilarityAlignment(fit.rotation_rad, cb - scale * fit.matrix @ ca, scale)


def rigid_alignment(learned: np.ndarray, surveyed: np.ndarray) -> RigidAlignment | None:
    """The rotation and translation laying ``learned`` on ``surveyed`` ((L, 2) each, NaN rows skipped)
    in least squares; None with fewer than two landmarks in both."""
    ok = np.isfinite(learned).all(axis=1) & np.isfinite(surveyed).all(axis=1)
    if ok.sum() < 2:
        return None
    a, b = learned[ok], surveyed[ok]
    ca, cb = a.mean(axis=0), b.mean(axis=0)
    h = (a - ca).T @ (b - cb)  # cross-covariance; the best rotation maximizes trace(R h)
    angle = float(np.arctan2(h[0, 1] - h[1, 0], h[0, 0] + h[1, 1]))
    c, s = np.cos(angle), np.sin(angle)
    return RigidAlignment(angle, cb - np.array([[c, -s], [s, c]]) @ ca)


def map_scores(
    learned_xy: np.ndarray, surveyed: np.ndarray, sightings: np.ndarray
) -> tuple[JsonObject, RigidAlignment | None]:
    """``evaluation.map``: ``rms_mm`` after the best rigid alignment, ``landmarks_placed`` of
    ``landmarks_total`` (the surveyed ones), and how many seen ``SEEN_ENOUGH`` times or more were not
    placed; and the alignment, for the path."""
    surveyed_rows = np.isfinite(surveyed).all(axis=1)
    placed = np.isfinite(learned_xy).all(axis=1) & surveyed_rows
    fit = rigid_alignment(learned_xy, surveyed)
    rms = float("nan")
    if fit is not None:
        err = fit.points(learned_xy[placed]) - surveyed[placed]
        rms = float(np.sqrt(np.mean(np.sum(err**2, axis=1))))
    seen = np.asarray(sightings) >= SEEN_ENOUGH
    similar = similarity_alignment(learned_xy, surveyed)
    similar_rms, scale = float("nan"), float("nan")
    if similar is not None:
        err = similar.points(learned_xy[placed]) - surveyed[placed]
        similar_rms, scale = float(np.sqrt(np.mean(np.sum(err**2, axis=1)))), 1.0 / similar.scale
    return {
        "rms_mm": rms,
        # the learned map's size over the survey's (1.02: 2 % too large), and its RMS with that taken out
        "scale": scale,
        "similarity_rms_mm": similar_rms,
        "landmarks_placed": int(placed.sum()),
        "landmarks_total": int(surveyed_rows.sum()),
        "seen_enough_not_placed": int((seen & surveyed_rows & ~placed).sum()),
        "alignment": None
        if fit is None
        else {"rotation_rad": fit.rotation_rad, "translation_mm": fit.translation_mm.tolist()},
    }, fit
