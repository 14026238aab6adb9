"""EM started from a learned model instead of sec. 4.4.1's poor guess (beyond the thesis; only when asked).

The thesis starts EM from a model that knows nothing: the robot does not move and f is a poor line. A
robot of a fleet, or the same robot after a change (a new floor, a remounted camera), has a model close
to its own already: one learned on a sibling, or before the change. Started there, EM needs no start
race: the model places the robot on the new log by the E-step alone (``uses/place.localize``, as
`sensact localize` does), and EM learns on from that start and those parameters, with nothing held
(``EMConfig.warm_start``).

The M-step keeps a model's families (the action basis, each channel's degree, window and robust
readings: ``mstep.py`` fits each channel in its previous form), so the model must be of the families the
config describes; a model of others is refused, naming the first setting that differs.
"""

from __future__ import annotations

from typing import Any

from sensact.errors import ConfigError
from sensact.learn.em.config import EMConfig
from sensact.learn.em.initial import initial_model
from sensact.learn.em.uses.place import Localized, localize
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.em_model import EMModel
from sensact.progress import Progress


def families(model: EMModel) -> list[tuple[str, Any]]:
    """What the M-step keeps of ``model``, each under the config field that sets it: the geometry, the
    action model's form, each channel's form, the bearing's and Sigma_m's."""
    out: list[tuple[str, Any]] = [("geometry", model.geometry)]
    out += model.action.form()
    s = model.sensor
    out.append(("channels", tuple(c.name for c in s.channels)))
    for c in s.channels:
        out += [
            (f"channels: {c.name}: degree", c.function.degree),
            (f"channels: {c.name}: valid_min", c.valid_min),
            (f"channels: {c.name}: valid_max", c.valid_max),
            (f"channels: {c.name}: robust", c.robust),
            (f"channels: {c.name}: robust_param", c.robust_param if c.robust != "none" else None),
            (f"channels: {c.name}: bearing_degree", len(c.bearing_terms)),
        ]
    bearing = s.reads_bearing
    out += [
        ("bearing", "read" if bearing else "none"),
        ("robust.bearing", s.bearing_robust if bearing else None),
        ("robust.bearing_param", s.bearing_robust_param if bearing and s.bearing_robust != "none" else None),
        ("robust.joint_student_t", s.joint_student_t),
        (
            "motion_noise.kind",
            "per_action" if model.per_action_noise else "turning" if model.turn_var is not None else "shared",
        ),
    ]
    return out


def refuse_other_families(model: EMModel, fresh: EMModel, source: str) -> None:
    """``model`` (the start) against ``fresh`` (the config's own starting model): the first family that
    differs is one line naming its config field."""
    for (field, have), (_, want) in zip(families(model), families(fresh), strict=False):
        if have != want:
            raise ConfigError(
                f"the start model has {field} {have!r} and the settings {want!r}; EM keeps a model's families, "
                "so it cannot learn the settings' from this start.",
                file=source,
                field=field,
                fix="learn with the settings the start model was learned with (drop the --config or --set that "
                "changes it), or learn from the thesis's start (without --start-from).",
            )


def start_from_model(
    model: EMModel,
    data: LandmarkLog,
    config: EMConfig,
    progress: Progress | None = None,
    *,
    source: str = "model",
) -> tuple[Localized, EMConfig]:
    """``model`` placed on ``data`` (``localize``: the start found by the model, held), and the config EM
    then runs with from ``Localized.model``: ``warm_start``, so that nothing is held (the model has
    settled: holding Sigma_m and reading Gaussian again would undo what it learned) and the start is not
    searched for again."""
    refuse_other_families(model, initial_model(data, config), source)
    placed = localize(model, data, config, progress=progress)
    return placed, config.replace(warm_start=True)
