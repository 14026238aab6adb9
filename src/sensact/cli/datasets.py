"""``sensact convert`` and ``sensact evaluate``: a public dataset to a log folder, and a learned model
scored against the dataset's own ground truth."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from sensact.cli.base import console, convert_app, evaluate_app, friendly
from sensact.cli.scores import print_truth_score

MRCLAM_CONFIG_HEADER = """The EM settings behind docs/em-real.md's MRCLAM results
(sensact.experiments.real.mrclam_config()), as the fields that differ from EMConfig's defaults.
Edit them for your robot (docs/em-real.md, section 2) and pass this file with --config;
--set overrides single fields."""


@convert_app.command("mrclam")
@friendly
def convert_mrclam(
    dataset: Annotated[Path, typer.Argument(help="An MRCLAM dataset folder, e.g. .../MRCLAM_Dataset6.")],
    robot: Annotated[int, typer.Option(help="Robot 1-5.")] = 1,
    out: Annotated[Path, typer.Option("--out", help="The log folder to write.")] = Path("mrclam_log"),
    dt: Annotated[float, typer.Option(help="Step (s); commands are held between their rows.")] = 1.0 / 30.0,
) -> None:
    """Write one MRCLAM robot as an EM log folder, with its EM settings in em_config.yaml.

    Commands are resampled with a zero-order hold; only landmark sightings are kept (range in mm and
    bearing); the landmark map goes into meta.json and Vicon into groundtruth.csv (for `sensact learn
    em` to score against; it is never learned from)."""
    from sensact.config import config_to_yaml
    from sensact.experiments.real import mrclam_config
    from sensact.io.atomic import write_text
    from sensact.io.landmark_log import write_landmark_log
    from sensact.io.mrclam import read_mrclam

    ml = read_mrclam(dataset, robot, dt_s=dt)
    console.print(ml.summary_line())
    write_landmark_log(
        out,
        ml.data,
        t0_s=0.0,
        groundtruth=ml.groundtruth,
        meta_extra={"source": {"dataset": str(dataset), "robot": robot, "t0_s": ml.t0_s, "rows": ml.summary}},
    )
    cfg = out / "em_config.yaml"
    write_text(cfg, config_to_yaml(mrclam_config(), MRCLAM_CONFIG_HEADER))
    console.print(f"wrote {out} and its EM settings {cfg}; learn with `sensact learn em {out} --config {cfg}`")


@evaluate_app.command("mrclam")
@friendly
def evaluate_mrclam_cmd(
    dataset: Annotated[Path, typer.Argument(help="An MRCLAM dataset folder, e.g. .../MRCLAM_Dataset6.")],
    model: Annotated[Path, typer.Option("--model", help="A model.json written by `sensact learn em`.")],
    robot: Annotated[int, typer.Option(help="Robot 1-5.")] = 1,
    out: Annotated[
        Path | None,
        typer.Option("--out", help="Write the scores here (JSON), and four figures beside it (OUT_actions.png, ...)."),
    ] = None,
) -> None:
    """Score a learned MRCLAM model against Vicon, next to From-Truth.

    From-Truth is the same model families fitted directly to the ground truth. With --out, also draw
    the action curves, the range function, the heading noise and the bearing noise against Vicon's,
    as `reproduce real` does."""
    import json

    from sensact.errors import ModelFormatError
    from sensact.evaluate.landmark_truth import score_against_truth
    from sensact.experiments.real import bar_checks
    from sensact.io.atomic import write_json
    from sensact.io.mrclam import read_mrclam
    from sensact.models.em_model import EMModel

    if not model.is_file():
        raise ModelFormatError("file not found.", file=model, fix="give the model.json `sensact learn em` wrote.")
    doc = json.loads(model.read_text())
    m = EMModel.from_dict(doc.get("model", doc), source=str(model))
    ml = read_mrclam(dataset, robot, dt_s=float(doc.get("dt_s", 1.0 / 30.0)))
    sc = score_against_truth(m, ml.data, *ml.truth_poses())
    sc["bars"] = bar_checks(sc)
    print_truth_score(sc)
    if out is not None:
        from sensact.report.figures_real import write_robot

        write_json(out, sc)
        figures = write_robot(ml, m, sc, out.with_suffix(""), f"robot {robot}")
        console.print("wrote " + ", ".join(str(p) for p in (out, *figures)))
