"""Where the real-data folder is: ``$SENSACT_DATA``, else ``../shared/data`` from the working directory."""

from __future__ import annotations

import os
from pathlib import Path


def data_root() -> Path:
    env = os.environ.get("SENSACT_DATA")
    return Path(env) if env else Path("..") / "shared" / "data"
