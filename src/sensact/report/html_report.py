"""``RESULTS/index.html``: every experiment's tables and figures in a results folder on one page, so that
a reader sees the thesis's numbers, ours and the pictures behind them together.

It is built from the files the experiments wrote (``<name>.md`` tables, ``*.png`` figures), not from
the runs, so a folder filled by several ``sensact reproduce`` runs gets one page for all of them."""

from __future__ import annotations

import html
import json
from pathlib import Path

from sensact.evaluate.bars import BarCheck, checks_from_json, counts, miss_text
from sensact.io.atomic import write_text
from sensact.report.tables import Table

# (experiment, heading, the figure names that belong to it), in the thesis's order
SECTIONS: tuple[tuple[str, str, tuple[str, ...]], ...] = (
    ("track1d", "Chapter 3: learning S and A from each other, simulated (Table 3.1)", ("fig3_", "fig_degree")),
    ("turtlebot", "Chapter 3 on a real Turtlebot", ("turtlebot_",)),
    ("field2d", "Chapter 4: EM on the simulated field (secs. 4.4.1-4.4.2)", ("fig4_2", "fig4_3", "fig4_4", "fig4_5")),
    ("em1d", "Chapter 4: EM in one dimension (sec. 4.4.3)", ("fig4_6", "fig4_7")),
    ("monitor", "Beyond the thesis: noticing when a robot changes (sec. 4.4.3)", ("monitor_",)),
    ("car", "Chapter 5: a car and its HDL-64E (Table 5.1)", ("fig5_",)),
    ("diffdrive", "Beyond the thesis: EM on simulated differential drives (MRCLAM's settings)", ("diffdrive_",)),
    ("real", "Beyond the thesis: EM on real robots (MRCLAM, Turtlebot)", ("real_",)),
)

STYLE = """
body { font-family: system-ui, sans-serif; margin: 2em auto; max-width: 1200px; padding: 0 1em; color: #222; }
table { border-collapse: collapse; margin: 0.5em 0 1.5em; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: left; vertical-align: top; }
th { background: #f3f3f3; }
img { max-width: 100%; border: 1px solid #eee; margin: 0.5em 0; }
figure { margin: 0 0 1.5em; }
figcaption { font-size: 0.85em; color: #555; }
td.missed { color: #b00; font-weight: bold; }
"""
MISSED = ' class="missed"'


def tables_from_markdown(text: str) -> list[Table]:
    """The inverse of ``tables.to_markdown``: ``### title``, a header row, a separator, the rows."""
    tables: list[Table] = []
    lines = text.splitlines()
    i = 0
    while i < len(lines):
        if not lines[i].startswith("### "):
            i += 1
            continue
        title = lines[i][4:]
        i += 1
        while i < len(lines) and not lines[i].strip():
            i += 1
        rows = []
        while i < len(lines) and lines[i].startswith("|"):
            rows.append([c.strip() for c in lines[i].strip()[1:-1].split(" | ")])
            i += 1
        if len(rows) >= 2:  # a header and its separator at least
            tables.append((title, rows[0], rows[2:]))
    return tables


def folder_scorecards(out: Path) -> list[tuple[str, str, list[BarCheck]]]:
    """(experiment, heading, its bars) for every experiment in ``out`` whose JSON holds a ``scorecard``,
    in the thesis's order."""
    found = []
    for name, heading, _ in SECTIONS:
        path = out / f"{name}.json"
        if path.is_file():
            rows = json.loads(path.read_text(encoding="utf-8")).get("scorecard")
            if rows:
                found.append((name, heading, checks_from_json(rows)))
    return found


def _overview_html(cards: list[tuple[str, str, list[BarCheck]]]) -> str:
    """One row per experiment: its bars cleared, and each one missed."""
    rows = []
    for name, heading, checks in cards:
        missed = "<br>".join(html.escape(miss_text(c)) for c in checks if c.cleared is False) or "none"
        done, scored = counts(checks)
        rows.append(
            f'<tr><td><a href="#{name}">{html.escape(heading)}</a></td><td>{done} of {scored} cleared</td>'
            f"<td>{missed}</td></tr>"
        )
    return (
        "<h2>Bars</h2>\n<p>The bars are the thesis's published results (chapters 3-5) and, for the real robots, "
        "sensact's own (docs/em-real.md); each section below lists its own.</p>\n"
        f"<table><tr><th>experiment</th><th>bars</th><th>missed</th></tr>{''.join(rows)}</table>"
    )


def _table_html(table: Table) -> str:
    title, headers, rows = table
    head = "".join(f"<th>{html.escape(h)}</th>" for h in headers)
    body = "".join(
        "<tr>" + "".join(f"<td{MISSED if c == 'missed' else ''}>{html.escape(c)}</td>" for c in r) + "</tr>"
        for r in rows
    )
    return f"<h3>{html.escape(title)}</h3>\n<table><tr>{head}</tr>{body}</table>"


def write_html_report(out: Path) -> Path | None:
    """Write ``out/index.html`` from the experiments' files in ``out``; None when there are none."""
    sections, contents = [], []
    cards = folder_scorecards(out)
    for name, heading, prefixes in SECTIONS:
        md = out / f"{name}.md"
        if not md.is_file():
            continue
        figures = sorted(p.name for p in out.glob("*.png") if p.name.startswith(prefixes))
        links = " · ".join(
            f'<a href="{html.escape(f)}">{html.escape(f)}</a>'
            for f in (f"{name}.json", f"{name}.md")
            if (out / f).is_file()
        )
        parts = [f'<h2 id="{name}">{html.escape(heading)}</h2>', f"<p>{links}</p>"]
        parts += [_table_html(t) for t in tables_from_markdown(md.read_text(encoding="utf-8"))]
        parts += [
            f'<figure><img src="{html.escape(f)}" alt="{html.escape(f)}"><figcaption>{html.escape(f)}</figcaption>'
            "</figure>"
            for f in figures
        ]
        sections.append("\n".join(parts))
        contents.append(f'<li><a href="#{name}">{html.escape(heading)}</a></li>')
    if not sections:
        return None
    page = (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8"><title>sensact results</title>'
        f"<style>{STYLE}</style></head><body>\n<h1>sensact results</h1>\n"
        "<p>Each table sets the thesis's numbers (Stronger 2008) beside ours; the JSON beside each section "
        "holds every number and the configuration that produced it.</p>\n"
        f"<ul>{''.join(contents)}</ul>\n"
        + (_overview_html(cards) + "\n" if cards else "")
        + "\n".join(sections)
        + "\n</body></html>\n"
    )
    return write_text(out / "index.html", page)
