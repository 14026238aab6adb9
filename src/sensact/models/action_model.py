"""What every action model does for EM (sec. 4.1's ``A``): the protocol the table, the linear model and
the wheel drive (a linear model on wheel speeds) implement. EM's loop, its searches and the uses of a
model reach the action model only through these, so a new family of action model is one new module.
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np

from sensact.records import JsonObject


class CommandLog(Protocol):
    """The part of a log an action model reads: which action or command is in force at each step."""

    dt_s: float
    actions: np.ndarray  # (T,) discrete action index, -1 = none
    action_commands: np.ndarray  # (A, k) the command each discrete action stands for
    command_names: tuple[str, ...]
    step_commands: np.ndarray | None  # (T, k) continuous commands
    n_actions: int
    n_steps: int

    @property
    def is_continuous(self) -> bool: ...


class ActionModel(Protocol):
    command_names: tuple[str, ...]
    velocity_names: tuple[str, ...]  # robot-frame velocities, as the geometry names them
    zero_mean: tuple[str, ...]  # velocity components held at zero mean (a robot that cannot side-step)
    delay_steps: int

    @property
    def noise_groups(self) -> int:
        """How many rows a per-group Sigma_m may have (one per action of a table; 1 = shared only)."""

    @property
    def can_delay(self) -> bool:
        """Whether the M-step may search the command delay."""

    @property
    def parameters(self) -> np.ndarray:
        """The learned array (a table's velocities, a linear model's coefficients)."""

    def with_parameters(self, values: np.ndarray) -> ActionModel: ...

    def step_velocity(self, data: CommandLog) -> np.ndarray:
        """``(T, n)``: the mean robot-frame velocity in force from each step to the next."""

    def update(self, data: CommandLog, disp_mean: np.ndarray, var: np.ndarray, max_delay_steps: int) -> ActionModel:
        """The M-step (eq. 4.18 or its weighted least-squares form) from the smoothed displacements."""

    def named_parameters(self) -> dict[str, float]:
        """Every learned number by a readable name (for error bars and tables)."""

    def linear(self) -> Any:
        """The model as coefficients on features of continuous commands (a ``LinearActionModel``: its gains
        and offsets are what exports and scores read), or None where it is not one (a table of actions)."""

    @property
    def binned_commands(self) -> np.ndarray | None:
        """``(A, k)``: the commands a table's actions stand for, onto which another log's continuous commands
        are binned; None for a model on continuous commands."""

    def mismatch(self, data: CommandLog) -> tuple[str, str] | None:
        """Why this model cannot run on ``data``'s commands, and the model's field that says so; None if it can."""

    def form(self) -> list[tuple[str, Any]]:
        """The config fields that fix this model's form (what a warm start keeps)."""

    def table(self) -> tuple[str, list[str], list[list[str]]]:
        """A title, column names and rows to print the learned model."""

    def to_dict(self) -> JsonObject: ...
