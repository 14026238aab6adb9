"""Speed of chapter 4's EM: one E-step, one full iteration, and the time to convergence.

    python benchmarks/em_speed.py [--repeat 7] [--json out.json]

* One E-step (forward EKF + two-filter smoother + xi) on a 27,000-step log: 15 minutes at 30 Hz, the
  thesis's real-robot run (goal <= 50 ms).
* One full EM iteration (E-step + M-step) on the same log.
* Time to convergence on the simulation setting of sec. 4.4.2 (15 minutes of 0.05 s steps).

Each is printed with the thesis's figure beside it (152 iterations in about 10 minutes on a 2.79 GHz
Pentium 4, i.e. about 3.9 s per iteration; 959 iterations in about an hour in simulation) and, as a
baseline measured in the same run, a plain-Python EKF forward pass (the test suite's reference) timed
on the first 2,000 steps and scaled to the whole log.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

import numpy as np

from sensact.core.geometry import PLANAR
from sensact.learn.em import EMConfig, e_step, fit_em, initial_model, m_step
from sensact.learn.em.stage import HELD
from sensact.sim.field2d import Field2DConfig, simulate_field, to_landmark_log

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from reference_ekf import reference_ekf  # the test suite's reference is the baseline

THESIS_REAL_S_PER_ITERATION = 600.0 / 152
THESIS_SIM_CONVERGENCE_S = 3600.0
THESIS_SIM_ITERATIONS = 959


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=7, help="timed E-steps and iterations; the median is reported")
    ap.add_argument("--json", type=str, default=None, help="also write the numbers here")
    args = ap.parse_args()

    real = to_landmark_log(simulate_field(Field2DConfig.preset("real_robot", seed=0)))
    cfg = EMConfig()
    var = PLANAR.motion_variance(cfg.thesis.motion_sd_mm, cfg.thesis.motion_sd_rad)
    model = initial_model(real, cfg)
    post = e_step(model, real, var)  # compile outside the timing
    rng = np.random.default_rng(0)
    m_step(post, real, model, n_samples=1, floor_var=np.ones(3) * 1e-6, rng=rng, stage=HELD)

    e_times, it_times = [], []
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        post = e_step(model, real, var)
        t1 = time.perf_counter()
        m_step(post, real, model, n_samples=1, floor_var=np.ones(3) * 1e-6, rng=rng, stage=HELD)
        t2 = time.perf_counter()
        e_times.append(t1 - t0)
        it_times.append(t2 - t0)
    e_ms, it_ms = 1e3 * float(np.median(e_times)), 1e3 * float(np.median(it_times))

    base_steps = 2000
    t0 = time.perf_counter()
    reference_ekf(model, real, var, base_steps)
    py_forward_ms = 1e3 * (time.perf_counter() - t0) * real.n_steps / base_steps

    sim = to_landmark_log(simulate_field(Field2DConfig(seed=0)))
    sim_cfg = EMConfig.of(prune_rad_per_step=0.0)
    res = fit_em(sim, initial_model(sim, sim_cfg), sim_cfg)

    out = {
        "machine": f"{platform.processor() or platform.machine()}, {platform.python_version()}",
        "steps": real.n_steps,
        "observations": real.n_observations,
        "estep_ms": e_ms,
        "estep_goal_ms": 50.0,
        "iteration_ms": it_ms,
        "python_forward_pass_ms": py_forward_ms,
        "speedup_vs_python_forward": py_forward_ms / e_ms,
        "thesis_s_per_iteration": THESIS_REAL_S_PER_ITERATION,
        "speedup_vs_thesis_iteration": 1e3 * THESIS_REAL_S_PER_ITERATION / it_ms,
        "sim_convergence_s": res.seconds,
        "sim_iterations": res.iterations,
        "sim_stop_reason": res.stop_reason,
        "thesis_sim_convergence_s": THESIS_SIM_CONVERGENCE_S,
        "thesis_sim_iterations": THESIS_SIM_ITERATIONS,
    }
    print(f"log: {real.n_steps} steps (15 min at 30 Hz), {real.n_observations} observations; {out['machine']}")
    print(
        f"one E-step            {e_ms:8.1f} ms   goal <= 50 ms; a plain-Python forward pass alone: "
        f"{py_forward_ms:,.0f} ms ({out['speedup_vs_python_forward']:.0f}x slower)"
    )
    print(
        f"one EM iteration      {it_ms:8.1f} ms   thesis: about {THESIS_REAL_S_PER_ITERATION:.1f} s "
        f"({out['speedup_vs_thesis_iteration']:.0f}x faster)"
    )
    print(
        f"field2d to converge   {res.seconds:8.1f} s    {res.iterations} iterations ({res.stop_reason}); "
        f"thesis: about {THESIS_SIM_CONVERGENCE_S:.0f} s for {THESIS_SIM_ITERATIONS} iterations"
    )
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(out, fh, indent=2)


if __name__ == "__main__":
    main()
