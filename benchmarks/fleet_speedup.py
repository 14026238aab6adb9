"""`sensact fleet learn` on a 2-worker LocalCluster against `sensact learn em` one log after another
(issues 76 and 94): MRCLAM Dataset 6's robots, both in this process, one after the other, at the same
threads (issue 94's bar: 4 logs, 2 workers of one thread each, against the 4 one after another on one
thread: SENSACT_THREADS=1 here, --threads-per-worker 1 there).

    python benchmarks/fleet_speedup.py [--data ../shared/data] [--workers 2] [--threads 1] [--robots 1 2 3 4]
        [--out fleet_speedup.json]

Converts each robot (`sensact convert mrclam`), then runs `sensact learn em rK --out serial/rK/model.json`
for each robot in turn, and `sensact fleet learn r1 ... r5 --out fleet --workers N --no-cross-scores`.
Prints both wall times and their ratio, whether every model file is the same (its `summary.seconds`
aside), and the two things that bound the ratio on a machine of two cores: how many cores `learn em`
kept busy on its own (this process's CPU seconds over its wall seconds: the start race runs its trials in
threads, one per core, and numpy's BLAS has threads of its own), and how much longer each log's EM took
in the fleet, two at once, than alone (its `summary.seconds`, fleet over serial).
"""

from __future__ import annotations

import os
import sys

# the serial runs at the workers' threads: numpy's BLAS reads its count when it is first imported, below
_THREADS = sys.argv[sys.argv.index("--threads") + 1] if "--threads" in sys.argv else "1"
for _name in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS", "SENSACT_THREADS"):
    os.environ[_name] = _THREADS

import argparse  # noqa: E402
import json  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

from typer.testing import CliRunner  # noqa: E402

from sensact.cli import app  # noqa: E402


def _run(args: list) -> tuple[float, float]:
    """Wall and CPU seconds (this process and the threads it started) of one command."""
    w0, c0 = time.perf_counter(), time.process_time()
    res = CliRunner().invoke(app, [str(a) for a in args])
    if res.exit_code != 0:
        raise SystemExit(res.output)
    return time.perf_counter() - w0, time.process_time() - c0


def _model(path: Path) -> dict:
    doc = json.loads(path.read_text())
    doc["summary"].pop("seconds")  # EM's own timing: the one field that may differ
    return doc


def _em_seconds(path: Path) -> float:
    return float(json.loads(path.read_text())["summary"]["seconds"])


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[2] / "shared" / "data")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--robots", type=int, nargs="+", default=[1, 2, 3, 4])
    p.add_argument("--threads", type=int, default=1, help="threads of each worker, and of the serial runs")
    p.add_argument("--out", type=Path, default=None, help="write the numbers as JSON here")
    args = p.parse_args()
    dataset = args.data / "mrclam" / "MRCLAM_Dataset6"
    if not dataset.is_dir():
        raise SystemExit(f"{dataset}: not found; pass --data with the shared data folder")
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        logs = [root / f"r{k}" for k in args.robots]
        names = [log.name for log in logs]
        for k, log in zip(args.robots, logs, strict=True):
            _run(["convert", "mrclam", dataset, "--robot", k, "--out", log])
        serial_wall = serial_cpu = 0.0
        per_log = {}
        for log in logs:
            wall, cpu = _run(["learn", "em", log, "--out", root / "serial" / log.name / "model.json"])
            per_log[log.name] = {"wall_s": wall, "cores_busy": cpu / wall}
            serial_wall, serial_cpu = serial_wall + wall, serial_cpu + cpu
        fleet_args = ["--workers", args.workers, "--threads-per-worker", args.threads, "--no-cross-scores"]
        fleet_wall, _ = _run(["fleet", "learn", *logs, "--out", root / "fleet", *fleet_args])
        printed = json.loads((root / "fleet" / "fleet.json").read_text())
        slower = {
            g: _em_seconds(root / "fleet" / g / "model.json") / _em_seconds(root / "serial" / g / "model.json")
            for g in names
        }
        same = {
            g: _model(root / "serial" / g / "model.json") == _model(root / "fleet" / g / "model.json") for g in names
        }
    cores = serial_cpu / serial_wall
    result = {
        "robots": [f"r{k}" for k in args.robots],
        "workers": args.workers,
        "threads_per_worker": args.threads,
        "cpu_count": os.cpu_count(),
        "serial_wall_s": serial_wall,
        "fleet_wall_s": fleet_wall,
        "speedup": serial_wall / fleet_wall,
        "speedup_bar": 1.7,
        "models_identical": same,
        "serial_cores_busy": cores,
        "em_seconds_fleet_over_alone": slower,
        "per_log": per_log,
        "fleet_printed": {k: printed[k] for k in ("seconds", "jobs_seconds", "cpu_seconds", "speedup_at_most")},
    }
    print(f"learn em one after another: {serial_wall:.1f} s, {cores:.2f} cores busy on average")
    print(f"fleet learn on {args.workers} workers: {fleet_wall:.1f} s")
    print(f"speedup {result['speedup']:.2f}x (bar 1.7x)")
    fp = result["fleet_printed"]
    print(f"fleet learn's own line: wall {fp['seconds']:.1f} s, jobs {fp['jobs_seconds']:.1f} s, ", end="")
    print(f"speedup at most {fp['speedup_at_most']:.2f}")
    print(
        "each log's EM in the fleet took "
        + ", ".join(f"{g} {v:.2f}" for g, v in slower.items())
        + " times as long as alone (two at once on this machine's cores)"
    )
    print("models identical to learn em's: " + ", ".join(f"{k} {'yes' if v else 'NO'}" for k, v in same.items()))
    if args.out is not None:
        args.out.write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
