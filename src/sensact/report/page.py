"""One self-contained HTML page for one calibration (``MODEL.report.html`` beside it, ``report_path``): sections of
paragraphs, tables, flags and figures, every figure inlined as a data URI, no script and no link out, so
that the page opens offline, mailed or copied on its own."""

from __future__ import annotations

import base64
import html
from dataclasses import dataclass
from pathlib import Path

from sensact.io.atomic import write_text
from sensact.report.html_report import STYLE

PAGE_STYLE = (
    STYLE
    + """
.flags li { color: #8a5a00; }
.ok { color: #276b2e; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
"""
)


@dataclass(frozen=True)
class Section:
    title: str
    paragraphs: tuple[str, ...] = ()
    table: tuple[tuple[str, ...], tuple[tuple[str, ...], ...]] | None = None  # header, rows
    flags: tuple[str, ...] = ()  # warnings: shown as a list, "none" when empty and ``flag_list`` is set
    flag_list: bool = False
    figures: tuple[tuple[Path, str], ...] = ()  # (a PNG, its caption)


def report_path(model: Path) -> Path:
    """Where a model's report goes: named after the model, so that two models in one folder never share a
    page (``run_a.json`` -> ``run_a.report.html``), ``report.html`` for the usual ``model.json``."""
    return model.with_name("report.html" if model.name == "model.json" else f"{model.stem}.report.html")


def _image(png: Path) -> str:
    data = base64.b64encode(png.read_bytes()).decode("ascii")
    return f'<img src="data:image/png;base64,{data}" alt="{html.escape(png.stem)}">'


def _table(header: tuple[str, ...], rows: tuple[tuple[str, ...], ...]) -> str:
    def cell(text: str, tag: str) -> str:
        numeric = tag == "td" and text.replace(".", "", 1).replace("-", "", 1).replace("e", "", 1).isdigit()
        return f"<{tag}{' class=num' if numeric else ''}>{html.escape(text)}</{tag}>"

    head = "".join(cell(h, "th") for h in header)
    body = "".join("<tr>" + "".join(cell(c, "td") for c in row) + "</tr>" for row in rows)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def _section(s: Section) -> str:
    parts = [f"<h2>{html.escape(s.title)}</h2>"]
    parts += [f"<p>{html.escape(p)}</p>" for p in s.paragraphs]
    if s.table is not None:
        parts.append(_table(*s.table))
    if s.flags:
        parts.append('<ul class="flags">' + "".join(f"<li>{html.escape(f)}</li>" for f in s.flags) + "</ul>")
    elif s.flag_list:
        parts.append('<p class="ok">No flag raised.</p>')
    for png, caption in s.figures:
        if png.is_file():
            parts.append(f"<figure>{_image(png)}<figcaption>{html.escape(caption)}</figcaption></figure>")
    return "<section>" + "".join(parts) + "</section>"


def write_report(path: Path, title: str, lead: str, sections: list[Section]) -> Path:
    """The page at ``path`` (written atomically)."""
    body = "".join(_section(s) for s in sections)
    page = (
        '<!DOCTYPE html><html lang="en"><head><meta charset="utf-8">'
        f"<title>{html.escape(title)}</title><style>{PAGE_STYLE}</style></head><body>"
        f"<h1>{html.escape(title)}</h1><p>{html.escape(lead)}</p>{body}</body></html>\n"
    )
    return write_text(path, page)
