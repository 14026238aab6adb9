"""EM speed on one real robot: MRCLAM Dataset 6, robot 3 (about 27,000 steps at 1/30 s).

    python benchmarks/em_real_speed.py [--robot N]

Prints the time of one E-step, of one full EM iteration and of the whole fit to convergence (goal: <= 30 s),
with the configuration `sensact reproduce real` uses, and how much of it the start search and race took.
Needs ../shared/data/mrclam (or $SENSACT_DATA).
"""

from __future__ import annotations

import argparse
import platform
import sys
import time

import numpy as np

from sensact.experiments.real import mrclam_folder
from sensact.io.mrclam import read_mrclam
from sensact.learn.em import e_step, fit_em, initial_model, m_step
from sensact.learn.em.stage import NO_MOUNT, Stage
from sensact.presets import mrclam_config


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", type=int, default=3, help="MRCLAM robot 1-5")
    args = parser.parse_args()
    folder = mrclam_folder()
    if not folder.is_dir():
        sys.exit(f"MRCLAM data not found at {folder}; set SENSACT_DATA")
    ml = read_mrclam(folder, args.robot)
    data = ml.data
    cfg = mrclam_config()
    model = initial_model(data, cfg)
    post = e_step(model, data)  # compile outside the timing
    rng = np.random.default_rng(0)
    kw = dict(
        n_samples=1,
        floor_var=np.ones(3) * 1e-6,
        rng=rng,
        stage=Stage("free", True, True, NO_MOUNT, True),
        motion_floor_sd=np.array([0.05, 0.05, 5e-4]),
        max_delay_steps=15,
    )
    m_step(post, data, model, **kw)
    e_times, it_times = [], []
    for _ in range(5):
        t0 = time.perf_counter()
        post = e_step(model, data)
        t1 = time.perf_counter()
        m_step(post, data, model, **kw)
        t2 = time.perf_counter()
        e_times.append(t1 - t0)
        it_times.append(t2 - t0)
    t0 = time.perf_counter()
    res = fit_em(data, None, cfg)
    total = time.perf_counter() - t0
    print(f"log: {ml.summary_line()}; {platform.machine()}, {platform.python_version()}")
    print(f"one E-step            {1000 * min(e_times):6.1f} ms")
    print(f"one EM iteration      {1000 * min(it_times):6.1f} ms   (with the 16 command delays tried)")
    race = res.start_search.race.winner_iterations if res.start_search and res.start_search.race else 0
    print(
        f"whole fit             {total:6.1f} s    {res.iterations} iterations ({res.stop_reason}) after the start "
        f"race's {race}; goal <= 30 s"
    )
    print(f"  of which start      {total - res.seconds:6.1f} s    the start search and race (their trials in threads)")


if __name__ == "__main__":
    main()
