"""A continuous-command action model, linear in its parameters: ``A(c) = Phi(c) beta``.

Beyond the thesis, whose robots had 40 discrete actions (sec. 4.1): a real robot is commanded with
continuous velocities. The basis ``Phi`` is chosen by name:

* ``affine``: ``(1, c_1, ..., c_k)``;
* ``cross``: affine plus every product ``c_i c_j`` (i < j), so a turn can change the forward speed;
* ``polynomial``: every monomial of total degree ``<= degree``.

A real robot's motion also lags its commands; ``delay_steps`` makes step ``t`` move by
``A(c_{t - delay})`` (0, the thesis's assumption, by default).

``zero_mean`` names velocity components whose mean is held at zero: a differential-drive robot cannot
move sideways, and a free lateral column would let EM explain sensor error as sideways motion (Sigma_m
still allows some). The thesis's Aibo could side-step, so nothing is held by default.

``inputs`` restricts which commands a velocity component may depend on: ``"v_y_mm_s:v_mm_s"`` fits the
forward speed from the forward command alone (its constant always stays). A differential drive's forward
speed is the wheels' mean and its turn rate their difference, so a turn command moves the axle's centre
forward only through a wheel mismatch, a few mm/s per rad/s for a 0.25-m axle. Left free, that column
lets EM track a point off the axle: the point is carried forward or back as the robot turns (MRCLAM
robot 4 learned 117 mm/s per rad/s; its Vicon-derived value is 0.9). Components not named use every
command. A bracketed sum or difference of commands is one input, for the affine basis: on wheel speeds
``"v_theta_rad_s:(right_mm_s-left_mm_s)"`` lets the turn rate depend on the wheels' difference alone, as
``"v_theta_rad_s:omega_rad_s"`` does on (v, omega), whatever the axle's length (the fitted coefficients
of the two wheels are equal and opposite).

The discrete action table is the same model with a one-hot basis (``one_hot``), which is how the
M-step's weighted least squares reduces to eq. 4.18.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, replace
from itertools import combinations_with_replacement
from typing import Any

import numpy as np

from sensact.errors import ModelFormatError
from sensact.limits import MAX_STEPS
from sensact.models.action_model import CommandLog
from sensact.models.linear_action_fit import delayed, fits_by_delay
from sensact.records import JsonObject

BASES = ("affine", "cross", "polynomial")


def monomials(basis: str, k: int, degree: int) -> list[tuple[int, ...]]:
    """Each feature as the tuple of command indices it multiplies (``()`` is the constant)."""
    if basis == "affine":
        return [()] + [(i,) for i in range(k)]
    if basis == "cross":
        return [()] + [(i,) for i in range(k)] + [(i, j) for i in range(k) for j in range(i + 1, k)]
    if basis == "polynomial":
        return [m for d in range(degree + 1) for m in combinations_with_replacement(range(k), d)]
    raise ValueError(f"basis must be one of {BASES}, not {basis!r}")


def command_features(basis: str, degree: int, commands: np.ndarray) -> np.ndarray:
    """``Phi(c)`` for each row of ``commands`` (T, k): shape (T, n_features)."""
    c = np.atleast_2d(np.asarray(commands, dtype=float))
    cols = [np.prod(c[:, list(m)], axis=1) if m else np.ones(len(c)) for m in monomials(basis, c.shape[1], degree)]
    return np.column_stack(cols)


def one_hot(actions: np.ndarray, n_actions: int) -> np.ndarray:
    """The discrete table's basis: row t is e_{a_t} (all zero where no action ran)."""
    a = np.asarray(actions)
    out = np.zeros((a.size, n_actions))
    ok = a >= 0
    out[np.flatnonzero(ok), a[ok]] = 1.0
    return out


def _terms(text: str) -> list[str]:
    """``text`` split at each ``+`` outside brackets."""
    terms, depth, start = [], 0, 0
    for k, ch in enumerate(text):
        depth += (ch == "(") - (ch == ")")
        if ch == "+" and depth == 0:
            terms.append(text[start:k])
            start = k + 1
    return [t.strip() for t in [*terms, text[start:]] if t.strip()]


def _term_weights(entry: str, term: str, command_names: tuple[str, ...]) -> np.ndarray:
    """One input as weights over the commands: a command's name, or ``(a-b+c)`` with unit weights."""
    inner = term[1:-1] if term.startswith("(") and term.endswith(")") else None
    signed = [("+", term)] if inner is None else re.findall(r"([+-]?)\s*([^+\-\s()]+)", inner)
    weights = np.zeros(len(command_names))
    for sign, name in signed:
        if name not in command_names:
            hint = f"; a combined input is bracketed, as ({name})" if inner is None and "-" in name else ""
            raise ValueError(f"inputs entry {entry!r} names {name!r}, not one of {list(command_names)}{hint}")
        weights[command_names.index(name)] += -1.0 if sign == "-" else 1.0
    if inner is not None and (
        not weights.any() or "".join(s + n for s, n in signed).lstrip("+") != inner.replace(" ", "")
    ):
        raise ValueError(f"inputs entry {entry!r}: write a combined input as (command-command) or (command+command)")
    return weights


def parse_inputs(
    inputs: tuple[str, ...], command_names: tuple[str, ...], velocity_names: tuple[str, ...]
) -> dict[str, list[np.ndarray]]:
    """``{velocity: each input it may use, as weights over the commands}`` from
    ``("velocity:input+input", ...)``, an input being a command or a bracketed sum or difference."""
    out: dict[str, list[np.ndarray]] = {}
    for entry in inputs:
        velocity, sep, rest = str(entry).partition(":")
        if not sep or velocity.strip() not in velocity_names or velocity.strip() in out:
            raise ValueError(
                f"inputs entry {entry!r} must be 'velocity:command+command' with one of {list(velocity_names)}, "
                "each velocity named once"
            )
        out[velocity.strip()] = [_term_weights(entry, t, command_names) for t in _terms(rest)]
    return out


def _is_command(weights: np.ndarray) -> bool:
    return int(np.count_nonzero(weights)) == 1 and float(weights.sum()) == 1.0


def feature_names(basis: str, degree: int, command_names: tuple[str, ...]) -> list[str]:
    return ["*".join(command_names[i] for i in m) or "1" for m in monomials(basis, len(command_names), degree)]


@dataclass(frozen=True, eq=False)
class LinearActionModel:
    basis: str
    degree: int  # used by the polynomial basis
    coefficients: np.ndarray  # (n_features, n): beta
    command_names: tuple[str, ...]
    velocity_names: tuple[str, ...]
    delay_steps: int = 0  # the command in force at step t acts from step t + delay_steps
    zero_mean: tuple[str, ...] = ()  # velocity components whose mean is held at 0 (no sideways motion)
    inputs: tuple[str, ...] = ()  # "velocity:command+command": the only commands that velocity depends on

    def __post_init__(self) -> None:
        object.__setattr__(self, "zero_mean", tuple(self.zero_mean))
        object.__setattr__(self, "inputs", tuple(self.inputs))
        unknown = [v for v in self.zero_mean if v not in self.velocity_names]
        if unknown:
            raise ValueError(f"zero_mean names {unknown[0]!r}, not one of {list(self.velocity_names)}")
        allowed = parse_inputs(self.inputs, tuple(self.command_names), tuple(self.velocity_names))
        combined = any(not _is_command(w) for terms in allowed.values() for w in terms)
        if combined and self.basis != "affine":
            raise ValueError(f"a combined input such as (a-b) needs the affine action basis, not {self.basis!r}")
        if not 0 <= self.delay_steps <= MAX_STEPS:
            raise ValueError(f"delay_steps must be 0 to {MAX_STEPS} (given {self.delay_steps})")
        beta = np.atleast_2d(np.asarray(self.coefficients, dtype=float))
        if not np.all(np.isfinite(beta)):
            raise ValueError("the action coefficients must be finite numbers")
        object.__setattr__(self, "coefficients", beta)
        object.__setattr__(self, "command_names", tuple(self.command_names))
        object.__setattr__(self, "velocity_names", tuple(self.velocity_names))
        if self.basis == "polynomial" and self.degree < 1:
            raise ValueError("a polynomial action basis needs degree >= 1")
        nf = len(monomials(self.basis, len(self.command_names), self.degree))
        if beta.shape != (nf, len(self.velocity_names)):
            raise ValueError(f"coefficients must be ({nf}, {len(self.velocity_names)}) for this basis")

    @classmethod
    def zero(cls, basis: str, degree: int, command_names, velocity_names, zero_mean=(), inputs=()) -> LinearActionModel:
        """The thesis's starting point (sec. 4.4.1): no command has any effect."""
        nf = len(monomials(basis, len(command_names), degree))
        beta = np.zeros((nf, len(velocity_names)))
        return cls(basis, degree, beta, command_names, velocity_names, 0, zero_mean, inputs)

    @property
    def free_coefficients(self) -> np.ndarray:
        """(n_features, n) bool: the coefficients the M-step fits; the rest stay zero (``zero_mean``
        components have none, an ``inputs`` restriction drops the features of other commands)."""
        allowed = parse_inputs(self.inputs, self.command_names, self.velocity_names)
        monos = monomials(self.basis, len(self.command_names), self.degree)
        free = np.ones((len(monos), len(self.velocity_names)), dtype=bool)
        combined = self.combined_inputs
        for i, v in enumerate(self.velocity_names):
            if v in self.zero_mean:
                free[:, i] = False
            elif i in combined:
                free[:, i] = combined[i].any(axis=1)
            elif v in allowed:
                used = {int(np.flatnonzero(w)[0]) for w in allowed[v]}
                free[:, i] = [all(c in used for c in m) for m in monos]
        return free

    @property
    def combined_inputs(self) -> dict[int, np.ndarray]:
        """``{component: P}`` for each velocity restricted to a combined input such as ``(a-b)``: its
        coefficients are ``P theta``, the affine basis's constant and one column per input (the M-step
        fits ``theta``); other components are described by ``free_coefficients`` alone."""
        allowed = parse_inputs(self.inputs, self.command_names, self.velocity_names)
        out: dict[int, np.ndarray] = {}
        for i, v in enumerate(self.velocity_names):
            terms = allowed.get(v, [])
            if v in self.zero_mean or all(_is_command(w) for w in terms):
                continue
            P = np.zeros((1 + len(self.command_names), 1 + len(terms)))
            P[0, 0] = 1.0  # the constant always stays
            for k, w in enumerate(terms):
                P[1:, 1 + k] = w
            out[i] = P
        return out

    def features(self, commands: np.ndarray) -> np.ndarray:
        return command_features(self.basis, self.degree, commands)

    def step_features(self, step_commands: np.ndarray, delay_steps: int | None = None) -> np.ndarray:
        """``Phi`` of the command acting at each step of a log, after the delay (the first command
        stands in before it)."""
        return self.features(delayed(step_commands, self.delay_steps if delay_steps is None else delay_steps))

    def with_coefficients(self, beta: np.ndarray, delay_steps: int | None = None) -> LinearActionModel:
        delay = self.delay_steps if delay_steps is None else delay_steps
        return replace(self, coefficients=beta, delay_steps=delay)

    # ---------------------------------------------------------------- the action-model protocol

    noise_groups = 1  # Sigma_m is shared: the commands are continuous
    can_delay = True

    @property
    def parameters(self) -> np.ndarray:
        return self.coefficients

    def with_parameters(self, values: np.ndarray) -> LinearActionModel:
        return self.with_coefficients(values)

    def step_velocity(self, data: CommandLog) -> np.ndarray:
        if data.step_commands is None:
            raise ValueError("a continuous action model needs a log with per-step commands")
        return self.step_features(data.step_commands) @ self.coefficients

    def update(
        self, data: CommandLog, disp_mean: np.ndarray, var: np.ndarray, max_delay_steps: int
    ) -> LinearActionModel:
        """The M-step of ``A(c) = Phi(c) beta`` with its command delay: for each delay in
        ``0..max_delay_steps`` the weighted least-squares beta, and of those the pair with the least
        weighted squared error (the same expected log-likelihood, maximized over a discrete parameter too)."""
        delays = list(range(max_delay_steps + 1)) if max_delay_steps > 0 else [self.delay_steps]
        Phi0 = self.step_features(data.step_commands, 0)
        free, combined = self.free_coefficients, self.combined_inputs
        fits = fits_by_delay(Phi0, disp_mean, var, data.dt_s, self.coefficients, free, delays, combined)
        best = min(range(len(fits)), key=lambda k: fits[k][0])  # the first of equals, as a strict < keeps
        return self.with_coefficients(fits[best][1], delays[best])

    def named_parameters(self) -> dict[str, float]:
        return {
            f"action.{v}[{feature}]": float(self.coefficients[i, j])
            for i, feature in enumerate(feature_names(self.basis, self.degree, self.command_names))
            for j, v in enumerate(self.velocity_names)
        }

    def linear(self) -> LinearActionModel:
        return self

    @property
    def binned_commands(self) -> None:
        return None  # continuous commands, read as they are

    def mismatch(self, data: CommandLog) -> tuple[str, str] | None:
        if tuple(self.command_names) == tuple(data.command_names):
            return None
        return (
            f"the model's commands are {', '.join(self.command_names)} and the log's "
            f"{', '.join(data.command_names) or 'discrete actions'}",
            "action.command_names",
        )

    def form(self) -> list[tuple[str, Any]]:
        return [
            ("action.basis", self.basis),
            ("action.degree", self.degree if self.basis == "polynomial" else None),
            ("action.zero_mean", tuple(self.zero_mean)),
            ("action.inputs", tuple(self.inputs)),
        ]

    def table(self) -> tuple[str, list[str], list[list[str]]]:
        rows = [
            [fname, *(f"{x:.4g}" for x in row)]
            for fname, row in zip(
                feature_names(self.basis, self.degree, self.command_names), self.coefficients, strict=True
            )
        ]
        title = f"learned A(c) = Phi(c) beta ({self.basis}; delay {self.delay_steps} steps)"
        return title, ["feature", *self.velocity_names], rows

    def to_dict(self) -> JsonObject:
        return {
            "kind": "linear_action_model",
            "basis": self.basis,
            "degree": self.degree,
            "command_names": list(self.command_names),
            "velocity_names": list(self.velocity_names),
            "feature_names": feature_names(self.basis, self.degree, self.command_names),
            "coefficients": self.coefficients.tolist(),
            "delay_steps": self.delay_steps,
            "zero_mean": list(self.zero_mean),
            "inputs": list(self.inputs),
        }

    @classmethod
    def from_dict(cls, data: JsonObject, *, source: str = "model") -> LinearActionModel:
        for key in ("degree", "delay_steps"):  # counts: a fraction is no model's (2.5 steps of delay)
            v = data.get(key, 0)
            if isinstance(v, bool) or not (isinstance(v, int) or (isinstance(v, float) and v.is_integer())):
                raise ModelFormatError(
                    f"{key} is {v!r}, not a whole number.",
                    file=source,
                    field=f"action.{key}",
                    fix="rewrite it with `sensact learn em`.",
                )
        try:
            return cls(
                str(data["basis"]),
                int(data.get("degree", 1)),
                np.asarray(data["coefficients"], dtype=float),
                tuple(data["command_names"]),
                tuple(data["velocity_names"]),
                int(data.get("delay_steps", 0)),
                tuple(data.get("zero_mean", ())),
                tuple(data.get("inputs", ())),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise ModelFormatError(
                f"bad linear action model ({exc}).",
                file=source,
                field="coefficients",
                fix="one row per basis feature and one column per velocity; rewrite it with `sensact learn em`.",
            ) from None
