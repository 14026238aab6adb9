"""An in-memory log of a robot among known landmarks: what EM learns from (sec. 4.1).

``actions[t]`` is the discrete action in force from step ``t`` to ``t+1``; each observation row names its
step, its landmark, the beacon height and (planar only) the bearing. ``sensact.io.landmark_log`` reads
it from a log folder; simulators and experiments build it directly.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from sensact.core.pose_models import PLANAR, TRACK


@dataclass(frozen=True, eq=False)
class LandmarkLog:
    geometry: str  # "planar" or "track"
    dt_s: float
    actions: np.ndarray  # (T,) int, index into action_commands; -1 = no motion
    action_commands: np.ndarray  # (A, k) attempted command of each action
    command_names: tuple[str, ...]
    obs_step: np.ndarray  # (K,) int, non-decreasing
    obs_landmark: np.ndarray  # (K,) int, index into landmarks_xy
    obs_height_px: np.ndarray  # (K,)
    obs_bearing_rad: np.ndarray  # (K,) NaN when not measured
    landmarks_xy: np.ndarray  # (L, 2); unused on a track
    landmark_names: tuple[str, ...] = ()
    source: str = ""
    obs_ptr: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        if self.geometry not in ("planar", "track"):
            raise ValueError("geometry must be 'planar' or 'track'")
        conv = {
            "actions": np.int64,
            "obs_step": np.int64,
            "obs_landmark": np.int64,
            "action_commands": float,
            "obs_height_px": float,
            "obs_bearing_rad": float,
            "landmarks_xy": float,
        }
        for name, dtype in conv.items():
            object.__setattr__(self, name, np.ascontiguousarray(getattr(self, name), dtype=dtype))
        object.__setattr__(self, "action_commands", np.atleast_2d(self.action_commands))
        object.__setattr__(self, "landmarks_xy", self.landmarks_xy.reshape(-1, 2))
        T, K = self.actions.size, self.obs_step.size
        problems = []
        if T < 2:
            problems.append("a log needs at least 2 steps")
        if not self.dt_s > 0:
            problems.append("dt_s must be > 0")
        if self.actions.max(initial=-1) >= len(self.action_commands):
            problems.append("an action index is past the action list")
        for name in ("obs_landmark", "obs_height_px", "obs_bearing_rad"):
            if getattr(self, name).shape != (K,):
                problems.append(f"{name} needs one entry per observation")
        if K and (self.obs_step.min() < 0 or self.obs_step.max() >= T or np.any(np.diff(self.obs_step) < 0)):
            problems.append("obs_step must be sorted step indices within the log")
        if K and (self.obs_landmark.min() < 0 or self.obs_landmark.max() >= max(1, len(self.landmarks_xy))):
            problems.append("obs_landmark must index landmarks_xy")
        if problems:
            raise ValueError("; ".join(problems))
        object.__setattr__(self, "obs_ptr", np.searchsorted(self.obs_step, np.arange(T + 1)).astype(np.int64))

    @classmethod
    def track(
        cls,
        dt_s: float,
        actions: np.ndarray,
        action_commands: np.ndarray,
        command_name: str,
        obs_step: np.ndarray,
        heights_px: np.ndarray,
        source: str = "",
    ) -> LandmarkLog:
        """A 1-D log: one beacon, heights only (sec. 4.4.3)."""
        k = len(obs_step)
        return cls(
            "track",
            dt_s,
            actions,
            np.asarray(action_commands, dtype=float).reshape(-1, 1),
            (command_name,),
            obs_step,
            np.zeros(k, dtype=np.int64),
            heights_px,
            np.full(k, np.nan),
            np.zeros((1, 2)),
            ("beacon",),
            source,
        )

    @property
    def mode(self) -> int:
        return PLANAR if self.geometry == "planar" else TRACK

    @property
    def n_steps(self) -> int:
        return int(self.actions.size)

    @property
    def n_observations(self) -> int:
        return int(self.obs_step.size)

    @property
    def n_actions(self) -> int:
        return len(self.action_commands)

    @property
    def duration_s(self) -> float:
        return (self.n_steps - 1) * self.dt_s

    def slice_steps(self, start: int, stop: int) -> LandmarkLog:
        """The steps ``start:stop`` as a log of their own (for learning each half of a run)."""
        keep = (self.obs_step >= start) & (self.obs_step < stop)
        return LandmarkLog(
            self.geometry,
            self.dt_s,
            self.actions[start:stop],
            self.action_commands,
            self.command_names,
            self.obs_step[keep] - start,
            self.obs_landmark[keep],
            self.obs_height_px[keep],
            self.obs_bearing_rad[keep],
            self.landmarks_xy,
            self.landmark_names,
            f"{self.source}[{start}:{stop}]",
        )
