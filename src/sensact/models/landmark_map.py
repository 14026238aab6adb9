"""The landmark map as a parameter of the model (docs/map.md): where each landmark is, which positions were
given (held) and which EM learned, how sure it is of each, and what fixes the map's frame and scale.

A log with no surveyed map learns one: the path and the map share one rigid frame, fixed by the robot's
start (at the origin, facing REP 103's +x: sensact's heading -pi/2, as its 0 faces +y), unless given
positions fix it; and one scale, which bearings cannot fix, taken from what is metric (``scale``)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sensact.records import JsonObject

SCALES = ("range", "map")  # what is metric: a range channel's unit, or given positions


@dataclass(frozen=True, eq=False)
class LandmarkMap:
    xy: np.ndarray  # (L, 2) mm, in the log's frame; NaN where not placed
    held: np.ndarray  # (L,) bool: given positions, held
    sd: np.ndarray  # (L, 2) mm: each learned position's sd; NaN where held or not placed
    scale: str  # SCALES: what fixes the map's scale
    # (L,) bool: positions the log pins (held, or learned from enough sightings and baseline); the rest EM
    # carries as it must (their sightings are read) but reports as not placed. None: every finite position
    placed: np.ndarray | None = None

    def __post_init__(self) -> None:
        xy = np.asarray(self.xy, dtype=float).reshape(-1, 2)
        held = np.asarray(self.held, dtype=bool).reshape(len(xy))
        sd = np.asarray(self.sd, dtype=float).reshape(len(xy), 2)
        placed = np.isfinite(xy).all(axis=1) if self.placed is None else np.asarray(self.placed, dtype=bool)
        if self.scale not in SCALES:
            raise ValueError(f"map scale must be one of {', '.join(SCALES)}, not {self.scale!r}")
        if not np.isfinite(xy[held]).all():
            raise ValueError("a held landmark needs a finite position")
        for name, v in (("xy", xy), ("held", held), ("sd", sd), ("placed", placed.reshape(len(xy)) | held)):
            object.__setattr__(self, name, v)

    @property
    def learned(self) -> np.ndarray:
        return ~self.held

    @property
    def frame(self) -> str:
        """What fixes the map's frame and scale, in words (``map.frame`` of model.json)."""
        held = int(self.held.sum())
        where = (
            f"{held} given landmark positions (held)"
            if held >= 2
            else "the robot's start (the origin, facing +x in REP 103)"
            + (", and 1 given landmark position (held)" if held else "")
        )
        scale = {
            "range": "the range readings (in mm, their function's slope held at 1 at the middle of its distances)",
            "map": "the given positions",
        }[self.scale]
        return f"frame: {where}; scale: {scale}"

    def to_arrays(self) -> JsonObject:
        """As the model JSON keeps it (``from_arrays`` reads it back); NaN as null."""
        return {
            "xy": [[None if not np.isfinite(v) else float(v) for v in row] for row in self.xy],
            "held": self.held.tolist(),
            "sd": [[None if not np.isfinite(v) else float(v) for v in row] for row in self.sd],
            "scale": self.scale,
            "placed": self.placed.tolist(),
        }

    @classmethod
    def from_arrays(cls, data: JsonObject) -> LandmarkMap:
        def arr(rows: list) -> np.ndarray:
            return np.array([[np.nan if v is None else float(v) for v in row] for row in rows], dtype=float)

        placed = None if data.get("placed") is None else np.asarray(data["placed"], dtype=bool)
        return cls(arr(data["xy"]), np.asarray(data["held"], dtype=bool), arr(data["sd"]), str(data["scale"]), placed)

    def to_dict(self, ids: tuple[str, ...], sightings: np.ndarray | None = None) -> JsonObject:
        """model.json's ``map``: each landmark's position and sd (null where not placed: seen too rarely or
        from too narrow a baseline), whether it was given, and how often it was seen; and ``frame``."""

        def mm(v: float, placed: bool) -> float | None:
            return float(v) if placed and np.isfinite(v) else None

        marks = []
        for i, name in enumerate(ids):
            (x, y), (sx, sy), ok = self.xy[i], self.sd[i], bool(self.placed[i])
            marks.append(
                {
                    "id": name,
                    "x_mm": mm(x, ok),
                    "y_mm": mm(y, ok),
                    "sd_x_mm": mm(sx, ok),
                    "sd_y_mm": mm(sy, ok),
                    "held": bool(self.held[i]),
                    "placed": ok,
                    **({} if sightings is None else {"sightings": int(sightings[i])}),
                }
            )
        return {"landmarks": marks, "frame": self.frame}

    def placed_xy(self) -> np.ndarray:
        """(L, 2) mm: the placed positions, NaN where not placed (what export and scoring read)."""
        return np.where(self.placed[:, None], self.xy, np.nan)
