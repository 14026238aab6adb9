"""Which of the real-data folder's logs (``app.logs.data_root``) the reproduce commands run."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any


def turtlebot_logs(root: Path) -> list[Path]:
    """Every Turtlebot training log, ``root/turtlebot1d/training*.csv``, in natural order (``training1.csv``
    first, the issue's log, then ``training2.csv``, ...), so that the same command runs on whichever of the
    course's training logs a data folder holds (one without a recorded range is refused by
    ``run_turtlebot_em``). ``calibration.csv`` is not one: it holds one speed, so its gain cannot be
    scored (docs/em-real.md)."""
    base = root / "turtlebot1d"
    if not base.is_dir():
        return []

    def natural(p: Path) -> list[Any]:
        return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", p.name)]

    return sorted((p for p in base.glob("training*.csv") if p.is_file()), key=natural)
