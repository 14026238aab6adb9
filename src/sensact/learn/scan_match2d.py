"""Point-to-line ICP between two planar scans (Censi's PLICP, 2008, in its plainest form), for the 2-D
lidar's calibration (docs/lidar2d.md).

Why not KISS-ICP (the ``kiss`` extra): it registers 3-D points point to point against a voxel map; a
planar scan leaves its z, roll and pitch unconstrained, and point to point on beams a degree apart is
biased by the beams' spacing, which is the size of the mount offsets to be learned. Point to line on the
reference scan's own surfaces has no such bias, and with scipy's k-d tree it is a few lines of numpy.

A pose is ``(x_mm, y_mm, theta)``: the current scan's frame in the reference scan's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

GATE_MM = (400.0, 80.0)  # correspondences farther apart than this are not one surface: first, last iteration
MIN_POINTS = 40


@dataclass(frozen=True, eq=False)
class Reference:
    """A scan's points with the normal of the surface through each (points with no clear surface dropped)."""

    xy: np.ndarray
    normals: np.ndarray
    tree: cKDTree


@dataclass(frozen=True)
class Match:
    pose: np.ndarray  # (3,) the current scan's frame in the reference's
    rms_mm: float  # point-to-line, of the pairs kept
    used: int  # pairs kept at the end
    ok: bool


def scan_xy(ranges_mm: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """(beams, 2) points in the scan's frame, NaN where no return."""
    return np.column_stack([ranges_mm * np.cos(angles), ranges_mm * np.sin(angles)])


def reference_of(xy: np.ndarray, increment_rad: float) -> Reference | None:
    """The surfaces of one scan: each point's normal from its two neighbours in beam order, kept where the three
    lie on one surface (their spacing no more than a grazing beam's, the middle one on the chord)."""
    prev, nxt = np.roll(xy, 1, axis=0), np.roll(xy, -1, axis=0)
    chord = nxt - prev
    length = np.hypot(chord[:, 0], chord[:, 1])
    r = np.hypot(xy[:, 0], xy[:, 1])
    gap = 2 * (10 * r * increment_rad + 20.0)  # two spacings of a beam at 84 degrees' incidence
    with np.errstate(invalid="ignore", divide="ignore"):
        normal = np.column_stack([-chord[:, 1], chord[:, 0]]) / length[:, None]
        off_chord = np.abs(np.sum((xy - prev) * normal, axis=1))
        ok = np.isfinite(length) & np.isfinite(r) & (length < gap) & (length > 0) & (off_chord < 0.05 * length + 30.0)
    ok[[0, -1]] &= increment_rad * xy.shape[0] > 2 * np.pi - 2 * increment_rad  # neighbours across the ends
    if ok.sum() < MIN_POINTS:
        return None
    return Reference(xy[ok], normal[ok], cKDTree(xy[ok]))


def _rot(th: float) -> np.ndarray:
    c, s = np.cos(th), np.sin(th)
    return np.array([[c, -s], [s, c]])


def icp(ref: Reference, cur: np.ndarray, guess: np.ndarray, iterations: int = 40) -> Match:
    """The pose that lays ``cur`` (finite points, the current scan's frame) on ``ref``'s surfaces, from
    ``guess``: Gauss-Newton on point-to-line distances, Huber-weighted, each pair from the nearest
    reference point within a gate that narrows from 400 to 80 mm."""
    pose = np.asarray(guess, dtype=float).copy()
    rms, used = np.inf, 0
    for it in range(iterations):
        gate = GATE_MM[0] + (GATE_MM[1] - GATE_MM[0]) * min(1.0, it / 8)
        p = cur @ _rot(pose[2]).T + pose[:2]
        d, j = ref.tree.query(p, distance_upper_bound=gate)
        m = np.isfinite(d)
        used = int(m.sum())
        if used < MIN_POINTS:
            return Match(pose, np.inf, used, False)
        pm, n = p[m], ref.normals[j[m]]
        e = np.sum(n * (pm - ref.xy[j[m]]), axis=1)
        scale = max(1.4826 * float(np.median(np.abs(e))), 3.0)
        w = np.minimum(1.0, 2.5 * scale / np.maximum(np.abs(e), 1e-12))  # Huber
        A = np.column_stack([n, n[:, 1] * pm[:, 0] - n[:, 0] * pm[:, 1]])
        H = (A * w[:, None]).T @ A
        try:
            delta = -np.linalg.solve(H, (A * w[:, None]).T @ e)
        except np.linalg.LinAlgError:
            return Match(pose, np.inf, used, False)
        R = _rot(delta[2])
        pose = np.array([*(R @ pose[:2] + delta[:2]), pose[2] + delta[2]])
        rms = float(np.sqrt(np.sum(w * e**2) / np.sum(w)))
        if it >= 8 and abs(delta[0]) + abs(delta[1]) < 0.01 and abs(delta[2]) < 1e-5:
            break
    return Match(pose, rms, used, used >= max(MIN_POINTS, 0.3 * cur.shape[0]))
