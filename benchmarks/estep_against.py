"""This tree's E-step against a git revision's: the same posteriors?, its speed and its first compile, as ratios.

    python benchmarks/estep_against.py REV [--runs 40] [--compiles 3] [--json out.json]

Both E-steps run on the 27,000-step log of ``em_speed.py`` (15 minutes at 30 Hz), each in a child process
of its own: REV's from ``git archive REV src``, this tree's from ``src``. This machine's timings drift by
a third between minutes, so the two are timed in turns, one E-step each, and only their ratio is
reported (median and minimum of ``--runs`` turns). The first compile is measured the same way: ``--compiles``
pairs of fresh children, each with an empty numba cache, the CPU seconds of the first E-step less a
warm one's. The posteriors (alpha, gamma, the displacement moments under xi, the weights, the
likelihood) are compared bit for bit.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tarfile
import tempfile
from io import BytesIO
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]

WORKER = r"""
import json, sys, time
import numpy as np
import sensact
from sensact.core.geometry import PLANAR
from sensact.learn.em import EMConfig, e_step, initial_model
from sensact.sim.field2d import Field2DConfig, simulate_field, to_landmark_log

log = to_landmark_log(simulate_field(Field2DConfig.preset("real_robot", seed=0)))
cfg = EMConfig()
var = PLANAR.motion_variance(cfg.thesis.motion_sd_mm, cfg.thesis.motion_sd_rad)
model = initial_model(log, cfg)
t0 = time.process_time()
e_step(model, log, var)
first = time.process_time() - t0
t0 = time.process_time()
post = e_step(model, log, var)
print(json.dumps({"source": sensact.__file__, "compile_s": first - (time.process_time() - t0)}), flush=True)
for line in sys.stdin:
    cmd = line.split()
    if cmd[0] == "run":
        t0 = time.perf_counter()
        e_step(model, log, var)
        print(time.perf_counter() - t0, flush=True)
    elif cmd[0] == "save":
        fields = ("mean_alpha", "cov_alpha", "mean_gamma", "cov_gamma", "disp_mean", "disp_cov", "weights")
        np.savez(cmd[1], loglik=post.loglik, **{f: getattr(post, f) for f in fields})
        print("saved", flush=True)
"""


class Worker:
    """One child process holding a log and a model, running an E-step on each request."""

    def __init__(self, src: Path, cache: Path) -> None:
        env = os.environ | {"PYTHONPATH": str(src), "NUMBA_CACHE_DIR": str(cache)}
        self.proc = subprocess.Popen(
            [sys.executable, "-c", WORKER], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env
        )
        first = json.loads(self._line())
        if not first["source"].startswith(str(src)):
            sys.exit(f"the child imported sensact from {first['source']}, not from {src}")
        self.compile_s = float(first["compile_s"])

    def _line(self) -> str:
        line = self.proc.stdout.readline()
        if not line:
            sys.exit(f"a child failed (exit {self.proc.wait()}); run it by hand to see why")
        return line.strip()

    def ask(self, command: str) -> str:
        self.proc.stdin.write(command + "\n")
        self.proc.stdin.flush()
        return self._line()

    def close(self) -> None:
        self.proc.stdin.close()
        self.proc.wait()


def export_source(rev: str, into: Path) -> Path:
    """``src`` as it was at ``rev``, unpacked under ``into``."""
    done = subprocess.run(["git", "-C", str(REPO), "archive", rev, "src"], capture_output=True, check=False)
    if done.returncode != 0:
        sys.exit(f"git archive {rev} failed: {done.stderr.decode().strip()}")
    with tarfile.open(fileobj=BytesIO(done.stdout)) as tar:
        tar.extractall(into, filter="data")
    return into / "src"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("rev", help="the git revision to compare with, e.g. 10f298e")
    ap.add_argument("--runs", type=int, default=40, help="timed E-steps of each, in turns")
    ap.add_argument("--compiles", type=int, default=3, help="fresh-cache first runs of each, in turns")
    ap.add_argument("--json", type=str, default=None, help="also write the numbers here")
    args = ap.parse_args()

    with tempfile.TemporaryDirectory() as tmp_dir:
        tmp = Path(tmp_dir)
        sources = {"rev": export_source(args.rev, tmp / "rev"), "tree": REPO / "src"}
        compiles: dict[str, list[float]] = {"rev": [], "tree": []}
        workers: dict[str, Worker] = {}
        for i in range(args.compiles):
            for name, src in sources.items():
                if name in workers:
                    workers[name].close()
                workers[name] = Worker(src, tmp / f"cache-{name}-{i}")
                compiles[name].append(workers[name].compile_s)
        times: dict[str, list[float]] = {"rev": [], "tree": []}
        for _ in range(args.runs):
            for name, worker in workers.items():
                times[name].append(float(worker.ask("run")))
        for name, worker in workers.items():
            worker.ask(f"save {tmp / name}.npz")
            worker.close()
        old, new = np.load(tmp / "rev.npz"), np.load(tmp / "tree.npz")
        differing = [k for k in old.files if not np.array_equal(old[k], new[k], equal_nan=True)]

    out = {
        "rev": args.rev,
        "identical": not differing,
        "differing": differing,
        "estep_ms": {k: 1e3 * float(np.median(v)) for k, v in times.items()},
        "speed_ratio_median": float(np.median(times["tree"]) / np.median(times["rev"])),
        "speed_ratio_min": float(min(times["tree"]) / min(times["rev"])),
        "compile_s": {k: float(np.median(v)) for k, v in compiles.items()},
        "compile_ratio": float(np.median(compiles["tree"]) / np.median(compiles["rev"])),
    }
    print(
        f"posteriors {'bit for bit the same' if not differing else 'differ in ' + ', '.join(differing)} as {args.rev}'s"
    )
    print(
        f"E-step      {out['estep_ms']['tree']:6.1f} ms against {out['estep_ms']['rev']:6.1f} ms: "
        f"{out['speed_ratio_median']:.2f}x (median of {args.runs} in turns), {out['speed_ratio_min']:.2f}x (minimum)"
    )
    print(
        f"first compile {out['compile_s']['tree']:5.1f} s against {out['compile_s']['rev']:5.1f} s of CPU: "
        f"{out['compile_ratio']:.2f}x (median of {args.compiles} fresh caches each)"
    )
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
