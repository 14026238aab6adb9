"""A calibration written out: the model JSON, EM's history and smoothed path as .npz, the figure of the fit
and, when the log has truth, the figures against it. Every write is atomic."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sensact.app.em import Calibration
from sensact.app.scores import Scores
from sensact.io.atomic import write_json, write_npz
from sensact.records import JsonObject

# the figures drawn against a log's truth (OUT_<kind>.png): recorded poses (report.figures_real.write_robot)
# or a 1-D robot's recorded distance; one an earlier run at the same OUT drew, and this run does not, is
# removed so that it cannot pass for this fit
TRUTH_FIGURES = ("actions", "range", "heading_noise", "bearing", "against_range", "path")


@dataclass(frozen=True)
class Saved:
    written: tuple[Path, ...]
    removed: tuple[Path, ...]  # an earlier run's figures at the same OUT against a truth this log does not have
    removed_halves: Path | None  # an earlier run's --halves figure
    not_drawn: tuple[str, ...] = ()  # a figure that failed, one line each: the model and the rest are written

    def __repr__(self) -> str:
        if not self.written:
            return "Saved(nothing)"
        head = f"Saved({self.written[0]} and {len(self.written) - 1} files beside it"
        return head + (f"; not drawn: {'; '.join(self.not_drawn)})" if self.not_drawn else ")")


def save_model(
    out: Path, doc: JsonObject, page: Callable[[], tuple[Path, list[str]]] | None, beside: tuple[Path, ...] = ()
) -> Saved:
    """A kind's model JSON at ``out``, the files already written ``beside`` it, and its report page (``page``
    draws it; None: no page), as the kinds learned in one fit save them."""
    written = [write_json(out, doc), *beside]
    not_drawn: list[str] = []
    if page is not None:
        drawn, not_drawn = page()
        written.append(drawn)
    return Saved(tuple(written), (), None, tuple(not_drawn))


def halves_figure(out: Path) -> Path:
    """Where `learn em --halves --out OUT.json` draws the halves: OUT_halves.png."""
    return out.with_name(f"{out.stem}_halves.png")


def write_smoothed_path(path: Path, posteriors: Any, data: Any) -> Path:
    """Where EM puts the robot at every step: the smoothed mean and sd of each state component (eqs. 4.9,
    4.10), for a user's own plots or as the robot's path; ``time_s`` counts from the log's first step."""
    names = data.geometry.state_names
    return write_npz(
        path,
        time_s=np.arange(data.n_steps) * data.dt_s,
        mean=posteriors.mean_gamma,
        sd=np.sqrt(np.diagonal(posteriors.cov_gamma, axis1=1, axis2=2)),
        state=np.array(names),
    )


def _page_and_figures(cal: Calibration, out: Path, written: list[Path]) -> list[Path]:
    from sensact.app.report import write_em_report

    page, figures = write_em_report(cal, out, written)
    return [*figures, page]


def save_em_calibration(
    cal: Calibration, out: str | Path, report: bool = True, *, document: JsonObject | None = None
) -> Saved:
    """``cal`` at ``out`` (its JSON, or ``document`` in its place), OUT.history.npz, OUT.path.npz, OUT.png,
    the figures against the log's truth and, with ``report``, report.html beside them (``app.report``); an
    earlier run's halves figure, and its figures against a truth this log does not have, removed."""
    out = Path(out)
    res, log = cal.result, cal.log
    write_json(out, document if document is not None else cal.to_json())
    failed: list[str] = []

    def drawn(draw: Callable[[], list[Path]]) -> list[Path]:
        """A figure is drawn after the model is written: one that fails is reported, never the run's end."""
        try:
            return draw()
        except Exception as exc:  # matplotlib on a degenerate fit (NaN limits, an empty panel)
            failed.append(f"{type(exc).__name__}: {exc}")
            return []

    write_npz(
        out.with_suffix(".history.npz"),
        loglik=res.loglik_history,
        velocities=res.velocity_history,
        sigmas=res.sigma_history,
    )
    written = [out, out.with_suffix(".history.npz")]
    if res.posteriors is not None:
        from sensact.report.figures_fit import figure_em_fit

        written.append(write_smoothed_path(out.with_suffix(".path.npz"), res.posteriors, log.data))
        written += drawn(lambda: [figure_em_fit(res, log.data, out.with_suffix(".png"), f"EM on {log.name}")])
    scores = cal.scores.evaluation if isinstance(cal.scores, Scores) else None
    if scores is not None and scores.get("truth_noise") and log.folder is not None:  # against recorded poses
        from sensact.report.figures_real import write_robot

        folder, posteriors = cal.in_truth_frame  # on a learned map: its survey, and the path aligned to it
        written += drawn(
            lambda: write_robot(
                folder, cal.model, scores, out.with_suffix(""), log.name, posteriors, truth="ground truth"
            )
        )
    elif scores is not None and log.recorded_distance_mm is not None:  # against a recorded distance
        from sensact.evaluate.turtlebot_em import TurtlebotEMRun
        from sensact.report.figures_turtlebot_em import figure_turtlebot_em

        run = TurtlebotEMRun(log.data, log.recorded_distance_mm, res)
        path = out.with_name(f"{out.stem}_against_range.png")
        written += drawn(lambda: [figure_turtlebot_em(run, scores, path, f"EM on {log.name}")])
    if report:
        written += drawn(lambda: _page_and_figures(cal, out, written))
    stale = [
        p for kind in TRUTH_FIGURES if (p := out.with_name(f"{out.stem}_{kind}.png")).exists() and p not in written
    ]
    halves = halves_figure(out)
    earlier_halves = halves if halves.exists() else None  # this run's, if any, is drawn after the halves
    for p in [*stale, *([earlier_halves] if earlier_halves else [])]:
        p.unlink()
    return Saved(tuple(written), tuple(stale), earlier_halves, tuple(failed))
