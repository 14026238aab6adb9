"""Issue 106 part 5: why the action model's heading-rate intervals are too narrow (docs/uncertainty.md).

    python benchmarks/noise_split.py [--logs 12] [--seeds 8]

On the truth of `sensact reproduce uncertainty` (a 90-s simulated differential drive with a camera):

1. one drawn log learned with ``--seeds`` EM seeds: the returned parameters' spread over their standard
   error (EM's own randomness);
2. ``--logs`` drawn logs, each learned by the thesis's EM and by the accelerated one: each parameter's
   error over its standard error (mean: bias; spread: how far the intervals hold);
3. on the same logs, the heading-rate coefficients' standard errors at the truth against those at the
   estimate;
4. one M-step of the motion noise from the truth, and the share of its second moments the data give.

Writes ``results/noise_split.json``; takes about 15 minutes on one core.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import replace
from pathlib import Path

import numpy as np

from sensact.experiments.coverage import CoverageExperiment, truth_of
from sensact.io.atomic import write_text
from sensact.learn.em import fit_em
from sensact.learn.em.actions import motion_second_moments
from sensact.learn.em.estep import e_step
from sensact.learn.em.uses.draw_log import simulate_from_model
from sensact.learn.em.uses.error_bars import f_distances, model_parameters
from sensact.learn.em.uses.information import likelihood_intervals

HEADING = ("action.v_theta_rad_s[1]", "action.v_theta_rad_s[v_mm_s]", "action.v_theta_rad_s[omega_rad_s]")


def _intervals(model, log):
    post = e_step(model, log)
    f_at = tuple(float(d) for d in f_distances(model, log, post.mean_gamma))
    info, _ = likelihood_intervals(model, log, f_at, (True, True, True))
    return f_at, {p.name: p.se for p in info.parameters if p.se}


def em_seeds(template, truth, config, n: int) -> dict:
    log, _ = simulate_from_model(truth, template, 1)
    fits = [fit_em(log, None, replace(config, thesis=replace(config.thesis, seed=s))).model for s in range(n)]
    f_at, se = _intervals(fits[0], log)
    values = [{k: v for k, (_, v) in model_parameters(m, f_at).items()} for m in fits]
    return {k: float(np.std([v[k] for v in values], ddof=1) / se[k]) for k in se}


def errors(template, truth, config, logs: int, accelerate: bool) -> dict:
    config = replace(config, accelerate=accelerate)
    out: dict[str, list] = {}
    for s in range(1, logs + 1):
        log, _ = simulate_from_model(truth, template, s)
        model = fit_em(log, None, config).model
        f_at, se = _intervals(model, log)
        true = {k: v for k, (_, v) in model_parameters(truth, f_at).items()}
        est = {k: v for k, (_, v) in model_parameters(model, f_at).items()}
        for k in se:
            out.setdefault(k, []).append([(est[k] - true[k]) / se[k], est[k] - true[k], se[k], true[k]])
        if not accelerate:
            _, se_true = _intervals(truth, log)
            for k in HEADING:
                out.setdefault(f"{k} se at truth", []).append([se_true.get(k, np.nan)])  # None: unbounded there
        print(f"{'accelerated' if accelerate else 'thesis'}: log {s} of {logs}", flush=True)
    return out


def m_step_from_truth(template, truth, logs: int) -> dict:
    rows = []
    for s in range(1, logs + 1):
        log, _ = simulate_from_model(truth, template, s)
        post = e_step(truth, log)
        mean_disp = truth.action.step_velocity(log)[:-1] * log.dt_s
        second = motion_second_moments(post.disp_mean, post.disp_cov, mean_disp)
        spread = np.diagonal(post.disp_cov, axis1=1, axis2=2)
        rows.append((np.sqrt(second.mean(axis=0)), 1 - spread.mean(axis=0) / second.mean(axis=0)))
    sd = np.mean([r[0] for r in rows], axis=0)
    share = np.mean([r[1] for r in rows], axis=0)
    return {"ratio_to_truth": (sd / truth.motion_sd[0]).tolist(), "data_share": share.tolist()}


def summary(errs: dict) -> dict:
    out = {}
    for k, rows in errs.items():
        a = np.asarray(rows, dtype=float)
        if a.shape[1] == 4 and len(a) > 1:
            out[k] = {"logs": len(a), "mean_z": float(a[:, 0].mean()), "sd_z": float(a[:, 0].std(ddof=1))}
            out[k]["mean_relative_error"] = float(np.mean(a[:, 1] / a[:, 3])) if np.all(a[:, 3]) else None
    for k in HEADING:
        if f"{k} se at truth" in errs:
            a, t = np.asarray(errs[k]), np.asarray(errs[f"{k} se at truth"])[:, 0]
            out[k]["se_truth_over_se_estimate"] = float(np.nanmean(t) / a[:, 2].mean())
            out[k]["sd_error_over_se_truth"] = float(a[:, 1].std(ddof=1) / np.nanmean(t))
            out[k]["logs_with_se_at_truth"] = int(np.isfinite(t).sum())
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--logs", type=int, default=12)
    ap.add_argument("--seeds", type=int, default=8)
    args = ap.parse_args()
    template, truth, config = truth_of(CoverageExperiment())
    result = {
        "em_seeds_spread_over_se": em_seeds(template, truth, config, args.seeds),
        "thesis": summary(errors(template, truth, config, args.logs, accelerate=False)),
        "accelerated": summary(errors(template, truth, config, args.logs, accelerate=True)),
        "m_step_from_truth": m_step_from_truth(template, truth, args.logs),
    }
    for name in ("thesis", "accelerated"):
        for k in (*HEADING, "Sigma_m[0].v_theta_rad_s", "sigma.bearing_rad"):
            print(name, k, json.dumps(result[name].get(k)))
    print("EM seeds:", json.dumps({k: round(v, 3) for k, v in result["em_seeds_spread_over_se"].items()}))
    print("M-step from the truth:", json.dumps(result["m_step_from_truth"]))
    out = Path("results") / "noise_split.json"
    out.parent.mkdir(exist_ok=True)
    write_text(out, json.dumps(result, indent=1))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
