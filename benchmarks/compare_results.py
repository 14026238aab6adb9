"""Compare every JSON under two results folders, value for value but timings: the proof a refactor owes
(DESIGN.md's rule: compare every ``reproduce`` JSON and the real-data models before and after).

    python benchmarks/compare_results.py BEFORE_DIR AFTER_DIR

Keys naming seconds, elapsed or wall time are left out; every other key and value must be equal. Prints
each file that differs with its first differences, then a count; exits 1 when any differs.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

TIMING = ("seconds", "elapsed", "wall", "cpu_s", "time_s_taken")


def without_timings(x: Any) -> Any:
    if isinstance(x, dict):
        return {k: without_timings(v) for k, v in x.items() if not any(t in k.lower() for t in TIMING)}
    if isinstance(x, list):
        return [without_timings(v) for v in x]
    return x


def differences(a: Any, b: Any, path: str = "") -> list[str]:
    if type(a) is not type(b):
        return [f"{path}: {type(a).__name__} vs {type(b).__name__}"]
    if isinstance(a, dict):
        out = []
        for k in sorted(set(a) | set(b)):
            if k not in a or k not in b:
                out.append(f"{path}.{k}: only {'after' if k not in a else 'before'}")
            else:
                out += differences(a[k], b[k], f"{path}.{k}")
        return out
    if isinstance(a, list):
        if len(a) != len(b):
            return [f"{path}: length {len(a)} vs {len(b)}"]
        return [d for i, (x, y) in enumerate(zip(a, b, strict=True)) for d in differences(x, y, f"{path}[{i}]")]
    return [] if a == b else [f"{path}: {a!r} vs {b!r}"]


def main() -> int:
    before, after = Path(sys.argv[1]), Path(sys.argv[2])
    files = sorted(p.relative_to(before) for p in before.rglob("*.json"))
    bad = 0
    for rel in files:
        if not (after / rel).exists():
            print(f"{rel}: missing after")
            bad += 1
            continue
        a, b = (without_timings(json.loads((d / rel).read_text())) for d in (before, after))
        found = differences(a, b)
        if found:
            bad += 1
            print(f"{rel}: {len(found)} differences, e.g. {found[:3]}")
    print(f"{len(files)} JSON files compared, {bad} differ")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
