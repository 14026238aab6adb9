"""Progress a person can read: EM's end projected from its convergence rate (not max_iterations), no count
over its total, the count and ETA whole at 80 columns, and one overall line for several experiments."""

from __future__ import annotations

import io
import math
import re

from rich.console import Console

from sensact.cli.base import ProgressRows, progress_bar
from sensact.learn.em.progress import TOL, ConvergenceEta


def test_the_projection_finds_where_a_linearly_converging_fit_stops():
    """best_k = L - c r^k: its best stops moving (gain below TOL) at a known k; EM ends patience later."""
    c, r, patience = 200.0, 0.93, 50
    k_stop = math.ceil(math.log(TOL * (1 - r) / (c * (1 - r) * r)) / math.log(r))  # gain c(1-r) r^(k-1) < TOL
    eta = ConvergenceEta()
    projections = [eta.total(k, -c * r**k, 0, patience, 5000) for k in range(40)]
    assert all(p > k + 1 for k, p in enumerate(projections))  # never a count over its total
    assert abs(projections[-1] - (k_stop + patience)) <= 0.15 * (k_stop + patience), (projections[-1], k_stop)


def test_a_plateau_ends_patience_iterations_after_the_last_best_and_the_cap_holds():
    eta = ConvergenceEta()
    for k in range(30):
        eta.total(k, -100.0 + k, 0, 50, 5000)
    assert eta.total(30, -70.0, 10, 50, 5000) == 31 + 40
    assert ConvergenceEta().total(0, 0.0, 0, 50, 20) == 20  # max_iterations caps it


class _Bar:
    """rich's Progress as ProgressRows drives it, recorded."""

    def __init__(self):
        from rich.progress import Progress

        self.p = Progress(disable=True)

    def __getattr__(self, name):
        return getattr(self.p, name)


def test_no_count_over_its_total():
    """A race with a total, then EM under the same label with none: rich keeps an old total on update, so
    EM gets a row of its own (diffdrive showed 322/11); an estimate that falls short is raised to the count."""
    bar = _Bar()
    rows = ProgressRows(bar)
    rows("diffdrive seed1: start race", 11, 11)
    rows("diffdrive seed1: EM iteration 322", 322, None)
    assert [(t.completed, t.total) for t in bar.tasks] == [(11, 11), (322, None)]
    rows("fit: EM", 30, 20)
    assert bar.tasks[-1].completed <= bar.tasks[-1].total


def test_at_80_columns_the_count_and_the_eta_stay_whole():
    out = io.StringIO()
    console = Console(file=out, width=80, force_terminal=True, color_system=None)
    with progress_bar(console) as progress:
        desc = "EM: log-likelihood -12345.6 (best -12340.1, 12 of 50 since) and more words to crowd it"
        progress(desc, 123, 400)
    text = re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", out.getvalue()).replace("\r", "\n")
    last = [ln for ln in text.splitlines() if "EM:" in ln][-1]
    assert len(last) <= 80 and "123/400" in last, last
    assert re.fullmatch(r"(\d+:\d\d:\d\d|-:--:--)", last.split()[-1]), last  # the ETA, whole


def test_several_experiments_get_one_overall_line_with_an_eta_from_the_pace(monkeypatch):
    import sensact.cli.reproduce as rep

    printed = []
    monkeypatch.setattr(rep.console, "print", lambda text, **kw: printed.append(text))
    overall = rep.Overall(["track1d", "field2d", "car"])
    now = [0.0]
    overall.t0, overall.clock = 0.0, lambda: now[0]
    overall.start("track1d")
    now[0] = 2 * 60 * rep.EXPECTED_MIN["track1d"]  # this machine at half the measured pace
    overall.start("field2d")
    left = 2 * (rep.EXPECTED_MIN["field2d"] + rep.EXPECTED_MIN["car"])
    assert "experiment 1 of 3: track1d" in printed[0]
    assert "experiment 2 of 3: field2d" in printed[1] and f"about {rep._minutes(left)} left" in printed[1]


def test_the_eta_is_the_rows_own_pace_whatever_its_total_did():
    """rich forgets its pace whenever a row's total changes, as EM's projection does each iteration: the
    ETA column reads the row's elapsed time over its count instead."""
    from sensact.cli.base import _remaining_column

    class Task:
        total, completed, elapsed = 300, 100, 50.0  # 0.5 s an iteration, 200 left

    assert str(_remaining_column().render(Task())) == "0:01:40"
    Task.total = None
    assert str(_remaining_column().render(Task())) == "-:--:--"
