"""An action model as a table: the mean velocity of each discrete action (sec. 4.1, eq. 2.28)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from sensact.errors import ModelFormatError


@dataclass(frozen=True, eq=False)
class ActionTable:
    """``velocities[a]`` is the robot-frame velocity of action ``a``; ``commands[a]`` what was attempted."""

    commands: np.ndarray  # (A, k) attempted command of each action
    velocities: np.ndarray  # (A, n) learned mean velocity, robot frame
    command_names: tuple[str, ...]
    velocity_names: tuple[str, ...]  # with units, e.g. v_x_mm_s

    def __post_init__(self) -> None:
        c = np.atleast_2d(np.asarray(self.commands, dtype=float))
        v = np.atleast_2d(np.asarray(self.velocities, dtype=float))
        if c.shape[0] != v.shape[0]:
            raise ValueError("commands and velocities need one row per action")
        if len(self.command_names) != c.shape[1] or len(self.velocity_names) != v.shape[1]:
            raise ValueError("one name per command and velocity column")
        object.__setattr__(self, "commands", c)
        object.__setattr__(self, "velocities", v)
        object.__setattr__(self, "command_names", tuple(self.command_names))
        object.__setattr__(self, "velocity_names", tuple(self.velocity_names))

    @property
    def n_actions(self) -> int:
        return self.velocities.shape[0]

    def with_velocities(self, velocities: np.ndarray) -> ActionTable:
        return ActionTable(self.commands, np.array(velocities, dtype=float), self.command_names, self.velocity_names)

    def to_dict(self) -> dict[str, Any]:
        return {
            "kind": "action_table",
            "command_names": list(self.command_names),
            "velocity_names": list(self.velocity_names),
            "commands": self.commands.tolist(),
            "velocities": self.velocities.tolist(),
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any], *, source: str = "model") -> ActionTable:
        if not isinstance(data, dict) or data.get("kind") != "action_table":
            raise ModelFormatError(
                "not an action table.", file=source, field="kind", fix="give a model written by `sensact learn em`."
            )
        try:
            return cls(
                np.asarray(data["commands"], dtype=float),
                np.asarray(data["velocities"], dtype=float),
                tuple(data["command_names"]),
                tuple(data["velocity_names"]),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise ModelFormatError(
                f"bad action table ({exc}).",
                file=source,
                field="velocities",
                fix="commands and velocities must be lists of equal-length rows, one per action.",
            ) from None
