"""``sensact localize`` (and the placing `evaluate log` does): a learned model run over another log with
every parameter held, the E-step alone (``learn/em/uses/place.py``), under the settings it was learned with
and ``--config``/``--set`` over them."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from sensact.app.settings import layered_config
from sensact.learn.em.config import EMConfig
from sensact.learn.em.uses.place import Localized, learned_config, localize
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.em_model import EMModel
from sensact.progress import Progress
from sensact.records import JsonObject


def place_robot(
    doc: JsonObject,
    model: EMModel,
    data: LandmarkLog,
    source: Path,
    config: Path | None = None,
    sets: list[str] | None = None,
    start: Any = None,
    progress: Progress | None = None,
) -> Localized:
    """``model`` (from the model.json ``doc`` at ``source``) placed on ``data``: where the robot started (``start``
    given, else found), the smoothed path and the likelihood, every parameter held."""
    summary = doc.get("summary") or {}
    cfg = layered_config(EMConfig, config, sets, base=learned_config(summary.get("config"), str(source)))
    return localize(model, data, cfg, start, progress)
