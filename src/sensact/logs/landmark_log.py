"""An in-memory log of a robot among known landmarks: what EM learns from (sec. 4.1).

``actions[t]`` is the discrete action in force from step ``t`` to ``t+1``; a robot driven by continuous
commands has ``step_commands[t]`` instead (and ``actions`` all -1). Each observation row names its step,
its landmark, one value per reading channel (the thesis's single channel is the beacon height; NaN when
a channel did not read) and, planar only, the bearing. ``sensact.io.landmark_folder`` reads
it from a log folder; simulators and experiments build it directly.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from sensact.core.geometry import Geometry, geometry_named
from sensact.reprs import compact_repr


@dataclass(frozen=True, eq=False)
class LandmarkLog:
    __repr__ = compact_repr  # a line, never the arrays
    geometry: Geometry  # or its name, "planar" or "track"
    dt_s: float
    actions: np.ndarray  # (T,) int, index into action_commands; -1 = no discrete action
    action_commands: np.ndarray  # (A, k) attempted command of each action; (0, k) for continuous logs
    command_names: tuple[str, ...]
    obs_step: np.ndarray  # (K,) int, non-decreasing
    obs_landmark: np.ndarray  # (K,) int, index into landmarks_xy
    obs_readings: np.ndarray  # (K, C) or (K,) for one channel (the beacon height)
    obs_bearing_rad: np.ndarray  # (K,) NaN when not measured
    landmarks_xy: np.ndarray  # (L, 2); unused on a track
    landmark_names: tuple[str, ...] = ()
    source: str = ""
    reading_names: tuple[str, ...] = ("height_px",)
    step_commands: np.ndarray | None = None  # (T, k) continuous commands; None = action_commands[actions]
    obs_ptr: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "geometry", geometry_named(self.geometry))
        conv = {
            "actions": np.int64,
            "obs_step": np.int64,
            "obs_landmark": np.int64,
            "action_commands": float,
            "obs_readings": float,
            "obs_bearing_rad": float,
            "landmarks_xy": float,
        }
        for name, dtype in conv.items():
            object.__setattr__(self, name, np.ascontiguousarray(getattr(self, name), dtype=dtype))
        if self.action_commands.ndim == 1:
            object.__setattr__(self, "action_commands", self.action_commands.reshape(-1, len(self.command_names)))
        if self.obs_readings.ndim == 1:
            object.__setattr__(self, "obs_readings", self.obs_readings.reshape(-1, 1))
        object.__setattr__(self, "reading_names", tuple(self.reading_names))
        if self.step_commands is not None:
            sc = np.ascontiguousarray(self.step_commands, dtype=float)
            object.__setattr__(self, "step_commands", sc.reshape(len(self.actions), -1))
        object.__setattr__(self, "landmarks_xy", self.landmarks_xy.reshape(-1, 2))
        T, K = self.actions.size, self.obs_step.size
        problems = []
        if T < 2:
            problems.append("a log needs at least 2 steps")
        if not self.dt_s > 0:
            problems.append("dt_s must be > 0")
        if self.actions.max(initial=-1) >= len(self.action_commands):
            problems.append("an action index is past the action list")
        for name in ("obs_landmark", "obs_bearing_rad"):
            if getattr(self, name).shape != (K,):
                problems.append(f"{name} needs one entry per observation")
        if self.obs_readings.shape != (K, len(self.reading_names)):
            problems.append("obs_readings needs one row per observation and one column per reading name")
        if self.action_commands.shape[1] != len(self.command_names):
            problems.append("one command name per command column")
        if self.step_commands is not None:
            if self.step_commands.shape[1] != len(self.command_names):
                problems.append("step_commands needs one column per command name")
            if not np.all(np.isfinite(self.step_commands)):
                problems.append("step_commands must be finite")
        elif self.n_actions == 0:
            problems.append("a log without discrete actions needs step_commands")
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

    @classmethod
    def continuous_track(
        cls,
        dt_s: float,
        command_names: tuple[str, ...],
        step_commands: np.ndarray,
        obs_step: np.ndarray,
        readings: np.ndarray,
        reading_names: tuple[str, ...],
        source: str = "",
    ) -> LandmarkLog:
        """A 1-D robot's log of continuous commands (the Turtlebot, docs/em-real.md): one wall it ranges to, and
        each observation's readings of its several sensors (NaN where one did not read)."""
        k = len(obs_step)
        return cls(
            "track",
            dt_s,
            np.full(len(step_commands), -1, dtype=np.int64),
            np.zeros((0, len(command_names))),
            command_names,
            obs_step,
            np.zeros(k, dtype=np.int64),
            readings,
            np.full(k, np.nan),
            np.zeros((1, 2)),
            ("wall",),
            source,
            reading_names,
            step_commands,
        )

    @property
    def mode(self) -> int:
        return self.geometry.mode

    @property
    def map_given(self) -> np.ndarray:
        """(L,) bool: landmarks whose position the log gives (a surveyed map); the rest EM learns."""
        return np.isfinite(self.landmarks_xy).all(axis=1)

    def with_landmarks(self, landmarks_xy: np.ndarray) -> LandmarkLog:
        """The same log on another map (EM's learned one)."""
        return replace(self, landmarks_xy=landmarks_xy)

    @property
    def obs_height_px(self) -> np.ndarray:
        """The first reading channel: the thesis's beacon height."""
        return self.obs_readings[:, 0]

    @property
    def is_continuous(self) -> bool:
        return self.step_commands is not None

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

    def keep_sightings(self, keep: np.ndarray) -> LandmarkLog:
        """The same log with only the sightings ``keep`` ((K,) bool) selects."""
        return replace(
            self,
            obs_step=self.obs_step[keep],
            obs_landmark=self.obs_landmark[keep],
            obs_readings=self.obs_readings[keep],
            obs_bearing_rad=self.obs_bearing_rad[keep],
        )

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
            self.obs_readings[keep],
            self.obs_bearing_rad[keep],
            self.landmarks_xy,
            self.landmark_names,
            f"{self.source}[{start}:{stop}]",
            self.reading_names,
            None if self.step_commands is None else self.step_commands[start:stop],
        )
