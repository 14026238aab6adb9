"""An action model as a table: the mean velocity of each discrete action (sec. 4.1, eq. 2.28)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from sensact.errors import ModelFormatError
from sensact.models.action_model import CommandLog
from sensact.records import JsonObject


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

    # ---------------------------------------------------------------- the action-model protocol

    zero_mean: ClassVar[tuple[str, ...]] = ()  # a table's velocities are free: the thesis's Aibo side-steps
    delay_steps = 0
    can_delay = False

    @property
    def noise_groups(self) -> int:
        return self.n_actions

    @property
    def parameters(self) -> np.ndarray:
        return self.velocities

    def with_parameters(self, values: np.ndarray) -> ActionTable:
        return self.with_velocities(values)

    def step_velocity(self, data: CommandLog) -> np.ndarray:
        if data.n_actions != self.n_actions:
            raise ValueError(f"the action table has {self.n_actions} actions but the log has {data.n_actions}")
        out = np.zeros((data.n_steps, self.velocities.shape[1]))
        ok = data.actions >= 0
        out[ok] = self.velocities[data.actions[ok]]
        return out

    def update(self, data: CommandLog, disp_mean: np.ndarray, var: np.ndarray, max_delay_steps: int) -> ActionTable:
        """Eq. 4.18 (``var`` and the delay do not enter: each action's velocity is its steps' mean)."""
        return self.with_velocities(table_velocities(disp_mean, data, self.velocities))

    def named_parameters(self) -> dict[str, float]:
        return {
            f"action[{i}].{v}": float(self.velocities[i, j])
            for i in range(self.n_actions)
            for j, v in enumerate(self.velocity_names)
        }

    def linear(self) -> None:
        return None  # velocities per action, no gains

    @property
    def binned_commands(self) -> np.ndarray:
        return self.commands

    def mismatch(self, data: CommandLog) -> tuple[str, str] | None:
        if data.is_continuous or self.n_actions != data.n_actions:
            has = "continuous commands" if data.is_continuous else f"{data.n_actions} actions"
            return f"the model has a table of {self.n_actions} actions and the log {has}", "action"
        if not np.allclose(self.commands, data.action_commands, rtol=1e-9, atol=1e-9):
            # a track log bins its own commands: the same count of actions can mean other commands
            return "the model's actions are other commands than the log's", "action.commands"
        return None

    def form(self) -> list[tuple[str, Any]]:
        return [("action.basis", "table"), ("actions", self.n_actions)]

    def table(self) -> tuple[str, list[str], list[list[str]]]:
        rows = [
            [*(f"{x:.3g}" for x in c), *(f"{x:.4g}" for x in v)]
            for c, v in zip(self.commands, self.velocities, strict=True)
        ]
        return "learned velocity of each action", [*self.command_names, *self.velocity_names], rows

    def to_dict(self) -> JsonObject:
        return {
            "kind": "action_table",
            "command_names": list(self.command_names),
            "velocity_names": list(self.velocity_names),
            "commands": self.commands.tolist(),
            "velocities": self.velocities.tolist(),
        }

    @classmethod
    def from_dict(cls, data: JsonObject, *, source: str = "model") -> ActionTable:
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


def table_velocities(disp_mean: np.ndarray, data: CommandLog, previous: np.ndarray) -> np.ndarray:
    """Eq. 4.18: mu_a is the mean of D(mu_xi,t) over Q(a) = {t : c_t = a}, divided by dt.

    An action that never ran keeps its previous velocity.
    """
    a = data.actions[:-1]
    valid = a >= 0
    counts = np.bincount(a[valid], minlength=data.n_actions).astype(float)
    out = np.array(previous, dtype=float, copy=True)
    seen = counts > 0
    for i in range(out.shape[1]):
        sums = np.bincount(a[valid], weights=disp_mean[valid, i], minlength=data.n_actions)
        out[seen, i] = sums[seen] / counts[seen] / data.dt_s
    return out
