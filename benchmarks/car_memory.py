"""Peak memory of `sensact learn car` on the simulated 200-s drive, as a user runs it.

    python benchmarks/car_memory.py [--seconds 200] [--log DIR] [--json out.json]

Simulates the drive (or takes ``--log``), runs ``sensact learn car LOG --out ...`` (report included) in a
child process and reads its peak resident memory from the operating system (``RUSAGE_CHILDREN``). Goal
(issue 77): under 1 GB. Printed beside it, measured in the same run: the float32 distances the learner
reads, which the command holds once (the floor), and the capture's size on disk.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
from pathlib import Path

from sensact.app.velodyne_car import simulate_car_log
from sensact.sim.velodyne_car import CarConfig

GOAL_BYTES = 1 << 30


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=200.0, help="length of the simulated drive")
    ap.add_argument("--log", type=Path, default=None, help="an HDL-64E car log folder to run on instead")
    ap.add_argument("--json", type=str, default=None, help="also write the numbers here")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.log
        if folder is None:
            folder = Path(tmp) / "car"
            simulate_car_log(CarConfig(seconds=args.seconds), folder)
        capture = next(folder.glob("velodyne.pcap*"))
        # an HDL-64E packet is a 1264-byte pcap record holding six firings
        firings = capture.stat().st_size // 1264 * 6
        cmd = [sys.executable, "-m", "sensact", "learn", "car", str(folder), "--out", str(Path(tmp) / "out" / "c.json")]
        done = subprocess.run(cmd, capture_output=True, text=True)
        peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024  # kB on Linux
    if done.returncode not in (0, 3):
        sys.exit(f"learn car failed ({done.returncode}): {done.stderr.strip()}")
    distances = firings * 64 * 4
    out = {
        "firings": firings,
        "peak_bytes": peak,
        "goal_bytes": GOAL_BYTES,
        "distances_bytes": distances,
        "capture_bytes": capture.stat().st_size,
        "peak_over_distances": peak / distances,
        "peak_over_goal": peak / GOAL_BYTES,
    }
    print(
        f"learn car, {firings:,} firings: peak {peak / 2**20:,.0f} MiB (goal < {GOAL_BYTES / 2**20:,.0f} MiB; "
        f"{out['peak_over_goal']:.2f} of it); the float32 distances alone {distances / 2**20:,.0f} MiB "
        f"(peak {out['peak_over_distances']:.2f}x), the capture {out['capture_bytes'] / 2**20:,.0f} MiB"
    )
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
