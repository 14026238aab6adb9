"""Run by .ci/run in a fresh virtual environment holding sensact's base dependencies only (`pip install .`,
no extras): every module of the package imports, and a small job runs end to end (simulate a short log,
learn it, export it). Prints one closing line, 'N passed, N failed'; exits 1 on any failure.

    python tests/bare_install.py
"""

from __future__ import annotations

import importlib
import pkgutil
import subprocess
import sys
import tempfile
import traceback
from pathlib import Path


def main() -> int:
    import sensact

    passed, failed = 0, []
    for mod in pkgutil.walk_packages(sensact.__path__, "sensact."):
        if mod.name.endswith("__main__"):  # running it is the command itself
            continue
        try:
            importlib.import_module(mod.name)
            passed += 1
        except Exception:
            failed.append(f"import {mod.name}: {traceback.format_exc(limit=1).strip().splitlines()[-1]}")
    sensact_cli = [sys.executable, "-m", "sensact"]
    with tempfile.TemporaryDirectory() as tmp:
        log, model = Path(tmp) / "log", Path(tmp) / "model.json"
        for args in (
            ["--help"],
            ["simulate", "diffdrive", "--seconds", "60", "--seed", "1", "--out", str(log)],
            ["learn", "em", str(log), "--out", str(model)],
            ["export", str(model), "--format", "robot-localization"],
        ):
            run = subprocess.run([*sensact_cli, *args], capture_output=True, text=True)
            if run.returncode in (0, 3):  # 3: written and flagged, a result all the same
                passed += 1
            else:
                failed.append(f"sensact {' '.join(args[:2])}: exit {run.returncode}: {run.stderr.strip()[-500:]}")
        if not model.is_file():
            failed.append("learn em wrote no model")
    for line in failed:
        print(f"FAILED {line}")
    print(f"{passed} passed, {len(failed)} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
