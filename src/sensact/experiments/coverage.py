"""Are `--uncertainty`'s 90 % intervals honest? (docs/uncertainty.md; `sensact reproduce
uncertainty`)

A simulated differential drive with a camera (``DiffDriveConfig``, shortened to ``seconds``) gives the
commands, map and sighting times; the model EM learns on it is the truth. Each of ``sims`` seeded logs is
drawn from that truth (``learn.em.uses.draw_log``), learned by EM from the thesis's poor start as `learn em`
learns it, and given error bars three ways: from the likelihood's curvature, from the sandwich around it
(``uses/information.py``), and by ``replicates`` bootstrap replicates (``uses/error_bars.py``; none with 0).
Per method and parameter family, the share of intervals that hold the true value should be near 90 %: the
bar is 85-95 % (Sigma_m's 85-97 %). The method with more families inside their bars is ``chosen`` (by
coverage, docs/uncertainty.md), and ``coverage`` is its.
Each log is a job of the engine (its replicates run inside it, one after another).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

from sensact.config import config_to_dict
from sensact.engine import Engine, InProcess, Job
from sensact.evaluate.bars import BarCheck
from sensact.learn.em import EMConfig, fit_em
from sensact.learn.em.uses.draw_log import simulate_from_model
from sensact.learn.em.uses.error_bars import FAMILIES, Uncertainty, coverage, f_distances, model_parameters, replicate
from sensact.learn.em.uses.error_bars import summarize as summarize_draws
from sensact.learn.em.uses.information import likelihood_intervals
from sensact.models.em_model import EMModel
from sensact.records import JsonObject
from sensact.sim.diffdrive import DiffDriveConfig, simulate_diffdrive

# each family's 90 % intervals hold the truth 85-95 % of the time; Sigma_m's 85-97 %
COVERAGE_BAR = (0.85, 0.95)
FAMILY_BARS = {"Sigma_m": (0.85, 0.97)}
INFORMATION, SANDWICH, BOOTSTRAP = "observed information", "sandwich", "parametric bootstrap"


@dataclass(frozen=True)
class CoverageExperiment:
    sims: int = 20
    replicates: int = 20
    seed: int = 0
    simulator: DiffDriveConfig = field(default_factory=lambda: DiffDriveConfig(seconds=90.0))


def truth_of(exp: CoverageExperiment) -> tuple[Any, EMModel, EMConfig]:
    """The template log (the simulator's, seed ``exp.seed``), the true model (EM's on it) and the settings."""
    from sensact.presets import simulator_settings

    sim = replace(exp.simulator, seed=exp.seed)
    run = simulate_diffdrive(sim)
    data = run.log(f"simulated {sim.robot_kind}, seed {sim.seed}")
    config = simulator_settings(sim)
    return data, fit_em(data, None, config).model, config


@dataclass(frozen=True)
class Trial:
    """One simulated log's error bars by each method, the true parameters (f read at the same distances)
    and the bootstrap replicates' own parameters (so that any other interval can be judged from the file)."""

    bootstrap: Uncertainty | None  # None: no replicates asked
    information: Uncertainty
    sandwich: Uncertainty | None  # None: a filter failed on a score's difference
    truth: dict[str, float]
    replicates: list[dict[str, float]]


def coverage_trial(
    template: Any, truth: EMModel, config: EMConfig, seed: int, replicates: int, *, progress: Any = None
) -> Trial:
    """One log drawn from ``truth`` (``seed``), learned from the poor start, and given its error bars both ways."""
    drawn, _ = simulate_from_model(truth, template, seed)
    res = fit_em(drawn, None, config)
    f_at = tuple(float(d) for d in f_distances(res.model, drawn, res.posteriors.mean_gamma))
    information, sandwich = likelihood_intervals(
        res.model, drawn, f_at, None if res.mount is None else res.mount.free, sandwich=True
    )
    draws: list[Any] = []
    for b in range(replicates):
        if progress is not None:
            progress(f"coverage log {seed}: replicates", b, replicates)
        try:
            draws.append(replicate(res.model, drawn, config, 10_000 * seed + b, f_at))
        except ValueError as exc:  # EM diverged on the replicate: left out, as `--uncertainty` leaves it
            draws.append(str(exc))
    truth_values = {name: value for name, (_, value) in model_parameters(truth, f_at).items()}
    used = [d for d in draws if not isinstance(d, str)]
    boot = summarize_draws(res.model, draws, f_at, 10_000 * seed) if replicates else None
    return Trial(boot, information, sandwich, truth_values, used)


def _families_in_bar(cov: JsonObject) -> tuple[int, float]:
    """How many families' shares are inside their bars, and (negated) how far outside the rest are."""
    inside, outside = 0, 0.0
    for family in FAMILIES:
        low, high = FAMILY_BARS.get(family, COVERAGE_BAR)
        share = cov[family]["share"]
        if not cov[family]["intervals"]:
            continue
        inside += bool(low <= share <= high)
        outside += max(low - share, share - high, 0.0)
    return inside, -outside


def scorecard(out: JsonObject) -> list[BarCheck]:
    checks = []
    for family in FAMILIES:
        low, high = FAMILY_BARS.get(family, COVERAGE_BAR)
        c = out["coverage"][family]
        if not c["intervals"]:
            continue
        share = c["share"]
        checks.append(
            BarCheck(
                f"coverage.{family}",
                f"{family}: intervals holding the truth",
                f"{100 * low:.0f}-{100 * high:.0f} %",
                f"{100 * share:.1f} % ({c['covered']} of {c['intervals']})",
                bool(low <= share <= high),
            )
        )
    return checks


def run_coverage(
    exp: CoverageExperiment | None = None,
    progress: Callable[[str, int, int | None], None] | None = None,
    engine: Engine | None = None,
) -> JsonObject:
    """``uncertainty.json``: coverage per family over ``exp.sims`` logs, each log's intervals and truths."""
    exp = exp or CoverageExperiment()
    t0 = time.perf_counter()
    template, truth, config = truth_of(exp)
    seeds = [exp.seed + 1 + k for k in range(exp.sims)]
    jobs = [Job(coverage_trial, (template, truth, config, s, exp.replicates), f"log-{s}") for s in seeds]
    done_count = [0]

    def on_done(i: int, _: Any) -> None:
        done_count[0] += 1
        if progress is not None:
            progress("coverage: logs learned and bootstrapped", done_count[0], exp.sims)

    fits: list[Trial] = (engine or InProcess()).run(jobs, on_done=on_done)
    by_method = {INFORMATION: coverage([(t.information, t.truth) for t in fits])}
    by_method[SANDWICH] = coverage([(t.sandwich, t.truth) for t in fits if t.sandwich is not None])
    if exp.replicates:
        by_method[BOOTSTRAP] = coverage([(t.bootstrap, t.truth) for t in fits if t.bootstrap is not None])
    chosen = max(by_method, key=lambda m: _families_in_bar(by_method[m]))  # ties: the likelihood's, seconds a log
    out: JsonObject = {
        "experiment": "uncertainty",
        "coverage": by_method[chosen],
        "chosen": chosen,
        "methods": {m: {"coverage": c} for m, c in by_method.items()},
        "bar": list(COVERAGE_BAR),
        "bars": {family: list(FAMILY_BARS.get(family, COVERAGE_BAR)) for family in FAMILIES},
        "level": 0.9,
        "sims": exp.sims,
        "replicates": exp.replicates,
        "truth": {name: value for name, (_, value) in model_parameters(truth, fits[0].information.f_at_mm).items()},
        "logs": [
            {
                "seed": s,
                "information": t.information.to_dict(),
                "sandwich": None if t.sandwich is None else t.sandwich.to_dict(),
                "uncertainty": None if t.bootstrap is None else t.bootstrap.to_dict(),
                "truth": t.truth,
                "replicates": t.replicates,
            }
            for s, t in zip(seeds, fits, strict=True)
        ],
        "config": {"simulator": config_to_dict(exp.simulator), "learner": config_to_dict(config)},
    }
    out["scorecard"] = [c.to_dict() for c in scorecard(out)]
    out["seconds"] = time.perf_counter() - t0
    return out
