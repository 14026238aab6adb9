"""What each command's result JSON is, as stamped beside ``sensact_version``: a command's ``--out`` replaces
an existing file only when it is a sensact output of the same kind (``--force`` overrides), so that a user's
own file, or another command's result, is never lost to a mistyped path."""

from __future__ import annotations

import json
from pathlib import Path

OUTPUT_KEY = "sensact_output"
EM_MODEL = "em model"  # learn em (and fleet learn's models, monitor --relearn)
BOOTSTRAP_MODEL = "bootstrap model"  # learn bootstrap
CAR_MODEL = "car model"  # learn car
LOCALIZATION = "localization"  # localize
EVALUATION = "evaluation"  # evaluate mrclam, evaluate log
FLEET_EVALUATION = "fleet evaluation"  # evaluate fleet
MONITOR = "monitor result"  # monitor


def is_output_of(path: Path, kind: str) -> bool:
    """Whether ``path`` is a JSON that sensact wrote as ``kind`` (one from before outputs named their kind
    counts as any kind)."""
    try:
        doc = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError, RecursionError):
        return False
    return isinstance(doc, dict) and "sensact_version" in doc and doc.get(OUTPUT_KEY, kind) == kind
