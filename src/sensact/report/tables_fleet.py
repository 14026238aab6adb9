"""A fleet's tables (``app.fleet.score_fleet``): every model on every log, a row per model and a
column per log, against the truth, against a Turtlebot CSV's range column, and by the likelihood, with the
lines that say what each table shows."""

from __future__ import annotations

from collections.abc import Callable

from sensact.records import JsonObject
from sensact.report.tables import Table, bars_sentence, one_command_reason

FLEET_TITLE = "translation / rotation RMS over From-Truth's, range residual about the truth, bearing sigma ratio"
FLEET_BARS = {  # a fleet cell's part and the bars it answers to (experiments.real.robot_checks)
    "translation": ("action_translation_ratio", "action_translation_abs"),
    "rotation": ("action_rotation_ratio",),
    "bearing": ("bearing_sigma",),
}


def fleet_table(
    fleet: JsonObject,
    title: str = FLEET_TITLE,
    miss: Callable[[str], str] = lambda s: f"{s} (miss)",
    own: Callable[[str], str] = lambda s: f"**{s}**",
) -> Table:
    """``app.fleet.score_fleet``'s pairs, a row per model and a column per log, and From-Truth's
    range residual per log; ``miss`` marks a number that misses its bar, ``own`` a robot's own pair (the
    console passes colour, Markdown the defaults)."""

    def cell(m: str, g: str) -> str:
        c = fleet["cells"][m][g]

        def shown(text: str, part: str) -> str:
            return text if all(c["bars"][b] for b in FLEET_BARS[part]) else miss(text)

        tr, rot = (f"{c[k]:.2f}" for k in ("translation_ratio", "rotation_ratio"))
        b = c["bearing_sigma_ratio"]
        text = f"{shown(tr, 'translation')} / {shown(rot, 'rotation')}, {c['range_residual_rms_mm']:.0f} mm, " + (
            "no bearing" if b is None else shown(f"{b:.2f}", "bearing")
        )
        return own(text) if fleet["own"].get(m) == g else text

    first = fleet["models"][0]
    rows = [[m, *(cell(m, g) for g in fleet["logs"])] for m in fleet["models"]]
    rows.append(
        ["From-Truth", *(f"{fleet['cells'][first][g]['range_from_truth_rms_mm']:.0f} mm" for g in fleet["logs"])]
    )
    return title, ["model \\ log", *fleet["logs"]], rows


def fleet_lines(fleet: JsonObject) -> list[str]:
    """What the fleet table says over the robots' own pairs and over the others."""
    lines = [
        f"bars: {bars_sentence(fleet['bars'])}; the range residual has no bar (From-Truth's, the last row, is its "
        "floor)"
    ]
    for group, s in fleet["summary"].items():
        if not s["pairs"]:
            continue
        lo, hi = s["range_residual_rms_mm"]
        who = "a robot's own model" if group == "own" else "another robot's model" if fleet["own"] else "every pair"
        lines.append(
            f"{who} ({s['pairs']} pairs): {s['clear_action_bars']} clear the action bars "
            f"(worst translation {s['translation_ratio_max']:.2f}, rotation {s['rotation_ratio_max']:.2f}), "
            f"{s['clear_range_sigma_bar']} the range sigma bar, {s['clear_bearing_sigma_bar']} the bearing sigma "
            "bar"
            + (
                f" (of the {s['bearing_pairs']} pairs whose model reads bearings)"
                if s.get("bearing_pairs", s["pairs"]) < s["pairs"]
                else ""
            )
            + f"; range residual {lo:.0f}-{hi:.0f} mm"
        )
    return lines


FLEET_LIKELIHOOD_TITLE = (
    "log-likelihood a sighting, each model placed on each log by the E-step alone (no ground truth); in brackets, "
    "how far below the log's most likely model"
)


def fleet_likelihood_table(
    fleet: JsonObject, title: str = FLEET_LIKELIHOOD_TITLE, own: Callable[[str], str] = lambda s: f"**{s}**"
) -> Table:
    """``app.fleet.likelihood_grid``'s pairs, a row per model and a column per log, and the
    sightings each log's likelihood is over; ``own`` marks a robot's own pair."""
    lk = fleet["likelihood"]

    def cell(m: str, g: str) -> str:
        c = lk["cells"][m][g]
        if c["per_sighting"] is None:
            text = "the filter failed"
        else:
            below = c["below_best"]
            text = f"{c['per_sighting']:.3f} ({'most likely' if below == 0 else f'{below:.3f} below'})"
            if not c["filter_ok"]:
                text += ", the filter lost positive definiteness"
        return own(text) if fleet["own"].get(m) == g else text

    def used(g: str) -> str:
        n = sorted(
            {lk["cells"][m][g]["n_used"] for m in fleet["models"] if lk["cells"][m][g]["per_sighting"] is not None}
        )
        return "-" if not n else str(n[0]) if len(n) == 1 else f"{n[0]}-{n[-1]}"

    rows = [[m, *(cell(m, g) for g in fleet["logs"])] for m in fleet["models"]]
    rows.append(["sightings used", *(used(g) for g in fleet["logs"])])
    return title, ["model \\ log", *fleet["logs"]], rows


def fleet_likelihood_lines(fleet: JsonObject) -> list[str]:
    """What the likelihood table says: whether each log's own model is its most likely, and how close the
    best of the others comes on each log."""
    lk = fleet["likelihood"]
    s = lk["summary"]
    lines = []
    if s["logs_with_own"]:
        lines.append(
            f"by the likelihood (no ground truth): on {s['own_most_likely']} of {s['logs_with_own']} logs the "
            "robot's own model is the most likely (it has a small edge there, having been fitted to those sightings)"
        )
    owner = {g: m for m, g in fleet["own"].items()}
    found = [(g, p) for g, p in s["per_log"].items() if p["closest_other"] is not None]

    def closest_cell(g: str, p: JsonObject, first: bool) -> str:
        own_below = lk["cells"][owner[g]][g]["below_best"] if g in owner else None
        if p["closest_other_below"] == 0 and own_below:  # another model explains the run better than its own
            return f"{p['closest_other']} on {g} (the most likely: {owner[g]}, its own, {own_below:.3f} below)"
        return f"{p['closest_other']} on {g} ({p['closest_other_below']:.3f}{' a sighting below' if first else ''})"

    closest = [closest_cell(g, p, i == 0) for i, (g, p) in enumerate(found)]  # the unit said once, on the first
    if closest:
        lines.append(
            ("the closest other model on each log: " if fleet["own"] else "the runner-up on each log: ")
            + ", ".join(closest)
        )
    beaten = [
        (g, p["closest_other"])
        for g, p in found
        if g in owner and p["closest_other_below"] == 0 and lk["cells"][owner[g]][g]["below_best"]
    ]
    if beaten:  # the log's own fit is not the most likely one: EM from the better model may find a likelier own
        lines.append(
            "a log's own model that another beats may be learned again from that one ("
            + ", ".join(f"{g} from {m}'s" for g, m in beaten)
            + "): sensact learn em LOG --start-from MODEL.json"
        )
    failed = [
        f"{m} on {g}: {c['failed']}"
        for m, row in lk["cells"].items()
        for g, c in row.items()
        if c["per_sighting"] is None
    ]
    return lines + [f"not placed: {f}" for f in failed]


FLEET_RANGE_TITLE = (
    "each model placed on each Turtlebot CSV and scored against its range column (optimal scale and offset, "
    "sec. 4.4.3): the action gain's error; the best sensor's, in % of its span"
)


def fleet_range_table(
    fleet: JsonObject,
    title: str = FLEET_RANGE_TITLE,
    miss: Callable[[str], str] = lambda s: f"{s} (miss)",
    own: Callable[[str], str] = lambda s: f"**{s}**",
) -> Table:
    """``app.fleet.range_grid``'s pairs, a row per model and a column per CSV with its range; ``miss``
    marks a number past its bar, ``own`` a robot's own pair."""
    rng = fleet["range"]

    def cell(m: str, g: str) -> str:
        c = rng["cells"][m][g]
        if "failed" in c:
            return "the filter failed"
        if c["gain_error_pct"] is None:
            gain = f"gain {one_command_reason(c['one_command_share'])}"
        else:
            gain = f"gain {c['gain_error_pct']:.2f} % off"
            gain = gain if c["bars"]["gain"] else miss(gain)
        if c["best_sensor"] is None:
            sensor = "no sensor scored"
        else:
            sensor = f"{c['best_sensor']} {c['best_sensor_pct']:.2f} %"
            sensor = sensor if c["bars"]["sensor"] else miss(sensor)
        text = f"{gain}, {sensor}"
        return own(text) if fleet["own"].get(m) == g else text

    rows = [[m, *(cell(m, g) for g in rng["logs"])] for m in fleet["models"]]
    return title, ["model \\ log", *rng["logs"]], rows


def fleet_range_lines(fleet: JsonObject) -> list[str]:
    """What the range table says over the robots' own pairs and over the others, and which Turtlebot CSVs
    could not be scored against their range."""
    rng = fleet.get("range")
    if not rng:
        return []
    lines = []
    if rng["logs"]:
        b = rng["bars"]
        lines.append(
            f"bars: the action gain within {b['gain_pct_max']:g} % of the range's, the best sensor within "
            f"{b['sensor_pct_max']:g} % of its span"
        )
    for group, s in rng["summary"].items():
        if not s["pairs"]:
            continue
        who = "a robot's own model" if group == "own" else "another robot's model" if fleet["own"] else "every pair"
        gains = (
            f"{s['clear_gain_bar']} of the {s['gain_scored']} with a scored gain clear the gain bar (worst "
            f"{s['gain_error_pct_max']:.2f} % off)"
            if s["gain_scored"]
            else "no gain scored"
        )
        lines.append(f"{who} ({s['pairs']} pairs): {gains}, {s['clear_sensor_bar']} the sensor bar")
    if rng["no_range"]:
        lines.append("not scored against the range: " + ", ".join(f"{g} ({why})" for g, why in rng["no_range"].items()))
    return lines
