"""The stages of EM: what the M-step may move in each (its contract, as dynamax's ``props`` say which
parameters a fit may change), and the plan of stages for a fit: what may move is data, not flags threaded
through the loop."""

from __future__ import annotations

from dataclasses import dataclass
from dataclasses import replace as dc_replace

from sensact.learn.em.config import EMConfig
from sensact.learn.em.mount import MountFreedom
from sensact.models.em_model import EMModel

NO_MOUNT = (False, False, False)


@dataclass(frozen=True)
class Stage:
    """What the M-step may move in one stage of EM, and how the E-step reads the readings.
    A stage ends when EM has converged in it, or at iteration ``ends_by``; EM ends with its last."""

    name: str
    motion_noise: bool  # Sigma_m learned (motion_noise is not "fixed")
    bearing_terms: bool  # the channels' bearing terms fitted
    mount: tuple[bool, bool, bool]  # the sensor mount's components moved (forward, left, yaw)
    robust: bool  # the configured robust readings; False: Gaussian ones
    ends_by: int | None = None  # the iteration it ends at, converged or not (None: when converged)
    landmarks: bool = True  # a learned map's free positions moved (docs/map.md; the log's own map never is)

    def with_end(self, ends_by: int) -> Stage:
        return dc_replace(self, ends_by=ends_by)


# Sigma_m as configured, the bearing terms and the mount held, every reading Gaussian
HELD = Stage("held", False, False, NO_MOUNT, False, landmarks=False)


def plan_stages(cfg: EMConfig, model: EMModel, freedom: MountFreedom, spent: int = 0) -> tuple[Stage, ...]:
    """Sigma_m, the bearing terms, the mount and the robust readings are held while EM first settles from a
    poor start, until ``refine_from`` or convergence, then freed: learned from a poor start, they let EM
    settle on a trajectory shifted behind the robot (docs/em-real.md). A start race's ``spent`` held
    iterations count; nothing to hold, ``refine_from`` 0 without a race, or a learned start (warm_start,
    settled already): the free stage alone."""
    free = Stage("free", cfg.motion_noise.kind != "fixed", True, freedom.free, True)
    nothing_held = cfg.search.refine_from <= 0 and spent == 0
    if not holds_anything(cfg, model, freedom) or nothing_held or cfg.search.warm_start:
        return (free,)
    return (HELD.with_end(cfg.search.refine_from - spent), free)


def holds_anything(cfg: EMConfig, model: EMModel, freedom: MountFreedom) -> bool:
    """Whether a held stage would differ from the free one."""
    terms = any(c.bearing_terms for c in model.sensor.channels)
    return cfg.motion_noise.kind != "fixed" or model.sensor.is_robust or terms or freedom.any
