"""Fit health (docs/errors.md): a result that is degenerate or unfinished is written, flagged in its JSON
(``health``), and ends the command with exit code 3 (``errors.EXIT_FLAGGED``), never reported as a success.

Each learner names its own checks (``learn/em/checks/fit_health.py``, ``learn/bootstrap.py``,
``learn/velodyne_car_dynamics.py``); a flag is a code a script can test and one line a person can read.
"""

from __future__ import annotations

from dataclasses import dataclass

from sensact.records import JsonObject

# shared by every learner whose models explain readings (EM's fit_health, Algorithm 1's bootstrap_health)
MIN_EXPLAINED = 0.05  # 1 - residual variance / readings' variance below this: the model explains (almost) nothing
MIN_READINGS = 20  # a channel with fewer readings is not judged


@dataclass(frozen=True)
class HealthFlag:
    code: str  # e.g. "not_converged", "sigma_collapsed", "reading_constant"
    message: str  # one line: what is wrong and what to do


@dataclass(frozen=True)
class Health:
    flags: tuple[HealthFlag, ...] = ()

    @property
    def ok(self) -> bool:
        return not self.flags

    def to_dict(self) -> JsonObject:
        return {"ok": self.ok, "flags": [{"code": f.code, "message": f.message} for f in self.flags]}

    @classmethod
    def of(cls, *flags: HealthFlag | None) -> Health:
        return cls(tuple(f for f in flags if f is not None))


def _learned_flags(doc: JsonObject) -> list[JsonObject]:
    node = doc.get("health")
    flags = node.get("flags") if isinstance(node, dict) else None
    return [f for f in flags if isinstance(f, dict)] if isinstance(flags, list) else []


def learned_flag_codes(doc: JsonObject) -> tuple[str, ...]:
    """The codes of the flags a model.json was written with (none in a file that predates them)."""
    return tuple(str(f.get("code")) for f in _learned_flags(doc))


def learned_health(doc: JsonObject) -> Health:
    """What a model.json says of its own fit (``health``, as the learner wrote it; none in a file that predates
    it), kept as flags: a path placed or a change tested with a flagged model is as doubtful as the model."""
    return Health.of(
        *(
            HealthFlag(
                "model_flagged",
                f"the model was flagged when it was learned ({f.get('code')}: "
                f"{str(f.get('message')).rstrip('.')}); what it gives here is as doubtful.",
            )
            for f in _learned_flags(doc)
        )
    )


def filter_failed(ok: bool, what: str) -> HealthFlag | None:
    """The flag of an E-step whose covariances lost positive definiteness (``what``: what not to trust)."""
    if ok:
        return None
    return HealthFlag("filter_failed", f"the Kalman filter lost positive definiteness: {what} is not to be trusted.")
