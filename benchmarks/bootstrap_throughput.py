"""Throughput of the chapter-3 learner on a one-hour simulated log (72,000 steps at 20 Hz).

    python benchmarks/bootstrap_throughput.py [--hours 1] [--repeat 5] [--json out.json]

Reports steps per second on the compiled batch path (goal >= 1,000,000) and microseconds per
``update()`` on the streaming path (goal <= 10), each as a ratio against the streaming path measured
in the same run and against the thesis's real-time rate: Algorithm 1 ran at the camera's ~20 Hz on the
Aibo's 576 MHz processor (sec. 3.3.2).
"""

from __future__ import annotations

import argparse
import json
import platform
import time

import numpy as np

from sensact.learn.bootstrap import BootstrapConfig, BootstrapLearner, Normalization, learn_bootstrap
from sensact.sim.track1d import Track1DConfig, simulate_track

THESIS_STEPS_PER_S = 20.0  # "processed as they were received, at a frequency of roughly 20 Hz"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", type=float, default=1.0, help="length of the simulated log")
    ap.add_argument("--repeat", type=int, default=5, help="timed runs; the best is reported")
    ap.add_argument("--json", type=str, default=None, help="also write the numbers here")
    args = ap.parse_args()

    run = simulate_track(Track1DConfig(seconds=3600.0 * args.hours, seed=0))
    t, c, o = run.times_s, run.commands_mm_s, run.heights_px
    T = len(t)
    cfg = BootstrapConfig()
    norm = Normalization.from_data(c, o, cfg)
    learn_bootstrap(t[:200], c[:200], o[:200], cfg, normalization=norm)  # compile outside the timing

    batch = []
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        res = learn_bootstrap(t, c, o, cfg, normalization=norm)
        batch.append(time.perf_counter() - t0)
    assert res.status == "ok"
    batch_steps_s = T / min(batch)

    obs = [None if np.isnan(v) else float(v) for v in o]
    tl, cl = t.tolist(), c.tolist()
    stream = []
    for _ in range(max(1, args.repeat // 2)):
        learner = BootstrapLearner(cfg, normalization=norm)
        update = learner.update
        t0 = time.perf_counter()
        for k in range(T):
            update(tl[k], cl[k], obs[k])
        stream.append(time.perf_counter() - t0)
    assert learner.result().sensor.coef == res.sensor.coef  # the two paths agree bit for bit
    us_per_update = 1e6 * min(stream) / T
    stream_steps_s = 1e6 / us_per_update

    rows = [
        (
            "batch path",
            f"{batch_steps_s:,.0f} steps/s",
            ">= 1,000,000",
            batch_steps_s / stream_steps_s,
            batch_steps_s / THESIS_STEPS_PER_S,
        ),
        ("streaming update()", f"{us_per_update:.2f} µs/update", "<= 10 µs", 1.0, stream_steps_s / THESIS_STEPS_PER_S),
    ]
    cpu = platform.processor() or platform.machine()
    print(f"Algorithm 1 on a {args.hours:g} h log ({T:,} steps), best of {args.repeat}; {cpu}")
    print(f"{'path':<20}{'measured':>22}{'goal':>16}{'× streaming':>14}{'× thesis (20 Hz)':>20}")
    for name, meas, goal, vs_stream, vs_thesis in rows:
        print(f"{name:<20}{meas:>22}{goal:>16}{vs_stream:>14.1f}{vs_thesis:>20,.0f}")
    print("thesis: real time at ~20 Hz on the Aibo's 576 MHz processor (sec. 3.3.2)")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(
                {
                    "steps": T,
                    "batch_steps_per_s": batch_steps_s,
                    "stream_us_per_update": us_per_update,
                    "thesis_steps_per_s": THESIS_STEPS_PER_S,
                },
                fh,
                indent=2,
            )


if __name__ == "__main__":
    main()
